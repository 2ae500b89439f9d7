//! The β-weighted consensus update of the consensus seed, eqs. (5)–(10), and its feasibility conditions (17), (19).
//!
//! With β₀ = 0 and one measurement of weight 1 it is exactly the Kalman update: z̃ = z − ẑ, P̄ = 0 and
//! P = P − K S Kᵀ.

use nalgebra::{DMatrix, DVector};

use super::kalman::{effective_observation, kalman_update, Gaussian, MissingChannels, Observation};
use super::{cholesky, eigenvalues, symmetrize, EstimateError};

/// One measurement that reached the node in time: its weight βⱼ, its value, and which rows it carries.
#[derive(Debug, Clone)]
pub struct Source<'a> {
    pub beta: f64,
    pub z: &'a DVector<f64>,
    pub present: &'a [bool],
}

/// The two LMI conditions evaluated at the β actually used.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmiCheck {
    /// ‖Z‖₂ of eq. (15); (17) holds when it is < 1.
    pub norm_z: f64,
    /// Smallest eigenvalue of D + Σ βⱼ Fⱼ (eq. (19)), which equals P_{k|k}; (19) holds when it is > 0.
    pub min_eig: f64,
}

impl LmiCheck {
    /// NaN (an eigenvalue problem that did not converge) counts as infeasible.
    pub fn feasible(&self) -> bool {
        self.norm_z < 1.0 && self.min_eig > 0.0
    }
}

#[derive(Debug, Clone)]
pub struct ConsensusOutcome {
    pub posterior: Gaussian,
    pub lmi: LmiCheck,
}

/// Eqs. (5)–(10): S = H P Hᵀ + R, K = P Hᵀ S⁻¹, z̃ = Σ βⱼ (zⱼ − ẑ), x = x + K z̃,
/// P̄ = Σ βⱼ z̃ⱼ z̃ⱼᵀ − z̃ z̃ᵀ, P = P − (1 − β₀) K S Kᵀ + K P̄ Kᵀ.
/// A row missing from a source contributes no innovation; a row missing from every source is handled by `policy`.
/// `k` is the step number and `alpha`, `gamma` the parameters of (15); k₀ = 0.
#[allow(clippy::too_many_arguments)]
pub fn consensus_update(
    prior: &Gaussian,
    obs: &Observation,
    beta0: f64,
    sources: &[Source<'_>],
    policy: MissingChannels,
    k: u64,
    alpha: f64,
    gamma: f64,
) -> Result<ConsensusOutcome, EstimateError> {
    let m = obs.dim();
    let mut present_any = vec![false; m];
    for s in sources {
        if s.z.len() != m || s.present.len() != m {
            return Err(EstimateError::Dimension {
                what: format!("measurement of {} rows, expected {m}", s.z.len()),
            });
        }
        for (a, p) in present_any.iter_mut().zip(s.present) {
            *a |= *p;
        }
    }
    if !present_any.iter().any(|p| *p) {
        // Intermittent observation: prediction only; P_{k|k} = P_{k|k−1} satisfies (19) trivially.
        let min_eig = eigenvalues(&prior.P).map_or(f64::NAN, |e| e.min());
        return Ok(ConsensusOutcome {
            posterior: prior.clone(),
            lmi: LmiCheck { norm_z: 0.0, min_eig },
        });
    }
    let (H, R, keep) = effective_observation(obs, &present_any, policy);
    let P = &prior.P;
    let S = &H * P * H.transpose() + &R; // (5)
    let chol = cholesky(&S, "innovation covariance S")?;
    let K = chol.solve(&(&H * P)).transpose(); // (6)

    // (10): per-source innovations on the kept rows, zero where the source lacks the row.
    let mk = keep.len();
    let mut z_tilde = DVector::zeros(mk);
    let mut spread = DMatrix::zeros(mk, mk); // Σ βⱼ z̃ⱼ z̃ⱼᵀ
    for s in sources {
        let full = obs.innovation(s.z, &prior.x);
        let zj = DVector::from_iterator(mk, keep.iter().map(|&i| if s.present[i] { full[i] } else { 0.0 }));
        z_tilde += &zj * s.beta;
        spread += &zj * zj.transpose() * s.beta;
    }
    let x = &prior.x + &K * &z_tilde; // (7)
    let P_bar = &spread - &z_tilde * z_tilde.transpose(); // (9)
    let KSK = &K * &S * K.transpose();
    let mut Pn = P - &KSK * (1.0 - beta0) + &K * &P_bar * K.transpose(); // (8)
    symmetrize(&mut Pn);
    if x.iter().chain(Pn.iter()).any(|v| !v.is_finite()) {
        return Err(EstimateError::NonFinite {
            what: "consensus posterior",
        });
    }

    // (15)–(17): Z = (1/α) e^{γ(k−k₀)} (−A − C + Σ βⱼ Fⱼ) = (1/α) e^{γk} (P_{k|k} − P_{k|k−1}); symmetric, so its
    // 2-norm is its largest |eigenvalue|. (19): D + Σ βⱼ Fⱼ = P_{k|k}.
    let mut delta = &Pn - P;
    symmetrize(&mut delta);
    let scale = (gamma * k as f64).exp() / alpha;
    // NaN (no convergence) fails both comparisons: infeasible.
    let norm_z = eigenvalues(&delta).map_or(f64::NAN, |e| e.amax() * scale);
    let min_eig = eigenvalues(&Pn).map_or(f64::NAN, |e| e.min());
    Ok(ConsensusOutcome {
        posterior: Gaussian { x, P: Pn },
        lmi: LmiCheck { norm_z, min_eig },
    })
}

/// The LMI guard around [`consensus_update`]: when (17) or (19) fails, or the update itself fails, the node uses the
/// independent update this step — the seed's practical rule (§5) — a Joseph-form Kalman update with `fallback` (the
/// node's own measurement, or, for a node without one, its highest-weight source). Returns the posterior and whether
/// the consensus update was used.
#[allow(clippy::too_many_arguments)]
pub fn guarded_update(
    prior: &Gaussian,
    obs: &Observation,
    beta0: f64,
    sources: &[Source<'_>],
    fallback: Option<&Source<'_>>,
    policy: MissingChannels,
    k: u64,
    lmi: Option<(f64, f64)>,
) -> (Result<Gaussian, EstimateError>, bool) {
    let (alpha, gamma) = lmi.unwrap_or((1.0, 0.0));
    match consensus_update(prior, obs, beta0, sources, policy, k, alpha, gamma) {
        Ok(o) if lmi.is_none() || o.lmi.feasible() => (Ok(o.posterior), true),
        _ => {
            let post = match fallback {
                Some(f) => kalman_update(prior, obs, f.z, f.present, policy),
                None => Ok(prior.clone()),
            };
            (post, false)
        }
    }
}
