//! Attitude from a recording, scored against the recording's own reference orientation: the quaternion EKF of
//! Lesecq's slides beside Madgwick's and Mahony's filters on the same samples, with noise levels, gyro bias and the
//! navigation-frame field estimated from the recording itself rather than set by hand.
//!
//! The navigation frame is z up with x along the horizontal part of the field (magnetic north); a reference given
//! z down (NED) is turned into it. Errors are split into heading (the rotation about the vertical between estimate
//! and reference) and tilt (the rest), and given as recorded and with the constant heading offset removed: a
//! reference whose north is not magnetic north differs by that offset alone.

use nalgebra::{DMatrix, DVector, Matrix3, Vector3, Vector4};

use crate::estimate::ahrs::{Madgwick, Mahony, MADGWICK_BETA_IMU, MADGWICK_BETA_MARG, MAHONY_KI, MAHONY_KP};
use crate::estimate::attitude::{from_euler, level, rotate_to_body, AttitudeEkf, AttitudeModel, Form};
use crate::estimate::EstimateError;
use crate::imu_csv::ImuRecording;

#[derive(Debug, thiserror::Error)]
pub enum AttitudeError {
    #[error("the recording has no reference orientation (quaternion or roll, pitch, yaw columns) to score against")]
    NoReference,
    #[error("{0}")]
    Estimate(#[from] EstimateError),
}

/// What the recording says of its sensor, estimated from its quietest second.
#[derive(Debug, Clone, PartialEq)]
pub struct Estimated {
    /// The quietest window: first and last sample.
    pub window: (usize, usize),
    pub gyro_bias: Vector3<f64>,
    /// Gyro noise variance per axis (mean of the three), (rad/s)².
    pub gyro_var: f64,
    /// Accelerometer noise variance, (m/s²)².
    pub accel_var: f64,
    /// |a| over the window: the local g as the sensor reads it, m/s².
    pub g: f64,
    /// Magnetometer noise variance and the field's magnitude (file unit) and dip (rad, positive down).
    pub mag_var: Option<f64>,
    pub field: Option<(f64, f64)>,
}

fn mean_var(v: &[Vector3<f64>]) -> (Vector3<f64>, f64) {
    let n = v.len() as f64;
    let m = v.iter().sum::<Vector3<f64>>() / n;
    let var = v.iter().map(|x| (x - m).norm_squared()).sum::<f64>() / (3.0 * (n - 1.0).max(1.0));
    (m, var)
}

/// The one-second window (at least 10 samples) where the gyro varies least, and what it gives.
pub fn estimate(rec: &ImuRecording, rate_hz: f64) -> Estimated {
    let n = rec.t.len();
    let w = ((rate_hz.round() as usize).max(10)).min(n);
    let mut best = (f64::INFINITY, 0);
    let mut i = 0;
    while i + w <= n {
        let (_, v) = mean_var(&rec.gyro[i..i + w]);
        let (_, a) = mean_var(&rec.accel[i..i + w]);
        // Quiet in rotation and in acceleration alike.
        let score = v + a * 1e-3;
        if score < best.0 {
            best = (score, i);
        }
        i += (w / 4).max(1);
    }
    let s = best.1;
    let (bias, gyro_var) = mean_var(&rec.gyro[s..s + w]);
    let (a, accel_var) = mean_var(&rec.accel[s..s + w]);
    let (mag_var, field) = match &rec.mag {
        Some(m) => {
            let (mm, var) = mean_var(&m[s..s + w]);
            // Dip: the angle of the field below the horizontal, the vertical being −a ("down").
            let down = -a.normalize();
            let dip = (mm.normalize().dot(&down)).clamp(-1.0, 1.0).asin();
            (Some(var), Some((mm.norm(), dip)))
        }
        None => (None, None),
    };
    Estimated {
        window: (s, s + w - 1),
        gyro_bias: bias,
        gyro_var,
        accel_var,
        g: a.norm(),
        mag_var,
        field,
    }
}

/// One filter's error against the reference, degrees.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct Errors {
    pub mean: f64,
    pub rms: f64,
    pub max: f64,
    pub heading_mean: f64,
    pub tilt_mean: f64,
}

