//! Covariance bounds of Kalman filtering with intermittent observations (Sinopoli et al., IEEE TAC 49(9), 2004),
//! for x⁺ = A x + w, y = C x + v with measurements arriving independently with probability λ:
//!
//! - λ_min = 1 − 1/ρ(A)² ≤ λ_c ≤ λ̄;
//! - for λ > λ_c, S̄ ≤ lim E[P_{t|t−1}] ≤ V̄ with S̄ = (1−λ) A S̄ Aᵀ + Q and V̄ = g_λ(V̄), where
//!   g_λ(X) = A X Aᵀ + Q − λ A X Cᵀ (C X Cᵀ + R)⁻¹ C X Aᵀ (the modified algebraic Riccati equation, MARE);
//! - λ̄ is where the MARE stops having a solution: the iteration V_{k+1} = g_λ(V_k) from V₀ = 0 converges exactly when
//!   λ > λ̄ (Sinopoli et al., Thms. 3–5), which is the test bisected here in place of the LMI of Cor. 1. The iterates
//!   rise monotonically; near λ̄ they creep, so a point the iteration decides neither way within its budget is left
//!   out of the bisection and the bracket it leaves is reported ([`Critical`]). With C square and invertible
//!   λ̄ = λ_min exactly (Sinopoli et al., Thm. 6).
//!
//! For Markov (Gilbert–Elliott) loss the condition is on the loss runs: with T = [[1−p, p], [r, 1−r]] and
//! D = diag(1−k, 1−h), the probability of n losses in a row decays like ρ(T D)ⁿ, and the expected covariance needs
//! ρ(A)² ρ(T D) < 1. That is necessary in general (Huang & Dey, Automatica 43(4), 2007), and also sufficient for
//! scalar systems or when C is invertible (one-step observable; You, Fu & Xie, Automatica 47(12), 2011). With 1−k = 0
//! it reduces to (1−r)(1−h) ρ(A)² < 1.
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
    /// The iterates settled: the fixed point.
    Converged(DMatrix<f64>),
    /// The iterates grew past any bound: no positive semidefinite fixed point.
    Diverged,
    /// Still creeping after the iteration budget (at the edge of stability): neither shown.
    Undecided,
}

impl FixedPoint {
    /// The fixed point, if the iterates settled.
    pub fn matrix(&self) -> Option<&DMatrix<f64>> {
        match self {
            FixedPoint::Converged(m) => Some(m),
            _ => None,
        }
    }
}

const LIMIT: f64 = 1e14;
/// Iterations before a fixed-point search gives up.
pub const MAX_ITER: usize = 2_000_000;

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
    Ok(FixedPoint::Undecided)
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

/// λ̄ as far as it is known: lo < λ̄ ≤ hi, with every λ ≥ hi shown to converge and every λ ≤ lo shown to diverge
/// (or lo = λ_min, which λ̄ never undercuts).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Critical {
    /// Every rate up to this one is shown to diverge (or it is λ_min).
    pub lo: f64,
    /// Every rate from this one on is shown to converge.
    pub hi: f64,
    /// hi − lo reached the requested tolerance, or λ̄ is known in closed form.
    pub to_tolerance: bool,
}

impl Critical {
    /// The critical rate's upper end: the rate that is known to suffice.
    pub fn value(&self) -> f64 {
        self.hi
    }
}

/// λ̄: the smallest arrival rate at which the MARE has a fixed point, by bisection on [λ_min, 1] to `tol`; ∞ when
/// even the loss-free filter is unstable. A midpoint the iteration cannot decide ends the bisection there.
pub fn critical_upper(
    A: &DMatrix<f64>,
    C: &DMatrix<f64>,
    Q: &DMatrix<f64>,
    R: &DMatrix<f64>,
    tol: f64,
) -> Result<Critical, EstimateError> {
    let lo0 = lambda_min(A).ok_or(EstimateError::NonFinite {
        what: "eigenvalues of A",
    })?;
    let exact = |v: f64| Critical {
        lo: v,
        hi: v,
        to_tolerance: true,
    };
    if C.is_square() && C.clone().try_inverse().is_some() {
        // Sinopoli et al., Thm. 6: with C invertible the upper bound meets the lower one.
        return Ok(exact(lo0));
    }
    match upper_bound(A, C, Q, R, 1.0)? {
        FixedPoint::Converged(_) => {}
        // Not even the loss-free filter is stable (an undetectable unstable mode).
        _ => return Ok(exact(f64::INFINITY)),
    }
    let (mut lo, mut hi) = (lo0, 1.0);
    while hi - lo > tol {
        let mid = 0.5 * (lo + hi);
        match upper_bound(A, C, Q, R, mid)? {
            FixedPoint::Converged(_) => hi = mid,
            FixedPoint::Diverged => lo = mid,
            FixedPoint::Undecided => {
                return Ok(Critical {
                    lo,
                    hi,
                    to_tolerance: false,
                })
            }
        }
    }
    Ok(Critical {
        lo,
        hi,
        to_tolerance: true,
    })
}

