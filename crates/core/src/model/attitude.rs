//! The attitude model: the quaternion EKF of Lesecq's slides (Lesecq 2009), built on [`crate::estimate::attitude`].
//! The gyro drives the prediction; the accelerometer (channel 0) and the magnetometer (channel 1) are the
//! measurements that travel over the network, linearised about each filter's prior.

use std::borrow::Cow;

use nalgebra::{DMatrix, DVector, Matrix3, Vector3, Vector4};

use super::{
    stacked, Dynamics, FusionLayout, GroundTruth, ImuRow, Manifold, Measurement, Report, Sensed, Sensing, Site, Truth,
};
use crate::estimate::attitude::{from_euler, level, measurement, predict, to_euler};
use crate::estimate::{Gaussian, Observation};
use crate::rng::Rng;
use crate::sensor::{ImuInterval, ImuSample, Sensor, SensorProfile};

/// The attitude model's noise and field (the `[model]` keys of `kind = "attitude"`).
#[derive(Debug, Clone)]
pub struct Attitude {
    /// Accelerometer noise variance in the filter, (m/s²)²; covers unmodelled linear acceleration too.
    pub r_acc: f64,
    /// Magnetometer noise variance, in the squared unit of `mag_field`.
    pub r_mag: f64,
    /// Earth's field in the navigation frame (z up).
    pub mag_field: [f64; 3],
    /// Prior variance of each Euler angle, rad².
    pub p0_att: f64,
}

impl Default for Attitude {
    fn default() -> Attitude {
        Attitude {
            r_acc: 0.01,
            r_mag: 1e-5,
            mag_field: [0.25, 0.0, -0.433],
            p0_att: 0.003,
        }
    }
}

impl Attitude {
    /// Gravity in the navigation frame (z up).
    pub fn gravity(&self) -> Vector3<f64> {
        Vector3::new(0.0, 0.0, -crate::geom::GRAVITY)
    }

    /// Earth's field in the navigation frame.
    pub fn field(&self) -> Vector3<f64> {
        Vector3::from(self.mag_field)
    }
}

fn quaternion(x: &DVector<f64>) -> Vector4<f64> {
    Vector4::new(x[0], x[1], x[2], x[3])
}

impl Dynamics for Attitude {
    /// R_g, the gyro noise covariance. Without a gyro the filter assumes no rotation and covers the turn rate with
    /// process noise.
    fn process_noise(&self, imu: Option<&SensorProfile>, dt: f64) -> DMatrix<f64> {
        let gyro = imu.map_or(0.3, |s| s.gyro_noise);
        DMatrix::identity(3, 3) * (gyro * gyro / dt)
    }

    /// The mean rate over the interval drives q⁺ = A_t q; without a gyro the body is assumed not to turn.
    fn predict(&self, g: &Gaussian, imu: Option<&ImuInterval>, noise: &DMatrix<f64>, dt: f64) -> Gaussian {
        let w = imu.map_or(Vector3::zeros(), |s| (s.start.gyro + s.end.gyro) * 0.5);
        let Rg = Matrix3::from_iterator(noise.iter().copied());
        let (q, P) = predict(&quaternion(&g.x), &g.P, &w, dt, &Rg);
        Gaussian {
            x: DVector::from_column_slice(q.as_slice()),
            P,
        }
    }
}

impl Sensing for Attitude {
    fn observation(&self) -> Observation {
        let (a, m) = (self.r_acc, self.r_mag);
        Observation {
            H: DMatrix::zeros(6, 4),
            R: DMatrix::from_diagonal(&DVector::from_vec(vec![a, a, a, m, m, m])),
            angle_rows: vec![false; 6],
            channel_of_row: (0..6).map(|i| i / 3).collect(),
        }
    }

    /// The EKF's first-order expansion h(q) ≈ h(q̂) + C (q − q̂), i.e. H = C and z − (h(q̂) − C q̂), so that the
    /// linear (consensus) update sees the innovation z − h(q̂).
    fn linearize_at<'a>(
        &self,
        template: &'a Observation,
        prior: &Gaussian,
        _site: Site,
        z: &[&'a DVector<f64>],
    ) -> (Cow<'a, Observation>, Vec<Cow<'a, DVector<f64>>>) {
        let (h, C) = measurement(&quaternion(&prior.x), &self.gravity(), &self.field());
        let offset = h - &C * &prior.x;
        let obs = Observation {
            H: C,
            ..template.clone()
        };
        (Cow::Owned(obs), z.iter().map(|z| Cow::Owned(*z - &offset)).collect())
    }