#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Score {
    pub filter: &'static str,
    pub as_recorded: Errors,
    /// With the constant heading offset (reported) removed.
    pub offset_removed: Errors,
    pub heading_offset_deg: f64,
}

/// The rotation about the vertical (z) of q and what is left: (twist angle, swing angle), rad.
fn swing_twist(q: &Vector4<f64>) -> (f64, f64) {
    let twist = 2.0 * q[3].atan2(q[0]);
    // |swing| from q = swing ⊗ twist: cos(swing/2) = √(w² + z²).
    let swing = 2.0 * (q[0] * q[0] + q[3] * q[3]).sqrt().min(1.0).acos();
    (crate::geom::wrap_angle(twist), swing)
}

fn mul(a: &Vector4<f64>, b: &Vector4<f64>) -> Vector4<f64> {
    Vector4::new(
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    )
}

fn conj(q: &Vector4<f64>) -> Vector4<f64> {
    Vector4::new(q[0], -q[1], -q[2], -q[3])
}

fn errors_of(est: &[Vector4<f64>], reference: &[Vector4<f64>], offset: f64) -> Errors {
    let rz = Vector4::new((offset / 2.0).cos(), 0.0, 0.0, (offset / 2.0).sin());
    let (mut sum, mut sq, mut max, mut head, mut tilt) = (0.0, 0.0, 0f64, 0.0, 0.0);
    for (e, r) in est.iter().zip(reference) {
        // The navigation-frame rotation from the (offset) reference to the estimate.
        let d = mul(e, &conj(&mul(&rz, r)));
        let angle = crate::estimate::attitude::angle_between(e, &mul(&rz, r));
        let (tw, sw) = swing_twist(&d);
        sum += angle;
        sq += angle * angle;
        max = max.max(angle);
        head += tw.abs();
        tilt += sw;
    }
    let n = est.len().max(1) as f64;
    Errors {
        mean: (sum / n).to_degrees(),
        rms: (sq / n).sqrt().to_degrees(),
        max: max.to_degrees(),
        heading_mean: (head / n).to_degrees(),
        tilt_mean: (tilt / n).to_degrees(),
    }
}

/// The constant rotation about the vertical that best takes the reference to the estimate: the circular mean of
/// the heading differences.
fn heading_offset(est: &[Vector4<f64>], reference: &[Vector4<f64>]) -> f64 {
    let (mut s, mut c) = (0.0, 0.0);
    for (e, r) in est.iter().zip(reference) {
        let (tw, _) = swing_twist(&mul(e, &conj(r)));
        s += tw.sin();
        c += tw.cos();
    }
    s.atan2(c)
}

/// The reference as z-up quaternions: a reference whose "up" is −z (NED) is turned by π about x. Which one the
/// file uses is read off its first sample: the accelerometer points up.
pub fn reference_up(rec: &ImuRecording) -> Result<(Vec<Vector4<f64>>, bool), AttitudeError> {
    let q: Vec<Vector4<f64>> = match (&rec.quat, &rec.euler) {
        (Some(q), _) => q.clone(),
        (None, Some(e)) => e.iter().map(from_euler).collect(),
        _ => return Err(AttitudeError::NoReference),
    };
    let f = rec.accel[0].normalize();
    let (up, _) = rotate_to_body(&q[0], &Vector3::z());
    let z_down = up.dot(&f) < 0.0;
    let flip = Vector4::new(0.0, 1.0, 0.0, 0.0);
    Ok((
        if z_down {
            q.iter().map(|x| mul(&flip, x)).collect()
        } else {
            q
        },
        z_down,
    ))
}

