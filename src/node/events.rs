//! What a node reports: the rows of `trace.csv`, the estimate each step hands the observer, its counters and its
//! end-of-run report.

use crate::estimate::{Gaussian, LmiTerms};
use crate::imu_csv::ImuRow;
use crate::link::LinkCounters;
use crate::observe::metrics::{FilterMetrics, RxCounters};
use crate::scenario::Role;
use nalgebra::DVector;

/// One row of `trace.csv`.
#[derive(Debug, Clone)]
pub struct TraceRow {
    pub step: u64,
    pub t: f64,
    pub node: u32,
    pub networked: bool,
    pub truth: Vec<f64>,
    pub est: Vec<f64>,
    pub trace_p_prior: f64,
    pub trace_p_post: f64,
    /// Source ids whose measurements were used.
    pub received: Vec<u32>,
    pub feasible: bool,
    pub nees: f64,
    /// The step's error figure ([`crate::model::Model::error`]); NaN where the truth is unknown.
    pub error: f64,
    /// The posterior variances of the reported columns (±3σ bands).
    pub var: Vec<f64>,
    /// The filter has diverged at or before this step.
    pub diverged: bool,
}

/// What a node hands the observer after each update (for fusion and plots).
#[derive(Debug, Clone)]
pub struct StepEstimate {
    pub node: usize,
    pub step: u64,
    pub truth: DVector<f64>,
    /// The coordinate frame of `truth` and `networked` (see `Truth::frame`).
    pub frame: u64,
    pub networked: Gaussian,
    pub diverged: bool,
}

/// A datagram the node accepted as coming from a neighbour (its shell learns addresses and step timing from it).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Arrival {
    pub src: usize,
    pub step: u64,
    pub measurement: bool,
}

/// Datagram counters not tied to a link.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct NodeCounters {
    pub datagrams_in: u64,
    /// Undecodable datagrams other than checksum failures (garbage, wrong magic, unknown source, …).
    pub malformed: u64,
    /// Checksum failures of datagrams from known peers.
    pub corrupted: u64,
    /// Measurements for a step this node has not reached yet, held until it does.
    pub early: u64,
    pub restarts: u64,
    pub steps_down: u64,
    /// Networked updates whose LMI terms could not be computed for a protocol search (left out of it).
    #[serde(default)]
    pub lmi_failures: u64,
    /// The first step this node ran (0 unless it joined a running network late).
    pub first_step: u64,
    pub steps_run: u64,
}

/// Everything a node reports at the end of a run.
#[derive(Debug, Clone)]
pub struct NodeReport {
    pub index: usize,
    pub id: u32,
    pub role: Role,
    pub networked: Option<FilterMetrics>,
    pub independent: Option<FilterMetrics>,
    /// Outgoing links (sender-side counters).
    pub links_out: Vec<(usize, LinkCounters)>,
    /// Per-source receive counters, indexed by node index.
    pub rx: Vec<RxCounters>,
    pub counters: NodeCounters,
    pub trace: Vec<TraceRow>,
    /// The IMU samples with the true pose, when traces are recorded (pose model, sensing nodes).
    pub imu: Vec<ImuRow>,
}

/// One networked update's LMI terms with the node index of each source (own measurement included), in the order of
/// `terms.kz`.
#[derive(Debug, Clone)]
pub struct LmiStep {
    pub k: u64,
    pub sources: Vec<usize>,
    pub terms: LmiTerms,
}
