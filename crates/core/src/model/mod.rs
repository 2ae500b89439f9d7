//! The estimation models: [`Model`] is five traits by role — [`Dynamics`] (process noise, prediction), [`Sensing`]
//! (observation, its linearisation, a step's IMU sample and measurement), [`Manifold`] (angles, unit quaternions,
//! a double cover), [`GroundTruth`] (the truth and the prior) and [`Report`] (columns, fusion layout, error) — and
//! any type with the five is a model; [`register`] names one so that a topology file can run it. A caller holding a concrete model imports the role it calls
//! (`use simnet::model::Dynamics` for `predict`); a `&dyn Model` has them all. [`pose`] (position, velocity and Euler angles
//! driven by the IMU, §2 of Sequeira (2023)), [`attitude`] (the quaternion EKF of Lesecq's slides) and [`linear`]
//! (x⁺ = A x + w, y = C x + v, the setting of Sinopoli et al. (2004)).
//!
//! Everything that depends on which model a scenario runs is a method of [`Model`]; the rest of simnet holds a
//! `&dyn Model` and never asks which one it is. A measurement's observation may depend on who took it ([`Site`]: a
//! range from where each node stands); [`Observed`] gives a model's dynamics, truth and report another
//! [`Sensing`].
#![allow(non_snake_case)]

pub mod attitude;
pub mod linear;
mod observed;
mod parse;
pub mod pose;
pub mod ranges;
mod registry;
mod truth;

use std::borrow::Cow;
use std::sync::Arc;

use nalgebra::{DMatrix, DVector, Vector3};
use serde::{Deserialize, Serialize};

use crate::estimate::{Gaussian, Observation};
pub use crate::imu_csv::ImuRow;
use crate::imu_csv::StepRecording;
use crate::motion::Trajectory;
use crate::rng::Rng;
use crate::sensor::{ImuInterval, ImuSample, Sensor, SensorProfile};

pub use attitude::Attitude;
pub use linear::Linear;
pub use observed::Observed;
pub use parse::RawModel;
pub use parse::{matrix_rows, parse, to_raw};
pub use pose::Pose;
pub use ranges::Ranges;
pub use registry::{register, Builder, Kind, RegisterError, Registration};
pub use truth::{psd_sqrt, Truth, REBASE_LIMIT};

/// The model a scenario runs, as validated.
#[derive(Debug, Clone)]
#[allow(clippy::large_enum_variant)] // one per scenario
pub enum ModelConfig {
    /// The pose model.
    Pose(Pose),
    /// The attitude model.
    Attitude(Attitude),
    /// A linear model.
    Linear(Linear),
    /// A linear model's body ranged by every node from where it stands (`observe = "ranges"`): [`Ranges`] on
    /// [`Linear`]'s dynamics.
    Ranged {
        /// The dynamics, truth and prior (its C unused: a zero row).
        linear: Linear,
        /// The model the nodes run.
        model: Observed<Ranges>,
    },
    /// A model a program registered ([`register`]), built from its `[model.params]` table.
    Registered {
        /// Its place in the registry.
        kind: Kind,
        /// The `[model.params]` table it was built from (a scenario written back to TOML carries it).
        params: toml::Table,
        /// The model.
        model: Arc<dyn Model>,
    },
}

impl ModelConfig {
    /// The model behind its trait.
    pub fn get(&self) -> &dyn Model {
        match self {
            ModelConfig::Pose(m) => m,
            ModelConfig::Attitude(m) => m,
            ModelConfig::Linear(m) => m,
            ModelConfig::Ranged { model, .. } => model,
            ModelConfig::Registered { model, .. } => &**model,
        }
    }

    /// Which model it is.
    pub fn kind(&self) -> Kind {
        match self {
            ModelConfig::Pose(_) => Kind::Pose,
            ModelConfig::Attitude(_) => Kind::Attitude,
            ModelConfig::Linear(_) | ModelConfig::Ranged { .. } => Kind::Linear,
            ModelConfig::Registered { kind, .. } => *kind,
        }
    }

