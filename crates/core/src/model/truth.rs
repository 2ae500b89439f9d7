//! The ground truth as each node computes it for itself: the analytic trajectory, the reference columns of its
//! recorded IMU file, or a linear system driven by its own seeded process noise. Every node derives the same truth
//! from the run seed, so no truth crosses the network and separate processes agree on it. The model turns it into
//! the filter's coordinates ([`super::GroundTruth::kinematic_state`]).
#![allow(non_snake_case)]

use std::sync::Arc;

use nalgebra::{DMatrix, DVector, Vector3};

use super::{randn, Model};
use crate::imu_csv::StepRecording;
use crate::motion::{PoseTruth, Trajectory};
use crate::rng::Rng;

/// The truth a node is scored against, step by step.
#[derive(Debug, Clone)]
#[allow(clippy::large_enum_variant)] // one per node
pub enum Truth {
    /// An analytic trajectory sampled at step k.
    Motion {
        /// The trajectory.
        trajectory: Trajectory,
        /// Step length, s.
        dt: f64,
        /// The step.
        k: u64,
    },
    /// A recording's reference columns; a missing column is NaN, and its errors are not computed.
    Recorded {
        /// The recording, per step.
        rec: Arc<StepRecording>,
        /// The step.
        k: u64,
    },
    /// x⁺ = A x + w.
    Linear {
        /// The state.
        x: DVector<f64>,
        /// The transition matrix A.
        A: DMatrix<f64>,
        /// A square root of Q, to draw w.
        Q_sqrt: DMatrix<f64>,
        /// The process noise's stream.
        rng: Rng,
        /// The step.
        k: u64,
        /// Shift of coordinates not yet applied to the estimates (see [`REBASE_LIMIT`]).
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

impl Truth {
    /// The trajectory's truth from step 0, steps `dt` s apart.
    pub fn motion(trajectory: Trajectory, dt: f64) -> Truth {
        Truth::Motion { trajectory, dt, k: 0 }
    }

    /// The recording's truth from step 0.
    pub fn recorded(rec: Arc<StepRecording>) -> Truth {
        Truth::Recorded { rec, k: 0 }
    }

    /// x₀ ~ N(x̂₀, P₀), so that the filter's prior is consistent with the truth.
    pub fn linear(A: &DMatrix<f64>, Q: &DMatrix<f64>, x0: &DVector<f64>, P0: &DMatrix<f64>, mut rng: Rng) -> Truth {
        let x = x0 + psd_sqrt(P0) * randn(&mut rng, x0.len());
        Truth::Linear {
            x,
            A: A.clone(),
            Q_sqrt: psd_sqrt(Q),
            rng,
            k: 0,
            shift: None,
            frame: 0,
        }
    }

    /// Move on to step `target` (a later one).
    pub fn advance_to(&mut self, target: u64) {
        match self {
            Truth::Motion { k, .. } | Truth::Recorded { k, .. } => *k = target,
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
            _ => 0,
        }
    }

    /// A change of origin to add to every estimate predicted to the current step, once.
    pub fn take_shift(&mut self) -> Option<DVector<f64>> {
        match self {
            Truth::Linear { shift, .. } => shift.take(),
            _ => None,
        }
    }

    /// The analytic motion at the current step (not for recorded or linear truths).
    pub fn motion_now(&self) -> Option<PoseTruth> {
        match self {
            Truth::Motion { trajectory, dt, k } => Some(trajectory.at(*k as f64 * dt)),
            _ => None,
        }
    }

    /// The recording and the current row.
    pub fn recording(&self) -> Option<(&StepRecording, usize)> {
        match self {
            Truth::Recorded { rec, k } => Some((rec, *k as usize)),
            _ => None,
        }
    }

    /// The true state of a linear system.
    pub fn linear_state(&self) -> Option<&DVector<f64>> {
        match self {
            Truth::Linear { x, .. } => Some(x),
            _ => None,
        }
    }

    /// The true state in `model`'s coordinates. A recording has no velocity (NaN).
    pub fn state(&self, model: &dyn Model) -> DVector<f64> {
        match self {
            Truth::Motion { trajectory, dt, k } => {
                let s = trajectory.at(*k as f64 * dt);
                model.kinematic_state(Some(s.p), Some(s.v), Some(s.euler))
            }
            Truth::Recorded { rec, k } => {
                let at = |v: &Option<Vec<Vector3<f64>>>| v.as_ref().and_then(|v| v.get(*k as usize).copied());
                model.kinematic_state(at(&rec.position), None, at(&rec.euler))
            }
            Truth::Linear { x, .. } => x.clone(),
        }
    }
}
