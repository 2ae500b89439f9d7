//! The medium: what carries the datagrams a node sends to the nodes that receive them. A node only says what it
//! sends — a [`Transmission`] to one neighbour or to every node that hears it ([`Dest::Broadcast`]) at a time, on a
//! stream — and never decides a datagram's fate; the driver hands each transmission to the medium and takes from it
//! what is delivered, when. A medium sees every transmission of the senders it carries and the run's fault windows;
//! a broadcast is one transmission, and the medium decides who hears it.
//!
//! [`PairwiseMedium`] is simnet's channel today: each directed link decides alone, from its own rules
//! ([`crate::link`]) and its own seeded streams, what becomes of each datagram (loss, outage, delay, duplication,
//! corruption). Because its links are independent it can be split by sender: a UDP worker or a node process carries
//! only its own senders' part, and every part decides exactly what the whole would. A broadcast goes out on each of
//! the sender's links, each deciding alone, as that many unicasts would.
//!
//! A medium of your own implements [`Medium`]. This one sees the [`crate::world::World`]: it carries a datagram only
//! to a receiver within 30 m of its sender at the time of sending, 4 ms later; a broadcast reaches every node in
//! range:
//!
//! ```
//! use std::collections::VecDeque;
//! use std::time::Duration;
//! use bytes::Bytes;
//! use nalgebra::Vector3;
//! use simnet_core::link::{FaultSchedule, LinkCounters, Stream};
//! use simnet_core::medium::{Delivery, Dest, Medium, Transmission};
//! use simnet_core::time::Time;
//! use simnet_core::world::{Place, World};
//!
//! #[derive(Debug)]
//! struct InRange {
//!     world: World,
//!     queue: VecDeque<(Time, Delivery)>,
//!     sent: Vec<(usize, usize, u64)>,
//! }
//!
//! impl Medium for InRange {
//!     fn transmit(&mut self, from: usize, tx: Transmission, faults: &FaultSchedule) {
//!         let to: Vec<usize> = match tx.to {
//!             Dest::Node(to) => vec![to],
//!             Dest::Broadcast => (0..self.world.len()).filter(|&j| j != from).collect(),
//!         };
//!         for to in to {
//!             match self.sent.iter_mut().find(|(f, t, _)| (*f, *t) == (from, to)) {
//!                 Some(s) => s.2 += 1,
//!                 None => self.sent.push((from, to, 1)),
//!             }
//!             if !faults.link_up(from, to, tx.at) || self.world.distance(from, to, tx.at) > 30.0 {
//!                 continue;
//!             }
//!             for bytes in &tx.group {
//!                 let at = tx.at + Duration::from_millis(4);
//!                 self.queue.push_back((at, Delivery { from, to, at, bytes: bytes.clone() }));
//!             }
//!         }
//!     }
//!     fn poll_delivery(&mut self, from: usize, now: Time) -> Option<Delivery> {
//!         let i = self.queue.iter().position(|(at, d)| d.from == from && *at <= now)?;
//!         self.queue.remove(i).map(|(_, d)| d)
//!     }
//!     fn poll_timeout(&self, from: usize) -> Option<Time> {
//!         self.queue.iter().filter(|(_, d)| d.from == from).map(|(at, _)| *at).min()
//!     }
//!     fn counters(&self, from: usize) -> Vec<(usize, LinkCounters)> {
//!         let sent = self.sent.iter().filter(|(f, _, _)| *f == from);
//!         sent.map(|&(_, to, n)| (to, LinkCounters { sent: n, ..Default::default() })).collect()
//!     }
//! }
//!
//! let mut world = World::new();
//! for x in [0.0, 20.0, 50.0] {
//!     world.place(Place::Fixed(Vector3::new(x, 0.0, 0.0)));
//! }
//! let mut air = InRange { world, queue: VecDeque::new(), sent: Vec::new() };
//! let faults = FaultSchedule::default();
//! let ms = |n: u64| Time::from_nanos(n * 1_000_000);
//! let tx = Transmission { to: Dest::Broadcast, at: ms(10), group: vec![Bytes::from_static(b"hi")], stream: Stream::Measurement };
//! air.transmit(0, tx, &faults);
//! assert!(air.poll_delivery(0, ms(12)).is_none());
//! assert_eq!(air.poll_timeout(0), Some(ms(14)));
//! let d = air.poll_delivery(0, ms(14)).unwrap();
//! assert_eq!((d.from, d.to, &d.bytes[..]), (0, 1, &b"hi"[..]));
//! assert!(air.poll_delivery(0, Time::MAX).is_none(), "node 2 is 50 m away");
//! assert_eq!(air.counters(0).len(), 2);
//! // Node 1 to node 2 alone, 30 m apart.
//! let tx = Transmission { to: Dest::Node(2), at: ms(20), group: vec![Bytes::from_static(b"yo")], stream: Stream::Measurement };
//! air.transmit(1, tx, &faults);
//! assert_eq!(air.poll_delivery(1, ms(30)).map(|d| d.to), Some(2));
//! ```