/// The Gilbert–Elliott condition ρ(A)² ρ(T D) < 1 (module doc), with its left-hand side and ρ(T D), the decay per
/// step of the probability of a run of losses.
pub fn markov_condition(
    A: &DMatrix<f64>,
    p: f64,
    r: f64,
    one_minus_h: f64,
    one_minus_k: f64,
) -> Option<(f64, f64, bool)> {
    let rho = spectral_radius(A)?;
    let td = nalgebra::Matrix2::new(
        (1.0 - p) * one_minus_k,
        p * one_minus_h,
        r * one_minus_k,
        (1.0 - r) * one_minus_h,
    );
    // A 2×2 non-negative matrix: its spectral radius is the larger root of λ² − tr λ + det.
    let (tr, det) = (td.trace(), td.determinant());
    let decay = 0.5 * (tr + (tr * tr - 4.0 * det).max(0.0).sqrt());
    let v = rho * rho * decay;
    Some((v, decay, v < 1.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scalar() -> [DMatrix<f64>; 4] {
        [-1.25, 1.0, 1.0, 2.5].map(|v| DMatrix::from_element(1, 1, v))
    }

    /// Sinopoli et al.'s scalar example (Sinopoli et al. 2004, §VI).
    #[test]
    fn scalar_example_matches_the_published_values() {
        let [A, C, Q, R] = scalar();
        assert!((lambda_min(&A).unwrap() - 0.36).abs() < 1e-12);
        // C invertible: λ̄ = λ_min exactly (Thm. 6), not a bisection's 0.360006.
        let lbar = critical_upper(&A, &C, &Q, &R, 1e-6).unwrap();
        assert!((lbar.lo - 0.36).abs() < 1e-15 && lbar.lo == lbar.hi, "{lbar:?}");
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

    /// Sinopoli et al.'s two-state example (C = [1 0], not invertible): the bisection's bracket is honest —
    /// above it the iteration converges, below it it diverges.
    #[test]
    fn the_bracket_of_lambda_bar_is_decided_on_both_sides() {
        let A = DMatrix::from_row_slice(2, 2, &[1.25, 1.0, 0.0, 0.9]);
        let C = DMatrix::from_row_slice(1, 2, &[1.0, 0.0]);
        let Q = DMatrix::from_row_slice(2, 2, &[20.0, 0.0, 0.0, 20.0]);
        let R = DMatrix::from_element(1, 1, 2.5);
        let c = critical_upper(&A, &C, &Q, &R, 1e-6).unwrap();
        assert!(c.lo >= lambda_min(&A).unwrap() && c.lo < c.hi);
        assert!(matches!(
            upper_bound(&A, &C, &Q, &R, c.hi).unwrap(),
            FixedPoint::Converged(_)
        ));
        assert!(!matches!(
            upper_bound(&A, &C, &Q, &R, c.lo).unwrap(),
            FixedPoint::Converged(_)
        ));
        assert!(!c.to_tolerance || c.hi - c.lo <= 1e-6);
    }

    /// The example: p = r = 0.05, 1−h = 0.5, 1−k = 0.75 decays at 0.716 per step, not (1−r)(1−h) = 0.475.
    #[test]
    fn the_gilbert_elliott_condition_counts_loss_in_good() {
        let A = DMatrix::from_element(1, 1, 1.25);
        let (lhs, decay, ok) = markov_condition(&A, 0.05, 0.05, 0.5, 0.75).unwrap();
        assert!((decay - 0.716_36).abs() < 1e-4, "{decay}");
        assert!((lhs - 1.5625 * decay).abs() < 1e-12 && lhs > 1.0 && !ok);
        // 1−k = 0: the textbook (1−r)(1−h).
        let (_, d0, _) = markov_condition(&A, 0.05, 0.2, 1.0, 0.0).unwrap();
        assert!((d0 - 0.8).abs() < 1e-12);
        // The decay is the probability ratio of loss runs, checked against the chain itself: P(n losses in a row
        // from the stationary law) grows by ρ(T D) per extra loss for large n.
        let (p, r, h1, k1) = (0.05f64, 0.05f64, 0.5f64, 0.75f64);
        let pi = [r / (p + r), p / (p + r)];
        let step = |v: [f64; 2]| {
            [
                v[0] * k1 * (1.0 - p) + v[1] * h1 * r,
                v[0] * k1 * p + v[1] * h1 * (1.0 - r),
            ]
        };
        let mut v = pi;
        for _ in 0..200 {
            v = step(v);
        }
        let w = step(v);
        assert!(((w[0] + w[1]) / (v[0] + v[1]) - decay).abs() < 1e-9);
    }

    #[test]
    fn degenerate_matrices_do_not_hang() {
        assert_eq!(spectral_radius(&DMatrix::zeros(3, 3)), Some(0.0));
        assert_eq!(spectral_radius(&DMatrix::from_element(2, 2, f64::NAN)), None);
    }
}
