//! Measurement models: accelerometer and gyro (white noise, constant bias, Wiener drift), pose fixes, and the
//! linear model's y = C x + v. Pure: randomness comes from the node's own seeded stream.

use nalgebra::{DMatrix, DVector, Vector3};
use rand::Rng as _;
use rand_distr::StandardNormal;

use crate::geom::{rotation, GRAVITY};
use crate::motion::PoseTruth;
use crate::rng::Rng;

/// One node's sensor parameters; every field can be overridden per node in the topology (`[node.sensor]`).
#[derive(Debug, Clone, PartialEq)]
pub struct SensorProfile {
    /// Accelerometer white-noise density, m/s²/√Hz (MPU-6050: 400 µg/√Hz).
    pub accel_noise: f64,
    /// Gyro white-noise density, rad/s/√Hz (MPU-6050: 0.005 °/s/√Hz).
    pub gyro_noise: f64,
    /// Constant offsets, m/s² and rad/s.
    pub accel_bias: [f64; 3],
    /// Constant gyro offset, rad/s.
    pub gyro_bias: [f64; 3],
    /// Wiener drift per step: a_offset_k = a_offset_k−1 + drift·randn (the paper's §2.1 uses 0.05 on x).
    pub accel_drift: [f64; 3],
    /// Gyro Wiener drift per step, rad/s.
    pub gyro_drift: [f64; 3],
    /// Pose-fix noise variances (paper §2.2: N(0, 0.01) position, N(0, 0.001) orientation).
    pub pos_noise: f64,
    /// Orientation-fix noise variance, rad².
    pub att_noise: f64,
    /// Magnetometer noise variance per sample, in the squared unit of `model.mag_field` (attitude model).
    pub mag_noise: f64,
}

impl Default for SensorProfile {
    fn default() -> Self {
        SensorProfile {
            accel_noise: 400e-6 * GRAVITY,
            gyro_noise: 0.005_f64.to_radians(),
            accel_bias: [0.0; 3],
            gyro_bias: [0.0; 3],
            accel_drift: [0.0; 3],
            gyro_drift: [0.0; 3],
            pos_noise: 0.01,
            att_noise: 0.001,
            // 2 mG on a 0.5 G field.
            mag_noise: 4e-6,
        }
    }
}

/// One IMU reading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuSample {
    /// Specific force in the body frame, m/s².
    pub accel: Vector3<f64>,
    /// Body rate, rad/s.
    pub gyro: Vector3<f64>,
}

/// IMU samples at the start and the end of one prediction interval.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuInterval {
    /// The reading at the interval's start.
    pub start: ImuSample,
    /// The reading at its end.
    pub end: ImuSample,
}

/// A node's sensors: its profile, its random stream and the drift state.
#[derive(Debug, Clone)]
pub struct Sensor {
    profile: SensorProfile,
    rng: Rng,
    dt: f64,
    accel_offset: Vector3<f64>,
    gyro_offset: Vector3<f64>,
}

fn randn3(rng: &mut Rng) -> Vector3<f64> {
    Vector3::new(
        rng.sample(StandardNormal),
        rng.sample(StandardNormal),
        rng.sample(StandardNormal),
    )
}

impl Sensor {
    /// A sensor of `profile` sampled every `dt` s, drawing from `rng`.
    pub fn new(profile: SensorProfile, rng: Rng, dt: f64) -> Sensor {
        Sensor {
            profile,
            rng,
            dt,
            accel_offset: Vector3::zeros(),
            gyro_offset: Vector3::zeros(),
        }
    }

    /// Its noise and bias profile.
    pub fn profile(&self) -> &SensorProfile {
        &self.profile
    }

    /// One IMU sample of the truth; advances the drift by one step.
    pub fn imu(&mut self, truth: &PoseTruth) -> ImuSample {
        let p = &self.profile;
        let r = rotation(&truth.euler);
        // Specific force: f_b = Rᵀ (a − g), g = (0, 0, −9.81).
        let f = r.transpose() * (truth.a + Vector3::new(0.0, 0.0, GRAVITY));
        // White noise of density σ sampled at 1/Δt has standard deviation σ/√Δt.
        let sa = p.accel_noise / self.dt.sqrt();
        let sg = p.gyro_noise / self.dt.sqrt();
        let accel = f + Vector3::from(p.accel_bias) + self.accel_offset + randn3(&mut self.rng) * sa;
        let gyro = truth.omega_body + Vector3::from(p.gyro_bias) + self.gyro_offset + randn3(&mut self.rng) * sg;
        self.accel_offset += randn3(&mut self.rng).component_mul(&Vector3::from(p.accel_drift));
        self.gyro_offset += randn3(&mut self.rng).component_mul(&Vector3::from(p.gyro_drift));
        ImuSample { accel, gyro }
    }

    /// A pose fix z = [p, θ] + noise.
    pub fn pose_fix(&mut self, truth: &PoseTruth) -> [f64; 6] {
        let sp = self.profile.pos_noise.sqrt();
        let sa = self.profile.att_noise.sqrt();
        let np = randn3(&mut self.rng) * sp;
        let na = randn3(&mut self.rng) * sa;
        let mut z = [0.0; 6];
        for i in 0..3 {
            z[i] = truth.p[i] + np[i];
            z[3 + i] = crate::geom::wrap_angle(truth.euler[i] + na[i]);
        }
        z
    }

    /// A magnetometer sample: the navigation-frame field `h` seen in the body frame, C(q) h + noise.
    pub fn magnetometer(&mut self, truth: &PoseTruth, h: &Vector3<f64>) -> Vector3<f64> {
        rotation(&truth.euler).transpose() * h + randn3(&mut self.rng) * self.profile.mag_noise.sqrt()
    }

    /// y = C x + v, v ~ N(0, R) with `r_chol` the lower Cholesky factor of R.
    pub fn linear(&mut self, c: &DMatrix<f64>, r_chol: &DMatrix<f64>, x: &DVector<f64>) -> DVector<f64> {
        c * x + self.noise(r_chol)
    }

    /// v ~ N(0, R), `r_chol` the lower Cholesky factor of R: the noise on a measurement h(x) + v of any h.
    pub fn noise(&mut self, r_chol: &DMatrix<f64>) -> DVector<f64> {
        let n = DVector::from_fn(r_chol.nrows(), |_, _| self.rng.sample::<f64, _>(StandardNormal));
        r_chol * n
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::Trajectory;

    #[test]
    fn noiseless_imu_reads_gravity_at_rest() {
        let profile = SensorProfile {
            accel_noise: 0.0,
            gyro_noise: 0.0,
            ..Default::default()
        };
        let mut s = Sensor::new(profile, crate::rng::stream(1, "t", 0, 0), 0.01);
        let m = s.imu(&Trajectory::Rest.at(3.0));
        assert!((m.accel - Vector3::new(0.0, 0.0, GRAVITY)).norm() < 1e-12);
        assert!(m.gyro.norm() < 1e-12);
    }
}
