//! One shared IEEE 802.15.4 channel as a [`Medium`]: every node a radio at its place in the [`World`], every datagram
//! one or more frames ([`super::frame`]) that each sender's MAC puts on the air by unslotted CSMA/CA
//! ([`super::csma`]) over one agenda of every sender's next step (`access.rs`), every frame heard by every node in
//! range at the power the path loss leaves ([`super::phy`]; who hears whom: `reach.rs`), and its fate at each
//! receiver decided by what that receiver makes of all the frames around it ([`super::air`]), each node's receiver
//! keeping its state as frames begin and end (`ears.rs`), the path loss with each pair's shadowing
//! ([`super::shadow`]) if the radio has it. A broadcast is one frame sequence, heard by all; a unicast is the same
//! frames, kept by the one it names and acknowledged (`ack.rs`). Loss here comes from distance, noise and
//! contention, not from a set p.
//!
//! The medium is whole: it decides a frame's fate only once every frame that could overlap it is known, so a
//! driver hands it every sender's transmissions up to an instant before it asks for deliveries up to that instant
//! (as [`crate::medium::Medium`]'s callers in memory do); it cannot be split by sender.
//!
//! ```
//! use bytes::Bytes;
//! use nalgebra::Vector3;
//! use simnet_core::link::{FaultSchedule, Stream};
//! use simnet_core::medium::radio::{Radio, RadioMedium};
//! use simnet_core::medium::{Dest, Medium, Transmission};
//! use simnet_core::time::Time;
//! use simnet_core::world::{Place, World};
//!
//! let mut world = World::new();
//! for x in [0.0, 10.0, 400.0] {
//!     world.place(Place::Fixed(Vector3::new(x, 0.0, 0.0)));
//! }
//! let mut air = RadioMedium::new(Radio::default(), world, 1);
//! let tx = Transmission { to: Dest::Broadcast, at: Time::ZERO, group: vec![Bytes::from(vec![7; 40])], stream: Stream::Measurement };
//! air.transmit(0, tx, &FaultSchedule::default());
//! let got: Vec<_> = std::iter::from_fn(|| air.poll_delivery(0, Time::from_secs(0.1))).collect();
//! // Node 1, 10 m away, hears it; node 2, 400 m away, does not.
//! assert_eq!(got.iter().map(|d| d.to).collect::<Vec<_>>(), vec![1]);
//! // Sent after a backoff of at most 7 × 320 µs, a 128 µs assessment and a 192 µs turnaround, on the air 1.856 ms.
//! assert!(got[0].at >= Time::from_nanos(2_176_000) && got[0].at <= Time::from_nanos(4_416_000), "{:?}", got[0].at);
//! ```

use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashSet, VecDeque};

use bytes::Bytes;

use super::air::Reception;
use super::csma::{self, Csma, CsmaParams};
use super::frame::{self, Security};
use super::phy::{self, LogDistance, Receiver};
use super::shadow::{ShadowField, Shadowing};
use super::{Delivery, Dest, Medium, Transmission};
use crate::link::{FaultSchedule, LinkCounters};
use crate::rng::Rng;
use crate::time::Time;
use crate::world::World;

mod access;
mod ack;
mod counters;
mod ears;
mod quality;
mod reach;
use ack::{ifs, Awaiting};
pub use ack::{ACK_PSDU, ACK_WAIT};
pub use counters::RadioCounters;
use ears::Ear;
pub use quality::{lqi, LinkQuality};
use reach::{Hearers, Reach};

/// The radios' settings, the same at every node.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Radio {
    /// Transmit power, dBm.
    pub tx_dbm: f64,
    /// The path loss over distance.
    pub path_loss: LogDistance,
    /// The receiver (its sensitivity sets its noise floor and the ED threshold).
    pub receiver: Receiver,
    /// The MAC's CSMA/CA parameters.
    pub csma: CsmaParams,
    /// Whether frames carry 802.15.4 security: then each datagram is a sealed one ([`crate::wire::secure`]), whose
    /// sequence number and tag ([`crate::wire::secure::OVERHEAD`] octets) are the frame's security header and MIC.
    pub security: Security,
    /// Unicasts are acknowledged and sent again up to this many times when no ACK comes (macMaxFrameRetries);
    /// none: unacknowledged.
    pub max_frame_retries: Option<u8>,
    /// Log-normal shadowing over the path loss; none: the path loss alone (as ns-3's log-distance model).
    #[serde(default)]
    pub shadowing: Option<Shadowing>,
}

impl Default for Radio {
    /// 0 dBm, ns-3's log-distance defaults, a CC2420 receiver, the standard's CSMA/CA, no security, unicasts
    /// acknowledged with the standard's 3 retries.
    fn default() -> Radio {
        Radio {
            tx_dbm: 0.0,
            path_loss: LogDistance::NS3,
            receiver: Receiver::CC2420,
            csma: CsmaParams::STANDARD,
            security: Security::None,
            max_frame_retries: Some(3),
            shadowing: None,
        }
    }
}

