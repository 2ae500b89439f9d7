//! What a node's radio did over a run.

/// Per-node figures of the channel.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RadioCounters {
    /// Frames sent.
    pub frames: u64,
    /// Time on the air sending, ns.
    pub airtime_ns: u64,
    /// Frames abandoned after macMaxCSMABackoffs busy assessments.
    pub csma_failures: u64,
    /// Busy assessments.
    pub busy: u64,
    /// ACK frames it sent (their airtime is in `airtime_ns`).
    pub acks: u64,
    /// Frames it sent again for want of an ACK.
    pub retries: u64,
    /// Unicast messages it gave up after macMaxFrameRetries retries without an ACK.
    pub no_ack: u64,
    /// When its last frame left the air, ns (a run's last step flushes what is queued: this may be past its end).
    pub last_end_ns: u64,
}
