//! Covariance intersection (Julier–Uhlmann): P⁻¹ = ω P₁⁻¹ + (1 − ω) P₂⁻¹, x = P (ω P₁⁻¹ x₁ + (1 − ω) P₂⁻¹ x₂),
//! cascaded over nodes as in §7 of the consensus seed, with a fixed ω or the ω that minimises trace P; and the
//! sliding median filter the seed applies to the fused trajectory.

use super::{cholesky, symmetrize, wrap_rows, EstimateError, Gaussian};

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Omega {
    Fixed(f64),
    /// ω ∈ [0, 1] minimising trace P, by golden-section search (trace P(ω) is convex).
    TraceOptimal,
}

/// Fuse two estimates; `angle_states` marks rows that wrap (b is unwrapped towards a first).
pub fn intersect(a: &Gaussian, b: &Gaussian, omega: f64, angle_states: &[bool]) -> Result<Gaussian, EstimateError> {
    let ia = cholesky(&a.P, "P₁")?.inverse();
    let ib = cholesky(&b.P, "P₂")?.inverse();
    let mut xb = b.x.clone();
    for (i, ang) in angle_states.iter().enumerate() {
        if *ang {
            xb[i] = a.x[i] + crate::geom::wrap_angle(b.x[i] - a.x[i]);
        }
    }
    let info = &ia * omega + &ib * (1.0 - omega);
    let chol = cholesky(&info, "fused information")?;
    let mut P = chol.inverse();
    symmetrize(&mut P);
    let mut x = &P * (&ia * &a.x * omega + &ib * &xb * (1.0 - omega));
    wrap_rows(&mut x, angle_states);
    Ok(Gaussian { x, P })
}

/// The ω that minimises trace P of `intersect(a, b, ω)`.
pub fn trace_optimal_omega(a: &Gaussian, b: &Gaussian) -> Result<f64, EstimateError> {
    let ia = cholesky(&a.P, "P₁")?.inverse();
    let ib = cholesky(&b.P, "P₂")?.inverse();
    let trace = |w: f64| -> f64 {
        match cholesky(&(&ia * w + &ib * (1.0 - w)), "fused information") {
            Ok(c) => c.inverse().trace(),
            Err(_) => f64::INFINITY,
        }
    };
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut c, mut d) = (hi - g * (hi - lo), lo + g * (hi - lo));
    let (mut fc, mut fd) = (trace(c), trace(d));
    for _ in 0..60 {
        if fc < fd {
            hi = d;
            d = c;
            fd = fc;
            c = hi - g * (hi - lo);
            fc = trace(c);
        } else {
            lo = c;
            c = d;
            fc = fd;
            d = lo + g * (hi - lo);
            fd = trace(d);
        }
    }
    let mid = 0.5 * (lo + hi);
    // The optimum may sit on the boundary (one estimate dominates).
    Ok([0.0, mid, 1.0]
        .into_iter()
        .min_by(|x, y| trace(*x).total_cmp(&trace(*y)))
        .unwrap_or(mid))
}

/// Cascade: fuse the first two, then the result with the third, and so on (§7).
pub fn cascade(estimates: &[Gaussian], omega: Omega, angle_states: &[bool]) -> Result<Gaussian, EstimateError> {
    let mut it = estimates.iter();
    let Some(first) = it.next() else {
        return Err(EstimateError::Dimension {
            what: "no estimate to fuse".into(),
        });
    };
    let mut acc = first.clone();
    for e in it {
        let w = match omega {
            Omega::Fixed(w) => w,
            Omega::TraceOptimal => trace_optimal_omega(&acc, e)?,
        };
        acc = intersect(&acc, e, w, angle_states)?;
    }
    Ok(acc)
}

/// Median filter over a centred window of `window` samples (k − window/2 … k + window/2 − 1, shortened at the
/// ends), per coordinate.
pub fn centred_median(series: &[Vec<f64>], window: usize) -> Vec<Vec<f64>> {
    let w = window.max(1);
    let n = series.len();
    (0..n)
        .map(|k| {
            let lo = k.saturating_sub(w / 2);
            let hi = (k + w - w / 2).min(n);
            let dim = series[k].len();
            (0..dim)
                .map(|i| {
                    let mut col: Vec<f64> = series[lo..hi].iter().map(|v| v[i]).collect();
                    col.sort_by(f64::total_cmp);
                    let m = col.len();
                    if m % 2 == 1 {
                        col[m / 2]
                    } else {
                        0.5 * (col[m / 2 - 1] + col[m / 2])
                    }
                })
                .collect()
        })
        .collect()
}