    /// A shared handle for the nodes of a run.
    pub fn shared(&self) -> Arc<dyn Model> {
        match self {
            ModelConfig::Pose(m) => Arc::new(m.clone()),
            ModelConfig::Attitude(m) => Arc::new(m.clone()),
            ModelConfig::Linear(m) => Arc::new(m.clone()),
            ModelConfig::Ranged { model, .. } => Arc::new(model.clone()),
            ModelConfig::Registered { model, .. } => model.clone(),
        }
    }

    /// Where each node stands (node i at `sites[i]`, m, in the plane): the sites a ranged model's nodes measure
    /// from; nothing for any other model.
    pub fn stand_at(&mut self, sites: Vec<[f64; 2]>) {
        if let ModelConfig::Ranged { linear, model } = self {
            if let Some(s) = Ranges::planar(sites, linear.A().nrows(), model.sensing.r()) {
                model.sensing = s;
            }
        }
    }

    /// The linear system y = C x + v, for the analyses that need one (Sinopoli's bounds); none for a ranged model,
    /// whose observation is not C x.
    pub fn as_linear(&self) -> Option<&Linear> {
        match self {
            ModelConfig::Linear(m) => Some(m),
            _ => None,
        }
    }
}

/// A measurement: values and which rows are present.
#[derive(Debug, Clone, PartialEq)]
pub struct Measurement {
    /// The measurement vector (a missing row holds any value).
    pub z: DVector<f64>,
    /// Which rows arrived.
    pub present: Vec<bool>,
}

impl Measurement {
    /// Every row present.
    pub fn full(z: DVector<f64>) -> Measurement {
        let m = z.len();
        Measurement {
            z,
            present: vec![true; m],
        }
    }

    /// `m` rows, none present.
    pub fn empty(m: usize) -> Measurement {
        Measurement {
            z: DVector::zeros(m),
            present: vec![false; m],
        }
    }

    /// No row present again (its buffers kept for another step).
    pub fn clear(&mut self) {
        self.z.fill(0.0);
        self.present.fill(false);
    }

    /// Merge rows; false when every row was already there (a duplicate).
    pub fn merge(&mut self, rows: u64, values: &[f64]) -> bool {
        let mut new = false;
        let mut it = values.iter();
        for r in 0..self.present.len().min(64) {
            if rows & (1 << r) != 0 {
                let v = *it.next().unwrap_or(&0.0);
                if !self.present[r] {
                    self.present[r] = true;
                    self.z[r] = v;
                    new = true;
                }
            }
        }
        new
    }
}

/// What a node senses at one step.
#[derive(Debug, Clone, Default)]
pub struct Sensed {
    /// The IMU sample that drives the prediction.
    pub imu: Option<ImuSample>,
    /// The measurement that travels to the neighbours.
    pub z: Option<Measurement>,
    /// The simulated IMU with its truth, for `imu-ID.csv`.
    pub row: Option<ImuRow>,
}

/// How the observer fuses the nodes' estimates and scores the result: data, so that a part of a multi-host run
/// carries it to `simnet collect`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FusionLayout {
    /// State rows that are angles (wrapped before averaging).
    pub angle_states: Vec<bool>,
    /// The rows the error is taken over (position for pose, all for attitude and linear).
    pub error_rows: Vec<usize>,
    /// The fused trajectory is median-filtered (pose).
    pub median: bool,
    /// The error rows are a unit quaternion: errors are rotation angles (degrees), and estimates share one sign
    /// before fusion.
    pub quaternion: bool,
}

impl FusionLayout {
    /// The error rows of `v`.
    pub fn pick(&self, v: &DVector<f64>) -> Vec<f64> {
        self.error_rows.iter().map(|&i| v[i]).collect()
    }

