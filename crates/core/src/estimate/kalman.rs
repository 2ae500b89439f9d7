//! The Kalman update in Joseph form, with the intermittent and per-channel treatment of missing data
//! (Lesecq's slides, Lesecq (2009)): nothing arrived → prediction only; a channel missing from every source →
//! R̄ᵢᵢ = λ² Rᵢᵢ (equal to dropping the row when R is diagonal), or its row dropped when R is correlated.

use nalgebra::{DMatrix, DVector};

use super::{cholesky, symmetrize, wrap_rows, EstimateError};

pub use super::types::{Gaussian, MissingChannels, Observation};

/// The observation restricted to what arrived: (H, R̄, kept-row indices).
pub fn effective_observation(
    obs: &Observation,
    present: &[bool],
    policy: MissingChannels,
) -> (DMatrix<f64>, DMatrix<f64>, Vec<usize>) {
    match policy {
        MissingChannels::Inflate(lambda) => {
            let mut R = obs.R.clone();
            for (i, p) in present.iter().enumerate() {
                if !p {
                    R[(i, i)] *= lambda * lambda;
                }
            }
            (obs.H.clone(), R, (0..obs.dim()).collect())
        }
        MissingChannels::Drop => {
            let keep: Vec<usize> = (0..obs.dim()).filter(|&i| present[i]).collect();
            let H = obs.H.select_rows(keep.iter());
            let R = obs.R.select_rows(keep.iter()).select_columns(keep.iter());
            (H, R, keep)
        }
    }
}

/// Linear prediction: x⁺ = A x, P⁺ = A P Aᵀ + Q.
pub fn predict(g: &Gaussian, A: &DMatrix<f64>, Q: &DMatrix<f64>) -> Gaussian {
    // A P Aᵀ + Q in one pass over Q's copy, with no temporary matrix.
    let mut P = Q.clone();
    P.quadform_tr(1.0, A, &g.P, 1.0);
    super::symmetrize(&mut P);
    Gaussian { x: A * &g.x, P }
}

/// Standard Kalman update (Joseph form, eq. (11) of Sequeira (2023)) with the rows flagged in `present`;
/// with no row present it returns the prior (intermittent observation, γ = 0).
pub fn kalman_update(
    prior: &Gaussian,
    obs: &Observation,
    z: &DVector<f64>,
    present: &[bool],
    policy: MissingChannels,
) -> Result<Gaussian, EstimateError> {
    if !present.iter().any(|p| *p) {
        return Ok(prior.clone());
    }
    if let Some(r) = policy
        .kept_rows_lambda(present)
        .and_then(|l| super::fixed::kalman_update(prior, obs, z, present, l))
    {
        return r;
    }
    joseph(prior, obs, z, present, policy)
}

/// [`kalman_update`] on dynamically sized matrices, for any size and row selection.
pub(super) fn joseph(
    prior: &Gaussian,
    obs: &Observation,
    z: &DVector<f64>,
    present: &[bool],
    policy: MissingChannels,
) -> Result<Gaussian, EstimateError> {
    let (H, R, keep) = effective_observation(obs, present, policy);
    let full = obs.innovation(z, &prior.x);
    let nu = DVector::from_iterator(keep.len(), keep.iter().map(|&i| if present[i] { full[i] } else { 0.0 }));
    let P = &prior.P;
    let HP = &H * P;
    let S = &HP * H.transpose() + &R;
    let chol = cholesky(&S, "innovation covariance S")?;
    // K = P Hᵀ S⁻¹, computed as (S⁻¹ H P)ᵀ since S and P are symmetric.
    let K = chol.solve(&HP).transpose();
    let x = &prior.x + &K * nu;
    let n = P.nrows();
    let IKH = DMatrix::identity(n, n) - &K * &H;
    let mut Pn = &IKH * P * IKH.transpose() + &K * R * K.transpose();
    symmetrize(&mut Pn);
    if x.iter().chain(Pn.iter()).any(|v| !v.is_finite()) {
        return Err(EstimateError::NonFinite { what: "posterior" });
    }
    Ok(Gaussian { x, P: Pn })
}

/// Normalised estimation error squared eᵀ P⁻¹ e, e = truth − estimate (angle states wrapped).
pub fn nees(g: &Gaussian, truth: &DVector<f64>, angle_states: &[bool]) -> Option<f64> {
    if let Some(v) = super::fixed::nees(g, truth, angle_states) {
        return v;
    }
    let mut e = truth - &g.x;
    wrap_rows(&mut e, angle_states);
    let chol = cholesky(&g.P, "P").ok()?;
    let v = e.dot(&chol.solve(&e));
    v.is_finite().then_some(v)
}
