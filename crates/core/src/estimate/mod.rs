//! Estimation, pure and allocation-light: Kalman prediction and update (Joseph form), intermittent and per-channel
//! handling, the β-weighted consensus update of Sequeira (2023) (eqs. 5–10) with its LMI conditions (17) and (19),
//! covariance intersection, NEES; the quaternion attitude EKF of Lesecq's slides in standard and square-root form.
//! `ahrs.rs`: the Madgwick and Mahony filters, to set beside the EKF on the same data; `mekf.rs`: the multiplicative
//! EKF with Gauss–Markov states for linear acceleration and the field's disturbance.
#![allow(non_snake_case)]

pub mod ahrs;
pub mod attitude;
pub mod bounds;
pub mod bvp;
pub mod consensus;
pub mod fixed;
pub mod fusion;
pub mod kalman;
pub mod mekf;
pub mod rigid_pair;
mod types;

use nalgebra::{DMatrix, DVector};

pub use consensus::{consensus_update, guarded_update, ConsensusOutcome, LmiCheck, LmiTerms, Source};
pub use fixed::{dynamic, fixed, symmetrize as symmetrize_fixed};
pub use kalman::{kalman_update, nees, predict, Gaussian, MissingChannels, Observation};

/// Why an estimation step could not run: the input, not the code, is at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EstimateError {
    #[error("{what} is not positive definite")]
    /// A covariance or innovation covariance that is not positive definite.
    NotPositiveDefinite {
        /// The matrix.
        what: &'static str,
    },
    #[error("non-finite value in {what}")]
    /// A NaN or an infinity.
    NonFinite {
        /// Where.
        what: &'static str,
    },
    #[error("{scheme} cannot run this model: {why}")]
    /// A scheme whose equations do not hold for the model.
    Unsupported {
        /// The scheme.
        scheme: &'static str,
        /// What of the model its equations exclude.
        why: &'static str,
    },
    #[error("dimension mismatch: {what}")]
    /// Sizes that do not fit together.
    Dimension {
        /// Which sizes disagree.
        what: String,
    },
}

/// Lower Cholesky factor, or the error naming the matrix.
pub fn cholesky(m: &DMatrix<f64>, what: &'static str) -> Result<nalgebra::Cholesky<f64, nalgebra::Dyn>, EstimateError> {
    if m.iter().any(|v| !v.is_finite()) {
        return Err(EstimateError::NonFinite { what });
    }
    nalgebra::Cholesky::new(m.clone()).ok_or(EstimateError::NotPositiveDefinite { what })
}

/// (M + Mᵀ)/2: rounding makes updated covariances drift from symmetry.
pub fn symmetrize(m: &mut DMatrix<f64>) {
    let n = m.nrows();
    for i in 0..n {
        for j in (i + 1)..n {
            let a = 0.5 * (m[(i, j)] + m[(j, i)]);
            m[(i, j)] = a;
            m[(j, i)] = a;
        }
    }
}

/// Eigenvalues of a symmetric matrix, or `None` when it holds non-finite values or the QR iteration does not
/// converge in a bounded number of sweeps (nalgebra's default is unbounded and can spin on overflowing input).
pub fn eigenvalues(m: &DMatrix<f64>) -> Option<DVector<f64>> {
    if m.iter().any(|v| !v.is_finite()) {
        return None;
    }
    m.clone()
        .try_symmetric_eigen(f64::EPSILON, 10_000)
        .map(|e| e.eigenvalues)
        .filter(|v| v.iter().all(|x| x.is_finite()))
}

/// True when `m` is symmetric (relative 1e-9) and its Cholesky factorisation succeeds.
pub fn is_spd(m: &DMatrix<f64>) -> bool {
    let scale = 1.0 + m.amax();
    (m - m.transpose()).amax() <= 1e-9 * scale && cholesky(m, "P").is_ok()
}

/// Wrap the rows flagged as angles to (−π, π].
pub fn wrap_rows(v: &mut DVector<f64>, angle: &[bool]) {
    for (i, a) in angle.iter().enumerate() {
        if *a {
            v[i] = crate::geom::wrap_angle(v[i]);
        }
    }
}
