//! A node's way out: each outgoing link's verdict carried out — copies queued at their delivery time, corrupted
//! copies with their bit flipped — and handed to the transport in delivery order. The node only says what it sends.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use bytes::Bytes;

use super::{FaultSchedule, Link, LinkCounters, Verdict};
use crate::time::Time;

/// A datagram ready to leave for node `to`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Transmit {
    /// Receiving node, by index.
    pub to: usize,
    /// The datagram.
    pub bytes: Bytes,
}

#[derive(Debug)]
struct Pending {
    at: Time,
    order: u64,
    tx: Transmit,
}
impl PartialEq for Pending {
    fn eq(&self, o: &Self) -> bool {
        self.at == o.at && self.order == o.order
    }
}
impl Eq for Pending {}
impl PartialOrd for Pending {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Pending {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        self.at.cmp(&o.at).then(self.order.cmp(&o.order))
    }
}

/// Which of a link's two seeded streams decides a group's fate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stream {
    /// The measurements (and the round-0 messages that travel with them).
    Measurement,
    /// Consensus round r with no measurement beside it: a stream of its own per round, so that the measurements'
    /// fates do not depend on which estimators a run holds, nor round r's on how many rounds there are.
    Round(usize),
}

/// The outgoing links of one node and the copies they have yet to deliver.
#[derive(Debug)]
pub struct Egress {
    links: Vec<Link>,
    /// `rounds[r][i]`: link i drawing from its stream of round r (empty when the run has no consensus rounds).
    rounds: Vec<Vec<Link>>,
    queue: BinaryHeap<Reverse<Pending>>,
    /// Ties in delivery time leave in the order they were queued.
    order: u64,
}

impl Egress {
    /// A node's egress over its out-links.
    pub fn new(links: Vec<Link>) -> Egress {
        Egress::with_rounds(links, Vec::new())
    }

    /// `rounds[r][i]`: link i on its stream of round r.
    pub fn with_rounds(links: Vec<Link>, rounds: Vec<Vec<Link>>) -> Egress {
        Egress {
            links,
            rounds,
            queue: BinaryHeap::new(),
            order: 0,
        }
    }

    /// The node out-link `link` goes to.
    pub fn to(&self, link: usize) -> usize {
        self.links[link].to
    }

    /// The out-link to node `to`, if there is one.
    pub fn link_to(&self, to: usize) -> Option<usize> {
        self.links.iter().position(|l| l.to == to)
    }

    /// Out-links.
    pub fn len(&self) -> usize {
        self.links.len()
    }

    /// No out-link.
    pub fn is_empty(&self) -> bool {
        self.links.is_empty()
    }

    /// Send the datagrams of one slot under one verdict, drawn from `stream` for the first datagram: every copy
    /// the link makes carries all of them with the same delay, and a corrupted copy has a bit flipped in each.
    pub fn push_group(&mut self, link: usize, now: Time, group: &[Bytes], faults: &FaultSchedule, stream: Stream) {
        let Some(first) = group.first() else { return };
        let l = match stream {
            Stream::Measurement => &mut self.links[link],
            Stream::Round(r) => match self.rounds.get_mut(r).and_then(|ls| ls.get_mut(link)) {
                Some(l) => l,
                None => return,
            },
        };
        let to = l.to;
        let Verdict::Deliver(copies) = l.verdict(now, first.len(), faults) else {
            return;
        };
        for c in copies {
            for bytes in group {
                let bytes = match c.flip_bit {
                    Some(bit) if !bytes.is_empty() => {
                        let bit = bit % (bytes.len() * 8);
                        let mut v = bytes.to_vec();
                        v[bit / 8] ^= 1 << (bit % 8);
                        Bytes::from(v)
                    }
                    _ => bytes.clone(),
                };
                self.order += 1;
                self.queue.push(Reverse(Pending {
                    at: now + c.delay,
                    order: self.order,
                    tx: Transmit { to, bytes },
                }));
            }
        }
    }

    /// The next copy due at or before `now`, in delivery order.
    pub fn poll_transmit(&mut self, now: Time) -> Option<(Time, Transmit)> {
        if self.queue.peek().is_some_and(|Reverse(p)| p.at <= now) {
            self.queue.pop().map(|Reverse(p)| (p.at, p.tx))
        } else {
            None
        }
    }

    /// When the next queued copy is due.
    pub fn poll_timeout(&self) -> Option<Time> {
        self.queue.peek().map(|Reverse(p)| p.at)
    }

    /// Sender-side counters of each outgoing link, by destination.
    pub fn counters(&self) -> Vec<(usize, LinkCounters)> {
        self.links.iter().map(|l| (l.to, *l.counters())).collect()
    }

    /// The same for the round streams, by round (empty without consensus rounds).
    pub fn round_counters(&self) -> Vec<Vec<(usize, LinkCounters)>> {
        self.rounds
            .iter()
            .map(|ls| ls.iter().map(|l| (l.to, *l.counters())).collect())
            .collect()
    }
}
