//! Acknowledged unicast (IEEE 802.15.4-2020 §6.7.4): a receiver that gets a unicast frame intact answers, a
//! turnaround after it ends, with a 5-octet ACK frame (no CSMA/CA) that is on the air like any other frame; the
//! sender that hears no ACK within macAckWaitDuration sends the frame again, through CSMA/CA, up to
//! macMaxFrameRetries times, then gives the message up. A frame received twice (its ACK lost) is delivered once.

use std::time::Duration;

use super::*;

/// An ACK frame's PSDU: frame control 2, sequence number 1, FCS 2 octets.
pub const ACK_PSDU: u32 = 5;

/// How long after its frame ends a sender waits for the ACK: macAckWaitDuration = aUnitBackoffPeriod (20) +
/// aTurnaroundTime (12) + phySHRDuration (10) + 6 octets × 2 symbols = 54 symbols (as ns-3's
/// `GetMacAckWaitDuration`).
pub const ACK_WAIT: Duration = Duration::from_micros(54 * 16);

/// A sender waiting for the ACK of the frame at the head of its queue.
#[derive(Debug, Clone, Copy)]
pub(super) struct Awaiting {
    /// The frame left the air.
    pub(super) data_end: Time,
    /// Its receiver's ACK, if it sent one.
    pub(super) ack: Option<u64>,
}

impl RadioMedium {
    /// Whether a frame to `to` is acknowledged.
    pub(super) fn acknowledged(&self, to: Dest) -> bool {
        self.radio.max_frame_retries.is_some() && matches!(to, Dest::Node(_))
    }

    /// Receiver `j` got sender `i`'s frame of `message` intact as it ended at `t`: its ACK, on the air after the
    /// turnaround; when it ends, and the frame.
    pub(super) fn send_ack(&mut self, j: usize, i: usize, message: u64, t: Time) -> (Time, u64) {
        let start = t + csma::TURNAROUND;
        let end = start + phy::airtime(ACK_PSDU);
        self.nodes[j].acks += 1;
        self.nodes[j].airtime_ns += end.since(start).as_nanos() as u64;
        self.nodes[j].last_end_ns = self.nodes[j].last_end_ns.max(end.as_nanos());
        let seq = self.put_on_air(j, (start, end), (message, Dest::Node(i), None));
        (end, seq)
    }

    /// Sender `i`'s wait for the ACK of the frame at the head of its queue ends at `t` (as the ACK ends, or
    /// macAckWaitDuration after the frame when none came): done, sent again, or given up.
    pub(super) fn ack_wait(&mut self, i: usize, t: Time) {
        let Some(w) = self.macs[i].awaiting.take() else {
            self.macs[i].next = Next::Idle;
            return;
        };
        let head = self.macs[i].queue.front().cloned().expect("a frame awaiting its ACK");
        let Dest::Node(j) = head.to else {
            unreachable!("only unicasts are acknowledged")
        };
        let ack = w.ack.and_then(|seq| self.air_index(seq));
        let got = ack.is_some_and(|m| {
            let success = match self.reception(m, i) {
                Reception::Locked { success, .. } => success,
                _ => 0.0,
            };
            rand::Rng::gen::<f64>(&mut self.fates[i]) < success
        });
        let retries = self.radio.max_frame_retries.unwrap_or(0);
        let mac = &mut self.macs[i];
        mac.next = Next::Idle;
        if got {
            mac.queue.pop_front();
            mac.free_at = t + ifs(head.psdu);
            if head.bytes.is_some() {
                self.delivered.remove(&(head.message, j));
                self.down.remove(&(head.message, j));
            }
            return;
        }
        mac.free_at = w.data_end + ACK_WAIT;
        if head.retries < retries {
            mac.queue.front_mut().expect("the head").retries += 1;
            self.nodes[i].retries += 1;
            return;
        }
        // Given up: the frame, and with it the rest of its message.
        while mac.queue.front().is_some_and(|r| r.message == head.message) {
            mac.queue.pop_front();
        }
        self.nodes[i].no_ack += 1;
        let delivered = self.delivered.remove(&(head.message, j));
        if !self.down.remove(&(head.message, j)) && !delivered {
            self.links[i].entry(j).or_default().lost_random += 1;
        }
    }
}

/// The interframe spacing after a frame of `psdu` octets: long (40 symbols) over aMaxSIFSFrameSize (18 octets),
/// short (12) else.
pub(super) fn ifs(psdu: u32) -> Duration {
    if psdu > 18 {
        csma::SYMBOL * 40
    } else {
        csma::SYMBOL * 12
    }
}
