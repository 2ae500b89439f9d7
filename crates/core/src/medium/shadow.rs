//! Log-normal shadowing: the slow loss obstacles add to the path loss, a normal variable in dB with standard deviation
//! σ, the same both ways of a pair (reciprocity), constant while neither end moves, and decorrelating as the ends move
//! with the exponential autocorrelation of Gudmundson ("Correlation model for shadow fading in mobile radio
//! systems", Electronics Letters 27(23), 1991, eq. 1: R(Δ) = σ² e^{−|Δ|/d_c}). Between two looks at a pair, Δ is the
//! larger displacement of its two ends, and the value follows the first-order autoregression that has exactly that
//! correlation: s ← ρ s + √(1 − ρ²) σ w, ρ = e^{−Δ/d_c}, w standard normal. Each pair draws from its own seeded
//! stream, so a pair's values do not depend on the other pairs.

use std::collections::HashMap;

use nalgebra::Vector3;

use crate::rng::Rng;

/// The shadowing's law.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Shadowing {
    /// σ, dB.
    pub sigma_db: f64,
    /// The distance moved over which the correlation falls to 1/e, m.
    pub decorrelation_m: f64,
}

impl Shadowing {
    /// Gudmundson's microcellular measurement (1700 MHz): correlation 0.3 at 10 m, so d_c = 10 / ln(1/0.3) m.
    pub const DECORRELATION_M: f64 = 8.305_835_451_214_08;
}

/// One pair's shadowing as last drawn, and where its ends stood.
#[derive(Debug, Clone)]
struct Pair {
    db: f64,
    a: Vector3<f64>,
    b: Vector3<f64>,
    rng: Rng,
}

/// Every pair's shadowing over a run.
#[derive(Debug, Clone)]
pub struct ShadowField {
    law: Shadowing,
    seed: u64,
    pairs: HashMap<(usize, usize), Pair>,
}

impl ShadowField {
    /// No pair drawn yet; each draws from streams of `seed`.
    pub fn new(law: Shadowing, seed: u64) -> ShadowField {
        ShadowField {
            law,
            seed,
            pairs: HashMap::new(),
        }
    }

    /// The shadowing between nodes `i` and `j` standing at `pi` and `pj`, dB (a loss added to the path loss).
    pub fn db(&mut self, i: usize, j: usize, pi: Vector3<f64>, pj: Vector3<f64>) -> f64 {
        let Shadowing {
            sigma_db,
            decorrelation_m,
        } = self.law;
        if sigma_db <= 0.0 {
            return 0.0;
        }
        // The pair in index order, its ends with it.
        let (key, a, b) = if i <= j { ((i, j), pi, pj) } else { ((j, i), pj, pi) };
        let normal = |rng: &mut Rng| -> f64 { rand::Rng::sample(rng, rand_distr::StandardNormal) };
        let seed = self.seed;
        let p = self.pairs.entry(key).or_insert_with(|| {
            let mut rng = crate::rng::stream(seed, "shadow", key.0 as u64, key.1 as u64);
            let db = sigma_db * normal(&mut rng);
            Pair { db, a, b, rng }
        });
        let moved = (a - p.a).norm().max((b - p.b).norm());
        if moved > 0.0 {
            let rho = (-moved / decorrelation_m).exp();
            p.db = rho * p.db + (1.0 - rho * rho).sqrt() * sigma_db * normal(&mut p.rng);
            p.a = a;
            p.b = b;
        }
        p.db
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LAW: Shadowing = Shadowing {
        sigma_db: 6.0,
        decorrelation_m: 10.0,
    };

    /// Over 4000 static pairs the values are N(0, σ²): the mean within 3 standard errors of 0, the variance within
    /// 3 of its standard errors (√(2/n) σ²) of σ²; each pair the same both ways and while neither end moves.
    #[test]
    fn static_pairs_are_normal_reciprocal_and_constant() {
        let mut f = ShadowField::new(LAW, 7);
        let (p, q) = (Vector3::zeros(), Vector3::new(3.0, 4.0, 0.0));
        let n = 4000;
        let v: Vec<f64> = (0..n).map(|k| f.db(2 * k, 2 * k + 1, p, q)).collect();
        for (k, &x) in v.iter().enumerate() {
            assert_eq!(f.db(2 * k + 1, 2 * k, q, p), x);
            assert_eq!(f.db(2 * k, 2 * k + 1, p, q), x);
        }
        let mean = v.iter().sum::<f64>() / n as f64;
        let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
        let s2 = LAW.sigma_db.powi(2);
        assert!(mean.abs() < 3.0 * LAW.sigma_db / (n as f64).sqrt(), "mean {mean}");
        assert!((var - s2).abs() < 3.0 * s2 * (2.0 / n as f64).sqrt(), "variance {var}");
    }

    /// A pair whose one end moves d_c / 4 between looks: the correlation of successive values over 4000 pairs is
    /// e^{−1/4} within 3 standard errors ((1 − ρ²)/√n), the variance stays σ², and a pair moved d_c · 5 apart is
    /// nearly independent of where it began.
    #[test]
    fn moving_ends_decorrelate_as_gudmundson_s_exponential() {
        let mut f = ShadowField::new(LAW, 11);
        let step = Vector3::new(LAW.decorrelation_m / 4.0, 0.0, 0.0);
        let n = 4000;
        let (mut xy, mut xx, mut yy, mut far) = (0.0, 0.0, 0.0, 0.0);
        for k in 0..n {
            let (i, j) = (2 * k, 2 * k + 1);
            let a = Vector3::zeros();
            let x = f.db(i, j, a, Vector3::zeros());
            let y = f.db(i, j, a, step);
            xy += x * y;
            xx += x * x;
            yy += y * y;
            let z = f.db(i, j, a, step * 21.0);
            far += x * z;
        }
        let rho = xy / (xx * yy).sqrt();
        let expected = (-0.25f64).exp();
        assert!(
            (rho - expected).abs() < 3.0 * (1.0 - expected * expected) / (n as f64).sqrt(),
            "ρ {rho}"
        );
        assert!((yy / n as f64 - 36.0).abs() < 3.0 * 36.0 * (2.0 / n as f64).sqrt());
        // Five decorrelation distances on: e^{−5} = 0.007, within 3/√n of 0.
        assert!((far / xx).abs() < 3.0 / (n as f64).sqrt(), "{}", far / xx);
    }

    #[test]
    fn no_sigma_no_shadowing() {
        let mut f = ShadowField::new(Shadowing { sigma_db: 0.0, ..LAW }, 1);
        assert_eq!(f.db(0, 1, Vector3::zeros(), Vector3::x()), 0.0);
    }
}
