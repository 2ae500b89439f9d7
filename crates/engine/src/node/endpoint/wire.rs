//! A node's two ends of the wire: what it sends (addressed to each receiver and numbered on its link; sealed for it
//! under the link's key when the run is authenticated) and what it accepts (checked, and authenticated against each
//! source's replay window), with the rejections counted by cause.

use bytes::Bytes;
use serde::{Deserialize, Serialize};

use crate::medium::Dest;
use crate::wire::secure::{Key, Opener, Rejected, Sealer, OVERHEAD};
use crate::wire::{Datagram, Header, WireError, BROADCAST};

/// Datagrams refused by authentication, by cause (zero in an unauthenticated run).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Rejections {
    /// The checksum held but no tag verified: forged, tampered with on the way, sent unsealed, or sealed for
    /// another node or another boot of this one (a redirect; an earlier run's datagram replayed).
    pub bad_tag: u64,
    /// A counter accepted before (an attacker's replay, or a link's duplicate copy).
    pub replay: u64,
    /// An earlier boot of the source, or a counter below its window.
    pub too_old: u64,
    /// A source this node does not hear from.
    pub unknown_source: u64,
}

impl Rejections {
    pub fn total(&self) -> u64 {
        self.bad_tag + self.replay + self.too_old + self.unknown_source
    }

    pub fn add(&mut self, o: &Rejections) {
        self.bad_tag += o.bad_tag;
        self.replay += o.replay;
        self.too_old += o.too_old;
        self.unknown_source += o.unknown_source;
    }
}

/// What a datagram turned out to be, when it is not accepted.
pub(super) enum Refused {
    /// The link's bit flip, caught by the checksum.
    Corrupted,
    Malformed(WireError),
    /// Refused by authentication (already counted in [`Rejections`]).
    Rejected(Rejected),
}

/// The node's sending and receiving ends.
pub(super) struct Wire {
    id: u32,
    /// By receiver id, the sequence number the next datagram to it takes (duplicates share one).
    seqs: Vec<(u32, u32)>,
    key: Option<Key>,
    /// This boot's epoch: each restart takes the next.
    epoch: u64,
    sealer: Option<Sealer>,
    opener: Option<Opener>,
    pub rejected: Rejections,
}

impl Wire {
    /// Node `id`'s ends; sealed under `key` from boot `epoch` when the run is authenticated.
    pub fn new(id: u32, key: Option<&Key>, epoch: u64) -> Wire {
        Wire {
            id,
            seqs: Vec::new(),
            key: key.cloned(),
            epoch,
            sealer: key.map(|k| Sealer::new(k, id, epoch)),
            opener: key.map(|k| Opener::new(k, id, epoch)),
            rejected: Rejections::default(),
        }
    }

    /// Boot from `epoch` (a process's boot time, or a run's in one process): no earlier boot of this node may have
    /// had it or a larger one. What neighbours seal for this node is bound to it until the next boot.
    pub fn boot(&mut self, epoch: u64) {
        self.epoch = epoch;
        if let Some(k) = &self.key {
            self.sealer = Some(Sealer::new(k, self.id, epoch));
            self.opener = Some(Opener::new(k, self.id, epoch));
        }
    }

    /// A restart inside a run (one process): the next epoch, every link's counter from 0 under its own key, so that
    /// no nonce is used twice. The neighbours keep sealing for the boot they know.
    pub fn reboot(&mut self) {
        self.epoch += 1;
        if let Some(k) = &self.key {
            self.sealer = Some(Sealer::new(k, self.id, self.epoch));
        }
    }

    pub fn id(&self) -> u32 {
        self.id
    }

    /// The epoch this boot seals under; none unauthenticated.
    pub fn sealing_epoch(&self) -> Option<u64> {
        self.sealer.as_ref().map(Sealer::epoch)
    }

    /// The sequence number of the next datagram to node `to` (then counted taken).
    fn next_seq(&mut self, to: u32) -> u32 {
        let i = match self.seqs.iter().position(|(id, _)| *id == to) {
            Some(i) => i,
            None => {
                self.seqs.push((to, 0));
                self.seqs.len() - 1
            }
        };
        let seq = self.seqs[i].1;
        self.seqs[i].1 = seq.wrapping_add(1);
        seq
    }