/// Every filter's attitudes over the recording and its scores.
#[derive(Debug, Clone)]
pub struct Comparison {
    pub estimated: Estimated,
    pub reference_z_down: bool,
    /// Navigation-frame gravity and field the filters use.
    pub g: Vector3<f64>,
    pub h: Option<Vector3<f64>>,
    pub scores: Vec<Score>,
    pub attitudes: Vec<(&'static str, Vec<Vector4<f64>>)>,
}

/// Run the EKF, Madgwick and Mahony on `rec`, each initialised from the first accelerometer and magnetometer
/// samples, with the noise levels and field of [`estimate`].
pub fn compare(rec: &ImuRecording, rate_hz: f64) -> Result<Comparison, AttitudeError> {
    let (reference, z_down) = reference_up(rec)?;
    let est = estimate(rec, rate_hz);
    let g = Vector3::new(0.0, 0.0, -est.g);
    let h = est
        .field
        .map(|(mag, dip)| Vector3::new(mag * dip.cos(), 0.0, -mag * dip.sin()));
    let hv = h.unwrap_or_else(Vector3::x);
    let m0 = rec.mag.as_ref().map(|m| m[0]);
    let q0 = from_euler(&level(&rec.accel[0], m0.as_ref(), &g, &hv));
    let n = rec.t.len();
    let dt_of = |k: usize| {
        if k == 0 {
            rec.t[1] - rec.t[0]
        } else {
            rec.t[k] - rec.t[k - 1]
        }
    };
    // The EKF: gyro noise and bias, accelerometer and magnetometer noise, all from the quiet window.
    let model = AttitudeModel {
        g,
        h: hv,
        Rg: Matrix3::identity() * est.gyro_var,
        R: DMatrix::from_diagonal(&DVector::from_vec(vec![
            est.accel_var,
            est.accel_var,
            est.accel_var,
            est.mag_var.unwrap_or(1.0),
            est.mag_var.unwrap_or(1.0),
            est.mag_var.unwrap_or(1.0),
        ])),
        lambda: 1e3,
    };
    let mut ekf = AttitudeEkf::new(q0, &(DMatrix::identity(4, 4) * 1e-2), Form::Standard)?;
    let marg = h.is_some();
    let mut mad = Madgwick::new(q0, if marg { MADGWICK_BETA_MARG } else { MADGWICK_BETA_IMU });
    let mut mah = Mahony::new(q0, MAHONY_KP, MAHONY_KI);
    let mut out: [Vec<Vector4<f64>>; 3] = [Vec::with_capacity(n), Vec::with_capacity(n), Vec::with_capacity(n)];
    for k in 0..n {
        let dt = dt_of(k);
        let w = rec.gyro[k] - est.gyro_bias;
        let f = rec.accel[k];
        let m = rec.mag.as_ref().map(|m| m[k]);
        if k > 0 {
            ekf.predict(&w, dt, &model)?;
            // The open filters take the raw gyro: estimating its bias is part of what they do (Mahony) or not.
            mad.update(&rec.gyro[k], Some(&f), m.as_ref().filter(|_| marg), &g, &hv, dt);
            mah.update(&rec.gyro[k], Some(&f), m.as_ref().filter(|_| marg), &g, &hv, dt);
        }
        let mut y = DVector::zeros(6);
        y.rows_mut(0, 3).copy_from(&f);
        if let Some(m) = m {
            y.rows_mut(3, 3).copy_from(&m);
        }
        ekf.update(&y, [true, marg], &model)?;
        out[0].push(ekf.q);
        out[1].push(mad.q);
        out[2].push(mah.q);
    }
    let names = ["ekf", "madgwick", "mahony"];
    let mut scores = Vec::new();
    for (name, q) in names.iter().zip(&out) {
        let off = heading_offset(q, &reference);
        scores.push(Score {
            filter: name,
            as_recorded: errors_of(q, &reference, 0.0),
            offset_removed: errors_of(q, &reference, off),
            heading_offset_deg: off.to_degrees(),
        });
    }
    let [a, b, c] = out;
    Ok(Comparison {
        estimated: est,
        reference_z_down: z_down,
        g,
        h,
        scores,
        attitudes: vec![(names[0], a), (names[1], b), (names[2], c)],
    })
}
