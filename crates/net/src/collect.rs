//! What the workers of both clocks hand in after each step, and the task that fuses the steps in order, off the
//! workers' path.

use std::collections::btree_map::Entry;
use std::collections::BTreeMap;
use std::sync::Arc;

use tokio::sync::mpsc;

use simnet_engine::node::{Closed, ImuRow, MeasurementRow, Node, StepEstimate, TraceRow};
use simnet_engine::observe::fusion::Observer;
use simnet_engine::report::trace::TraceWriter;
use simnet_engine::scenario::Scenario;
use simnet_engine::sim::{observer_for, Progress};

/// One worker's share of a step: its nodes' estimates and rows.
pub(super) struct StepOut {
    pub step: u64,
    pub estimates: Vec<StepEstimate>,
    pub rows: Vec<TraceRow>,
    pub imu: Vec<(u32, Vec<ImuRow>)>,
    pub measurements: Vec<MeasurementRow>,
    pub feeds: Vec<simnet_engine::node::Feed>,
}

impl StepOut {
    /// Nothing of step `step` yet.
    pub fn new(step: u64) -> StepOut {
        StepOut {
            step,
            estimates: Vec::new(),
            rows: Vec::new(),
            imu: Vec::new(),
            measurements: Vec::new(),
            feeds: Vec::new(),
        }
    }

    /// Close step `step` of `nodes` at its deadline: their estimates and rows.
    pub fn close<'a>(step: u64, nodes: impl ExactSizeIterator<Item = &'a mut Node>) -> StepOut {
        let mut out = StepOut::new(step);
        out.estimates.reserve(nodes.len());
        for node in nodes {
            let closed = node.handle_timeout(node.scenario().deadline(step));
            out.take(node, closed);
        }
        out
    }

    /// What `node` has of the step it just closed (`closed`, as its `handle_timeout` returned it).
    pub fn take(&mut self, node: &mut Node, closed: Option<Closed>) {
        self.measurements.append(&mut node.take_measurements());
        self.estimates.extend(closed.and_then(|c| c.estimate));
        self.feeds.extend(node.take_feed());
        self.rows.append(&mut node.take_trace());
        let imu = node.take_imu();
        if !imu.is_empty() {
            self.imu.push((node.id(), imu));
        }
    }
}

/// Fuse each step once all `workers` have handed it in, in step order; `on_fused(n)` hears that the first n steps
/// are fused. A step some worker never handed in (the run stopped first) is not fused.
pub(super) async fn observe(
    topo: Arc<Scenario>,
    workers: usize,
    mut trace: Option<TraceWriter>,
    progress: Option<Progress>,
    mut on_fused: impl FnMut(u64),
    mut steps_in: mpsc::UnboundedReceiver<StepOut>,
) -> (Observer, Option<TraceWriter>) {
    let mut observer = observer_for(&topo, trace.is_some());
    let steps = topo.sim().steps();
    let mut pending: BTreeMap<u64, (usize, StepOut)> = BTreeMap::new();
    let mut next = 0;
    while let Some(mut s) = steps_in.recv().await {
        match pending.entry(s.step) {
            Entry::Vacant(v) => {
                v.insert((1, s));
            }
            Entry::Occupied(mut o) => {
                let (n, acc) = o.get_mut();
                *n += 1;
                acc.estimates.append(&mut s.estimates);
                acc.rows.append(&mut s.rows);
                acc.imu.append(&mut s.imu);
                acc.measurements.append(&mut s.measurements);
                acc.feeds.append(&mut s.feeds);
            }
        }
        while pending
            .first_key_value()
            .is_some_and(|(k, (n, _))| *k == next && *n == workers)
        {
            let Some((_, (_, mut step))) = pending.pop_first() else {
                break;
            };
            observer.push_feeds(step.feeds);
            observer.push(step.estimates);
            if let Some(t) = trace.as_mut() {
                for (id, rows) in &step.imu {
                    t.imu(*id, rows);
                }
                step.measurements.sort_by_key(|m| m.node);
                t.measurements(&step.measurements);
                step.rows.sort_by_key(|r| (r.node, r.filter));
                t.rows(step.rows);
                t.fused(observer.drain_rows());
                t.estimators(&observer.drain_estimator_rows());
            }
            next += 1;
            on_fused(next);
            if let Some(p) = &progress {
                p(next, steps);
            }
        }
    }
    observer.finish();
    if let Some(t) = trace.as_mut() {
        t.fused(observer.drain_rows());
    }
    (observer, trace)
}

/// Contiguous blocks of the nodes, one per worker (neighbours in a ring or a grid mostly share one), and the number
/// of workers: one per core, at most one per node.
pub(super) fn blocks(n: usize) -> Vec<std::ops::Range<usize>> {
    let workers = std::thread::available_parallelism()
        .map_or(1, |p| p.get())
        .clamp(1, n.max(1));
    let per = n.div_ceil(workers).max(1);
    (0..workers).map(|w| (w * per).min(n)..((w + 1) * per).min(n)).collect()
}
