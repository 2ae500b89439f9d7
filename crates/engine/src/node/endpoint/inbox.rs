//! Step collection: the measurements of the open step, by source, and a bounded buffer of measurements for steps
//! this node has not reached yet (a peer whose clock runs ahead). Receive-side counters per source.

use crate::model::Measurement;
use crate::observe::metrics::RxBySource;
use crate::wire::sequence::Sequence;

/// Most early measurements a node holds.
pub(super) const EARLY_CAP: usize = 256;

/// Where a measurement went.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Received {
    /// For the open step.
    Collected,
    /// For a later step: held until the node reaches it.
    Held,
    /// For a closed step, or the early buffer is full.
    Late,
}

#[derive(Debug)]
pub(super) struct Inbox {
    /// Rows of a measurement.
    m: usize,
    /// The step whose measurements are being collected.
    open: Option<u64>,
    own: Option<Measurement>,
    /// The open step's measurements by source (sorted); a closed step's come back ([`Inbox::recycle`]), so that a
    /// step allocates none.
    from: Vec<(usize, Measurement)>,
    spare: Vec<Measurement>,
    /// (step, source, rows, values) of measurements for later steps.
    early: Vec<(u64, usize, u64, Vec<f64>)>,
    /// `early`'s other buffer: a step's opening sorts the held measurements from one into the other.
    early_back: Vec<(u64, usize, u64, Vec<f64>)>,
    /// Receive counters, by source node index.
    pub rx: RxBySource,
    /// The numbers seen on each link in, by (source, broadcast or addressed to this node), sorted.
    seqs: Vec<((usize, bool), Numbered)>,
}

/// The numbers one link in has carried: those of the sender's boot now, and the gaps of its earlier boots.
#[derive(Debug, Default)]
struct Numbered {
    /// The boot they are of (none before the first).
    boot: Option<u64>,
    now: Sequence,
    earlier: u64,
}

impl Inbox {
    /// `sources`: the in-neighbours, whose counters exist from the start.
    pub fn new(sources: impl IntoIterator<Item = usize>, m: usize) -> Inbox {
        Inbox {
            m,
            open: None,
            own: None,
            from: Vec::new(),
            spare: Vec::new(),
            early: Vec::new(),
            early_back: Vec::new(),
            rx: RxBySource::for_sources(sources),
            seqs: Vec::new(),
        }
    }

    /// Number `seq` of `src`'s broadcasts (or of its datagrams to this node) came, from its boot `boot` (one boot
    /// in a run of one process; a process's boot as its hellos vouch for it).
    pub fn numbered(&mut self, src: usize, broadcast: bool, boot: u64, seq: u32) {
        let key = (src, broadcast);
        let i = match self.seqs.binary_search_by_key(&key, |(k, _)| *k) {
            Ok(i) => i,
            Err(i) => {
                self.seqs.insert(i, (key, Numbered::default()));
                i
            }
        };
        let n = &mut self.seqs[i].1;
        match n.boot {
            Some(b) if b != boot => {
                // A later boot numbers again, from wherever it stands: counted from the first number accepted.
                n.earlier += n.now.missing();
                n.now = Sequence::from_first(seq);
            }
            _ => {
                n.now.see(seq);
            }
        }
        n.boot = Some(boot);
    }

    /// The receive counters with each source's sequence gaps.
    pub fn counters(&self) -> RxBySource {
        let mut rx = self.rx.clone();
        for ((src, _), n) in &self.seqs {
            rx.get_mut(*src).seq_gaps += n.earlier + n.now.missing();
        }
        rx
    }

    /// The node is down: nothing is collected.
    pub fn close_down(&mut self) {
        self.open = None;
        self.spare.extend(self.from.drain(..).map(|(_, m)| m));
    }

    /// A closed step's measurements, back for the next steps.
    pub fn recycle(&mut self, mut from: Vec<(usize, Measurement)>) {
        self.spare.extend(from.drain(..).map(|(_, m)| m));
        if self.from.is_empty() && from.capacity() > self.from.capacity() {
            self.from = from;
        }
    }

