//! Hard- and soft-iron calibration of a magnetometer from the recording itself: the readings of a turning sensor lie
//! on an ellipsoid (m = S R h + b, S the soft-iron matrix, b the hard-iron offset); a least-squares fit of the
//! general quadric (Kok, Hol & Schön 2012, "Calibration of a magnetometer in combination with inertial sensors", §II;
//! the algebraic fit of Li & Griffiths 2004) gives its centre b and shape, and m ↦ W (m − b) puts them back on a
//! sphere. W is found up to a rotation only, so it is taken symmetric, which leaves the body frame alone.
//!
//! A fit is only as good as the turning and the field: readings that do not cover enough of the sphere (a sensor
//! turned about one axis) give a quadric that is no ellipsoid, and a field disturbed along the way gives one that
//! does not explain why |m| varies. Either fit is refused with the reason.

use nalgebra::{DMatrix, DVector, Matrix3, SymmetricEigen, Vector3};

/// The least share of the readings' direction scatter along its thinnest axis (a sphere covered evenly has 1/3 on
/// each): below it the readings lie near a plane or a cone and do not fix the ellipsoid.
pub const MIN_COVERAGE: f64 = 0.05;

/// The share of the variance of |m| the ellipsoid must explain: the calibrated |m| must vary at most half as much
/// (in standard deviation) as the raw one, or the variation is not iron but a disturbance.
pub const MIN_EXPLAINED: f64 = 0.75;

#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    /// Hard-iron offset b (file unit).
    pub offset: Vector3<f64>,
    /// Soft-iron correction W (symmetric, scaled so that the corrected field keeps the readings' mean magnitude).
    pub matrix: Matrix3<f64>,
    /// Relative standard deviation of |m| before and after.
    pub spread_before: f64,
    pub spread_after: f64,
}

impl Calibration {
    pub fn apply(&self, m: &Vector3<f64>) -> Vector3<f64> {
        self.matrix * (m - self.offset)
    }
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Refused {
    #[error("{0} magnetometer readings: at least 20 are needed")]
    TooFew(usize),
    #[error(
        "the readings cover too little of the sphere (thinnest share of their directions {0:.3}, need {MIN_COVERAGE}): \
         turn the sensor about more than one axis"
    )]
    Coverage(f64),
    #[error("the fitted quadric is not an ellipsoid")]
    NotEllipsoid,
    #[error(
        "the ellipsoid explains too little of how |m| varies (relative spread {before:.3} before, {after:.3} after): \
         the field is disturbed, not distorted by iron"
    )]
    NoBetter { before: f64, after: f64 },
}

fn relative_spread(v: impl Iterator<Item = f64> + Clone) -> f64 {
    let n = v.clone().count() as f64;
    let mean = v.clone().sum::<f64>() / n;
    let var = v.map(|x| (x - mean).powi(2)).sum::<f64>() / n;
    var.sqrt() / mean
}

