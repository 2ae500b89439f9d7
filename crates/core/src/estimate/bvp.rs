//! Position as a boundary value problem (Nieminen et al., Nieminen et al. (2010)): x'' = a on [t₀, t_N] with hat functions on
//! the sample times (Galerkin). The weak form ∫x'φ' = −∫aφ + [x'φ] gives K x = −M a + e_N v(t_N) − e₀ v(t₀), K
//! tridiagonal SPD (eq. 16), solved in linear time; a Dirichlet end (known position) is moved to the right-hand side
//! and a Neumann end (known velocity) adds its term (§3). §5's sensor-error model writes the corrected acceleration
//! as a linear combination of known signals with unknown coefficients θ (bias, scale, gravity); the solution is then
//! x = x_bc + Σ θⱼ Xⱼ, and the additional constraints (positions or velocities at chosen times) fix θ by least squares
//! (eqs. 28–29).
#![allow(non_snake_case)]

use nalgebra::{DMatrix, DVector};

/// A boundary condition at one end of the recording.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum End {
    /// Dirichlet: the position is known.
    Position(f64),
    /// Neumann: the velocity is known.
    Velocity(f64),
}

/// Why a boundary value problem could not be set up.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BvpError {
    /// Fewer than 3 samples.
    #[error("need at least 3 samples, got {0}")]
    TooShort(usize),
    /// Sample times do not increase strictly at this sample.
    #[error("sample times must increase strictly (sample {0})")]
    Times(usize),
    /// This many values for that many sample times.
    #[error("{0} values for {1} sample times")]
    Length(usize, usize),
    /// Velocities at both ends and no position.
    #[error("velocities at both ends fix the shape, not the place: give a position at one end at least")]
    NoPosition,
    /// The constraints leave the error model undetermined: parameters, rank.
    #[error("the additional constraints do not determine the {0} error-model parameters (rank {1})")]
    Underdetermined(usize, usize),
    /// A constraint's time (s) outside the recording's first and last time.
    #[error("constraint time {0} s is outside the recording's [{1:.3}, {2:.3}] s")]
    OutOfRange(f64, f64, f64),
}

/// Solve a symmetric tridiagonal system (diagonal `d`, off-diagonal `e`, `e[i]` couples i and i+1) by the Thomas
/// algorithm: O(n), no pivoting needed for an SPD matrix.
pub fn solve_tridiagonal(d: &[f64], e: &[f64], rhs: &[f64]) -> Vec<f64> {
    let n = d.len();
    let mut c = vec![0.0; n];
    let mut y = vec![0.0; n];
    let mut m = d[0];
    y[0] = rhs[0] / m;
    for i in 1..n {
        c[i - 1] = e[i - 1] / m;
        m = d[i] - e[i - 1] * c[i - 1];
        y[i] = (rhs[i] - e[i - 1] * y[i - 1]) / m;
    }
    for i in (0..n - 1).rev() {
        y[i] -= c[i] * y[i + 1];
    }
    y
}

/// The stiffness matrix K (diagonal, off-diagonal) of the hat functions on `t`.
fn stiffness(t: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let n = t.len();
    let mut d = vec![0.0; n];
    let mut e = vec![0.0; n - 1];
    for i in 0..n - 1 {
        let k = 1.0 / (t[i + 1] - t[i]);
        d[i] += k;
        d[i + 1] += k;
        e[i] = -k;
    }
    (d, e)
}

/// ∫ a φᵢ with a piecewise linear between samples (eqs. 14–15): the consistent mass matrix times a.
pub fn load(t: &[f64], a: &[f64]) -> Vec<f64> {
    let n = t.len();
    let mut b = vec![0.0; n];
    for i in 0..n - 1 {
        let h = t[i + 1] - t[i];
        b[i] += h * (2.0 * a[i] + a[i + 1]) / 6.0;
        b[i + 1] += h * (a[i] + 2.0 * a[i + 1]) / 6.0;
    }
    b
}

fn check(t: &[f64], a: &[f64]) -> Result<(), BvpError> {
    if t.len() < 3 {
        return Err(BvpError::TooShort(t.len()));
    }
    if a.len() != t.len() {
        return Err(BvpError::Length(a.len(), t.len()));
    }
    if let Some(i) = t.windows(2).position(|w| w[1] <= w[0] || !w[1].is_finite()) {
        return Err(BvpError::Times(i + 1));
    }
    Ok(())
}