    /// The accelerometer and magnetometer, simulated or recorded (a recording without a magnetometer sends the
    /// accelerometer channel only).
    fn sense(&self, sensor: &mut Sensor, truth: &Truth, _site: Site, t: f64) -> Sensed {
        if let Some((rec, i)) = truth.recording() {
            let Some(sample) = rec.imu.get(i).copied() else {
                return Sensed::default();
            };
            let mag = rec.mag.as_ref().and_then(|v| v.get(i).copied());
            return Sensed {
                imu: Some(sample),
                z: Some(Measurement {
                    z: stacked(&sample.accel, &mag.unwrap_or_default()),
                    present: (0..6).map(|r| r < 3 || mag.is_some()).collect(),
                }),
                row: None,
            };
        }
        let Some(tr) = truth.motion_now() else {
            return Sensed::default();
        };
        let sample = sensor.imu(&tr);
        let mag = sensor.magnetometer(&tr, &self.field());
        Sensed {
            imu: Some(sample),
            z: Some(Measurement::full(stacked(&sample.accel, &mag))),
            row: Some(ImuRow {
                t,
                sample,
                mag: Some(mag),
                position: tr.p,
                euler: tr.euler,
            }),
        }
    }
}

impl Manifold for Attitude {
    fn angle_states(&self) -> Vec<bool> {
        vec![false; 4]
    }

    /// The slides' EKF normalises the quaternion after each correction.
    fn normalize(&self, g: &mut Gaussian) {
        let n = g.x.norm();
        if n > 0.0 && n.is_finite() {
            g.x /= n;
        }
    }

    /// q and −q are the same attitude.
    fn aligned(&self, truth: &DVector<f64>, est: &DVector<f64>) -> DVector<f64> {
        if truth.dot(est) < 0.0 {
            -truth
        } else {
            truth.clone()
        }
    }
}

impl GroundTruth for Attitude {
    fn kinematic_state(
        &self,
        _p: Option<Vector3<f64>>,
        _v: Option<Vector3<f64>>,
        e: Option<Vector3<f64>>,
    ) -> DVector<f64> {
        let e = e.unwrap_or(Vector3::repeat(f64::NAN));
        DVector::from_column_slice(from_euler(&e).as_slice())
    }

    /// The true Euler angles perturbed by N(0, P₀); where a recording has no reference, the attitude levelled from
    /// the accelerometer and magnetometer.
    fn initial(
        &self,
        truth: &DVector<f64>,
        first: Option<(&ImuSample, Option<&Vector3<f64>>)>,
        rng: &mut Rng,
    ) -> Gaussian {
        let euler = if truth.iter().all(|v| v.is_finite()) {
            to_euler(&quaternion(truth))
        } else {
            match first {
                Some((s, mag)) => level(&s.accel, mag, &self.gravity(), &self.field()),
                None => Vector3::zeros(),
            }
        };
        let noise = Vector3::from_fn(|_, _| rand::Rng::sample(rng, rand_distr::StandardNormal));
        let q = from_euler(&(euler + noise * self.p0_att.sqrt()));
        // δq ≈ ½ Ξ(q) δθ: an angle variance σ² is about σ²/4 per quaternion component.
        Gaussian {
            x: DVector::from_column_slice(q.as_slice()),
            P: DMatrix::identity(4, 4) * (self.p0_att / 4.0),
        }
    }
}

impl Report for Attitude {
    fn columns(&self) -> Vec<String> {
        ["roll", "pitch", "yaw"].iter().map(|s| s.to_string()).collect()
    }

    fn reported(&self, state: &DVector<f64>) -> Vec<f64> {
        to_euler(&quaternion(state)).iter().copied().collect()
    }

    /// The diagonal of J P Jᵀ, J the Jacobian of the Euler angles with respect to q (central differences).
    fn reported_var(&self, g: &Gaussian) -> Vec<f64> {
        let q = quaternion(&g.x);
        let h = 1e-6;
        let J = DMatrix::from_fn(3, 4, |i, j| {
            let mut e = Vector4::zeros();
            e[j] = h;
            let d = to_euler(&(q + e)) - to_euler(&(q - e));
            // Yaw and roll wrap at ±π: take the shorter way round.
            let d = d.map(|a| (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI);
            d[i] / (2.0 * h)
        });
        (&J * &g.P * J.transpose()).diagonal().iter().copied().collect()
    }

    fn fusion(&self) -> FusionLayout {
        FusionLayout {
            angle_states: self.angle_states(),
            error_rows: vec![0, 1, 2, 3],
            median: false,
            quaternion: true,
        }
    }
}