/// Fit the ellipsoid to the readings `m`.
pub fn fit(m: &[Vector3<f64>]) -> Result<Calibration, Refused> {
    let n = m.len();
    if n < 20 {
        return Err(Refused::TooFew(n));
    }
    // Centre the data first: the algebraic fit is then well scaled whatever the unit.
    let mean = m.iter().sum::<Vector3<f64>>() / n as f64;
    let scale = m.iter().map(|x| (x - mean).norm()).sum::<f64>() / n as f64;
    if scale <= 0.0 || !scale.is_finite() {
        return Err(Refused::NotEllipsoid);
    }
    let p: Vec<Vector3<f64>> = m.iter().map(|x| (x - mean) / scale).collect();
    // xᵀ A x + 2 uᵀ x = 1 in the nine unknowns of A (symmetric) and u.
    let design = DMatrix::from_fn(n, 9, |i, j| {
        let [x, y, z] = [p[i][0], p[i][1], p[i][2]];
        [
            x * x,
            y * y,
            z * z,
            2.0 * x * y,
            2.0 * x * z,
            2.0 * y * z,
            2.0 * x,
            2.0 * y,
            2.0 * z,
        ][j]
    });
    let v = design
        .svd(true, true)
        .solve(&DVector::from_element(n, 1.0), 1e-12)
        .map_err(|_| Refused::NotEllipsoid)?;
    let a = Matrix3::new(v[0], v[3], v[4], v[3], v[1], v[5], v[4], v[5], v[2]);
    let u = Vector3::new(v[6], v[7], v[8]);
    let centre = -a.try_inverse().ok_or(Refused::NotEllipsoid)? * u;
    // (x − c)ᵀ A (x − c) = 1 + cᵀ A c.
    let k = 1.0 + centre.dot(&(a * centre));
    // An eigen-decomposition of a non-finite matrix need not end: those are no ellipsoid.
    let eigen = |m: Matrix3<f64>| {
        if m.iter().all(|x| x.is_finite()) {
            SymmetricEigen::try_new(m, f64::EPSILON, 1000)
        } else {
            None
        }
    };
    let shape = eigen(a / k).ok_or(Refused::NotEllipsoid)?;
    if shape.eigenvalues.iter().any(|e| !e.is_finite() || *e <= 0.0) {
        return Err(Refused::NotEllipsoid);
    }
    // The directions from the centre: their scatter's thinnest axis says how much of the sphere was seen.
    let dirs: Vec<Vector3<f64>> = p.iter().filter_map(|x| (x - centre).try_normalize(1e-12)).collect();
    let scatter = dirs.iter().map(|d| d * d.transpose()).sum::<Matrix3<f64>>() / dirs.len().max(1) as f64;
    let thinnest = eigen(scatter).ok_or(Refused::NotEllipsoid)?.eigenvalues.min();
    if thinnest < MIN_COVERAGE {
        return Err(Refused::Coverage(thinnest));
    }
    // W = (A/k)^{1/2}, symmetric; then scaled to keep the mean magnitude of the readings about the centre.
    let root =
        shape.eigenvectors * Matrix3::from_diagonal(&shape.eigenvalues.map(f64::sqrt)) * shape.eigenvectors.transpose();
    let offset = mean + centre * scale;
    let raw: Vec<f64> = m.iter().map(|x| (x - offset).norm()).collect();
    let keep = raw.iter().sum::<f64>() / n as f64;
    let matrix = root * (keep / scale);
    let cal = Calibration {
        offset,
        matrix,
        spread_before: relative_spread(m.iter().map(|x| x.norm())),
        spread_after: relative_spread(m.iter().map(|x| (matrix * (x - offset)).norm())),
    };
    if (cal.spread_after / cal.spread_before).powi(2) > 1.0 - MIN_EXPLAINED {
        return Err(Refused::NoBetter {
            before: cal.spread_before,
            after: cal.spread_after,
        });
    }
    Ok(cal)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector4;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    use simnet_engine::estimate::attitude::{rotate_to_body, turn};

    /// Readings of a sensor tumbling about a changing axis (or about z alone), through soft iron S and hard iron b,
    /// with white noise.
    fn readings(tumble: bool, seed: u64) -> (Vec<Vector3<f64>>, Matrix3<f64>, Vector3<f64>) {
        let soft = Matrix3::new(1.2, 0.1, 0.0, 0.1, 0.9, 0.05, 0.0, 0.05, 1.05);
        let b = Vector3::new(0.3, -0.2, 0.1);
        let h = Vector3::new(0.25, 0.0, -0.433);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let noise = Normal::new(0.0, 0.002).unwrap();
        let mut q = Vector4::new(1.0, 0.0, 0.0, 0.0);
        let mut out = Vec::new();
        for k in 0..3000 {
            let t = k as f64 * 0.01;
            let w = if tumble {
                Vector3::new(1.1 * (0.5 * t).sin(), 0.9 * (0.37 * t).cos(), 0.7)
            } else {
                Vector3::new(0.0, 0.0, 0.7)
            };
            let e = Vector3::from_fn(|_, _| noise.sample(&mut rng));
            out.push(soft * rotate_to_body(&q, &h).0 + b + e);
            q = turn(&q, &w, 0.01);
        }
        (out, soft, b)
    }

    /// The fit finds the hard-iron offset, and W S is a rotation times a scale: W undoes the soft iron.
    #[test]
    fn a_tumbling_sensor_gives_back_its_hard_and_soft_iron() {
        let (m, soft, b) = readings(true, 5);
        let c = fit(&m).unwrap();
        assert!((c.offset - b).amax() < 0.005, "offset {:?}", c.offset);
        let ws = c.matrix * soft;
        let gram = ws.transpose() * ws;
        let s2 = gram.trace() / 3.0;
        assert!((gram / s2 - Matrix3::identity()).amax() < 0.02, "{gram}");
        assert!(c.spread_after < 0.01 && c.spread_before > 0.05, "{c:?}");
    }

    /// Turned about one axis the readings lie on a circle: refused, saying why.
    #[test]
    fn a_sensor_turned_about_one_axis_is_not_calibrated() {
        let (m, _, _) = readings(false, 6);
        let e = fit(&m).unwrap_err();
        assert!(matches!(e, Refused::Coverage(_) | Refused::NotEllipsoid), "{e}");
        assert!(matches!(fit(&m[..10]), Err(Refused::TooFew(10))));
    }
}
