//! The linear model x⁺ = A x + w, y = C x + v (w ~ N(0, Q), v ~ N(0, R)): the setting of Sinopoli et al. (2004)
//! and of the Riccati analyses in `estimate::bounds`. The truth is the system itself, driven by the node's seeded
//! process noise.
#![allow(non_snake_case)]

use nalgebra::{DMatrix, DVector, Vector3};

use super::{Dynamics, FusionLayout, GroundTruth, Manifold, Measurement, Report, Sensed, Sensing, Site, Truth};
use crate::estimate::{Gaussian, Observation};
use crate::imu_csv::StepRecording;
use crate::motion::Trajectory;
use crate::rng::Rng;
use crate::sensor::{ImuInterval, ImuSample, Sensor, SensorProfile};

/// x⁺ = A x + w, y = C x + v.
#[derive(Debug, Clone)]
pub struct Linear {
    A: DMatrix<f64>,
    C: DMatrix<f64>,
    Q: DMatrix<f64>,
    R: DMatrix<f64>,
    x0: DVector<f64>,
    P0: DMatrix<f64>,
    /// Lower Cholesky factor of R, for simulating the measurement noise (`None` when R is not positive definite,
    /// which validation rejects).
    R_chol: Option<DMatrix<f64>>,
}

impl Linear {
    /// The model of its matrices (validated by the caller); the truth's process noise is drawn from Q.
    pub fn new(
        A: DMatrix<f64>,
        C: DMatrix<f64>,
        Q: DMatrix<f64>,
        R: DMatrix<f64>,
        x0: DVector<f64>,
        P0: DMatrix<f64>,
    ) -> Linear {
        // nalgebra's Cholesky panics on a non-square matrix; validation reports that shape, here it only has no factor.
        let R_chol = R
            .is_square()
            .then(|| nalgebra::Cholesky::new(R.clone()))
            .flatten()
            .map(|c| c.l());
        Linear {
            A,
            C,
            Q,
            R,
            x0,
            P0,
            R_chol,
        }
    }

    /// The transition matrix A.
    pub fn A(&self) -> &DMatrix<f64> {
        &self.A
    }
    /// The observation matrix C.
    pub fn C(&self) -> &DMatrix<f64> {
        &self.C
    }
    /// The process noise covariance Q.
    pub fn Q(&self) -> &DMatrix<f64> {
        &self.Q
    }
    /// The measurement noise covariance R.
    pub fn R(&self) -> &DMatrix<f64> {
        &self.R
    }
    /// The initial state x₀.
    pub fn x0(&self) -> &DVector<f64> {
        &self.x0
    }
    /// The initial covariance P₀.
    pub fn P0(&self) -> &DMatrix<f64> {
        &self.P0
    }

    /// State dimension n.
    pub fn state_dim(&self) -> usize {
        self.A.nrows()
    }
}

impl Dynamics for Linear {
    fn imu_driven(&self) -> bool {
        false
    }

    fn process_noise(&self, _imu: Option<&SensorProfile>, _dt: f64) -> DMatrix<f64> {
        self.Q.clone()
    }

    fn predict(&self, g: &Gaussian, _imu: Option<&ImuInterval>, noise: &DMatrix<f64>, _dt: f64) -> Gaussian {
        crate::estimate::predict(g, &self.A, noise)
    }
}

impl Sensing for Linear {
    fn observation(&self) -> Observation {
        Observation {
            H: self.C.clone(),
            R: self.R.clone(),
            angle_rows: vec![false; self.C.nrows()],
            channel_of_row: vec![0; self.C.nrows()],
        }
    }

    /// y = C x + v.
    fn sense(&self, sensor: &mut Sensor, truth: &Truth, _site: Site, _t: f64) -> Sensed {
        let (Some(x), Some(r_chol)) = (truth.linear_state(), self.R_chol.as_ref()) else {
            return Sensed::default();
        };
        Sensed {
            imu: None,
            z: Some(Measurement::full(sensor.linear(&self.C, r_chol, x))),
            row: None,
        }
    }
}

impl Manifold for Linear {
    fn angle_states(&self) -> Vec<bool> {
        vec![false; self.state_dim()]
    }
}

impl GroundTruth for Linear {
    fn truth(
        &self,
        _trajectory: Trajectory,
        _dt: f64,
        seed: u64,
        _recorded: Option<std::sync::Arc<StepRecording>>,
    ) -> Truth {
        Truth::linear(
            &self.A,
            &self.Q,
            &self.x0,
            &self.P0,
            crate::rng::stream(seed, "truth", 0, 0),
        )
    }

    /// A linear system has no kinematics; its truth is its own state.
    fn kinematic_state(
        &self,
        _p: Option<Vector3<f64>>,
        _v: Option<Vector3<f64>>,
        _e: Option<Vector3<f64>>,
    ) -> DVector<f64> {
        DVector::repeat(self.state_dim(), f64::NAN)
    }

    /// x₀, P₀, from which the truth itself is drawn.
    fn initial(
        &self,
        _truth: &DVector<f64>,
        _first: Option<(&ImuSample, Option<&Vector3<f64>>)>,
        _rng: &mut Rng,
    ) -> Gaussian {
        Gaussian {
            x: self.x0.clone(),
            P: self.P0.clone(),
        }
    }
}

impl Report for Linear {
    fn columns(&self) -> Vec<String> {
        (0..self.state_dim()).map(|i| format!("x{i}")).collect()
    }

    fn reported(&self, state: &DVector<f64>) -> Vec<f64> {
        state.iter().copied().collect()
    }

    fn reported_var(&self, g: &Gaussian) -> Vec<f64> {
        g.P.diagonal().iter().copied().collect()
    }

    fn fusion(&self) -> FusionLayout {
        FusionLayout {
            angle_states: self.angle_states(),
            error_rows: (0..self.state_dim()).collect(),
            median: false,
            quaternion: false,
        }
    }
}
