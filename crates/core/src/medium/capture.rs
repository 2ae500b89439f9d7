//! A capture tap: a medium around another that records all it carries, as a packet capture at both ends of every
//! link would — each datagram sent (numbered by its sender, in sending order) and each copy delivered, matched to
//! the datagram it is a copy of — so that every datagram's fate (delivered, duplicated, corrupted on the way, lost)
//! can be read off a run. It changes nothing it carries: a run with the tap on gives the same figures as without.
//!
//! A copy is matched by its bytes to what its sender sent (a 64-bit hash per datagram, kept for the run); a copy
//! whose bytes match nothing its sender sent had a bit flipped on the way, and has no datagram number. Memory grows
//! with the run: 80 bytes a line (one per datagram sent, one per copy delivered) and some 50 a datagram for the
//! matching.

use std::collections::hash_map::DefaultHasher;
use std::collections::HashMap;
use std::hash::{Hash, Hasher};
use std::sync::{Arc, Mutex};

use super::{Delivery, Medium, Transmission};
use crate::link::{FaultSchedule, LinkCounters, Stream};
use crate::time::Time;

/// What a line of a capture records.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Event {
    /// A datagram handed to the medium.
    Sent,
    /// A copy the medium delivered.
    Delivered,
}

/// One line of a capture.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Captured {
    /// When it was sent, or when the copy is due at its receiver.
    pub at: Time,
    /// Sent or delivered.
    pub event: Event,
    /// The sending node, by index.
    pub from: usize,
    /// The receiving node, by index; none for a broadcast as sent (each copy delivered names its receiver).
    pub to: Option<usize>,
    /// The sender's number for the datagram (0, 1, … in sending order); for a copy, the number of the datagram it
    /// is a copy of, none when its bytes match nothing its sender sent (corrupted on the way).
    pub datagram: Option<u64>,
    /// Its length, bytes.
    pub len: usize,
    /// Which of the link's streams carried it (a corrupted copy's is unknown).
    pub stream: Option<Stream>,
}

/// Where a capture's lines go, shared by every part of a medium split by sender (one per UDP worker).
#[derive(Debug, Clone, Default)]
pub struct CaptureLog(Arc<Mutex<Vec<Captured>>>);

impl CaptureLog {
    /// An empty log.
    pub fn new() -> CaptureLog {
        CaptureLog::default()
    }

    fn push(&self, c: Captured) {
        self.0.lock().unwrap_or_else(|e| e.into_inner()).push(c);
    }

    /// Every line so far, in order of time (then sent before delivered, sender, receiver, number): the same order
    /// however the senders were split.
    pub fn take(&self) -> Vec<Captured> {
        let mut lines = std::mem::take(&mut *self.0.lock().unwrap_or_else(|e| e.into_inner()));
        lines.sort_by_key(|c| (c.at, c.event, c.from, c.to, c.datagram, c.len));
        lines
    }
}

/// One sender's numbers: the next, and those of what it sent, by the hash of the datagram's bytes.
#[derive(Debug, Default)]
struct Numbers {
    next: u64,
    sent: HashMap<u64, (u64, Stream)>,
}

/// `inner`, recording what it carries into a [`CaptureLog`] (or nothing, when off).
#[derive(Debug)]
pub struct Capture<M> {
    inner: M,
    log: Option<CaptureLog>,
    senders: HashMap<usize, Numbers>,
}

impl<M: Medium> Capture<M> {
    /// `inner` with the tap recording into `log`.
    pub fn new(inner: M, log: CaptureLog) -> Capture<M> {
        Capture {
            inner,
            log: Some(log),
            senders: HashMap::new(),
        }
    }

    /// `inner` with the tap off: it only passes everything on.
    pub fn off(inner: M) -> Capture<M> {
        Capture {
            inner,
            log: None,
            senders: HashMap::new(),
        }
    }

    /// The medium it taps.
    pub fn inner(&self) -> &M {
        &self.inner
    }
}

fn digest(bytes: &[u8]) -> u64 {
    // SipHash with fixed keys: the same numbers on every run.
    let mut h = DefaultHasher::new();
    bytes.hash(&mut h);
    h.finish()
}

impl<M: Medium> Medium for Capture<M> {
    fn transmit(&mut self, from: usize, tx: Transmission, faults: &FaultSchedule) {
        if let Some(log) = &self.log {
            let numbers = self.senders.entry(from).or_default();
            let to = match tx.to {
                super::Dest::Node(j) => Some(j),
                super::Dest::Broadcast => None,
            };
            for bytes in &tx.group {
                let n = numbers.next;
                numbers.next += 1;
                numbers.sent.insert(digest(bytes), (n, tx.stream));
                log.push(Captured {
                    at: tx.at,
                    event: Event::Sent,
                    from,
                    to,
                    datagram: Some(n),
                    len: bytes.len(),
                    stream: Some(tx.stream),
                });
            }
        }
        self.inner.transmit(from, tx, faults);
    }