pub mod air;
mod capture;
pub mod csma;
pub mod energy;
pub mod frame;
mod ingress;
pub mod phy;
pub mod radio;
pub mod shadow;

use bytes::Bytes;

pub use capture::{Capture, CaptureLog, Captured, Event};
pub use ingress::{Ingress, Injection, Refusals, Tally};

use crate::link::{Egress, FaultSchedule, LinkCounters, Stream};
use crate::time::Time;

/// Who a transmission is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dest {
    /// One node, by index.
    Node(usize),
    /// Every node that hears it (the medium decides who does).
    Broadcast,
}

/// What a node sends at one time to one neighbour or to all: datagrams that share one fate on each link (a
/// measurement and the round-0 messages that ride with it), drawn from one of the link's streams.
#[derive(Debug, Clone, PartialEq)]
pub struct Transmission {
    /// Who it is for.
    pub to: Dest,
    /// When it is sent.
    pub at: Time,
    /// The datagrams, in order.
    pub group: Vec<Bytes>,
    /// Which of the link's seeded streams decides their fate.
    pub stream: Stream,
}

/// A datagram the medium delivers.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Delivery {
    /// The sending node, by index.
    pub from: usize,
    /// The receiving node, by index.
    pub to: usize,
    /// When it is due at the receiver (sent, plus the link's delay).
    pub at: Time,
    /// The datagram as it arrives (a corrupted copy has a bit flipped).
    pub bytes: Bytes,
}

/// Carries transmissions from senders to receivers. Deliveries are asked for by sender, in delivery order, so that
/// a driver that holds the senders' parts apart (one per UDP worker or process) delivers what one whole would.
pub trait Medium: Send + std::fmt::Debug {
    /// `from` sends `tx`; the medium decides what becomes of it.
    fn transmit(&mut self, from: usize, tx: Transmission, faults: &FaultSchedule);
    /// The next datagram from `from` due at or before `now`.
    fn poll_delivery(&mut self, from: usize, now: Time) -> Option<Delivery>;
    /// When the next datagram from `from` is due.
    fn poll_timeout(&self, from: usize) -> Option<Time>;
    /// What each of `from`'s links carried, by receiver.
    fn counters(&self, from: usize) -> Vec<(usize, LinkCounters)>;
    /// What node `node`'s radio did on a shared channel (frames, airtime, channel access); none for a medium
    /// without radios.
    fn radio(&self, node: usize) -> Option<radio::RadioCounters> {
        let _ = node;
        None
    }
    /// What `from`'s frames were like at each receiver they were for, on a shared channel; none without radios.
    fn radio_links(&self, from: usize) -> Vec<(usize, radio::LinkQuality)> {
        let _ = from;
        Vec::new()
    }
}

/// A boxed medium is a medium (so that a tap such as [`Capture`] can wrap one chosen at run time).
impl<M: Medium + ?Sized> Medium for Box<M> {
    fn transmit(&mut self, from: usize, tx: Transmission, faults: &FaultSchedule) {
        (**self).transmit(from, tx, faults)
    }
    fn poll_delivery(&mut self, from: usize, now: Time) -> Option<Delivery> {
        (**self).poll_delivery(from, now)
    }
    fn poll_timeout(&self, from: usize) -> Option<Time> {
        (**self).poll_timeout(from)
    }
    fn counters(&self, from: usize) -> Vec<(usize, LinkCounters)> {
        (**self).counters(from)
    }
    fn radio(&self, node: usize) -> Option<radio::RadioCounters> {
        (**self).radio(node)
    }
    fn radio_links(&self, from: usize) -> Vec<(usize, radio::LinkQuality)> {
        (**self).radio_links(from)
    }
}

/// Each directed link deciding alone, from its rules and its seeded streams: one [`Egress`] per sender.
#[derive(Debug, Default)]
pub struct PairwiseMedium {
    /// `senders[from − base]`: found by index on every send and poll (a map cost a node-step 2 %).
    senders: Vec<Option<Egress>>,
    base: usize,
}

impl PairwiseMedium {
    /// A medium of no sender.
    pub fn new() -> PairwiseMedium {
        PairwiseMedium::default()
    }

    /// Whether it carries what `from` sends.
    pub fn carries(&self, from: usize) -> bool {
        self.sender(from).is_some()
    }

    /// Carry `from`'s out-links as `egress` holds them.
    pub fn with_sender(mut self, from: usize, egress: Egress) -> PairwiseMedium {
        if self.senders.is_empty() {
            self.base = from;
        } else if from < self.base {
            let shift = self.base - from;
            self.senders.splice(0..0, std::iter::repeat_with(|| None).take(shift));
            self.base = from;
        }
        let i = from - self.base;
        if i >= self.senders.len() {
            self.senders.resize_with(i + 1, || None);
        }
        self.senders[i] = Some(egress);
        self
    }

    fn sender(&self, from: usize) -> Option<&Egress> {
        self.senders.get(from.checked_sub(self.base)?)?.as_ref()
    }

