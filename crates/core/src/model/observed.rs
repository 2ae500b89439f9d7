//! A model observed another way: one model's dynamics, manifold, truth and report with a [`Sensing`] of your own,
//! so that a new measurement on an existing motion (ranges to a body the linear model moves, a bearing, a biased
//! fix) is one `Sensing` impl, not five roles.

use std::borrow::Cow;
use std::sync::Arc;

use nalgebra::{DMatrix, DVector, Vector3};

use super::{Dynamics, FusionLayout, GroundTruth, Manifold, Model, Report, Sensed, Sensing, Site, Truth};
use crate::estimate::{Gaussian, Observation};
use crate::imu_csv::StepRecording;
use crate::motion::Trajectory;
use crate::rng::Rng;
use crate::sensor::{ImuInterval, ImuSample, Sensor, SensorProfile};

/// `base`'s every role but [`Sensing`], which is `sensing`'s.
#[derive(Debug, Clone)]
pub struct Observed<S> {
    /// The model whose dynamics, manifold, truth and report it keeps.
    pub base: Arc<dyn Model>,
    /// What the nodes measure.
    pub sensing: S,
}

impl<S> Dynamics for Observed<S> {
    fn imu_driven(&self) -> bool {
        self.base.imu_driven()
    }
    fn process_noise(&self, imu: Option<&SensorProfile>, dt: f64) -> DMatrix<f64> {
        self.base.process_noise(imu, dt)
    }
    fn predict(&self, g: &Gaussian, imu: Option<&ImuInterval>, noise: &DMatrix<f64>, dt: f64) -> Gaussian {
        self.base.predict(g, imu, noise, dt)
    }
}

impl<S: Sensing> Sensing for Observed<S> {
    fn observation(&self) -> Observation {
        self.sensing.observation()
    }
    fn observes_alike(&self) -> bool {
        self.sensing.observes_alike()
    }
    fn linearize_at<'a>(
        &self,
        template: &'a Observation,
        prior: &Gaussian,
        site: Site,
        z: &[&'a DVector<f64>],
    ) -> (Cow<'a, Observation>, Vec<Cow<'a, DVector<f64>>>) {
        self.sensing.linearize_at(template, prior, site, z)
    }
    fn sense(&self, sensor: &mut Sensor, truth: &Truth, site: Site, t: f64) -> Sensed {
        self.sensing.sense(sensor, truth, site, t)
    }
}

impl<S> Manifold for Observed<S> {
    fn angle_states(&self) -> Vec<bool> {
        self.base.angle_states()
    }
    fn normalize(&self, g: &mut Gaussian) {
        self.base.normalize(g)
    }
    fn aligned(&self, truth: &DVector<f64>, est: &DVector<f64>) -> DVector<f64> {
        self.base.aligned(truth, est)
    }
}

impl<S> GroundTruth for Observed<S> {
    fn truth(&self, trajectory: Trajectory, dt: f64, seed: u64, recorded: Option<Arc<StepRecording>>) -> Truth {
        self.base.truth(trajectory, dt, seed, recorded)
    }
    fn kinematic_state(
        &self,
        p: Option<Vector3<f64>>,
        v: Option<Vector3<f64>>,
        euler: Option<Vector3<f64>>,
    ) -> DVector<f64> {
        self.base.kinematic_state(p, v, euler)
    }
    fn initial(
        &self,
        truth: &DVector<f64>,
        first: Option<(&ImuSample, Option<&Vector3<f64>>)>,
        rng: &mut Rng,
    ) -> Gaussian {
        self.base.initial(truth, first, rng)
    }
}

impl<S> Report for Observed<S> {
    fn columns(&self) -> Vec<String> {
        self.base.columns()
    }
    fn reported(&self, state: &DVector<f64>) -> Vec<f64> {
        self.base.reported(state)
    }
    fn reported_var(&self, g: &Gaussian) -> Vec<f64> {
        self.base.reported_var(g)
    }
    fn fusion(&self) -> FusionLayout {
        self.base.fusion()
    }
    fn error(&self, truth: &DVector<f64>, est: &DVector<f64>) -> Option<f64> {
        self.base.error(truth, est)
    }
}
