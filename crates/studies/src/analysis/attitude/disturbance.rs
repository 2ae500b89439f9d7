//! One component of a disturbance as a recording shows it — its size over the samples a gate passes and how long it
//! lasts — below both the sensor's characterisation ([`super::sensor`]) and the gyro-aided fit across g and the field
//! ([`super::across`]), which both measure disturbances this way.

/// One component of a disturbance: its mean square over the samples a gate passes, its correlation time over the
/// same samples, the others gaps ([`correlation_time_of`], samples), and their product, the white-noise variance a
/// filter that takes it as white should use.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Part {
    pub var: f64,
    pub tau: f64,
    pub white_equivalent: f64,
}

impl Part {
    pub fn of(series: &[f64], passed: impl Fn(usize) -> bool) -> Part {
        let kept: Vec<f64> = (0..series.len()).filter(|&k| passed(k)).map(|k| series[k]).collect();
        let var = mean_square(&kept);
        let tau = correlation_time_of(series, &passed);
        Part {
            var,
            tau,
            white_equivalent: var * tau,
        }
    }

    /// The mean of two components (the two horizontal axes).
    pub fn mean(a: Part, b: Part) -> Part {
        let (var, tau) = (0.5 * (a.var + b.var), 0.5 * (a.tau + b.tau));
        Part {
            var,
            tau,
            white_equivalent: 0.5 * (a.white_equivalent + b.white_equivalent),
        }
    }
}

pub(super) fn mean_square(x: &[f64]) -> f64 {
    x.iter().map(|d| d * d).sum::<f64>() / x.len().max(1) as f64
}

/// The longest lag [`correlation_time`] sums over, samples.
pub const MAX_LAG: usize = 2000;

/// The integrated autocorrelation time of a series, in samples: 1 + 2 Σ ρ_k over the initial positive sequence of
/// its autocorrelations ρ_k (Geyer 1992). A disturbance that lasts τ samples weighs in a filter that takes it as
/// white noise like τ independent ones: its white-noise equivalent has τ times its variance.
pub fn correlation_time(x: &[f64]) -> f64 {
    correlation_time_of(x, |_| true)
}

/// [`correlation_time`] of the samples `kept` keeps, the others gaps: each lag's autocovariance sums over the pairs
/// both of whose samples are kept, so that a refused stretch neither joins its neighbours nor counts.
pub fn correlation_time_of(x: &[f64], kept: impl Fn(usize) -> bool) -> f64 {
    let n = x.len();
    let keep: Vec<bool> = (0..n).map(kept).collect();
    let count = keep.iter().filter(|k| **k).count();
    if count < 3 {
        return 1.0;
    }
    let m = (0..n).filter(|&i| keep[i]).map(|i| x[i]).sum::<f64>() / count as f64;
    let c0 = (0..n).filter(|&i| keep[i]).map(|i| (x[i] - m).powi(2)).sum::<f64>() / count as f64;
    if c0 <= 0.0 {
        return 1.0;
    }
    let mut tau = 1.0;
    // At most MAX_LAG lags: a drifting series stays positively correlated far out, and the sum is then past any use.
    for k in 1..(n / 2).min(MAX_LAG) {
        let ck = (0..n - k)
            .filter(|&i| keep[i] && keep[i + k])
            .map(|i| (x[i] - m) * (x[i + k] - m))
            .sum::<f64>()
            / count as f64;
        let rho = ck / c0;
        if rho <= 0.0 {
            break;
        }
        tau += 2.0 * rho;
    }
    tau
}