    /// The error between two picks of the error rows: rotation angle in degrees, else the Euclidean distance.
    pub fn distance(&self, a: &[f64], b: &[f64]) -> f64 {
        if self.quaternion {
            let q = |v: &[f64]| nalgebra::Vector4::new(v[0], v[1], v[2], v[3]);
            crate::estimate::attitude::angle_between(&q(a), &q(b)).to_degrees()
        } else {
            a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>().sqrt()
        }
    }

    /// [`FusionLayout::distance`] of the error rows of `truth` and `est`, read in place; `None` where the truth is
    /// not known.
    pub fn error(&self, truth: &DVector<f64>, est: &DVector<f64>) -> Option<f64> {
        if !self.error_rows.iter().all(|&i| truth[i].is_finite()) {
            return None;
        }
        Some(if self.quaternion {
            let q = |v: &DVector<f64>| {
                let r = &self.error_rows;
                nalgebra::Vector4::new(v[r[0]], v[r[1]], v[r[2]], v[r[3]])
            };
            crate::estimate::attitude::angle_between(&q(truth), &q(est)).to_degrees()
        } else {
            self.error_rows
                .iter()
                .map(|&i| (truth[i] - est[i]).powi(2))
                .sum::<f64>()
                .sqrt()
        })
    }

    /// Bring estimates to one side of the double cover (q and −q are one attitude) before they are fused.
    pub fn align(&self, gs: &mut [Gaussian]) {
        if !self.quaternion || gs.is_empty() {
            return;
        }
        let first = gs[0].x.clone();
        for g in gs.iter_mut() {
            if g.x.dot(&first) < 0.0 {
                g.x = -&g.x;
            }
        }
    }
}

/// How the trajectory plot shows a model's reported columns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrajectoryView {
    /// Columns 0 and 1 in the plane, at equal scale (pose).
    Plane,
    /// Three angle columns against time, one panel each (attitude).
    Angles,
    /// Column 0 against time (linear).
    FirstColumn,
}

/// The words and units of a model's error figures.
#[derive(Debug, Clone, Copy)]
pub struct ErrorText {
    /// The unit with its leading space (" m", "°", "").
    pub unit: &'static str,
    /// For axis labels of campaign plots: "mean position error, m".
    pub label: &'static str,
    /// For the error-against-time plot: "position error (m)".
    pub axis: &'static str,
    /// The table's legend: "errors: mean position error, m".
    pub legend: &'static str,
}

/// How the state moves: the process noise a filter uses and one prediction step.
pub trait Dynamics {
    /// The node's IMU drives the prediction (so a recorded IMU may replace it).
    fn imu_driven(&self) -> bool {
        true
    }

    /// The process noise a node's filter uses: from its IMU's noise densities, or, without an IMU, wide enough to
    /// cover the motion it cannot sense.
    fn process_noise(&self, imu: Option<&SensorProfile>, dt: f64) -> DMatrix<f64>;

    /// One prediction step (eq. (4) of Sequeira (2023)); `imu` holds the samples at both ends of the interval.
    fn predict(&self, g: &Gaussian, imu: Option<&ImuInterval>, noise: &DMatrix<f64>, dt: f64) -> Gaussian;
}

/// Who took a measurement: the context an observation h(x, site) may depend on beyond the state. Every node of
/// simnet's built-in models observes alike (one h for all); a model whose nodes observe from where each stands — a
/// range from node `node` to a body whose position is in the state, or to another node — reads it here, and says so
/// with [`Sensing::observes_alike`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Site {
    /// The node that took the measurement, by index.
    pub node: usize,
}

