//! One shared IEEE 802.15.4 channel as a [`Medium`]: every node a radio at its place in the [`World`], every datagram
//! one or more frames ([`super::frame`]) that each sender's MAC puts on the air by unslotted CSMA/CA
//! ([`super::csma`]), every frame heard by every node in range at the power the path loss leaves
//! ([`super::phy`]), and its fate at each receiver decided by what that receiver makes of all the frames around it
//! ([`super::air`]). A broadcast is one frame sequence, heard by all; a unicast is the same frames, kept by the one
//! it names (no acknowledgement yet). Loss here comes from distance, noise and contention, not from a set p.
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
use super::{Delivery, Dest, Medium, Transmission};
use crate::link::{FaultSchedule, LinkCounters};
use crate::rng::Rng;
use crate::time::Time;
use crate::world::World;

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
    /// Whether frames carry 802.15.4 security.
    pub security: Security,
}

impl Default for Radio {
    /// 0 dBm, ns-3's log-distance defaults, a CC2420 receiver, the standard's CSMA/CA, no security.
    fn default() -> Radio {
        Radio {
            tx_dbm: 0.0,
            path_loss: LogDistance::NS3,
            receiver: Receiver::CC2420,
            csma: CsmaParams::STANDARD,
            security: Security::None,
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
}

#[derive(Debug)]
struct Mac {
    queue: VecDeque<Queued>,
    csma: Option<Csma>,
    next: Next,
    /// Not before: the end of its last frame and the interframe spacing after it.
    free_at: Time,
    rng: Rng,
}

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
    links: Vec<Vec<LinkCounters>>,
    nodes: Vec<RadioCounters>,
    fates: Vec<Rng>,
    messages: u64,
    /// The last event done: a datagram handed in later is queued from here at the earliest.
    clock: Time,
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
                })
                .collect(),
            air: Vec::new(),
            deliveries: (0..n).map(|_| VecDeque::new()).collect(),
            lost: HashSet::new(),
            down: HashSet::new(),
            links: vec![vec![LinkCounters::default(); n]; n],
            nodes: vec![RadioCounters::default(); n],
            fates: (0..n).map(|i| crate::rng::stream(seed, "air", i as u64, 0)).collect(),
            messages: 0,
            clock: Time::ZERO,
            radio,
            world,
        }
    }

    /// Node `i`'s figures of the channel.
    pub fn node_counters(&self, i: usize) -> RadioCounters {
        self.nodes.get(i).copied().unwrap_or_default()
    }

    /// The power of `from`'s frame at `to` at time `t`, W.
    fn power(&self, from: usize, to: usize, t: Time) -> f64 {
        let loss = self.radio.path_loss.loss_db(self.world.distance(from, to, t));
        phy::dbm_to_w(self.radio.tx_dbm - loss)
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
                    Next::Cca(t) => Some((t, 1, i)),
                    Next::Idle => None,
                })
                .min();
            let Some((t, kind, i)) = next.filter(|(t, ..)| *t <= until) else {
                break;
            };
            self.clock = self.clock.max(t);
            if kind == 0 {
                self.end_frame(i, t);
            } else {
                self.assess(i, t);
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
        let heard: Vec<(Time, Time, f64)> = self
            .air
            .iter()
            .filter(|f| f.from != i && f.start <= t && f.end > from)
            .map(|f| (f.start, f.end, self.power(f.from, i, f.start)))
            .collect();
        // The peak energy over the assessment: the sum at its start and at each frame's start within it.
        let peak = std::iter::once(from)
            .chain(heard.iter().map(|h| h.0).filter(|s| *s > from))
            .map(|at| heard.iter().filter(|h| h.0 <= at && h.1 > at).map(|h| h.2).sum::<f64>())
            .fold(0.0, f64::max);
        // Receiving: a frame on the air at the end that it could have locked onto as it began.
        let receiving = heard.iter().any(|h| {
            let others: f64 = heard.iter().filter(|o| o.0 < h.0 && o.1 > h.0).map(|o| o.2).sum();
            h.1 > t && 10.0 * (h.2 / (self.noise_w + others)).log10() > air::LOCK_SINR_DB
        });
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
                    let receivers: Vec<usize> = match q.to {
                        Dest::Node(j) => vec![j],
                        Dest::Broadcast => (0..self.world.len()).filter(|&j| j != i).collect(),
                    };
                    for j in receivers {
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
        self.air.push(AirFrame {
            from: i,
            start,
            end,
            message: q.message,
            to: q.to,
            bytes: q.bytes,
        });
    }

    /// Sender `i`'s frame leaves the air at `t`: its fate at every receiver it was for, then the interframe spacing.
    fn end_frame(&mut self, i: usize, t: Time) {
        let mac = &mut self.macs[i];
        let q = mac.queue.pop_front().expect("a frame on the air");
        mac.next = Next::Idle;
        // Long interframe spacing (40 symbols) after a frame over aMaxSIFSFrameSize (18 octets), short (12) else.
        mac.free_at = t + if q.psdu > 18 {
            csma::SYMBOL * 40
        } else {
            csma::SYMBOL * 12
        };
        let Some(k) = self.air.iter().rposition(|f| f.from == i && f.end == t) else {
            return;
        };
        let f = self.air[k].clone();
        let receivers: Vec<usize> = match f.to {
            Dest::Node(j) => vec![j],
            Dest::Broadcast => (0..self.world.len()).filter(|&j| j != i).collect(),
        };
        for j in receivers {
            let p = self.power(i, j, f.start);
            let success = if p < NEGLIGIBLE * self.noise_w {
                0.0
            } else {
                match self.reception(k, j) {
                    Reception::Locked { success, .. } => success,
                    _ => 0.0,
                }
            };
            let u: f64 = rand::Rng::gen(&mut self.fates[i]);
            if u >= success {
                self.lost.insert((f.message, j));
            }
            if let Some(bytes) = &f.bytes {
                let (down, lost) = (self.down.remove(&(f.message, j)), self.lost.remove(&(f.message, j)));
                if down {
                    continue;
                }
                if lost {
                    self.links[i][j].lost_random += 1;
                } else {
                    self.deliveries[i].push_back(Delivery {
                        from: i,
                        to: j,
                        at: t,
                        bytes: bytes.clone(),
                    });
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

    /// What receiver `j` makes of frame `k`: [`air::receive`] over the frames it heard that overlap `k` or, one
    /// after another, the frames before it, with its own frames as the times it transmitted.
    fn reception(&self, k: usize, j: usize) -> Reception {
        let f = &self.air[k];
        let mut lo = f.start;
        let members = loop {
            let members: Vec<usize> = (0..self.air.len())
                .filter(|&m| self.air[m].start < f.end && self.air[m].end > lo)
                .collect();
            let first = members.iter().map(|&m| self.air[m].start).min().unwrap_or(lo);
            if first >= lo {
                break members;
            }
            lo = first;
        };
        let (mut frames, mut index, mut sending) = (Vec::new(), None, Vec::new());
        for m in members {
            let g = &self.air[m];
            if g.from == j {
                sending.push((g.start, g.end));
                continue;
            }
            let p = self.power(g.from, j, g.start);
            if m == k {
                index = Some(frames.len());
            } else if p < NEGLIGIBLE * self.noise_w {
                continue;
            }
            frames.push(OnAir {
                start: g.start,
                end: g.end,
                power_w: p,
            });
        }
        let Some(index) = index else {
            return Reception::Weak { sinr: 0.0 };
        };
        air::receive(&frames, &sending, self.noise_w)[index]
    }
}

impl Medium for RadioMedium {
    fn transmit(&mut self, from: usize, tx: Transmission, faults: &FaultSchedule) {
        if from >= self.macs.len() {
            return;
        }
        let ready = tx.at.max(self.clock);
        for bytes in tx.group {
            let message = self.messages;
            self.messages += 1;
            let receivers: Vec<usize> = match tx.to {
                Dest::Node(j) if j < self.world.len() && j != from => vec![j],
                Dest::Node(_) => Vec::new(),
                Dest::Broadcast => (0..self.world.len()).filter(|&j| j != from).collect(),
            };
            for &j in &receivers {
                let link = &mut self.links[from][j];
                link.sent += 1;
                link.bytes += bytes.len() as u64;
                if !faults.link_up(from, j, tx.at) {
                    link.lost_down += 1;
                    self.down.insert((message, j));
                }
            }
            let frames = frame::psdus(bytes.len() as u32, self.radio.security);
            let last = frames.len() - 1;
            for (n, psdu) in frames.into_iter().enumerate() {
                self.macs[from].queue.push_back(Queued {
                    ready,
                    message,
                    to: tx.to,
                    psdu,
                    bytes: (n == last).then(|| bytes.clone()),
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
            Next::Cca(t) | Next::TxEnd(t) => Some(t),
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
}

#[cfg(test)]
mod tests;
