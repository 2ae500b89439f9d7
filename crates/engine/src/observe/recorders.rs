//! The rows a node keeps when asked: `trace.csv`'s, the IMU samples, the LMI terms of a protocol search.

use std::sync::Arc;

use super::{Filter, Probe, Score, Update};
use crate::estimate::LmiTerms;
use crate::imu_csv::ImuRow;
use crate::model::Model;

/// One row of `trace.csv`.
#[derive(Debug, Clone)]
pub struct TraceRow {
    pub step: u64,
    pub t: f64,
    pub node: u32,
    /// Which of the node's estimators.
    pub filter: Filter,
    pub truth: Vec<f64>,
    pub est: Vec<f64>,
    pub trace_p_prior: f64,
    pub trace_p_post: f64,
    /// Source ids whose measurements were used.
    pub received: Vec<u32>,
    pub feasible: bool,
    pub nees: f64,
    /// The step's error figure ([`crate::model::Report::error`]); NaN where the truth is unknown.
    pub error: f64,
    /// The posterior variances of the reported columns (±3σ bands).
    pub var: Vec<f64>,
    /// The filter has diverged at or before this step.
    pub diverged: bool,
}

/// Makes one [`TraceRow`] per update, in the model's reported columns.
pub struct TraceRecorder {
    model: Arc<dyn Model>,
    rows: Vec<TraceRow>,
}

impl TraceRecorder {
    pub fn new(model: Arc<dyn Model>) -> TraceRecorder {
        TraceRecorder {
            model,
            rows: Vec::new(),
        }
    }

    /// The rows made since the last call (a shell streams them out step by step).
    pub fn take(&mut self) -> Vec<TraceRow> {
        std::mem::take(&mut self.rows)
    }
}

impl Probe for TraceRecorder {
    fn on_update(&mut self, u: &Update<'_>, s: &Score) {
        self.rows.push(TraceRow {
            step: u.step,
            t: u.t,
            node: u.node,
            filter: u.filter,
            truth: self.model.reported(u.truth),
            est: self.model.reported(&u.post.x),
            trace_p_prior: s.trace_p_prior,
            trace_p_post: s.trace_p_post,
            received: u.received.to_vec(),
            feasible: u.feasible,
            nees: s.nees.unwrap_or(f64::NAN),
            error: s.error.unwrap_or(f64::NAN),
            var: self.model.reported_var(u.post),
            diverged: s.diverged,
        });
    }
}

/// Keeps the IMU samples with the true pose (for `imu-ID.csv`).
#[derive(Debug, Default)]
pub struct ImuRecorder {
    rows: Vec<ImuRow>,
}

impl ImuRecorder {
    /// The rows kept since the last call.
    pub fn take(&mut self) -> Vec<ImuRow> {
        std::mem::take(&mut self.rows)
    }
}

impl Probe for ImuRecorder {
    fn on_imu(&mut self, row: &ImuRow) {
        self.rows.push(*row);
    }
}

/// One networked update's LMI terms with the node index of each source (own measurement included), in the order of
/// `terms.kz`.
#[derive(Debug, Clone)]
pub struct LmiStep {
    pub k: u64,
    pub sources: Vec<usize>,
    pub terms: LmiTerms,
}

/// Keeps the LMI terms of every networked update (a protocol search scores β over them).
#[derive(Debug, Default)]
pub struct LmiRecorder {
    steps: Vec<LmiStep>,
}

impl LmiRecorder {
    pub fn take(&mut self) -> Vec<LmiStep> {
        std::mem::take(&mut self.steps)
    }
}

impl Probe for LmiRecorder {
    fn on_lmi(&mut self, step: &LmiStep) {
        self.steps.push(step.clone());
    }
}

/// One node's own measurement of one step: the rows it carries and their values (`measurements.csv`).
#[derive(Debug, Clone, PartialEq)]
pub struct MeasurementRow {
    pub step: u64,
    pub node: u32,
    /// Rows present, in order, and their values.
    pub rows: Vec<usize>,
    pub values: Vec<f64>,
}

/// Keeps each step's own measurement of a sensing node.
#[derive(Default)]
pub struct MeasurementRecorder {
    rows: Vec<MeasurementRow>,
}

impl MeasurementRecorder {
    pub fn take(&mut self) -> Vec<MeasurementRow> {
        std::mem::take(&mut self.rows)
    }
}

impl Probe for MeasurementRecorder {
    fn on_measurement(&mut self, m: &MeasurementRow) {
        self.rows.push(m.clone());
    }
}
