//! The β-weighted consensus update of Sequeira (2023), eqs. (5)–(10), and its feasibility conditions (17), (19).
//!
//! With β₀ = 0 and one measurement of weight 1 it is exactly the Kalman update: z̃ = z − ẑ, P̄ = 0 and
//! P = P − K S Kᵀ.

use nalgebra::{DMatrix, DVector};

use super::kalman::{effective_observation, kalman_update};
pub use super::types::{ConsensusOutcome, Source};
use super::types::{Gaussian, MissingChannels, Observation};
use super::{cholesky, eigenvalues, symmetrize, EstimateError};

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

/// The β-independent terms of one node's step, eqs. (5)–(6) and (13)–(19): P_{k|k−1}, A = (1 − β₀) K S Kᵀ, the
/// filtered innovations K z̃ⱼ of each source (Fⱼ = K z̃ⱼ z̃ⱼᵀ Kᵀ) and the scale e^{γ(k−k₀)}/α of (15). Given them,
/// the posterior covariance and both conditions are functions of β alone, which is what a protocol search varies.
#[derive(Debug, Clone)]
pub struct LmiTerms {
    /// The prior covariance P_{k|k−1}.
    pub P: DMatrix<f64>,
    /// A = (1 − β₀) K S Kᵀ.
    pub A: DMatrix<f64>,
    /// K z̃ⱼ, one per source, in the order the sources were given.
    pub kz: Vec<DVector<f64>>,
    /// e^{γ(k−k₀)}/α of (15).
    pub scale: f64,
}

impl LmiTerms {
    /// `sources`: (zⱼ, rows present) per source. A row missing from a source contributes no innovation; a row
    /// missing from every source is handled by `policy`. `None` when no source carries any row (prediction only).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        prior: &Gaussian,
        obs: &Observation,
        beta0: f64,
        sources: &[(&DVector<f64>, &[bool])],
        policy: MissingChannels,
        k: u64,
        alpha: f64,
        gamma: f64,
    ) -> Result<Option<LmiTerms>, EstimateError> {
        let m = obs.dim();
        let mut present_any = vec![false; m];
        for (z, present) in sources {
            if z.len() != m || present.len() != m {
                return Err(EstimateError::Dimension {
                    what: format!("measurement of {} rows, expected {m}", z.len()),
                });
            }
            for (a, p) in present_any.iter_mut().zip(present.iter()) {
                *a |= *p;
            }
        }
        if !present_any.iter().any(|p| *p) {
            return Ok(None);
        }
        let (H, R, keep) = effective_observation(obs, &present_any, policy);
        let P = &prior.P;
        let HP = &H * P;
        let S = &HP * H.transpose() + &R; // (5)
        let chol = cholesky(&S, "innovation covariance S")?;
        let K = chol.solve(&HP).transpose(); // (6)
                                             // (10): per-source innovations on the kept rows, zero where the source lacks the row.
        let kz = sources
            .iter()
            .map(|(z, present)| {
                let full = obs.innovation(z, &prior.x);
                let zj =
                    DVector::from_iterator(keep.len(), keep.iter().map(|&i| if present[i] { full[i] } else { 0.0 }));
                &K * zj
            })
            .collect();
        Ok(Some(LmiTerms {
            P: P.clone(),
            A: &K * &S * K.transpose() * (1.0 - beta0),
            kz,
            scale: (gamma * k as f64).exp() / alpha,
        }))
    }

    /// K z̃ = Σ βⱼ K z̃ⱼ, the correction of the mean (7).
    pub fn correction(&self, beta: &[f64]) -> DVector<f64> {
        let mut c = DVector::zeros(self.P.nrows());
        for (b, kz) in beta.iter().zip(&self.kz) {
            c.axpy(*b, kz, 1.0);
        }
        c
    }

    /// P_{k|k} of (8)–(9): P − A + Σ βⱼ Fⱼ − K z̃ z̃ᵀ Kᵀ = D + Σ βⱼ Fⱼ − C.
    pub fn posterior(&self, beta: &[f64]) -> DMatrix<f64> {
        let mut Pn = &self.P - &self.A;
        for (b, kz) in beta.iter().zip(&self.kz) {
            Pn.ger(*b, kz, kz, 1.0);
        }
        let c = self.correction(beta);
        Pn.ger(-1.0, &c, &c, 1.0);
        symmetrize(&mut Pn);
        Pn
    }

    /// (17) and (19) at `beta`: Z = scale · (P_{k|k} − P_{k|k−1}) is symmetric, so ‖Z‖₂ is its largest |eigenvalue|;
    /// D + Σ βⱼ Fⱼ − C = P_{k|k}. NaN (no convergence) fails both comparisons: infeasible.
    pub fn check(&self, beta: &[f64]) -> LmiCheck {
        check_posterior(&self.P, &self.posterior(beta), self.scale)
    }
}

/// (17) and (19) decided without an eigenvalue: Z = scale · (P_{k|k} − P_{k|k−1}) is symmetric, so ‖Z‖₂ < 1 exactly
/// when I − Z ≻ 0 and I + Z ≻ 0; (19) is P_{k|k} ≻ 0. Three Cholesky factorisations instead of two symmetric
/// eigendecompositions; non-finite input is infeasible.
pub fn feasible(prior: &DMatrix<f64>, post: &DMatrix<f64>, scale: f64) -> bool {
    let mut z = (post - prior) * scale;
    symmetrize(&mut z);
    let spd = |m: &DMatrix<f64>| cholesky(m, "LMI").is_ok();
    let i = DMatrix::<f64>::identity(z.nrows(), z.ncols());
    spd(post) && spd(&(&i - &z)) && spd(&(&i + &z))
}

