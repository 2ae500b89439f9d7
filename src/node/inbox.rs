//! Step collection: the measurements of the open step, by source, and a bounded buffer of measurements for steps
//! this node has not reached yet (a peer whose clock runs ahead). Receive-side counters per source.

use std::collections::BTreeMap;

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
    from: BTreeMap<usize, Measurement>,
    /// (step, source, rows, values) of measurements for later steps.
    early: Vec<(u64, usize, u64, Vec<f64>)>,
    /// Receive counters, by source node index.
    pub rx: RxBySource,
    /// The numbers seen on each link in: (source, broadcast or addressed to this node), sorted.
    seqs: Vec<((usize, bool), Sequence)>,
}

impl Inbox {
    /// `sources`: the in-neighbours, whose counters exist from the start.
    pub fn new(sources: impl IntoIterator<Item = usize>, m: usize) -> Inbox {
        Inbox {
            m,
            open: None,
            own: None,
            from: BTreeMap::new(),
            early: Vec::new(),
            rx: RxBySource::for_sources(sources),
            seqs: Vec::new(),
        }
    }

    /// Number `seq` of `src`'s broadcasts (or of its datagrams to this node) came.
    pub fn numbered(&mut self, src: usize, broadcast: bool, seq: u32) {
        let key = (src, broadcast);
        let i = match self.seqs.binary_search_by_key(&key, |(k, _)| *k) {
            Ok(i) => i,
            Err(i) => {
                self.seqs.insert(i, (key, Sequence::default()));
                i
            }
        };
        self.seqs[i].1.see(seq);
    }

    /// The receive counters with each source's sequence gaps.
    pub fn counters(&self) -> RxBySource {
        let mut rx = self.rx.clone();
        for ((src, _), q) in &self.seqs {
            rx.get_mut(*src).seq_gaps += q.missing();
        }
        rx
    }

    /// The node is down: nothing is collected.
    pub fn close_down(&mut self) {
        self.open = None;
        self.from.clear();
    }

    /// Collect for step `k`, the node's own measurement `own`; measurements held for `k` are collected now.
    pub fn open(&mut self, k: u64, own: Option<Measurement>) {
        self.open = Some(k);
        self.from.clear();
        self.own = own;
        for (step, src, rows, values) in std::mem::take(&mut self.early) {
            if step == k {
                self.collect(src, rows, &values);
            } else if step > k {
                self.early.push((step, src, rows, values));
            } else {
                self.rx.get_mut(src).late += 1;
            }
        }
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
        let m = self.m;
        let entry = self.from.entry(src).or_insert_with(|| Measurement::empty(m));
        if entry.merge(rows, values) {
            self.rx.get_mut(src).delivered += 1;
        } else {
            self.rx.get_mut(src).duplicates += 1;
        }
    }

    /// Close step `k`: what arrived from each source, counting the steps of `expected` sources that missed it.
    /// `None` when `k` is not the open step.
    pub fn close(&mut self, k: u64, expected: &[usize]) -> Option<BTreeMap<usize, Measurement>> {
        if self.open != Some(k) {
            return None;
        }
        self.open = None;
        let from = std::mem::take(&mut self.from);
        for &j in expected {
            self.rx.get_mut(j).steps += 1;
            if !from.contains_key(&j) {
                self.rx.get_mut(j).missing_steps += 1;
            }
        }
        Some(from)
    }
}