    /// Collect for step `k`, the node's own measurement `own`; measurements held for `k` are collected now.
    pub fn open(&mut self, k: u64, own: Option<Measurement>) {
        self.open = Some(k);
        self.spare.extend(self.from.drain(..).map(|(_, m)| m));
        self.own = own;
        std::mem::swap(&mut self.early, &mut self.early_back);
        let mut held = std::mem::take(&mut self.early_back);
        for (step, src, rows, values) in held.drain(..) {
            if step == k {
                self.collect(src, rows, &values);
            } else if step > k {
                self.early.push((step, src, rows, values));
            } else {
                self.rx.get_mut(src).late += 1;
            }
        }
        self.early_back = held;
    }

    pub fn own(&self) -> Option<&Measurement> {
        self.own.as_ref()
    }

    /// A measurement of `src` for `step`.
    pub fn receive(&mut self, src: usize, step: u64, rows: u64, values: Vec<f64>) -> Received {
        match self.open {
            Some(k) if step == k => {
                self.collect(src, rows, &values);
                Received::Collected
            }
            Some(k) if step > k && self.early.len() < EARLY_CAP => {
                self.early.push((step, src, rows, values));
                Received::Held
            }
            _ => {
                self.rx.get_mut(src).late += 1;
                Received::Late
            }
        }
    }

    fn collect(&mut self, src: usize, rows: u64, values: &[f64]) {
        let i = match self.from.binary_search_by_key(&src, |(s, _)| *s) {
            Ok(i) => i,
            Err(i) => {
                let m = match self.spare.pop() {
                    Some(mut m) => {
                        m.clear();
                        m
                    }
                    None => Measurement::empty(self.m),
                };
                self.from.insert(i, (src, m));
                i
            }
        };
        if self.from[i].1.merge(rows, values) {
            self.rx.get_mut(src).delivered += 1;
        } else {
            self.rx.get_mut(src).duplicates += 1;
        }
    }

    /// Close step `k`: what arrived from each source (by source), counting the steps of `expected` sources that
    /// missed it. `None` when `k` is not the open step.
    pub fn close(&mut self, k: u64, expected: &[usize]) -> Option<Vec<(usize, Measurement)>> {
        if self.open != Some(k) {
            return None;
        }
        self.open = None;
        let from = std::mem::take(&mut self.from);
        for &j in expected {
            self.rx.get_mut(j).steps += 1;
            if from.binary_search_by_key(&j, |(s, _)| *s).is_err() {
                self.rx.get_mut(j).missing_steps += 1;
            }
        }
        Some(from)
    }
}

#[cfg(test)]
mod tests {
    use super::Inbox;

    /// Gaps are counted per stream and per boot of the sender: a later boot, numbering afresh or going on from where
    /// its process stood, is counted from its first number accepted, and its earlier boot's gaps are kept.
    #[test]
    fn gaps_are_counted_per_stream_and_per_boot() {
        let mut inbox = Inbox::new([1, 2], 3);
        // Source 1's broadcasts 0–9 without 3 and 7; its unicasts 0, 2 (1 lost).
        for seq in (0..10).filter(|s| ![3, 7].contains(s)) {
            inbox.numbered(1, true, 5, seq);
        }
        inbox.numbered(1, false, 5, 0);
        inbox.numbered(1, false, 5, 2);
        assert_eq!(inbox.counters().get(1).seq_gaps, 3);
        // Its next boot numbers from 0 again: 0, 1, 3 (2 lost); then a third boot from 40 on: 40, 42 (41 lost).
        for seq in [0, 1, 3] {
            inbox.numbered(1, true, 6, seq);
        }
        for seq in [40, 42] {
            inbox.numbered(1, true, 7, seq);
        }
        assert_eq!(inbox.counters().get(1).seq_gaps, 3 + 1 + 1);
        assert_eq!(inbox.counters().get(2).seq_gaps, 0);
    }
}