    /// `d` (its header's destination and sequence number left to this end) as bytes on the wire for node `to`,
    /// whose boot this node knows as `to_boot`: addressed to it, numbered on its link, and sealed for that node and
    /// boot when the run is authenticated.
    pub fn encode(&mut self, d: &Datagram, to: u32, to_boot: u64) -> Result<Bytes, WireError> {
        let header = Header {
            dst: to,
            seq: self.next_seq(to),
            ..d.header
        };
        match &mut self.sealer {
            Some(s) => s.seal_parts(&header, &d.payload, to, to_boot),
            None => Datagram::encode_parts(&header, &d.payload),
        }
    }

    /// Whether `d` fits a datagram on every link, whatever its receiver and sequence number: a message sent to some
    /// neighbours and not others would be a fault no medium chose.
    pub fn fits(&self, d: &Datagram) -> Result<(), WireError> {
        // The largest id and sequence number: five bytes each on the wire (a broadcast takes one).
        let longest = Header {
            dst: BROADCAST - 1,
            seq: u32::MAX,
            ..d.header
        };
        let len = Datagram::encoded_len(&longest, &d.payload)? + if self.sealer.is_some() { OVERHEAD } else { 0 };
        if len > crate::wire::MAX_DATAGRAM {
            return Err(WireError::TooLong(len));
        }
        Ok(())
    }

    /// Checked (and, when authenticated, opened) bytes from a source `known(src)` accepts, with the epoch the
    /// source sealed them under (none unauthenticated).
    pub fn decode(&mut self, bytes: &[u8], known: impl Fn(u32) -> bool) -> Result<(Datagram, Option<u64>), Refused> {
        let Some(o) = &mut self.opener else {
            return Datagram::decode(bytes).map(|d| (d, None)).map_err(|e| match e {
                WireError::Checksum => Refused::Corrupted,
                e => Refused::Malformed(e),
            });
        };
        o.open(bytes, known).map(|(d, epoch, _)| (d, Some(epoch))).map_err(|r| {
            let c = &mut self.rejected;
            match r {
                Rejected::Corrupted(_) => return Refused::Corrupted,
                // Unsealed where every datagram must carry a tag.
                Rejected::Malformed(WireError::Flags(0)) => c.bad_tag += 1,
                Rejected::Malformed(e) => return Refused::Malformed(e),
                Rejected::BadTag => c.bad_tag += 1,
                Rejected::Replay { .. } => c.replay += 1,
                Rejected::TooOld { .. } => c.too_old += 1,
                Rejected::UnknownSource(_) => c.unknown_source += 1,
            }
            Refused::Rejected(r)
        })
    }
}

/// Sending: one broadcast to every out-neighbour, or (when the run is authenticated: each link has its own key) one
/// transmission to each, addressed to it and sealed for it.
impl super::Endpoint {
    /// `ds` as bytes, with whom they are for: one broadcast unsealed, else one unicast per out-link (every
    /// destination listed, its bytes empty when `ds` is). A round's message counts towards its scheme's traffic once
    /// per out-link either way.
    pub(super) fn addressed(&mut self, ds: &[Datagram]) -> Vec<(Dest, Vec<Bytes>)> {
        if self.outs.is_empty() {
            return Vec::new();
        }
        if self.wire.sealing_epoch().is_none() {
            let bytes = self.encode_for(BROADCAST, 0, self.outs.len(), ds);
            return vec![(Dest::Broadcast, bytes)];
        }
        (0..self.outs.len())
            .map(|li| {
                let j = self.outs[li];
                let (to, boot) = (self.topo.nodes()[j].id, self.boot_of(j));
                (Dest::Node(j), self.encode_for(to, boot, 1, ds))
            })
            .collect()
    }

    /// The boot node `j` is bound to in what this node seals for it: its boot as its hellos give it (one node per
    /// process; 0 before the first, which it refuses), or the run's boot that every node of an in-process run
    /// shares.
    pub(super) fn boot_of(&self, j: usize) -> u64 {
        if self.handshake {
            self.session.boot(j).unwrap_or(0)
        } else {
            self.booted
        }
    }

    /// `ds` as bytes for node id `to` (or [`BROADCAST`]) of boot `boot`, reaching `links` out-links.
    fn encode_for(&mut self, to: u32, boot: u64, links: usize, ds: &[Datagram]) -> Vec<Bytes> {
        let mut out = Vec::with_capacity(ds.len());
        for d in ds {
            match self.wire.encode(d, to, boot) {
                Ok(b) => {
                    if d.header.kind == crate::wire::KIND_ROUND {
                        self.schemes.count_sent(d.header.scheme, b.len(), links);
                    }
                    out.push(b);
                }
                Err(e) => tracing::error!(node = self.id, "cannot encode a datagram: {e}"),
            }
        }
        out
    }
}