    fn sender_mut(&mut self, from: usize) -> Option<&mut Egress> {
        self.senders.get_mut(from.checked_sub(self.base)?)?.as_mut()
    }
}

impl Medium for PairwiseMedium {
    fn transmit(&mut self, from: usize, tx: Transmission, faults: &FaultSchedule) {
        let Some(e) = self.sender_mut(from) else { return };
        match tx.to {
            Dest::Node(to) => {
                if let Some(li) = e.link_to(to) {
                    e.push_group(li, tx.at, &tx.group, faults, tx.stream);
                }
            }
            // Each out-link decides alone, in link order: the draws of as many unicasts.
            Dest::Broadcast => (0..e.len()).for_each(|li| e.push_group(li, tx.at, &tx.group, faults, tx.stream)),
        }
    }

    fn poll_delivery(&mut self, from: usize, now: Time) -> Option<Delivery> {
        let (at, t) = self.sender_mut(from)?.poll_transmit(now)?;
        Some(Delivery {
            from,
            to: t.to,
            at,
            bytes: t.bytes,
        })
    }

    fn poll_timeout(&self, from: usize) -> Option<Time> {
        self.sender(from)?.poll_timeout()
    }

    fn counters(&self, from: usize) -> Vec<(usize, LinkCounters)> {
        self.sender(from).map(Egress::counters).unwrap_or_default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::{Link, LinkConfig};
    use rand::SeedableRng;

    fn egress(from: usize, to: usize) -> Egress {
        Egress::new(vec![Link::new(
            from,
            to,
            LinkConfig::default(),
            crate::rng::Rng::seed_from_u64(1),
        )])
    }

    /// Senders added in any order are each found, and no other.
    #[test]
    fn senders_in_any_order_are_found() {
        let m = PairwiseMedium::new()
            .with_sender(5, egress(5, 6))
            .with_sender(2, egress(2, 3))
            .with_sender(9, egress(9, 1));
        for (from, to) in [(5, 6), (2, 3), (9, 1)] {
            assert!(m.carries(from));
            assert_eq!(m.counters(from)[0].0, to);
        }
        for from in [0, 1, 3, 4, 6, 8, 10, 1000] {
            assert!(!m.carries(from), "{from}");
        }
    }

    /// What a sender transmits is delivered from that sender alone, intact, on a link with no fault.
    #[test]
    fn a_transmission_is_delivered_from_its_sender() {
        let mut m = PairwiseMedium::new()
            .with_sender(3, egress(3, 4))
            .with_sender(1, egress(1, 4));
        let tx = Transmission {
            to: Dest::Node(4),
            at: Time::from_secs(0.5),
            group: vec![Bytes::from_static(b"a"), Bytes::from_static(b"b")],
            stream: Stream::Measurement,
        };
        m.transmit(3, tx, &FaultSchedule::default());
        assert!(m.poll_delivery(1, Time::MAX).is_none());
        let got: Vec<_> = std::iter::from_fn(|| m.poll_delivery(3, Time::from_secs(0.5)))
            .map(|d| (d.from, d.to, d.bytes))
            .collect();
        assert_eq!(
            got,
            vec![(3, 4, Bytes::from_static(b"a")), (3, 4, Bytes::from_static(b"b"))]
        );
        assert_eq!(m.counters(3)[0].1.sent, 1);
    }

    /// A broadcast is decided on each of the sender's links as that many unicasts are: the same fates, draw for
    /// draw, at 50 % loss with duplication and jitter.
    #[test]
    fn a_broadcast_is_each_link_deciding_alone() {
        let lossy = || {
            let c = LinkConfig {
                loss: crate::link::LossModel::Bernoulli { p: 0.5 },
                duplicate: 0.2,
                delay_ms: 5.0,
                jitter_ms: 4.0,
                ..LinkConfig::default()
            };
            let links = (1..4)
                .map(|to| Link::new(0, to, c, crate::rng::Rng::seed_from_u64(to as u64)))
                .collect();
            PairwiseMedium::new().with_sender(0, Egress::new(links))
        };
        let (mut broadcast, mut unicast) = (lossy(), lossy());
        let faults = FaultSchedule::default();
        for k in 0..200u8 {
            let at = Time::at_step(u64::from(k), 0.01);
            let group = vec![Bytes::from(vec![k; 3])];
            let tx = |to| Transmission {
                to,
                at,
                group: group.clone(),
                stream: Stream::Measurement,
            };
            broadcast.transmit(0, tx(Dest::Broadcast), &faults);
            for to in 1..4 {
                unicast.transmit(0, tx(Dest::Node(to)), &faults);
            }
        }
        let all = |m: &mut PairwiseMedium| {
            let mut v: Vec<_> = std::iter::from_fn(|| m.poll_delivery(0, Time::MAX))
                .map(|d| (d.to, d.bytes))
                .collect();
            v.sort();
            v
        };
        let got = all(&mut broadcast);
        assert!((250..450).contains(&got.len()), "{} delivered of 600 sent", got.len());
        assert_eq!(got, all(&mut unicast));
        assert_eq!(broadcast.counters(0), unicast.counters(0));
    }
}