/// What a node measures: the observation (H, R, channels), its linearisation about a prior, and the sampling of a
/// step's IMU and measurement.
///
/// A model whose nodes observe differently gives each [`Site`] its own h. Here every node measures its range to a
/// body at x = (p_x, p_y) from where it stands, h(x, site) = ‖x − a_site‖, linearised about the prior as an EKF does:
///
/// ```
/// use std::borrow::Cow;
/// use nalgebra::{DMatrix, DVector};
/// use simnet_core::estimate::{Gaussian, Observation};
/// use simnet_core::model::{Sensed, Sensing, Site, Truth};
/// use simnet_core::sensor::Sensor;
///
/// struct Ranges {
///     /// Where each node stands.
///     at: Vec<[f64; 2]>,
/// }
///
/// impl Sensing for Ranges {
///     fn observation(&self) -> Observation {
///         Observation {
///             H: DMatrix::zeros(1, 2),
///             R: DMatrix::from_element(1, 1, 0.01),
///             angle_rows: vec![false],
///             channel_of_row: vec![0],
///         }
///     }
///     fn observes_alike(&self) -> bool {
///         false
///     }
///     /// h(x) ≈ h(x̂) + H (x − x̂), H = (x̂ − a)ᵀ / ‖x̂ − a‖: the innovation z − h(x̂) for a linear update.
///     fn linearize_at<'a>(
///         &self,
///         template: &'a Observation,
///         prior: &Gaussian,
///         site: Site,
///         z: &[&'a DVector<f64>],
///     ) -> (Cow<'a, Observation>, Vec<Cow<'a, DVector<f64>>>) {
///         let a = DVector::from_column_slice(&self.at[site.node]);
///         let d = &prior.x - a;
///         let h = d.norm();
///         let H = DMatrix::from_row_slice(1, 2, &[d[0] / h, d[1] / h]);
///         let offset = h - (&H * &prior.x)[0];
///         let obs = Observation { H, ..template.clone() };
///         (Cow::Owned(obs), z.iter().map(|z| Cow::Owned(z.add_scalar(-offset))).collect())
///     }
///     fn sense(&self, _: &mut Sensor, _: &Truth, _: Site, _: f64) -> Sensed {
///         Sensed::default()
///     }
/// }
///
/// let ranges = Ranges { at: vec![[0.0, 0.0], [10.0, 0.0]] };
/// let prior = Gaussian { x: DVector::from_vec(vec![3.0, 4.0]), P: DMatrix::identity(2, 2) };
/// let z = DVector::from_vec(vec![5.0]);
/// let template = ranges.observation();
/// // Node 0 at the origin sees the body 5 m away along (0.6, 0.8); node 1 sees it along (−7, 4)/√65.
/// let (obs, zs) = ranges.linearize_at(&template, &prior, Site { node: 0 }, &[&z]);
/// assert!((obs.H[(0, 0)] - 0.6).abs() < 1e-12 && (obs.H[(0, 1)] - 0.8).abs() < 1e-12);
/// assert!((zs[0][0] - 5.0).abs() < 1e-12, "h(x̂) − H x̂ = 0 from the origin");
/// let (obs, _) = ranges.linearize_at(&template, &prior, Site { node: 1 }, &[&z]);
/// assert!((obs.H[(0, 0)] + 7.0 / 65f64.sqrt()).abs() < 1e-12);
/// ```
pub trait Sensing {
    /// The observation: H, R and the channel of each row (for a non-linear model a template whose H is
    /// [`Sensing::linearize_at`]'s).
    fn observation(&self) -> Observation;

    /// Whether every node observes by one h, so that a measurement reads the same whoever took it (the default).
    /// The β-weighted consensus of Sequeira (2023), eqs. (5)–(10), forms one gain for every source and needs it.
    fn observes_alike(&self) -> bool {
        true
    }

    /// The observation of the measurements `z` that node `site` took, about `prior`, and the measurements in its
    /// coordinates: as they are (borrowed), unless the model is non-linear or its nodes observe differently. Every
    /// estimator takes H and z from here, so a model that linearises says so here alone.
    fn linearize_at<'a>(
        &self,
        template: &'a Observation,
        _prior: &Gaussian,
        _site: Site,
        z: &[&'a DVector<f64>],
    ) -> (Cow<'a, Observation>, Vec<Cow<'a, DVector<f64>>>) {
        (Cow::Borrowed(template), z.iter().map(|z| Cow::Borrowed(*z)).collect())
    }