/// A frame waiting in a sender's MAC queue.
#[derive(Debug, Clone)]
struct Queued {
    ready: Time,
    message: u64,
    to: Dest,
    psdu: u32,
    /// The datagram, on the message's last frame.
    bytes: Option<Bytes>,
    /// Times sent again for want of an ACK.
    retries: u8,
}

/// A frame on the air.
#[derive(Debug, Clone)]
struct AirFrame {
    /// Frames are numbered in the order they go on the air.
    seq: u64,
    from: usize,
    start: Time,
    end: Time,
    message: u64,
    to: Dest,
    bytes: Option<Bytes>,
    /// The nodes that hear it, and its power at each (from the distance as it began).
    hearers: std::sync::Arc<Hearers>,
}

/// What a sender's MAC does next.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Next {
    /// Nothing queued, or the next frame's access not begun.
    Idle,
    /// A clear-channel assessment ends.
    Cca(Time),
    /// Its frame leaves the air.
    TxEnd(Time),
    /// Its wait for an ACK ends.
    AckWait(Time),
}

#[derive(Debug)]
struct Mac {
    queue: VecDeque<Queued>,
    csma: Option<Csma>,
    next: Next,
    /// Not before: the end of its last frame and the interframe spacing after it.
    free_at: Time,
    rng: Rng,
    /// The head frame's ACK, awaited.
    awaiting: Option<Awaiting>,
    /// Its frame on the air.
    on_air: Option<u64>,
}

/// The shared channel.
#[derive(Debug)]
pub struct RadioMedium {
    radio: Radio,
    world: World,
    macs: Vec<Mac>,
    air: VecDeque<AirFrame>,
    /// Frames decided, oldest first: `air[..decided]` have reached every receiver.
    deliveries: Vec<VecDeque<Delivery>>,
    /// (message, receiver): a frame of the message was lost there.
    lost: HashSet<(u64, usize)>,
    /// (message, receiver): the link was down when it was sent (counted as such, not as a loss on the air).
    down: HashSet<(u64, usize)>,
    /// (message, receiver): an acknowledged message delivered, until its sender is done with it.
    delivered: HashSet<(u64, usize)>,
    links: Vec<std::collections::BTreeMap<usize, LinkCounters>>,
    nodes: Vec<RadioCounters>,
    fates: Vec<Rng>,
    /// Each sender's frames at each receiver they were for.
    quality: Vec<std::collections::BTreeMap<usize, LinkQuality>>,
    /// Whom each node's broadcasts are for ([`RadioMedium::with_listeners`]); every other node when `None`.
    listeners: Option<Vec<Vec<usize>>>,
    messages: u64,
    /// The last event done: a datagram handed in later is queued from here at the earliest.
    clock: Time,
    /// Each pair's shadowing, with the radio's.
    shadow: Option<ShadowField>,
    /// Who hears whom.
    reach: Reach,
    /// Each node's receiver, and the frames put on the air so far.
    ears: Vec<Ear>,
    frames_sent: u64,
    /// Every sender's next step, earliest first.
    agenda: BinaryHeap<Reverse<(Time, u8, usize)>>,
    /// The latest end of a frame no longer kept in `air`.
    #[cfg(test)]
    dropped_until: Time,
}

impl RadioMedium {
    /// A channel shared by the nodes `world` places, each drawing its backoffs and its frames' fates from streams
    /// of `seed`.
    pub fn new(radio: Radio, world: World, seed: u64) -> RadioMedium {
        let n = world.len();
        RadioMedium {
            macs: (0..n)
                .map(|i| Mac {
                    queue: VecDeque::new(),
                    csma: None,
                    next: Next::Idle,
                    free_at: Time::ZERO,
                    rng: crate::rng::stream(seed, "csma", i as u64, 0),
                    awaiting: None,
                    on_air: None,
                })
                .collect(),
            air: VecDeque::new(),
            deliveries: (0..n).map(|_| VecDeque::new()).collect(),
            lost: HashSet::new(),
            down: HashSet::new(),
            delivered: HashSet::new(),
            links: vec![Default::default(); n],
            nodes: vec![RadioCounters::default(); n],
            fates: (0..n).map(|i| crate::rng::stream(seed, "air", i as u64, 0)).collect(),
            quality: (0..n).map(|_| Default::default()).collect(),
            listeners: None,
            messages: 0,
            clock: Time::ZERO,
            shadow: radio.shadowing.map(|law| ShadowField::new(law, seed)),
            reach: Reach::new(&radio, &world, radio.receiver.noise_w()),
            ears: (0..n).map(|_| Ear::new(radio.receiver.noise_w())).collect(),
            frames_sent: 0,
            agenda: BinaryHeap::new(),
            #[cfg(test)]
            dropped_until: Time::ZERO,
            radio,
            world,
        }
    }

