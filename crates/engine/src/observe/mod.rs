//! What is measured about a run as it goes. A node's testbed ([`crate::node::Testbed`]) scores every update its
//! endpoint hands out against the truth and gives it, each IMU sample and each set of LMI terms to its probes; the
//! fusion observer takes the nodes' estimates of each step.
//!
//! | file | owns |
//! |---|---|
//! | `scorer.rs` | [`Scorer`]: the truth against an update → error, NEES, trace P, divergence, the figures of each filter |
//! | `recorders.rs` | [`TraceRecorder`] (the rows of `trace.csv`), [`ImuRecorder`], [`LmiRecorder`] |
//! | `metrics.rs` | running statistics of one filter ([`metrics::FilterMetrics`]), per-source receive counters |
//! | `fusion.rs` | the observer: covariance-intersection fusion of the nodes' estimates each step, and its median |
//! | `schemes.rs` | the distributed estimators' disagreement and median error each step, the centralized reference |

pub mod fusion;
pub mod metrics;
mod recorders;
pub mod schemes;
mod scorer;

use nalgebra::DVector;

use crate::estimate::Gaussian;
use crate::imu_csv::ImuRow;

pub use fusion::{FusedRow, Observer, SchemeEstimate, StepEstimate};
pub use recorders::{ImuRecorder, LmiRecorder, LmiStep, MeasurementRecorder, MeasurementRow, TraceRecorder, TraceRow};
pub use scorer::Scorer;

/// Which of a node's estimators: its two filters, or a distributed estimator of the run. Ordered as `trace.csv`
/// lists a node's rows of a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Filter {
    /// Consensus over whatever arrived (Sequeira 2023).
    Networked,
    /// The node's own measurement only: the baseline.
    Independent,
    /// A distributed estimator of the run ([`crate::estimators::Kind`]).
    Scheme(crate::estimators::Kind),
}

impl Filter {
    /// Its name in `trace.csv`'s `estimator` column: `networked`, `independent`, or the scheme's name.
    pub fn name(self) -> &'static str {
        match self {
            Filter::Networked => "networked",
            Filter::Independent => "independent",
            Filter::Scheme(kind) => kind.name(),
        }
    }

    /// The estimator `trace.csv` names `name` (none for a fused row, or a scheme this process does not know).
    pub fn from_name(name: &str) -> Option<Filter> {
        match name {
            "networked" => Some(Filter::Networked),
            "independent" => Some(Filter::Independent),
            _ => crate::estimators::Kind::from_name(name).map(Filter::Scheme),
        }
    }
}

/// One filter's update at the deadline of one step, as probes see it.
#[derive(Debug, Clone, Copy)]
pub struct Update<'a> {
    /// The node's id in the file.
    pub node: u32,
    pub step: u64,
    pub t: f64,
    pub filter: Filter,
    /// The true state in the model's coordinates (NaN where a recording has no reference).
    pub truth: &'a DVector<f64>,
    pub prior: &'a Gaussian,
    /// The posterior; the prior carried on when the update `failed`.
    pub post: &'a Gaussian,
    pub failed: bool,
    /// (17) and (19) held (always true but for the networked filter).
    pub feasible: bool,
    /// Ids of the sources whose measurements the update used (left empty when the node has no probe, and for a
    /// distributed estimator, whose messages are not measurements).
    pub received: &'a [u32],
}

/// What the [`Scorer`] made of an update.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Score {
    /// [`crate::model::Report::error`]; none where the truth is unknown.
    pub error: Option<f64>,
    pub nees: Option<f64>,
    pub trace_p_prior: f64,
    pub trace_p_post: f64,
    /// The filter has diverged at or before this step.
    pub diverged: bool,
}

/// Something fed by a node as it runs. Each method defaults to ignoring its event.
///
/// A probe of your own goes on one node with [`crate::Sim::add_probe`] (or a node's `add_probe` under any driver).
/// This one keeps node 0's networked errors after the burn-in; their mean is the one `summary.json` reports:
///
/// ```
/// # extern crate simnet_engine as simnet;
/// use std::sync::{Arc, Mutex};
/// use simnet::observe::{Filter, Probe, Score, Update};
/// use simnet::{Overrides, Scenario, Sim};
///
/// struct Errors {
///     after: u64,
///     seen: Arc<Mutex<Vec<f64>>>,
/// }
///
/// impl Probe for Errors {
///     fn on_update(&mut self, u: &Update<'_>, s: &Score) {
///         if u.filter == Filter::Networked && u.step >= self.after {
///             self.seen.lock().unwrap().extend(s.error);
///         }
///     }
/// }
///
/// let scenario = Scenario::resolve("ring3")?.with(&Overrides { duration_s: Some(3.0), ..Default::default() })?;
/// let seen = Arc::new(Mutex::new(Vec::new()));
/// let mut sim = Sim::new(&scenario)?;
/// sim.add_probe(0, Box::new(Errors { after: scenario.sim().burn_in_steps(), seen: seen.clone() }))?;
/// let summary = sim.run()?.summary();
///
/// let seen = seen.lock().unwrap();
/// let mean = seen.iter().sum::<f64>() / seen.len() as f64;
/// let reported = summary.nodes[0].networked.as_ref().unwrap().mean_error.unwrap();
/// assert_eq!(seen.len() as u64, scenario.sim().steps() - scenario.sim().burn_in_steps());
/// assert!((mean - reported).abs() <= 1e-12 * reported, "{mean} against {reported}");
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub trait Probe: Send {
    /// One filter's update, scored.
    fn on_update(&mut self, _u: &Update<'_>, _s: &Score) {}
    /// The IMU sample of one step, with the true pose.
    fn on_imu(&mut self, _row: &ImuRow) {}
    /// The β-independent LMI terms of one networked update.
    fn on_lmi(&mut self, _step: &LmiStep) {}
    /// The node's own measurement of a step, as it was taken (before any link decided its fate).
    fn on_measurement(&mut self, _m: &MeasurementRow) {}
}

/// The probes of one node: the recorders that are on, then any added (a node's `add_probe`).
#[derive(Default)]
pub struct Probes {
    pub trace: Option<TraceRecorder>,
    pub imu: Option<ImuRecorder>,
    pub lmi: Option<LmiRecorder>,
    pub measurements: Option<MeasurementRecorder>,
    pub added: Vec<Box<dyn Probe>>,
}

impl Probes {
    pub fn is_empty(&self) -> bool {
        self.trace.is_none()
            && self.imu.is_none()
            && self.lmi.is_none()
            && self.measurements.is_none()
            && self.added.is_empty()
    }

    pub fn each(&mut self) -> impl Iterator<Item = &mut dyn Probe> + '_ {
        let trace = self.trace.iter_mut().map(|p| p as &mut dyn Probe);
        let imu = self.imu.iter_mut().map(|p| p as &mut dyn Probe);
        let lmi = self.lmi.iter_mut().map(|p| p as &mut dyn Probe);
        let measurements = self.measurements.iter_mut().map(|p| p as &mut dyn Probe);
        trace
            .chain(imu)
            .chain(lmi)
            .chain(measurements)
            .chain(self.added.iter_mut().map(|p| &mut **p as &mut dyn Probe))
    }
}