/// Position at every sample from the acceleration `a` and one condition per end.
pub fn solve(t: &[f64], a: &[f64], start: End, end: End) -> Result<Vec<f64>, BvpError> {
    check(t, a)?;
    let n = t.len();
    let (d, e) = stiffness(t);
    // K x = −∫aφ + e_N v_N − e₀ v₀.
    let mut rhs: Vec<f64> = load(t, a).into_iter().map(|v| -v).collect();
    if let End::Velocity(v) = start {
        rhs[0] -= v;
    }
    if let End::Velocity(v) = end {
        rhs[n - 1] += v;
    }
    let (lo, hi) = match (start, end) {
        (End::Velocity(_), End::Velocity(_)) => return Err(BvpError::NoPosition),
        _ => (
            matches!(start, End::Position(_)) as usize,
            n - matches!(end, End::Position(_)) as usize,
        ),
    };
    // Dirichlet ends: move K's column for the known value to the right-hand side and drop its row.
    if let End::Position(x0) = start {
        rhs[1] -= e[0] * x0;
    }
    if let End::Position(xn) = end {
        rhs[n - 2] -= e[n - 2] * xn;
    }
    let inner = solve_tridiagonal(&d[lo..hi], &e[lo..hi - 1], &rhs[lo..hi]);
    let mut x = vec![0.0; n];
    if let End::Position(x0) = start {
        x[0] = x0;
    }
    if let End::Position(xn) = end {
        x[n - 1] = xn;
    }
    x[lo..hi].copy_from_slice(&inner);
    Ok(x)
}

/// Velocity at every sample by three-point differences of the position (one-sided at the ends).
pub fn velocity(t: &[f64], x: &[f64]) -> Vec<f64> {
    let n = t.len();
    (0..n)
        .map(|i| {
            let (a, b, c) = if i == 0 {
                (0, 1, 2)
            } else if i == n - 1 {
                (n - 3, n - 2, n - 1)
            } else {
                (i - 1, i, i + 1)
            };
            // Derivative at t_i of the parabola through three samples.
            let (ta, tb, tc) = (t[a], t[b], t[c]);
            let ti = t[i];
            x[a] * (2.0 * ti - tb - tc) / ((ta - tb) * (ta - tc))
                + x[b] * (2.0 * ti - ta - tc) / ((tb - ta) * (tb - tc))
                + x[c] * (2.0 * ti - ta - tb) / ((tc - ta) * (tc - tb))
        })
        .collect()
}

/// Double integration by the trapezoid rule from x₀, v₀ (the initial value problem, method I).
pub fn trapezoid(t: &[f64], a: &[f64], x0: f64, v0: f64) -> Vec<f64> {
    let mut x = Vec::with_capacity(t.len());
    let (mut p, mut v) = (x0, v0);
    x.push(p);
    for i in 1..t.len() {
        let h = t[i] - t[i - 1];
        let v1 = v + 0.5 * h * (a[i - 1] + a[i]);
        p += 0.5 * h * (v + v1);
        v = v1;
        x.push(p);
    }
    x
}

/// An additional constraint: the position or the velocity of one axis at a time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Constraint {
    /// The position at `t`.
    Position {
        /// Time, s.
        t: f64,
        /// Position, m.
        value: f64,
    },
    /// The velocity at `t`.
    Velocity {
        /// Time, s.
        t: f64,
        /// Velocity, m/s.
        value: f64,
    },
}

/// Row of an interpolation (position) or differentiation (velocity) at time `tc` over the samples.
fn constraint_row(t: &[f64], c: &Constraint) -> Result<(Vec<f64>, f64), BvpError> {
    let (tc, value, vel) = match *c {
        Constraint::Position { t, value } => (t, value, false),
        Constraint::Velocity { t, value } => (t, value, true),
    };
    let n = t.len();
    if !(t[0]..=t[n - 1]).contains(&tc) {
        return Err(BvpError::OutOfRange(tc, t[0], t[n - 1]));
    }
    let i = t.partition_point(|&s| s <= tc).clamp(1, n - 1) - 1;
    let mut row = vec![0.0; n];
    if vel {
        // The three-point derivative at the nearest sample.
        let k = if tc - t[i] <= t[i + 1] - tc { i } else { i + 1 };
        let mut unit = vec![0.0; n];
        // The stencil `velocity` uses at k: one-sided at the ends.
        let first = k.saturating_sub(1).min(n - 3);
        for j in first..first + 3 {
            unit[j] = 1.0;
            row[j] = velocity(t, &unit)[k];
            unit[j] = 0.0;
        }
    } else {
        let w = (tc - t[i]) / (t[i + 1] - t[i]);
        row[i] = 1.0 - w;
        row[i + 1] = w;
    }
    Ok((row, value))
}

/// §5: the acceleration is a₀ + Σⱼ θⱼ gⱼ with known signals gⱼ (for bias: 1; scale: the measurement; …) and unknown
/// θ. Solves the BVP once per signal (linear in the data), then θ from the constraints by least squares, and returns
/// (θ, positions).
pub fn fit_error_model(
    t: &[f64],
    base: &[f64],
    signals: &[Vec<f64>],
    start: End,
    end: End,
    constraints: &[Constraint],
) -> Result<(Vec<f64>, Vec<f64>), BvpError> {
    let tagged: Vec<(usize, Constraint)> = constraints.iter().map(|c| (0, *c)).collect();
    let (theta, mut x) = fit_error_model_axes(t, &[base.to_vec()], &[signals.to_vec()], &[(start, end)], &tagged)?;
    Ok((theta, x.remove(0)))
}

