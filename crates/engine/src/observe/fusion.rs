//! The observer side of a run: covariance-intersection fusion of the nodes' networked estimates each step
//! (cascaded, ω = 0.5 as §7 of Sequeira (2023), and the trace-optimal ω), a 20-sample median filter on the
//! fused trajectory, and their figures. The median is centred (samples k−10 … k+9), as Sequeira (2023, §7) smooths an offline
//! reconstruction: a causal median would trail a moving package by half its window.

use nalgebra::DVector;
use serde::{Deserialize, Serialize};

use crate::estimate::fusion::{cascade, CentredMedian, Omega};
use crate::estimate::Gaussian;
use crate::model::FusionLayout;
use crate::observe::metrics::FilterMetrics;

/// What a node hands the observer after each update (for fusion and plots).
#[derive(Debug, Clone)]
pub struct StepEstimate {
    pub node: usize,
    pub step: u64,
    pub truth: DVector<f64>,
    /// The coordinate frame of `truth` and `networked` (see `Truth::frame`).
    pub frame: u64,
    /// The networked filter's estimate (none where the model's nodes observe differently: no such filter).
    pub networked: Option<Gaussian>,
    pub diverged: bool,
    /// Each distributed estimator's estimate, by kind (the run's order).
    pub schemes: Vec<SchemeEstimate>,
}

/// One distributed estimator's estimate at a node.
#[derive(Debug, Clone, PartialEq)]
#[allow(non_snake_case)]
pub struct SchemeEstimate {
    pub kind: crate::estimators::Kind,
    pub x: DVector<f64>,
    /// Its covariance; none where it is not known (a part of an earlier build that `simnet collect` reads back carries the estimate only).
    pub P: Option<nalgebra::DMatrix<f64>>,
}

/// The trace-optimal cascade runs a line search per stage; above this many nodes it is skipped.
pub const OPTIMAL_FUSION_MAX_NODES: usize = 16;
pub const MEDIAN_WINDOW: usize = 20;

/// One fused sample, for plots.
#[derive(Debug, Clone)]
pub struct FusedRow {
    pub step: u64,
    pub truth: Vec<f64>,
    pub fused: Vec<f64>,
    pub median: Vec<f64>,
    pub error: f64,
    pub median_error: f64,
    /// trace P of the fused estimate.
    pub trace_p: f64,
    /// `median` is the 20-sample median (pose); else it is the fused estimate itself.
    pub smoothed: bool,
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct FusedSummary {
    /// Nodes fused per step (estimating, not diverged).
    pub nodes: usize,
    pub omega: f64,
    pub mean_error: Option<f64>,
    pub mean_trace_p: Option<f64>,
    /// The fused trajectory after the 20-sample median filter (pose model only).
    pub median_mean_error: Option<f64>,
    /// Cascade with the trace-minimising ω at every stage.
    pub optimal_mean_error: Option<f64>,
    pub optimal_mean_trace_p: Option<f64>,
}

pub struct Observer {
    burn_in: u64,
    /// Angle rows, error rows, smoothing and quaternion sign of the model.
    layout: FusionLayout,
    fixed: FilterMetrics,
    optimal: FilterMetrics,
    /// (step, truth, fused, trace P) of the error rows whose median is not known yet, in step order.
    waiting: std::collections::VecDeque<(u64, Vec<f64>, Vec<f64>, f64)>,
    /// The centred median of the current coordinate frame.
    smoother: CentredMedian,
    frame: u64,
    /// Sum and count of the median-filtered error after the burn-in.
    median_sum: f64,
    median_n: u64,
    /// Finished rows not yet taken by [`Observer::drain_rows`] (kept only when `record`).
    rows: Vec<FusedRow>,
    nodes: usize,
    record: bool,
    /// The distributed estimators' agreement and the centralized reference (when the run holds any).
    schemes: Option<super::schemes::SchemeObserver>,
}

impl Observer {
    /// The observer of a run whose model fuses as `layout`; `record` keeps the fused rows for plots.
    pub fn new(burn_in: u64, layout: FusionLayout, record: bool) -> Observer {
        Observer {
            burn_in,
            layout,
            fixed: FilterMetrics::default(),
            optimal: FilterMetrics::default(),
            waiting: Default::default(),
            smoother: CentredMedian::new(MEDIAN_WINDOW),
            frame: 0,
            median_sum: 0.0,
            median_n: 0,
            rows: Vec::new(),
            nodes: 0,
            record,
            schemes: None,
        }
    }

    /// Also follow the distributed estimators.
    pub fn with_schemes(mut self, s: super::schemes::SchemeObserver) -> Observer {
        self.schemes = Some(s);
        self
    }

    pub fn schemes(&self) -> Option<&super::schemes::SchemeObserver> {
        self.schemes.as_ref()
    }

