//! What stands between the medium and one receiver, in the manner of smoltcp's `FaultInjector` around a device:
//! the receiver hands it each datagram that reaches it and each step it begins, puts what the stage adds through
//! its whole receive path ahead of them, and tells it what became of each. The receiver knows nothing of what the
//! stage is; the scenario's outsiders ([`crate::attack::Air`]) are one.

use bytes::Bytes;
use serde::{Deserialize, Serialize};

use crate::time::Time;

/// A stage in front of one receiver that can add datagrams to what reaches it.
pub trait Ingress: Send {
    /// A datagram from `from` (none: an address no neighbour has) reaches the receiver at `t`: what to take ahead
    /// of it.
    fn on_arrival(&mut self, t: Time, from: Option<usize>, bytes: &[u8]) -> Vec<Injection>;
    /// The receiver begins a step at `t`, `dt` seconds long: what to take as it does.
    fn on_step(&mut self, t: Time, dt: f64) -> Vec<Injection>;
    /// What the receiver made of one datagram of source `source` ([`Injection::attack`]): a tally of one.
    fn on_fate(&mut self, source: usize, fate: &Tally);
    /// What each source sent and what became of it, by source.
    fn tallies(&self) -> Vec<(usize, Tally)>;
}

/// Why an injected datagram was refused.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Refusals {
    /// The authentication tag failed (forged or tampered with, on a sealed network).
    pub bad_tag: u64,
    /// A counter already accepted.
    pub replay: u64,
    /// Below the receiver's replay window, or an earlier boot.
    pub too_old: u64,
    /// A source the receiver does not hear from.
    pub unknown_source: u64,
    /// Not a datagram (garbage), or a datagram naming the wrong source.
    pub malformed: u64,
    /// The checksum failed.
    pub corrupted: u64,
    /// A step the receiver could not be running.
    pub implausible_step: u64,
    /// From an address no neighbour has.
    pub unknown_address: u64,
}

impl Refusals {
    /// Every refusal.
    pub fn total(&self) -> u64 {
        self.bad_tag
            + self.replay
            + self.too_old
            + self.unknown_source
            + self.malformed
            + self.corrupted
            + self.implausible_step
            + self.unknown_address
    }

    /// Add `o`'s counts (saturating).
    pub fn add(&mut self, o: &Refusals) {
        self.bad_tag = self.bad_tag.saturating_add(o.bad_tag);
        self.replay = self.replay.saturating_add(o.replay);
        self.too_old = self.too_old.saturating_add(o.too_old);
        self.unknown_source = self.unknown_source.saturating_add(o.unknown_source);
        self.malformed = self.malformed.saturating_add(o.malformed);
        self.corrupted = self.corrupted.saturating_add(o.corrupted);
        self.implausible_step = self.implausible_step.saturating_add(o.implausible_step);
        self.unknown_address = self.unknown_address.saturating_add(o.unknown_address);
    }

    /// The causes with a count, for a table.
    pub fn causes(&self) -> Vec<(&'static str, u64)> {
        [
            ("bad tag", self.bad_tag),
            ("replay", self.replay),
            ("too old", self.too_old),
            ("unknown source", self.unknown_source),
            ("malformed", self.malformed),
            ("checksum", self.corrupted),
            ("implausible step", self.implausible_step),
            ("unknown address", self.unknown_address),
        ]
        .into_iter()
        .filter(|(_, n)| *n > 0)
        .collect()
    }
}

/// What became of one attack's datagrams.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Tally {
    /// Datagrams the attack put on the air.
    pub sent: u64,
    /// Accepted and taken as a step's data (a measurement nothing had delivered yet).
    pub used: u64,
    /// Accepted, but nothing new: a duplicate, a closed step, or a node that was down.
    pub ignored: u64,
    /// Refused, by cause.
    pub rejected: Refusals,
}

impl Tally {
    /// Used or ignored: the datagrams the node did not refuse.
    pub fn accepted(&self) -> u64 {
        self.used + self.ignored
    }

    /// Add `o`'s counts (saturating).
    pub fn add(&mut self, o: &Tally) {
        self.sent = self.sent.saturating_add(o.sent);
        self.used = self.used.saturating_add(o.used);
        self.ignored = self.ignored.saturating_add(o.ignored);
        self.rejected.add(&o.rejected);
    }
}

/// A datagram a stage adds (an outsider puts on the air): `from` is the address it arrives with (the claimed
/// source's, or none).
#[derive(Debug, Clone)]
pub struct Injection {
    /// Its source in the stage: for the scenario's outsiders, the attack's index in the scenario.
    pub attack: usize,
    /// The node whose address it arrives with (none: an address no neighbour has).
    pub from: Option<usize>,
    /// The datagram.
    pub bytes: Bytes,
}