    fn poll_delivery(&mut self, from: usize, now: Time) -> Option<Delivery> {
        let d = self.inner.poll_delivery(from, now)?;
        if let Some(log) = &self.log {
            let matched = self.senders.get(&from).and_then(|s| s.sent.get(&digest(&d.bytes)));
            log.push(Captured {
                at: d.at,
                event: Event::Delivered,
                from,
                to: Some(d.to),
                datagram: matched.map(|m| m.0),
                len: d.bytes.len(),
                stream: matched.map(|m| m.1),
            });
        }
        Some(d)
    }

    fn poll_timeout(&self, from: usize) -> Option<Time> {
        self.inner.poll_timeout(from)
    }

    fn counters(&self, from: usize) -> Vec<(usize, LinkCounters)> {
        self.inner.counters(from)
    }
    fn radio(&self, node: usize) -> Option<super::radio::RadioCounters> {
        self.inner.radio(node)
    }
    fn radio_links(&self, from: usize) -> Vec<(usize, super::radio::LinkQuality)> {
        self.inner.radio_links(from)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::{Egress, Link, LinkConfig, LossModel};
    use crate::medium::{Dest, PairwiseMedium};
    use bytes::Bytes;
    use rand::SeedableRng;

    /// Node 0 sends to nodes 1 and 2 over links that lose, duplicate and corrupt: every line of the capture agrees
    /// with the links' own counters, and the tap changes nothing delivered.
    #[test]
    fn the_capture_agrees_with_the_links_counters_and_changes_nothing() {
        let config = LinkConfig {
            loss: LossModel::Bernoulli { p: 0.3 },
            duplicate: 0.2,
            corrupt: 0.1,
            ..LinkConfig::default()
        };
        let medium = || {
            let links = (1..3)
                .map(|to| Link::new(0, to, config, crate::rng::Rng::seed_from_u64(to as u64)))
                .collect();
            PairwiseMedium::new().with_sender(0, Egress::new(links))
        };
        let log = CaptureLog::new();
        let (mut tapped, mut bare) = (Capture::new(medium(), log.clone()), medium());
        let faults = FaultSchedule::default();
        let (mut got, mut want) = (Vec::new(), Vec::new());
        for k in 0..500u64 {
            let to = if k % 5 == 0 { Dest::Node(2) } else { Dest::Broadcast };
            let tx = Transmission {
                to,
                at: Time::from_nanos(k * 10_000_000),
                group: vec![Bytes::from(format!("datagram {k}").into_bytes())],
                stream: Stream::Measurement,
            };
            tapped.transmit(0, tx.clone(), &faults);
            bare.transmit(0, tx, &faults);
            got.extend(std::iter::from_fn(|| tapped.poll_delivery(0, Time::MAX)));
            want.extend(std::iter::from_fn(|| bare.poll_delivery(0, Time::MAX)));
        }
        assert_eq!(got, want, "the tap changed what was delivered");
        let lines = log.take();
        let sent = lines.iter().filter(|c| c.event == Event::Sent).count();
        assert_eq!(sent, 500);
        for (to, c) in tapped.counters(0) {
            let copies: Vec<&Captured> = lines
                .iter()
                .filter(|l| l.event == Event::Delivered && l.to == Some(to))
                .collect();
            // Each datagram the link did not lose arrives once, twice when duplicated (a bit flipped in either copy or
            // neither).
            let delivered = c.sent - c.lost_random - c.lost_down + c.duplicated;
            assert_eq!(copies.len() as u64, delivered, "copies to {to}");
            assert!(c.corrupted > 0 && c.duplicated > 0 && c.lost_random > 0, "{c:?}");
            let unmatched = copies.iter().filter(|l| l.datagram.is_none()).count() as u64;
            assert_eq!(unmatched, c.corrupted, "corrupted copies to {to}");
            // A copy's number is a datagram sent to it, at or before the copy is due.
            for l in copies.iter().filter(|l| l.datagram.is_some()) {
                let s = lines
                    .iter()
                    .find(|s| s.event == Event::Sent && s.datagram == l.datagram)
                    .unwrap();
                assert!(s.to.is_none_or(|t| t == to) && s.at <= l.at);
            }
        }
        assert!(lines.windows(2).all(|w| w[0].at <= w[1].at));
    }
}