    /// Broadcasts from each node reach its MAC's listeners `listeners[i]` alone (the group the node sends to, as a
    /// PAN or group address would): every node still hears every frame on the air, as interference and when it
    /// assesses the channel. Without this, every other node listens.
    pub fn with_listeners(mut self, listeners: Vec<Vec<usize>>) -> RadioMedium {
        self.listeners = Some(listeners);
        self
    }

    /// Whom a datagram from `from` to `to` is for: the node named (if it is another node of the world), or `from`'s
    /// listeners.
    fn receivers(&self, from: usize, to: Dest) -> Vec<usize> {
        let n = self.world.len();
        match (to, &self.listeners) {
            (Dest::Node(j), _) => (j < n && j != from).then_some(j).into_iter().collect(),
            (Dest::Broadcast, Some(l)) => l
                .get(from)
                .map(|l| l.iter().copied().filter(|&j| j < n && j != from).collect())
                .unwrap_or_default(),
            (Dest::Broadcast, None) => (0..n).filter(|&j| j != from).collect(),
        }
    }

    /// Node `i`'s figures of the channel.
    pub fn node_counters(&self, i: usize) -> RadioCounters {
        self.nodes.get(i).copied().unwrap_or_default()
    }

    /// Sender `i`'s frame leaves the air at `t`: its fate at every receiver it was for, then the interframe spacing
    /// (or, for an acknowledged unicast, the wait for its ACK).
    fn end_frame(&mut self, i: usize, t: Time) {
        let acked = self.macs[i].queue.front().is_some_and(|q| self.acknowledged(q.to));
        let mac = &mut self.macs[i];
        mac.next = Next::Idle;
        if !acked {
            let q = mac.queue.pop_front().expect("a frame on the air");
            mac.free_at = t + ifs(q.psdu);
        }
        let Some(k) = self.macs[i].on_air.take().and_then(|seq| self.air_index(seq)) else {
            if acked {
                self.macs[i].queue.pop_front();
            }
            return;
        };
        let f = self.air[k].clone();
        debug_assert_eq!(f.from, i, "its own frame");
        for j in self.receivers(i, f.to) {
            let p = f.hearers.power(j);
            let heard = p.is_some();
            let (success, locked) = match heard.then(|| self.reception(k, j)) {
                Some(Reception::Locked { success, sinr_min }) => (success, Some((sinr_min, success))),
                _ => (0.0, None),
            };
            let u: f64 = rand::Rng::gen(&mut self.fates[i]);
            let down = self.down.contains(&(f.message, j));
            let distance_m = self.world.distance(i, j, f.start);
            let quality = self.quality[i].entry(j).or_default();
            quality.count(p.unwrap_or(0.0), heard, locked, u < success && !down, distance_m);
            if acked {
                let received = u < success && !down;
                if received && f.bytes.is_some() && self.delivered.insert((f.message, j)) {
                    self.deliver(i, j, t, f.bytes.clone());
                }
                let ack = received.then(|| self.send_ack(j, i, f.message, t));
                self.macs[i].awaiting = Some(Awaiting {
                    data_end: t,
                    ack: ack.map(|a| a.1),
                });
                self.macs[i].next = Next::AckWait(ack.map_or(t + ACK_WAIT, |a| a.0));
                continue;
            }
            if u >= success {
                self.lost.insert((f.message, j));
            }
            if f.bytes.is_some() {
                let (down, lost) = (self.down.remove(&(f.message, j)), self.lost.remove(&(f.message, j)));
                if down {
                    continue;
                }
                if lost {
                    self.links[i].entry(j).or_default().lost_random += 1;
                } else {
                    self.deliver(i, j, t, f.bytes.clone());
                }
            }
        }
        // Every fate is decided by the receivers' own state: the air keeps the frames of the last 50 ms for the
        // frames' ends and ACKs to find them (and test builds to check the fates against).
        let keep_from = Time::from_nanos(t.as_nanos().saturating_sub(50_000_000));
        while self.air.front().is_some_and(|f| f.end < keep_from) {
            let _f = self.air.pop_front();
            #[cfg(test)]
            if let Some(f) = _f {
                self.dropped_until = self.dropped_until.max(f.end);
            }
        }
    }

    /// Sender `i`'s datagram `bytes` reaches `j` at `t`.
    fn deliver(&mut self, i: usize, j: usize, t: Time, bytes: Option<Bytes>) {
        if let Some(bytes) = bytes {
            self.deliveries[i].push_back(Delivery {
                from: i,
                to: j,
                at: t,
                bytes,
            });
        }
    }

