//! Covariance bounds of Kalman filtering with intermittent observations (Sinopoli et al., IEEE TAC 49(9), 2004),
//! for x⁺ = A x + w, y = C x + v with measurements arriving independently with probability λ:
//!
//! - λ_min = 1 − 1/ρ(A)² ≤ λ_c ≤ λ̄;
//! - for λ > λ_c, S̄ ≤ lim E[P_{t|t−1}] ≤ V̄ with S̄ = (1−λ) A S̄ Aᵀ + Q and V̄ = g_λ(V̄), where
//!   g_λ(X) = A X Aᵀ + Q − λ A X Cᵀ (C X Cᵀ + R)⁻¹ C X Aᵀ (the modified algebraic Riccati equation, MARE);
//! - λ̄ is where the MARE stops having a solution: the iteration V_{k+1} = g_λ(V_k) from V₀ = 0 converges exactly when
//!   λ > λ̄ (Sinopoli et al., Thms. 3–5), which is the exact test bisected here in place of the LMI of Cor. 1.
//!
//! For Markov (Gilbert–Elliott) loss the relevant condition is on the bursts: with recovery probability r
//! (Bad→Good) and loss 1−h in Bad, the peak covariance is stable if (1−r)(1−h)·ρ(A)² < 1 when the loss-free filter
//! is stable (Huang & Dey 2007, for 1−h = 1; a burst then grows P by ρ(A)² per step with probability 1−r).
#![allow(non_snake_case)]

use nalgebra::DMatrix;

use super::{cholesky, symmetrize, EstimateError};

/// Spectral radius; `None` when the eigenvalue iteration does not converge (bounded, unlike nalgebra's default).
pub fn spectral_radius(A: &DMatrix<f64>) -> Option<f64> {
    if A.iter().any(|v| !v.is_finite()) {
        return None;
    }
    if A.iter().all(|v| *v == 0.0) {
        return Some(0.0);
    }
    let schur = nalgebra::Schur::try_new(A.clone(), f64::EPSILON, 100_000)?;
    Some(schur.complex_eigenvalues().iter().map(|e| e.norm()).fold(0.0, f64::max))
}

/// λ_min = 1 − 1/ρ(A)², 0 for a stable A.
pub fn lambda_min(A: &DMatrix<f64>) -> Option<f64> {
    let rho = spectral_radius(A)?;
    Some(if rho <= 1.0 { 0.0 } else { 1.0 - 1.0 / (rho * rho) })
}

/// g_λ(X), eq. of the MARE.
pub fn mare(
    A: &DMatrix<f64>,
    C: &DMatrix<f64>,
    Q: &DMatrix<f64>,
    R: &DMatrix<f64>,
    lambda: f64,
    X: &DMatrix<f64>,
) -> Result<DMatrix<f64>, EstimateError> {
    let S = C * X * C.transpose() + R;
    let chol = cholesky(&S, "C X Cᵀ + R")?;
    let AXC = A * X * C.transpose();
    let mut G = A * X * A.transpose() + Q - &AXC * chol.solve(&AXC.transpose()) * lambda;
    symmetrize(&mut G);
    Ok(G)
}

/// Outcome of a fixed-point iteration.
#[derive(Debug, Clone, PartialEq)]
pub enum FixedPoint {
    Converged(DMatrix<f64>),
    /// The iterates grew past any bound: no positive semidefinite fixed point.
    Diverged,
}

impl FixedPoint {
    pub fn matrix(&self) -> Option<&DMatrix<f64>> {
        match self {
            FixedPoint::Converged(m) => Some(m),
            FixedPoint::Diverged => None,
        }
    }
}

const LIMIT: f64 = 1e14;
const MAX_ITER: usize = 2_000_000;

fn iterate(
    mut X: DMatrix<f64>,
    mut f: impl FnMut(&DMatrix<f64>) -> Result<DMatrix<f64>, EstimateError>,
) -> Result<FixedPoint, EstimateError> {
    for _ in 0..MAX_ITER {
        let next = f(&X)?;
        let scale = next.amax().max(1e-300);
        if !next.iter().all(|v| v.is_finite()) || scale > LIMIT {
            return Ok(FixedPoint::Diverged);
        }
        let done = (&next - &X).amax() <= 1e-13 * scale;
        X = next;
        if done {
            return Ok(FixedPoint::Converged(X));
        }
    }
    // Still creeping after MAX_ITER steps: at the edge of stability, treated as no fixed point.
    Ok(FixedPoint::Diverged)
}

