//! Covariance intersection (Julier–Uhlmann): P⁻¹ = ω P₁⁻¹ + (1 − ω) P₂⁻¹, x = P (ω P₁⁻¹ x₁ + (1 − ω) P₂⁻¹ x₂),
//! cascaded over nodes as in §7 of Sequeira (2023), with a fixed ω or the ω that minimises trace P; and the
//! sliding median filter Sequeira (2023, §7) applies to the fused trajectory.

use super::{cholesky, symmetrize, wrap_rows, EstimateError, Gaussian};

/// The covariance-intersection weight ω.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Omega {
    /// This ω ∈ [0, 1].
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
///
/// With I_b = P_b⁻¹ = L Lᵀ and L⁻¹ P_a⁻¹ L⁻ᵀ = U Λ Uᵀ, the fused information is L U (ωΛ + (1−ω) I) Uᵀ Lᵀ, so
/// trace P(ω) = Σᵢ cᵢ / (1 + ω(λᵢ − 1)) with cᵢ = ‖(L⁻ᵀ U)ᵢ‖²: one eigen-decomposition, then a golden-section
/// search on a convex scalar function.
pub fn trace_optimal_omega(a: &Gaussian, b: &Gaussian) -> Result<f64, EstimateError> {
    let ia = cholesky(&a.P, "P₁")?.inverse();
    let ib = cholesky(&b.P, "P₂")?.inverse();
    let chol = cholesky(&ib, "P₂⁻¹")?;
    let l = chol.l();
    let linv = l
        .clone()
        .try_inverse()
        .ok_or(EstimateError::NotPositiveDefinite { what: "P₂⁻¹" })?;
    let mut m = &linv * &ia * linv.transpose();
    super::symmetrize(&mut m);
    if m.iter().any(|v| !v.is_finite()) {
        return Err(EstimateError::NonFinite {
            what: "whitened information",
        });
    }
    let eig = m
        .try_symmetric_eigen(f64::EPSILON, 10_000)
        .ok_or(EstimateError::NonFinite { what: "eigenvalues" })?;
    let w = linv.transpose() * &eig.eigenvectors;
    let c: Vec<f64> = (0..w.ncols()).map(|i| w.column(i).norm_squared()).collect();
    let lambda = eig.eigenvalues;
    let trace = |om: f64| -> f64 {
        c.iter()
            .zip(lambda.iter())
            .map(|(ci, li)| ci / (1.0 + om * (li - 1.0)))
            .sum()
    };
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut x1, mut x2) = (hi - g * (hi - lo), lo + g * (hi - lo));
    let (mut f1, mut f2) = (trace(x1), trace(x2));
    for _ in 0..80 {
        if f1 < f2 {
            hi = x2;
            x2 = x1;
            f2 = f1;
            x1 = hi - g * (hi - lo);
            f1 = trace(x1);
        } else {
            lo = x1;
            x1 = x2;
            f1 = f2;
            x2 = lo + g * (hi - lo);
            f2 = trace(x2);
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
    if let Omega::Fixed(w) = omega {
        if let Some(r) = super::fixed::cascade(estimates, w, angle_states) {
            return r;
        }
    }
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

/// Median filter over a centred window of `window` samples (k − window/2 … k + window/2 − 1), per coordinate; near
/// the ends the window shrinks symmetrically so that it stays centred.
pub fn centred_median(series: &[Vec<f64>], window: usize) -> Vec<Vec<f64>> {
    let mut m = CentredMedian::new(window);
    let mut out: Vec<Vec<f64>> = series
        .iter()
        .filter_map(|v| m.push(v.clone()))
        .map(|(_, v)| v)
        .collect();
    out.extend(m.finish().into_iter().map(|(_, v)| v));
    out
}

/// [`centred_median`] on a stream: sample k is emitted as soon as sample k + window/2 has arrived, and the tail by
/// [`CentredMedian::finish`]. Holds window + 1 samples at most.
#[derive(Debug, Clone)]
pub struct CentredMedian {
    window: usize,
    buf: std::collections::VecDeque<Vec<f64>>,
    /// Index of `buf[0]`.
    first: usize,
    /// Next index to emit.
    next: usize,
    /// Samples pushed.
    n: usize,
}

impl CentredMedian {
    /// A filter over `window` samples (centred: window/2 on each side).
    pub fn new(window: usize) -> CentredMedian {
        CentredMedian {
            window: window.max(1),
            buf: Default::default(),
            first: 0,
            next: 0,
            n: 0,
        }
    }

    /// Add the next sample; returns (index, median) of the sample whose window is now complete, if any.
    pub fn push(&mut self, v: Vec<f64>) -> Option<(usize, Vec<f64>)> {
        self.buf.push_back(v);
        self.n += 1;
        (self.n > self.next + self.window / 2).then(|| self.emit())
    }

    /// The medians of the samples not emitted yet (the series has ended); the filter starts afresh.
    pub fn finish(&mut self) -> Vec<(usize, Vec<f64>)> {
        let mut out = Vec::new();
        while self.next < self.n {
            out.push(self.emit());
        }
        *self = CentredMedian::new(self.window);
        out
    }

    /// The median of sample `next` over the samples known so far (`n` of them).
    fn emit(&mut self) -> (usize, Vec<f64>) {
        let (w, n, k) = (self.window, self.n, self.next);
        let half = (w / 2).min(k).min(n - 1 - k);
        let (lo, hi) = if half < w / 2 {
            (k - half, k + half + 1)
        } else {
            (k - w / 2, (k + w - w / 2).min(n))
        };
        let dim = self.buf[k - self.first].len();
        let median = (0..dim)
            .map(|i| {
                let mut col: Vec<f64> = (lo..hi).map(|j| self.buf[j - self.first][i]).collect();
                col.sort_by(f64::total_cmp);
                let m = col.len();
                if m % 2 == 1 {
                    col[m / 2]
                } else {
                    0.5 * (col[m / 2 - 1] + col[m / 2])
                }
            })
            .collect();
        self.next += 1;
        // The next window starts no lower than next − window/2.
        while self.first + w / 2 < self.next && !self.buf.is_empty() {
            self.buf.pop_front();
            self.first += 1;
        }
        (k, median)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};

    fn g(p: &[f64]) -> Gaussian {
        Gaussian {
            x: DVector::from_vec(vec![0.0, 1.0, 2.0]),
            P: DMatrix::from_row_slice(3, 3, p),
        }
    }

    /// The closed-form trace matches a direct inversion at every ω, and the optimum is no worse than any grid point.
    #[test]
    fn trace_optimal_omega_matches_direct_inversion() {
        let a = g(&[2.0, 0.3, 0.0, 0.3, 0.5, 0.1, 0.0, 0.1, 1.0]);
        let b = g(&[0.4, -0.1, 0.0, -0.1, 3.0, 0.2, 0.0, 0.2, 0.7]);
        let w = trace_optimal_omega(&a, &b).unwrap();
        let best = intersect(&a, &b, w, &[false; 3]).unwrap().P.trace();
        for i in 0..=100 {
            let t = intersect(&a, &b, i as f64 / 100.0, &[false; 3]).unwrap().P.trace();
            assert!(best <= t + 1e-12, "ω = {w}: {best} > {t} at {}", i as f64 / 100.0);
        }
    }

    /// The streaming median equals the whole-series definition, window by window, near both ends too.
    #[test]
    fn streaming_median_is_the_centred_median() {
        let series: Vec<Vec<f64>> = (0..57)
            .map(|i| vec![((i * 37) % 11) as f64, (i as f64).sin()])
            .collect();
        for w in [1, 2, 5, 20, 21] {
            let direct: Vec<Vec<f64>> = (0..series.len())
                .map(|k| {
                    let n = series.len();
                    let half = (w / 2).min(k).min(n - 1 - k);
                    let (lo, hi) = if half < w / 2 {
                        (k - half, k + half + 1)
                    } else {
                        (k - w / 2, (k + w - w / 2).min(n))
                    };
                    (0..2)
                        .map(|i| {
                            let mut c: Vec<f64> = series[lo..hi].iter().map(|v| v[i]).collect();
                            c.sort_by(f64::total_cmp);
                            let m = c.len();
                            if m % 2 == 1 {
                                c[m / 2]
                            } else {
                                0.5 * (c[m / 2 - 1] + c[m / 2])
                            }
                        })
                        .collect()
                })
                .collect();
            let mut m = CentredMedian::new(w);
            let mut got = Vec::new();
            for v in &series {
                got.extend(m.push(v.clone()));
                assert!(m.buf.len() <= w + 1, "window {w}: {} samples held", m.buf.len());
            }
            got.extend(m.finish());
            assert_eq!(
                got.iter().map(|g| g.0).collect::<Vec<_>>(),
                (0..series.len()).collect::<Vec<_>>()
            );
            assert_eq!(got.into_iter().map(|g| g.1).collect::<Vec<_>>(), direct, "window {w}");
        }
    }
}
