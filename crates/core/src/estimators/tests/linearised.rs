//! A model that linearises says so in `linearize_at` alone, and every estimator sees it.

use std::borrow::Cow;
use std::sync::Arc;

use nalgebra::{DMatrix, DVector, Vector3};

use super::*;
use crate::estimate::{kalman_update, MissingChannels};
use crate::imu_csv::StepRecording;
use crate::model::Dynamics;
use crate::model::{FusionLayout, GroundTruth, Linear, Manifold, Measurement, Report, Sensed, Sensing, Truth};
use crate::motion::Trajectory;
use crate::rng::Rng;
use crate::sensor::{ImuInterval, ImuSample, Sensor, SensorProfile};

/// z = H x + c: a linear model whose observation has an offset, which only its `linearize_at` takes off.
#[derive(Debug)]
struct Offset {
    inner: Linear,
    c: f64,
}

impl Dynamics for Offset {
    fn imu_driven(&self) -> bool {
        self.inner.imu_driven()
    }
    fn process_noise(&self, imu: Option<&SensorProfile>, dt: f64) -> DMatrix<f64> {
        self.inner.process_noise(imu, dt)
    }
    fn predict(&self, g: &Gaussian, imu: Option<&ImuInterval>, noise: &DMatrix<f64>, dt: f64) -> Gaussian {
        self.inner.predict(g, imu, noise, dt)
    }
}

impl Sensing for Offset {
    fn observation(&self) -> Observation {
        self.inner.observation()
    }
    fn linearize_at<'a>(
        &self,
        template: &'a Observation,
        _prior: &Gaussian,
        z: &[&'a DVector<f64>],
    ) -> (Cow<'a, Observation>, Vec<Cow<'a, DVector<f64>>>) {
        let shifted = z.iter().map(|z| Cow::Owned(z.add_scalar(-self.c))).collect();
        (Cow::Borrowed(template), shifted)
    }
    fn sense(&self, sensor: &mut Sensor, truth: &Truth, t: f64) -> Sensed {
        self.inner.sense(sensor, truth, t)
    }
}

impl Manifold for Offset {
    fn angle_states(&self) -> Vec<bool> {
        self.inner.angle_states()
    }
}

impl GroundTruth for Offset {
    fn truth(&self, trajectory: Trajectory, dt: f64, seed: u64, recorded: Option<Arc<StepRecording>>) -> Truth {
        self.inner.truth(trajectory, dt, seed, recorded)
    }
    fn kinematic_state(
        &self,
        p: Option<Vector3<f64>>,
        v: Option<Vector3<f64>>,
        a: Option<Vector3<f64>>,
    ) -> DVector<f64> {
        self.inner.kinematic_state(p, v, a)
    }
    fn initial(
        &self,
        truth: &DVector<f64>,
        imu: Option<(&ImuSample, Option<&Vector3<f64>>)>,
        rng: &mut Rng,
    ) -> Gaussian {
        self.inner.initial(truth, imu, rng)
    }
}

impl Report for Offset {
    fn columns(&self) -> Vec<String> {
        self.inner.columns()
    }
    fn reported(&self, state: &DVector<f64>) -> Vec<f64> {
        self.inner.reported(state)
    }
    fn reported_var(&self, g: &Gaussian) -> Vec<f64> {
        self.inner.reported_var(g)
    }
    fn fusion(&self) -> FusionLayout {
        self.inner.fusion()
    }
}

/// The independent filter of a model that only overrides `linearize_at` is the Kalman update of the measurement
/// it hands back (z − c), not of the raw one: the estimators ask the model nothing else.
#[test]
fn a_models_linearisation_reaches_every_update() {
    let A = DMatrix::from_row_slice(2, 2, &[1.0, 0.1, 0.0, 1.0]);
    let obs = Observation {
        H: DMatrix::from_row_slice(1, 2, &[1.0, 0.0]),
        R: DMatrix::from_element(1, 1, 0.25),
        angle_rows: vec![false],
        channel_of_row: vec![0],
    };
    let Q = DMatrix::identity(2, 2) * 0.01;
    let model = Offset {
        inner: linear_model(&A, &obs, &Q),
        c: 3.0,
    };
    let prior = Gaussian {
        x: DVector::from_vec(vec![0.5, -0.2]),
        P: DMatrix::from_row_slice(2, 2, &[1.0, 0.2, 0.2, 0.5]),
    };
    let own = Measurement::full(DVector::from_vec(vec![4.1]));
    let heard = [(0, &own)];
    let input = StepInput {
        model: &model,
        obs: &obs,
        own: Some(&own),
        heard: &heard,
        step: 1,
    };
    let mut local = Local::new(prior.clone(), MissingChannels::Drop);
    local.finish(&input).unwrap();
    let want = kalman_update(
        &prior,
        &obs,
        &DVector::from_vec(vec![1.1]),
        &[true],
        MissingChannels::Drop,
    )
    .unwrap();
    let got = local.state().unwrap();
    assert!(
        (&got.x - &want.x).amax() < 1e-12 && (&got.P - &want.P).amax() < 1e-12,
        "{got:?} against {want:?}"
    );
    // The raw measurement would have moved the estimate elsewhere: the test can tell the two apart.
    let raw = kalman_update(&prior, &obs, &own.z, &[true], MissingChannels::Drop).unwrap();
    assert!((&raw.x - &want.x).amax() > 0.1);
}