/// V̄ = g_λ(V̄), iterated from V₀ = 0.
pub fn upper_bound(
    A: &DMatrix<f64>,
    C: &DMatrix<f64>,
    Q: &DMatrix<f64>,
    R: &DMatrix<f64>,
    lambda: f64,
) -> Result<FixedPoint, EstimateError> {
    let n = A.nrows();
    iterate(DMatrix::zeros(n, n), |X| mare(A, C, Q, R, lambda, X))
}

/// S̄ = (1−λ) A S̄ Aᵀ + Q (a Lyapunov equation), iterated from 0: converges iff (1−λ) ρ(A)² < 1.
pub fn lower_bound(A: &DMatrix<f64>, Q: &DMatrix<f64>, lambda: f64) -> Result<FixedPoint, EstimateError> {
    let n = A.nrows();
    iterate(DMatrix::zeros(n, n), |X| {
        let mut S = A * X * A.transpose() * (1.0 - lambda) + Q;
        symmetrize(&mut S);
        Ok(S)
    })
}

/// λ̄: the smallest arrival rate at which the MARE has a fixed point, by bisection on [λ_min, 1] to `tol`.
pub fn critical_upper(
    A: &DMatrix<f64>,
    C: &DMatrix<f64>,
    Q: &DMatrix<f64>,
    R: &DMatrix<f64>,
    tol: f64,
) -> Result<f64, EstimateError> {
    let lo0 = lambda_min(A).ok_or(EstimateError::NonFinite {
        what: "eigenvalues of A",
    })?;
    let converges =
        |l: f64| -> Result<bool, EstimateError> { Ok(matches!(upper_bound(A, C, Q, R, l)?, FixedPoint::Converged(_))) };
    if !converges(1.0)? {
        // Not even the loss-free filter is stable (an undetectable unstable mode).
        return Ok(f64::INFINITY);
    }
    let (mut lo, mut hi) = (lo0, 1.0);
    while hi - lo > tol {
        let mid = 0.5 * (lo + hi);
        if converges(mid)? {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Ok(hi)
}

/// The Gilbert–Elliott burst condition (1−r)(1−h) ρ(A)² < 1, with its left-hand side.
pub fn markov_condition(A: &DMatrix<f64>, r: f64, one_minus_h: f64) -> Option<(f64, bool)> {
    let rho = spectral_radius(A)?;
    let v = (1.0 - r) * one_minus_h * rho * rho;
    Some((v, v < 1.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scalar() -> [DMatrix<f64>; 4] {
        [-1.25, 1.0, 1.0, 2.5].map(|v| DMatrix::from_element(1, 1, v))
    }

    /// Sinopoli et al.'s scalar example (`../shared/REFERENCE.md`).
    #[test]
    fn scalar_example_matches_the_published_values() {
        let [A, C, Q, R] = scalar();
        assert!((lambda_min(&A).unwrap() - 0.36).abs() < 1e-12);
        let lbar = critical_upper(&A, &C, &Q, &R, 1e-6).unwrap();
        assert!((lbar - 0.36).abs() < 1e-3, "λ̄ = {lbar}");
        for (l, s, v) in [(0.5, 4.5714, 11.9559), (0.8, 1.4545, 4.3382)] {
            let S = lower_bound(&A, &Q, l).unwrap();
            let V = upper_bound(&A, &C, &Q, &R, l).unwrap();
            let (S, V) = (S.matrix().unwrap()[(0, 0)], V.matrix().unwrap()[(0, 0)]);
            assert!(
                (S - s).abs() / s < 1e-3 && (V - v).abs() / v < 1e-3,
                "λ = {l}: {S}, {V}"
            );
        }
        assert_eq!(upper_bound(&A, &C, &Q, &R, 0.3).unwrap(), FixedPoint::Diverged);
    }

    #[test]
    fn degenerate_matrices_do_not_hang() {
        assert_eq!(spectral_radius(&DMatrix::zeros(3, 3)), Some(0.0));
        assert_eq!(spectral_radius(&DMatrix::from_element(2, 2, f64::NAN)), None);
    }
}
