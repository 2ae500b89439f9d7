//! One shared IEEE 802.15.4 channel as a [`Medium`]: every node a radio at its place in the [`World`], every datagram
//! one or more frames ([`super::frame`]) that each sender's MAC puts on the air by unslotted CSMA/CA
//! ([`super::csma`]), every frame heard by every node in range at the power the path loss leaves
//! ([`super::phy`]), and its fate at each receiver decided by what that receiver makes of all the frames around it
//! ([`super::air`]), the path loss with each pair's shadowing ([`super::shadow`]) if the radio has it. A broadcast is
//! one frame sequence, heard by all; a unicast is the same frames, kept by the one it names and acknowledged
//! (`ack.rs`). Loss here comes from distance, noise and contention, not from a set p.
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

use std::collections::{HashSet, VecDeque};

use bytes::Bytes;

use super::air::{self, OnAir, Reception};
use super::csma::{self, Attempt, Csma, CsmaParams};
use super::frame::{self, Security};
use super::phy::{self, LogDistance, Receiver};
use super::shadow::{ShadowField, Shadowing};
use super::{Delivery, Dest, Medium, Transmission};
use crate::link::{FaultSchedule, LinkCounters};
use crate::rng::Rng;
use crate::time::Time;
use crate::world::World;

mod ack;
mod counters;
mod quality;
use ack::{ifs, Awaiting};
pub use ack::{ACK_PSDU, ACK_WAIT};
pub use counters::RadioCounters;
pub use quality::LinkQuality;

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
    from: usize,
    start: Time,
    end: Time,
    message: u64,
    to: Dest,
    bytes: Option<Bytes>,
    /// An acknowledgement (of `message`, to `to`).
    ack: bool,
    /// Its power at every node, W (from the distance as it began).
    power_w: std::sync::Arc<[f64]>,
    /// Its sender's distance to every node as it began, m.
    distance_m: std::sync::Arc<[f64]>,
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
}

/// The shared channel.
#[derive(Debug)]
pub struct RadioMedium {
    radio: Radio,
    world: World,
    noise_w: f64,
    macs: Vec<Mac>,
    air: Vec<AirFrame>,
    /// Frames decided, oldest first: `air[..decided]` have reached every receiver.
    deliveries: Vec<VecDeque<Delivery>>,
    /// (message, receiver): a frame of the message was lost there.
    lost: HashSet<(u64, usize)>,
    /// (message, receiver): the link was down when it was sent (counted as such, not as a loss on the air).
    down: HashSet<(u64, usize)>,
    /// (message, receiver): an acknowledged message delivered, until its sender is done with it.
    delivered: HashSet<(u64, usize)>,
    links: Vec<Vec<LinkCounters>>,
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
    /// The longest frame put on the air: a frame that began that long before an instant has ended by it.
    longest: std::time::Duration,
}

/// Interference below a hundredth of the noise is left out.
const NEGLIGIBLE: f64 = 0.01;