fn check_posterior(prior: &DMatrix<f64>, post: &DMatrix<f64>, scale: f64) -> LmiCheck {
    let mut delta = post - prior;
    symmetrize(&mut delta);
    LmiCheck {
        norm_z: eigenvalues(&delta).map_or(f64::NAN, |e| e.amax() * scale),
        min_eig: eigenvalues(post).map_or(f64::NAN, |e| e.min()),
    }
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
    if let Some(r) = fixed_update(prior, obs, beta0, sources, policy, k, alpha, gamma) {
        return r;
    }
    dynamic_update(prior, obs, beta0, sources, policy, k, alpha, gamma)
}

/// The static-size path of [`consensus_update`], where the sizes are in its table, some source carries a row and
/// every row is kept.
#[allow(clippy::too_many_arguments)]
fn fixed_update(
    prior: &Gaussian,
    obs: &Observation,
    beta0: f64,
    sources: &[Source<'_>],
    policy: MissingChannels,
    k: u64,
    alpha: f64,
    gamma: f64,
) -> Option<Result<ConsensusOutcome, EstimateError>> {
    let mut any = [false; 8];
    let present_any = any.get_mut(..obs.dim())?;
    for s in sources {
        for (a, p) in present_any.iter_mut().zip(s.present) {
            *a |= *p;
        }
    }
    let lambda = policy.kept_rows_lambda(present_any)?;
    if !present_any.iter().any(|p| *p) {
        return None;
    }
    let scale = (gamma * k as f64).exp() / alpha;
    super::fixed::consensus_update(prior, obs, beta0, sources, present_any, lambda, scale)
}

/// [`consensus_update`] on dynamically sized matrices, through [`LmiTerms`].
#[allow(clippy::too_many_arguments)]
pub(super) fn dynamic_update(
    prior: &Gaussian,
    obs: &Observation,
    beta0: f64,
    sources: &[Source<'_>],
    policy: MissingChannels,
    k: u64,
    alpha: f64,
    gamma: f64,
) -> Result<ConsensusOutcome, EstimateError> {
    let data: Vec<(&DVector<f64>, &[bool])> = sources.iter().map(|s| (s.z, s.present)).collect();
    let Some(terms) = LmiTerms::new(prior, obs, beta0, &data, policy, k, alpha, gamma)? else {
        // Intermittent observation: prediction only; Z = 0, and (19) is P_{k|k−1} ≻ 0.
        return Ok(ConsensusOutcome {
            posterior: prior.clone(),
            feasible: cholesky(&prior.P, "LMI").is_ok(),
        });
    };
    let beta: Vec<f64> = sources.iter().map(|s| s.beta).collect();
    let x = &prior.x + terms.correction(&beta); // (7)
    let Pn = terms.posterior(&beta); // (8)
    if x.iter().chain(Pn.iter()).any(|v| !v.is_finite()) {
        return Err(EstimateError::NonFinite {
            what: "consensus posterior",
        });
    }
    let feasible = feasible(&terms.P, &Pn, terms.scale);
    Ok(ConsensusOutcome {
        posterior: Gaussian { x, P: Pn },
        feasible,
    })
}

/// The LMI guard around [`consensus_update`]: when (17) or (19) fails, or the update itself fails, the node uses the
/// independent update this step — the paper's practical rule (§5) — a Joseph-form Kalman update with `fallback` (the
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
        Ok(o) if lmi.is_none() || o.feasible => (Ok(o.posterior), true),
        _ => {
            let post = match fallback {
                Some(f) => kalman_update(prior, obs, f.z, f.present, policy),
                None => Ok(prior.clone()),
            };
            (post, false)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// The Cholesky decision of (17) and (19) is the eigenvalue one wherever the eigenvalues are not at the boundary
    /// to rounding: 2000 random prior/posterior pairs whose ‖Z‖₂ spans 1 and whose posteriors include indefinite ones.
    #[test]
    fn cholesky_feasibility_is_the_eigenvalue_one() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let (mut agree, mut infeasible, mut feasible_n) = (0, 0, 0);
        for _ in 0..2000 {
            let n = rng.gen_range(1..=6);
            let a = DMatrix::from_fn(n, n, |_, _| rng.gen_range(-1.0..1.0));
            let prior = &a * a.transpose() + DMatrix::identity(n, n) * 0.1;
            let b = DMatrix::from_fn(n, n, |_, _| rng.gen_range(-1.0..1.0));
            let mut post = &prior + (&b + b.transpose()) * rng.gen_range(-0.3..0.3);
            symmetrize(&mut post);
            let scale = rng.gen_range(0.1..4.0);
            let c = check_posterior(&prior, &post, scale);
            if (c.norm_z - 1.0).abs() < 1e-9 || c.min_eig.abs() < 1e-12 {
                continue;
            }
            let f = feasible(&prior, &post, scale);
            assert_eq!(f, c.feasible(), "‖Z‖ = {}, λmin = {}", c.norm_z, c.min_eig);
            agree += 1;
            if f {
                feasible_n += 1;
            } else {
                infeasible += 1;
            }
        }
        assert!(
            agree > 1900 && feasible_n > 200 && infeasible > 200,
            "{agree} {feasible_n} {infeasible}"
        );
    }
}