/// [`fit_error_model`] over several axes sharing θ (§5.3): axis k has its base acceleration, one signal per
/// parameter (zero where a parameter does not act on it) and its own ends; a constraint names its axis.
pub fn fit_error_model_axes(
    t: &[f64],
    bases: &[Vec<f64>],
    signals: &[Vec<Vec<f64>>],
    ends: &[(End, End)],
    constraints: &[(usize, Constraint)],
) -> Result<(Vec<f64>, Vec<Vec<f64>>), BvpError> {
    let homogeneous = |e: End| match e {
        End::Position(_) => End::Position(0.0),
        End::Velocity(_) => End::Velocity(0.0),
    };
    let p = signals.first().map_or(0, |s| s.len());
    let mut x0 = Vec::with_capacity(bases.len());
    let mut responses = Vec::with_capacity(bases.len());
    for (k, base) in bases.iter().enumerate() {
        let (start, end) = ends[k];
        x0.push(solve(t, base, start, end)?);
        // Each signal's response with homogeneous boundary values (the boundary values are exact, eq. 27).
        let r: Vec<Vec<f64>> = signals[k]
            .iter()
            .map(|g| solve(t, g, homogeneous(start), homogeneous(end)))
            .collect::<Result<_, _>>()?;
        responses.push(r);
    }
    let mut A = DMatrix::zeros(constraints.len(), p);
    let mut y = DVector::zeros(constraints.len());
    for (r, (k, c)) in constraints.iter().enumerate() {
        let (row, value) = constraint_row(t, c)?;
        let dot = |x: &[f64]| row.iter().zip(x).map(|(a, b)| a * b).sum::<f64>();
        y[r] = value - dot(&x0[*k]);
        for (j, resp) in responses[*k].iter().enumerate() {
            A[(r, j)] = dot(resp);
        }
    }
    let svd = A.svd(true, true);
    let rank = svd.rank(1e-12 * svd.singular_values.max().max(f64::MIN_POSITIVE));
    if rank < p {
        return Err(BvpError::Underdetermined(p, rank));
    }
    let theta = svd.solve(&y, 1e-14).map_err(|_| BvpError::Underdetermined(p, rank))?;
    for (k, x) in x0.iter_mut().enumerate() {
        for (j, resp) in responses[k].iter().enumerate() {
            for (xi, ri) in x.iter_mut().zip(resp) {
                *xi += theta[j] * ri;
            }
        }
    }
    Ok((theta.iter().copied().collect(), x0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fem_is_exact_for_quadratic_motion_with_either_boundary_type() {
        // x = 1 + 2t + 1.5 t², a = 3: piecewise linear FEM reproduces it at the nodes.
        let t: Vec<f64> = (0..=50)
            .map(|i| i as f64 * 0.02 + 0.01 * (i % 3) as f64 * 0.1)
            .collect();
        let x = |s: f64| 1.0 + 2.0 * s + 1.5 * s * s;
        let a = vec![3.0; t.len()];
        let tn = *t.last().unwrap();
        for (s, e) in [
            (End::Position(x(0.0)), End::Position(x(tn))),
            (End::Position(x(0.0)), End::Velocity(2.0 + 3.0 * tn)),
            (End::Velocity(2.0), End::Position(x(tn))),
        ] {
            let sol = solve(&t, &a, s, e).unwrap();
            for (ti, xi) in t.iter().zip(&sol) {
                assert!((xi - x(*ti)).abs() < 1e-9, "{s:?} {e:?}: {xi} vs {}", x(*ti));
            }
        }
        assert_eq!(
            solve(&t, &a, End::Velocity(0.0), End::Velocity(0.0)),
            Err(BvpError::NoPosition)
        );
    }

    #[test]
    fn thomas_matches_a_dense_solve() {
        let d = [4.0, 5.0, 6.0, 5.0];
        let e = [-1.0, -2.0, -1.5];
        let b = [1.0, -2.0, 3.0, 0.5];
        let x = solve_tridiagonal(&d, &e, &b);
        let mut m = DMatrix::zeros(4, 4);
        for i in 0..4 {
            m[(i, i)] = d[i];
            if i < 3 {
                m[(i, i + 1)] = e[i];
                m[(i + 1, i)] = e[i];
            }
        }
        let dense = m.lu().solve(&DVector::from_row_slice(&b)).unwrap();
        for i in 0..4 {
            assert!((x[i] - dense[i]).abs() < 1e-12);
        }
    }
}
