//! Statistics for tests and reports: quantiles of the normal, chi-square and Student's t distributions (statrs),
//! the median, and the mean of a sample with its Student-t confidence interval.

use statrs::distribution::{ChiSquared, ContinuousCDF, Normal, StudentsT};

/// Φ⁻¹(p) for 0 < p < 1.
pub fn normal_quantile(p: f64) -> f64 {
    Normal::standard().inverse_cdf(p)
}

/// The p-quantile of χ²(k); NaN for k ≤ 0.
pub fn chi2_quantile(p: f64, k: f64) -> f64 {
    ChiSquared::new(k).map_or(f64::NAN, |d| d.inverse_cdf(p))
}

/// The p-quantile of Student's t with `dof` degrees of freedom; NaN for dof ≤ 0.
pub fn t_quantile(p: f64, dof: f64) -> f64 {
    StudentsT::new(0.0, 1.0, dof).map_or(f64::NAN, |d| d.inverse_cdf(p))
}

/// The median of `v` (the mean of the middle two for an even count); NaN for an empty slice.
pub fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let m = s.len() / 2;
    if s.len() % 2 == 1 {
        s[m]
    } else {
        0.5 * (s[m - 1] + s[m])
    }
}

/// A sample's mean, standard deviation (n − 1) and the confidence interval of its mean from Student's t.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MeanCi {
    /// Values.
    pub n: usize,
    /// Their mean.
    pub mean: f64,
    /// NaN for fewer than two values.
    pub sd: f64,
    /// mean ∓ t_{(1+level)/2, n−1} · sd/√n; NaN for fewer than two values.
    pub low: f64,
    /// Upper end of the interval (see `low`).
    pub high: f64,
}

impl MeanCi {
    /// `mean ± half-width`, to the second significant digit of the half-width (four significant digits without
    /// one); `—` without a mean.
    pub fn text(&self) -> String {
        if !self.mean.is_finite() {
            return "—".into();
        }
        let half = self.high - self.mean;
        let digits =
            |v: f64, keep: i32| (keep - v.abs().log10().floor().clamp(-20.0, 20.0) as i32).clamp(0, 12) as usize;
        if half.is_finite() && half > 0.0 {
            let d = digits(half, 1);
            format!("{:.d$} ± {:.d$}", self.mean, half)
        } else if self.mean != 0.0 {
            let d = digits(self.mean, 3);
            format!("{:.d$}", self.mean)
        } else {
            "0".into()
        }
    }

    /// The same sample measured in another unit (× `k`, k > 0): a fraction as a percentage.
    pub fn scaled(&self, k: f64) -> MeanCi {
        MeanCi {
            mean: k * self.mean,
            sd: k * self.sd,
            low: k * self.low,
            high: k * self.high,
            ..*self
        }
    }

    /// Over the finite values of `v`, at confidence `level` (0.95 for 95 %).
    pub fn of(v: &[f64], level: f64) -> MeanCi {
        let v: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
        let n = v.len();
        let mean = if n == 0 {
            f64::NAN
        } else {
            v.iter().sum::<f64>() / n as f64
        };
        if n < 2 {
            return MeanCi {
                n,
                mean,
                sd: f64::NAN,
                low: f64::NAN,
                high: f64::NAN,
            };
        }
        let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt();
        let half = t_quantile(0.5 + level / 2.0, (n - 1) as f64) * sd / (n as f64).sqrt();
        MeanCi {
            n,
            mean,
            sd,
            low: mean - half,
            high: mean + half,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_quantiles() {
        assert!((normal_quantile(0.975) - 1.959964).abs() < 1e-6);
        assert!((normal_quantile(0.001) + 3.090232).abs() < 1e-6);
        // χ²(100): 2.5 % = 74.2219, 97.5 % = 129.5612 (tables).
        assert!((chi2_quantile(0.025, 100.0) - 74.2219).abs() < 1e-3);
        assert!((chi2_quantile(0.975, 100.0) - 129.5612).abs() < 1e-3);
        // t(9) 97.5 % = 2.262157, t(1) 97.5 % = 12.7062 (tables).
        assert!((t_quantile(0.975, 9.0) - 2.262157).abs() < 1e-5);
        assert!((t_quantile(0.975, 1.0) - 12.7062).abs() < 1e-3);
    }

    #[test]
    fn the_interval_of_a_known_sample() {
        // 1 … 10: mean 5.5, sd √(55/6) = 3.02765, half-width 2.262157 · 3.02765 / √10 = 2.165851.
        let ci = MeanCi::of(&(1..=10).map(f64::from).collect::<Vec<_>>(), 0.95);
        assert_eq!((ci.n, ci.mean), (10, 5.5));
        assert!((ci.sd - 3.027650).abs() < 1e-6);
        assert!((ci.high - 5.5 - 2.165851).abs() < 1e-5 && (5.5 - ci.low - 2.165851).abs() < 1e-5);
        let one = MeanCi::of(&[2.0, f64::NAN], 0.95);
        assert_eq!(one.n, 1);
        assert!(one.sd.is_nan() && one.low.is_nan());
        // Written to the second significant digit of the half-width.
        assert_eq!(ci.text(), "5.5 ± 2.2");
        assert_eq!(MeanCi::of(&[0.01, 0.012, 0.011], 0.95).text(), "0.0110 ± 0.0025");
        assert_eq!(one.text(), "2.000");
        assert_eq!(MeanCi::of(&[0.0, 0.0], 0.95).text(), "0");
        assert_eq!(MeanCi::of(&[], 0.95).text(), "—");
        assert_eq!(MeanCi::of(&[0.1, 0.3], 0.95).scaled(100.0).text(), "20 ± 127");
    }
}