    /// Node `from` puts a frame on the air from `start` to `end` (of `message`, to `to`, the datagram on its
    /// last frame): it reaches every node at the power the path loss leaves, and every node that
    /// hears it above the negligible is told. `air` stays in the order frames begin: they begin in the order of
    /// the events that start them, so this appends.
    fn put_on_air(&mut self, from: usize, (start, end): (Time, Time), what: (u64, Dest, Option<Bytes>)) -> u64 {
        let (message, to, bytes) = what;
        let hearers = self
            .reach
            .hearers(&self.radio, &self.world, &mut self.shadow, from, start);
        let seq = self.frames_sent;
        self.frames_sent += 1;
        let mut meant = self.receivers(from, to);
        meant.sort_unstable();
        self.ears[from].transmit((start, end));
        for (j, power_w) in hearers.iter() {
            self.ears[j].frame(seq, (start, end), power_w, meant.binary_search(&j).is_ok(), self.clock);
        }
        debug_assert!(
            self.air.back().is_none_or(|g| g.start <= start),
            "frames begin in order"
        );
        self.air.push_back(AirFrame {
            seq,
            from,
            start,
            end,
            message,
            to,
            bytes,
            hearers,
        });
        seq
    }

    /// Where frame `seq` is in `air` (in the order they were put there), if it is still kept.
    fn air_index(&self, seq: u64) -> Option<usize> {
        self.air.binary_search_by_key(&seq, |f| f.seq).ok()
    }

    /// What receiver `j` makes of frame `k`, meant for it, as the frame ends.
    fn reception(&mut self, k: usize, j: usize) -> Reception {
        let f = &self.air[k];
        let got = self.ears[j].fate(f.seq, f.end);
        #[cfg(test)]
        if let Some(want) = self.reception_by_chain(k, j) {
            assert_eq!(got, want, "frame {k} at {j}");
        }
        got
    }
}

impl Medium for RadioMedium {
    fn transmit(&mut self, from: usize, tx: Transmission, faults: &FaultSchedule) {
        if from >= self.macs.len() {
            return;
        }
        if matches!(tx.to, Dest::Node(j) if j >= self.world.len() || j == from) {
            return;
        }
        let ready = tx.at.max(self.clock);
        for bytes in tx.group {
            let message = self.messages;
            self.messages += 1;
            for j in self.receivers(from, tx.to) {
                let link = self.links[from].entry(j).or_default();
                link.sent += 1;
                link.bytes += bytes.len() as u64;
                if !faults.link_up(from, j, tx.at) {
                    link.lost_down += 1;
                    self.down.insert((message, j));
                }
            }
            // A sealed datagram's sequence number and tag travel as the frame's security header and MIC.
            let payload = match self.radio.security {
                Security::None => bytes.len(),
                Security::Mic64 => bytes.len().saturating_sub(crate::wire::secure::OVERHEAD),
            };
            let frames = frame::psdus(payload as u32, self.radio.security);
            let last = frames.len() - 1;
            for (n, psdu) in frames.into_iter().enumerate() {
                self.macs[from].queue.push_back(Queued {
                    ready,
                    message,
                    to: tx.to,
                    psdu,
                    bytes: (n == last).then(|| bytes.clone()),
                    retries: 0,
                });
            }
        }
        if self.macs[from].next == Next::Idle {
            self.schedule(from);
        }
    }

    fn poll_delivery(&mut self, from: usize, now: Time) -> Option<Delivery> {
        self.advance(now);
        let q = self.deliveries.get_mut(from)?;
        if q.front().is_some_and(|d| d.at <= now) {
            return q.pop_front();
        }
        None
    }

    fn poll_timeout(&self, from: usize) -> Option<Time> {
        if let Some(d) = self.deliveries.get(from)?.front() {
            return Some(d.at);
        }
        match self.macs.get(from)?.next {
            Next::Cca(t) | Next::TxEnd(t) | Next::AckWait(t) => Some(t),
            Next::Idle => (!self.macs[from].queue.is_empty()).then_some(self.clock),
        }
    }

    fn counters(&self, from: usize) -> Vec<(usize, LinkCounters)> {
        let Some(links) = self.links.get(from) else {
            return Vec::new();
        };
        (links.iter())
            .filter(|(j, c)| **j != from && c.sent > 0)
            .map(|(j, c)| (*j, *c))
            .collect()
    }
    fn radio(&self, node: usize) -> Option<RadioCounters> {
        self.nodes.get(node).copied()
    }

    fn radio_links(&self, from: usize) -> Vec<(usize, LinkQuality)> {
        self.quality
            .get(from)
            .map(|q| q.iter().map(|(j, l)| (*j, *l)).collect())
            .unwrap_or_default()
    }
}

#[cfg(test)]
mod tests;