impl RadioMedium {
    /// A channel shared by the nodes `world` places, each drawing its backoffs and its frames' fates from streams
    /// of `seed`.
    pub fn new(radio: Radio, world: World, seed: u64) -> RadioMedium {
        let n = world.len();
        RadioMedium {
            noise_w: radio.receiver.noise_w(),
            macs: (0..n)
                .map(|i| Mac {
                    queue: VecDeque::new(),
                    csma: None,
                    next: Next::Idle,
                    free_at: Time::ZERO,
                    rng: crate::rng::stream(seed, "csma", i as u64, 0),
                    awaiting: None,
                })
                .collect(),
            air: Vec::new(),
            deliveries: (0..n).map(|_| VecDeque::new()).collect(),
            lost: HashSet::new(),
            down: HashSet::new(),
            delivered: HashSet::new(),
            links: vec![vec![LinkCounters::default(); n]; n],
            nodes: vec![RadioCounters::default(); n],
            fates: (0..n).map(|i| crate::rng::stream(seed, "air", i as u64, 0)).collect(),
            quality: (0..n).map(|_| Default::default()).collect(),
            listeners: None,
            messages: 0,
            clock: Time::ZERO,
            shadow: radio.shadowing.map(|law| ShadowField::new(law, seed)),
            longest: std::time::Duration::ZERO,
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

    /// The power of `from`'s frame at every node if it begins at `t`, W (the path loss and the pair's shadowing),
    /// and the distance it crosses to each, m.
    fn reach(&mut self, from: usize, t: Time) -> (std::sync::Arc<[f64]>, std::sync::Arc<[f64]>) {
        let at = self.world.position(from, t);
        let places: Vec<_> = (0..self.world.len()).map(|to| self.world.position(to, t)).collect();
        let distance_m: std::sync::Arc<[f64]> = places.iter().map(|p| (p - at).norm()).collect();
        let power_w = places
            .iter()
            .enumerate()
            .map(|(to, &p)| {
                let shadow = match &mut self.shadow {
                    Some(s) if to != from => s.db(from, to, at, p),
                    _ => 0.0,
                };
                let loss = self.radio.path_loss.loss_db(distance_m[to]) + shadow;
                phy::dbm_to_w(self.radio.tx_dbm - loss)
            })
            .collect();
        (power_w, distance_m)
    }

    /// Run the channel to `until`: every assessment and every frame's end up to it, in time order (a frame's end
    /// before an assessment at the same instant; senders in index order).
    fn advance(&mut self, until: Time) {
        loop {
            for i in 0..self.macs.len() {
                self.begin_access(i);
            }
            let next = (0..self.macs.len())
                .filter_map(|i| match self.macs[i].next {
                    Next::TxEnd(t) => Some((t, 0, i)),
                    Next::AckWait(t) => Some((t, 1, i)),
                    Next::Cca(t) => Some((t, 2, i)),
                    Next::Idle => None,
                })
                .min();
            let Some((t, kind, i)) = next.filter(|(t, ..)| *t <= until) else {
                break;
            };
            self.clock = self.clock.max(t);
            match kind {
                0 => self.end_frame(i, t),
                1 => self.ack_wait(i, t),
                _ => self.assess(i, t),
            }
        }
    }

    /// A sender with a frame queued and nothing under way backs off before its first assessment.
    fn begin_access(&mut self, i: usize) {
        let mac = &mut self.macs[i];
        let (Next::Idle, Some(head)) = (mac.next, mac.queue.front()) else {
            return;
        };
        let csma = Csma::new(self.radio.csma);
        let from = head.ready.max(mac.free_at);
        mac.next = Next::Cca(from + csma.backoff(&mut mac.rng) + csma::CCA);
        mac.csma = Some(csma);
    }

    /// Sender `i`'s assessment ends at `t`: busy (ED over the threshold, or a frame it would be receiving), or
    /// clear and the frame goes on the air after the turnaround.
    fn assess(&mut self, i: usize, t: Time) {
        let from = Time::from_nanos(t.as_nanos().saturating_sub(csma::CCA.as_nanos() as u64));
        let threshold = phy::dbm_to_w(self.radio.receiver.sensitivity_dbm + 10.0);
        let heard: Vec<(Time, Time, f64)> = self.air[self.window(from, t)]
            .iter()
            .filter(|f| f.from != i && f.start <= t && f.end > from)
            .map(|f| (f.start, f.end, f.power_w[i]))
            .collect();
        // The peak energy over the assessment: the sum at its start and at each frame's start within it.
        let peak = std::iter::once(from)
            .chain(heard.iter().map(|h| h.0).filter(|s| *s > from))
            .map(|at| heard.iter().filter(|h| h.0 <= at && h.1 > at).map(|h| h.2).sum::<f64>())
            .fold(0.0, f64::max);
        // Receiving: a frame still on the air that it locked onto as it began (what it makes of the frames around it,
        // as at any receiver).
        let receiving = {
            let (frames, ids, sending) = self.heard_by(i, (t, t));
            let locks = air::locks(&frames, &sending, self.noise_w);
            ids.iter().zip(locks).any(|(&m, locked)| self.air[m].end > t && locked)
        };
        let mac = &mut self.macs[i];
        let mut csma = mac.csma.take().expect("an assessment belongs to an access");
        if peak >= threshold || receiving {
            self.nodes[i].busy += 1;
            match csma.busy() {
                Attempt::BackOff => {
                    mac.next = Next::Cca(t + csma.backoff(&mut mac.rng) + csma::CCA);
                    mac.csma = Some(csma);
                }
                Attempt::Fail => {
                    // The frame is abandoned, and with it the rest of its message: lost wherever it was going.
                    let q = mac.queue.pop_front().expect("a queued frame");
                    while mac.queue.front().is_some_and(|r| r.message == q.message) {
                        mac.queue.pop_front();
                    }
                    self.nodes[i].csma_failures += 1;
                    mac.next = Next::Idle;
                    mac.free_at = t;
                    for j in self.receivers(i, q.to) {
                        self.lost.remove(&(q.message, j));
                        if !self.down.remove(&(q.message, j)) {
                            self.links[i][j].lost_random += 1;
                        }
                    }
                }
            }
            return;
        }
        let q = mac.queue.front().expect("a queued frame").clone();
        let start = t + csma::TURNAROUND;
        let end = start + phy::airtime(q.psdu);
        mac.next = Next::TxEnd(end);
        self.nodes[i].frames += 1;
        self.nodes[i].airtime_ns += end.since(start).as_nanos() as u64;
        self.nodes[i].last_end_ns = end.as_nanos();
        let (power_w, distance_m) = self.reach(i, start);
        self.put_on_air(AirFrame {
            from: i,
            start,
            end,
            message: q.message,
            to: q.to,
            bytes: q.bytes,
            ack: false,
            power_w,
            distance_m,
        });
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
        let Some(k) = self.air.iter().rposition(|f| f.from == i && f.end == t && !f.ack) else {
            if acked {
                self.macs[i].queue.pop_front();
            }
            return;
        };
        let f = self.air[k].clone();
        for j in self.receivers(i, f.to) {
            let p = f.power_w[j];
            let heard = p >= NEGLIGIBLE * self.noise_w;
            let (success, sinr) = match heard.then(|| self.reception(k, j)) {
                Some(Reception::Locked { success, sinr_min }) => (success, Some(sinr_min)),
                _ => (0.0, None),
            };
            let u: f64 = rand::Rng::gen(&mut self.fates[i]);
            let down = self.down.contains(&(f.message, j));
            let quality = self.quality[i].entry(j).or_default();
            quality.count(p, heard, sinr, u < success && !down, f.distance_m[j]);
            if acked {
                let received = u < success && !down;
                if received && f.bytes.is_some() && self.delivered.insert((f.message, j)) {
                    self.deliver(i, j, t, f.bytes.clone());
                }
                let ack_end = received.then(|| self.send_ack(j, i, f.message, t));
                self.macs[i].awaiting = Some(Awaiting {
                    data_end: t,
                    ack_start: ack_end.map(|_| t + csma::TURNAROUND),
                });
                self.macs[i].next = Next::AckWait(ack_end.unwrap_or(t + ACK_WAIT));
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
                    self.links[i][j].lost_random += 1;
                } else {
                    self.deliver(i, j, t, f.bytes.clone());
                }
            }
        }
        // Frames that ended long before the earliest frame still on the air can no longer overlap a decision.
        let horizon = self
            .air
            .iter()
            .filter(|f| f.end > t)
            .map(|f| f.start)
            .min()
            .unwrap_or(t);
        let keep_from = Time::from_nanos(horizon.as_nanos().saturating_sub(50_000_000));
        self.air.retain(|f| f.end >= keep_from);
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

    /// Frame `f` goes on the air: `air` stays in the order frames begin (they begin in the order of the events that
    /// start them, so this appends; frames that begin together keep the order they were sent in).
    fn put_on_air(&mut self, f: AirFrame) {
        self.longest = self.longest.max(f.end.since(f.start));
        let at = self.air.partition_point(|g| g.start <= f.start);
        self.air.insert(at, f);
    }

    /// The frames of `air` that can overlap `[lo, hi]` (a range holding every frame with start ≤ hi and end > lo).
    fn window(&self, lo: Time, hi: Time) -> std::ops::Range<usize> {
        let first = self.air.partition_point(|g| g.start + self.longest <= lo);
        let last = self.air.partition_point(|g| g.start <= hi);
        first..last.max(first)
    }

    /// What receiver `j` makes of frame `k` ([`air::receive`] over what it heard around it, [`Self::heard_by`]).
    fn reception(&self, k: usize, j: usize) -> Reception {
        let f = &self.air[k];
        let (frames, ids, sending) = self.heard_by(j, (f.start, f.end));
        match ids.iter().position(|&m| m == k) {
            Some(index) => air::receive_one(&frames, &sending, self.noise_w, index),
            None => Reception::Weak { sinr: 0.0 },
        }
    }

    /// What receiver `j` heard around the interval `[lo, hi]`: every frame overlapping it or, one after another, the
    /// frames before it (whose start decides what `j` was locked onto), as [`OnAir`] with their indices in `air`
    /// (frames far below the noise left out), and `j`'s own frames as the times it transmitted.
    fn heard_by(&self, j: usize, (mut lo, hi): (Time, Time)) -> (Vec<OnAir>, Vec<usize>, Vec<(Time, Time)>) {
        // Only frames it hears decide what it was locked onto; its own frames end any lock.
        let heard = |g: &AirFrame| g.from != j && g.power_w[j] >= NEGLIGIBLE * self.noise_w;
        let members = loop {
            let members: Vec<usize> = self
                .window(lo, hi)
                .filter(|&m| self.air[m].start <= hi && self.air[m].end > lo && heard(&self.air[m]))
                .collect();
            let first = members.iter().map(|&m| self.air[m].start).min().unwrap_or(lo);
            if first >= lo {
                break members;
            }
            lo = first;
        };
        let sending = self.air[self.window(lo, hi)]
            .iter()
            .filter(|g| g.from == j && g.start <= hi && g.end > lo)
            .map(|g| (g.start, g.end))
            .collect();
        let frames = members
            .iter()
            .map(|&m| OnAir {
                start: self.air[m].start,
                end: self.air[m].end,
                power_w: self.air[m].power_w[j],
            })
            .collect();
        (frames, members, sending)
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
                let link = &mut self.links[from][j];
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
        links
            .iter()
            .enumerate()
            .filter(|(j, c)| *j != from && c.sent > 0)
            .map(|(j, c)| (j, *c))
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
