//! The ground truth as each node computes it for itself: the analytic trajectory (pose) or the linear system driven
//! by its own seeded process noise. Every node derives the same truth from the run seed, so no truth crosses the
//! network and separate processes agree on it.
#![allow(non_snake_case)]

use nalgebra::{DMatrix, DVector};
use rand::Rng as _;
use rand_distr::StandardNormal;

use crate::motion::Trajectory;
use crate::rng::Rng;
use crate::topology::{ModelConfig, Topology};

#[derive(Debug, Clone)]
#[allow(clippy::large_enum_variant)] // one per node
pub enum Truth {
    Pose {
        trajectory: Trajectory,
        dt: f64,
        k: u64,
    },
    Linear {
        x: DVector<f64>,
        A: DMatrix<f64>,
        Q_sqrt: DMatrix<f64>,
        rng: Rng,
        k: u64,
        /// Shift of coordinates not yet applied to the estimates (see `REBASE_LIMIT`).
        shift: Option<DVector<f64>>,
        /// Number of shifts so far: states of different frames must not be mixed (e.g. in a median).
        frame: u64,
    },
}

/// An unstable A makes the true state grow like ρ(A)ᵏ until it overflows (Sinopoli's scalar example: 1.25ᵏ). When
/// it passes this size, truth, estimates and later measurements move to coordinates centred on the current truth.
/// The Kalman filter is affine-equivariant, so errors, gains and covariances are unchanged; only the origin of the
/// reported states moves.
pub const REBASE_LIMIT: f64 = 1e6;

/// A square root of a symmetric positive semidefinite matrix (eigen-decomposition; Q may be singular).
pub fn psd_sqrt(m: &DMatrix<f64>) -> DMatrix<f64> {
    // Validated finite and symmetric PSD before it gets here.
    let e = m.clone().symmetric_eigen();
    let d = e.eigenvalues.map(|v| v.max(0.0).sqrt());
    &e.eigenvectors * DMatrix::from_diagonal(&d)
}

fn randn(rng: &mut Rng, n: usize) -> DVector<f64> {
    DVector::from_fn(n, |_, _| rng.sample(StandardNormal))
}

impl Truth {
    pub fn new(topo: &Topology) -> Truth {
        match &topo.model {
            ModelConfig::Pose(_) => Truth::Pose {
                trajectory: topo.sim.trajectory,
                dt: topo.sim.dt(),
                k: 0,
            },
            ModelConfig::Linear(m) => {
                let mut rng = crate::rng::stream(topo.sim.seed, "truth", 0, 0);
                // x₀ ~ N(x̂₀, P₀), so that the filter's prior is consistent with the truth.
                let x = &m.x0 + psd_sqrt(&m.P0) * randn(&mut rng, m.x0.len());
                Truth::Linear {
                    x,
                    A: m.A.clone(),
                    Q_sqrt: psd_sqrt(&m.Q),
                    rng,
                    k: 0,
                    shift: None,
                    frame: 0,
                }
            }
        }
    }

    pub fn advance_to(&mut self, target: u64) {
        match self {
            Truth::Pose { k, .. } => *k = target,
            Truth::Linear {
                x,
                A,
                Q_sqrt,
                rng,
                k,
                shift,
                frame,
            } => {
                while *k < target {
                    let w = &*Q_sqrt * randn(rng, x.len());
                    *x = &*A * &*x + w;
                    *shift = shift.take().map(|s| &*A * s);
                    if x.amax() > REBASE_LIMIT {
                        *shift = Some(shift.take().unwrap_or_else(|| DVector::zeros(x.len())) - &*x);
                        x.fill(0.0);
                        *frame += 1;
                    }
                    *k += 1;
                }
            }
        }
    }

    /// Which coordinate frame the current states are in (changes at each re-basing).
    pub fn frame(&self) -> u64 {
        match self {
            Truth::Linear { frame, .. } => *frame,
            Truth::Pose { .. } => 0,
        }
    }

    /// A change of origin to add to every estimate predicted to the current step, once.
    pub fn take_shift(&mut self) -> Option<DVector<f64>> {
        match self {
            Truth::Linear { shift, .. } => shift.take(),
            Truth::Pose { .. } => None,
        }
    }

    /// The true state in the filter's coordinates: [p, v, θ] or x.
    pub fn state(&self) -> DVector<f64> {
        match self {
            Truth::Pose { trajectory, dt, k } => {
                let s = trajectory.at(*k as f64 * dt);
                DVector::from_iterator(9, s.p.iter().chain(s.v.iter()).chain(s.euler.iter()).copied())
            }
            Truth::Linear { x, .. } => x.clone(),
        }
    }

    /// The columns written to `trace.csv`: position and attitude for pose, the whole state for linear.
    pub fn reported(&self, state: &DVector<f64>) -> Vec<f64> {
        match self {
            Truth::Pose { .. } => [0, 1, 2, 6, 7, 8].iter().map(|&i| state[i]).collect(),
            Truth::Linear { .. } => state.iter().copied().collect(),
        }
    }

    /// Names of the reported columns.
    pub fn columns(&self) -> Vec<String> {
        match self {
            Truth::Pose { .. } => ["x", "y", "z", "roll", "pitch", "yaw"]
                .iter()
                .map(|s| s.to_string())
                .collect(),
            Truth::Linear { x, .. } => (0..x.len()).map(|i| format!("x{i}")).collect(),
        }
    }
}