    /// One step's reference feeds (before [`Observer::push`] of the same step).
    pub fn push_feeds(&mut self, feeds: Vec<super::schemes::Feed>) {
        if let Some(s) = self.schemes.as_mut() {
            s.push_feeds(feeds);
        }
    }

    /// The estimators' node rows since the last call (with `record`), for `estimators.csv`.
    pub fn drain_estimator_rows(&mut self) -> Vec<super::schemes::EstimatorRow> {
        self.schemes.as_mut().map(|s| s.drain_node_rows()).unwrap_or_default()
    }

    pub fn layout(&self) -> &FusionLayout {
        &self.layout
    }

    fn error(&self, truth: &DVector<f64>, x: &DVector<f64>) -> f64 {
        self.layout.distance(&self.layout.pick(truth), &self.layout.pick(x))
    }

    /// Fuse one step's estimates (any order; they are sorted by node).
    pub fn push(&mut self, mut estimates: Vec<StepEstimate>) {
        estimates.sort_by_key(|e| e.node);
        if let Some(s) = self.schemes.as_mut() {
            s.push(&estimates);
        }
        estimates.retain(|e| !e.diverged && e.networked.is_some());
        let Some(first) = estimates.first() else { return };
        // The truth of the first node that knows it (a recording without reference columns does not).
        let scored = estimates
            .iter()
            .find(|e| e.truth.iter().all(|v| v.is_finite()))
            .unwrap_or(first);
        let (step, frame, truth) = (first.step, scored.frame, scored.truth.clone());
        let counted = step >= self.burn_in;
        self.nodes = self.nodes.max(estimates.len());
        let mut gs: Vec<Gaussian> = estimates.into_iter().filter_map(|e| e.networked).collect();
        self.layout.align(&mut gs);
        let Ok(fused) = cascade(&gs, Omega::Fixed(0.5), &self.layout.angle_states) else {
            return;
        };
        // A recording without reference has no truth to score against.
        let known = truth.iter().all(|v| v.is_finite());
        let err = known.then(|| self.error(&truth, &fused.x));
        let tr = fused.P.trace();
        self.fixed.record(counted, err, tr, tr, None, true);
        if gs.len() <= OPTIMAL_FUSION_MAX_NODES {
            if let Ok(opt) = cascade(&gs, Omega::TraceOptimal, &self.layout.angle_states) {
                let t2 = opt.P.trace();
                let e2 = known.then(|| self.error(&truth, &opt.x));
                self.optimal.record(counted, e2, t2, t2, None, true);
            }
        }
        let (t, f) = (self.layout.pick(&truth), self.layout.pick(&fused.x));
        // The median window never straddles a change of coordinate frame.
        if frame != self.frame {
            self.end_segment();
            self.frame = frame;
        }
        self.waiting.push_back((step, t, f.clone(), tr));
        // Without the smoother (attitude, linear) the "median" is the fused estimate itself.
        if !self.layout.median {
            self.release(f);
        } else if let Some((_, m)) = self.smoother.push(f) {
            self.release(m);
        }
    }

    /// The oldest waiting sample's median is known.
    fn release(&mut self, median: Vec<f64>) {
        let Some((step, truth, fused, trace_p)) = self.waiting.pop_front() else {
            return;
        };
        let median_error = self.layout.distance(&truth, &median);
        if step >= self.burn_in {
            self.median_sum += median_error;
            self.median_n += 1;
        }
        if self.record {
            self.rows.push(FusedRow {
                step,
                error: self.layout.distance(&truth, &fused),
                median_error,
                truth,
                fused,
                median,
                trace_p,
                smoothed: self.layout.median,
            });
        }
    }

    fn end_segment(&mut self) {
        for (_, m) in self.smoother.finish() {
            self.release(m);
        }
    }

    /// The run has ended: the last samples get their (shrunken-window) medians.
    pub fn finish(&mut self) {
        self.end_segment();
    }

    /// Fused rows finished since the last call, in step order (with `record`); a median lags its step by half the
    /// window.
    pub fn drain_rows(&mut self) -> Vec<FusedRow> {
        std::mem::take(&mut self.rows)
    }

    pub fn summary(&self) -> Option<FusedSummary> {
        if self.nodes == 0 {
            return None;
        }
        let f = self.fixed.summary(false);
        let o = self.optimal.summary(false);
        let median_mean_error =
            (self.layout.median && self.median_n > 0).then(|| self.median_sum / self.median_n as f64);
        Some(FusedSummary {
            nodes: self.nodes,
            omega: 0.5,
            mean_error: f.mean_error,
            mean_trace_p: f.mean_trace_p_post,
            median_mean_error: median_mean_error.filter(|v| v.is_finite()),
            optimal_mean_error: o.mean_error,
            optimal_mean_trace_p: o.mean_trace_p_post,
        })
    }
}