    /// This step's IMU sample and the measurement node `site` takes at `t`.
    fn sense(&self, sensor: &mut Sensor, truth: &Truth, site: Site, t: f64) -> Sensed;
}

/// Where the state lives: rows that are angles, the return to a unit quaternion, the sign of a double cover.
pub trait Manifold {
    /// State rows that are angles (wrapped after each step).
    fn angle_states(&self) -> Vec<bool>;

    /// Bring an updated state back onto its manifold.
    fn normalize(&self, _g: &mut Gaussian) {}

    /// The truth with the sign of `est` where states have two representations (a NEES needs it).
    fn aligned(&self, truth: &DVector<f64>, _est: &DVector<f64>) -> DVector<f64> {
        truth.clone()
    }
}

/// The ground truth: the truth a node computes, the true state from kinematics, and the prior a filter starts from.
pub trait GroundTruth {
    /// The ground truth a node computes for itself: the trajectory, its recording's reference columns, or the
    /// model's own random system.
    fn truth(&self, trajectory: Trajectory, dt: f64, _seed: u64, recorded: Option<Arc<StepRecording>>) -> Truth {
        match recorded {
            Some(rec) => Truth::recorded(rec),
            None => Truth::motion(trajectory, dt),
        }
    }

    /// The true state in the filter's coordinates, from the kinematics (a component not known is `None`).
    fn kinematic_state(
        &self,
        p: Option<Vector3<f64>>,
        v: Option<Vector3<f64>>,
        euler: Option<Vector3<f64>>,
    ) -> DVector<f64>;

    /// The prior a (re)started filter begins from, `truth` the true state (NaN where unknown) and `first` the
    /// recorded IMU sample and magnetometer at this step, where the IMU is a recording.
    fn initial(
        &self,
        truth: &DVector<f64>,
        first: Option<(&ImuSample, Option<&Vector3<f64>>)>,
        rng: &mut Rng,
    ) -> Gaussian;
}

/// What a run reports of the model: the columns of `trace.csv`, the fusion layout and the error figure.
pub trait Report {
    /// The names of the columns `trace.csv` reports.
    fn columns(&self) -> Vec<String>;

    /// The reported columns of a state.
    fn reported(&self, state: &DVector<f64>) -> Vec<f64>;

    /// The variances of the reported columns.
    fn reported_var(&self, g: &Gaussian) -> Vec<f64>;

    /// Which state rows the fusion observer fuses, and how.
    fn fusion(&self) -> FusionLayout;

    /// The error figure of an estimate over the fusion layout's error rows; `None` where the truth is not known.
    fn error(&self, truth: &DVector<f64>, est: &DVector<f64>) -> Option<f64> {
        self.fusion().error(truth, est)
    }
}

/// One estimation model: its [`Dynamics`], [`Sensing`], [`Manifold`], [`GroundTruth`] and [`Report`]. A node holds it as
/// `&dyn Model`; so do the observer, the recorders and the plots. Every type with the five roles is a model.
pub trait Model: Dynamics + Sensing + Manifold + GroundTruth + Report + Send + Sync + std::fmt::Debug {}

impl<T: Dynamics + Sensing + Manifold + GroundTruth + Report + Send + Sync + std::fmt::Debug> Model for T {}

/// Standard normal samples.
pub fn randn(rng: &mut Rng, n: usize) -> DVector<f64> {
    DVector::from_fn(n, |_, _| rand::Rng::sample(rng, rand_distr::StandardNormal))
}

/// The stacked measurement [a; b].
pub fn stacked(a: &Vector3<f64>, b: &Vector3<f64>) -> DVector<f64> {
    DVector::from_iterator(6, a.iter().chain(b.iter()).copied())
}
