//! The pose model of Sequeira (2023), §2: x = [p, v, θ] (position, velocity, Euler ZYX angles) driven by the node's
//! own IMU (eqs. (1)–(4)), measured by pose fixes z = [p, θ] + v in two channels (position, orientation).

use nalgebra::{DMatrix, DVector, Matrix3, SMatrix, Vector3};

use super::{Dynamics, FusionLayout, GroundTruth, ImuRow, Manifold, Measurement, Report, Sensed, Sensing, Site, Truth};
use crate::estimate::{wrap_rows, Gaussian, Observation};
use crate::geom::{euler_rates, euler_rates_jacobian, rotation, rotation_partials, wrap_angle, GRAVITY};
use crate::motion::PoseTruth;
use crate::rng::Rng;
use crate::sensor::{ImuInterval, ImuSample, Sensor, SensorProfile};

/// Process and observation noise of the pose EKF (variances per step), §2.2 of Sequeira (2023).
#[derive(Debug, Clone)]
pub struct Pose {
    /// Extra process noise on top of what the IMU noise densities imply (unmodelled effects).
    pub q_pos: f64,
    /// Extra velocity process noise, (m/s)² per step.
    pub q_vel: f64,
    /// Extra attitude process noise, rad² per step.
    pub q_att: f64,
    /// Position-fix noise variance, m².
    pub r_pos: f64,
    /// Attitude-fix noise variance, rad².
    pub r_att: f64,
    /// Initial position variance, m².
    pub p0_pos: f64,
    /// Initial velocity variance, (m/s)².
    pub p0_vel: f64,
    /// Initial attitude variance, rad².
    pub p0_att: f64,
}

impl Default for Pose {
    fn default() -> Pose {
        Pose {
            q_pos: 0.0,
            q_vel: 0.0,
            q_att: 0.0,
            r_pos: 0.01,
            r_att: 0.001,
            p0_pos: 0.25,
            p0_vel: 0.01,
            p0_att: 0.003,
        }
    }
}

/// The columns `trace.csv` reports: position and attitude.
const REPORTED: [usize; 6] = [0, 1, 2, 6, 7, 8];

impl Pose {
    /// Pose process noise from the IMU noise densities (n_a: velocity random walk, n_g: angle random walk) plus
    /// the extra per-step variances.
    pub fn noise(dt: f64, accel_noise: f64, gyro_noise: f64, q_pos: f64, q_vel: f64, q_att: f64) -> DMatrix<f64> {
        let mut Q = DMatrix::zeros(9, 9);
        let qa = accel_noise * accel_noise;
        let qg = gyro_noise * gyro_noise;
        for i in 0..3 {
            Q[(i, i)] = qa * dt.powi(3) / 4.0 + q_pos;
            Q[(i, 3 + i)] = qa * dt * dt / 2.0;
            Q[(3 + i, i)] = qa * dt * dt / 2.0;
            Q[(3 + i, 3 + i)] = qa * dt + q_vel;
            Q[(6 + i, 6 + i)] = qg * dt + q_att;
        }
        Q
    }

    /// x_{k|k−1} = f(x_{k−1|k−1}), P_{k|k−1} = F P Fᵀ + Q (eq. (4)).
    pub fn propagate(g: &Gaussian, imu: Option<&ImuInterval>, Q: &DMatrix<f64>, dt: f64) -> Gaussian {
        let (x, F) = step(&g.x, imu, dt);
        // On the stack: a pose state has nine entries.
        let nine = crate::estimate::fixed::<9, 9>;
        let mut P = F * nine(g.P.as_slice()) * F.transpose() + nine(Q.as_slice());
        crate::estimate::symmetrize_fixed(&mut P);
        Gaussian {
            x,
            P: crate::estimate::dynamic(&P),
        }
    }
}

impl Dynamics for Pose {
    fn process_noise(&self, imu: Option<&SensorProfile>, dt: f64) -> DMatrix<f64> {
        // Without an IMU the filter predicts with constant velocity and covers unknown acceleration and turn rate
        // with process noise.
        let (na, ng) = imu.map_or((2.0, 0.3), |s| (s.accel_noise, s.gyro_noise));
        Pose::noise(dt, na, ng, self.q_pos, self.q_vel, self.q_att)
    }

    fn predict(&self, g: &Gaussian, imu: Option<&ImuInterval>, noise: &DMatrix<f64>, dt: f64) -> Gaussian {
        Pose::propagate(g, imu, noise, dt)
    }
}

impl Sensing for Pose {
    fn observation(&self) -> Observation {
        let mut H = DMatrix::zeros(6, 9);
        for i in 0..3 {
            H[(i, i)] = 1.0;
            H[(3 + i, 6 + i)] = 1.0;
        }
        let (p, a) = (self.r_pos, self.r_att);
        Observation {
            H,
            R: DMatrix::from_diagonal(&DVector::from_vec(vec![p, p, p, a, a, a])),
            angle_rows: (0..6).map(|i| i >= 3).collect(),
            channel_of_row: (0..6).map(|i| i / 3).collect(),
        }
    }

    /// A simulated IMU and pose fix; or a recorded IMU's row, with pose fixes simulated from its reference columns
    /// (a channel the file lacks is missing).
    fn sense(&self, sensor: &mut Sensor, truth: &Truth, _site: Site, t: f64) -> Sensed {
        if let Some((rec, i)) = truth.recording() {
            let Some(sample) = rec.imu.get(i).copied() else {
                return Sensed::default();
            };
            let at = |v: &Option<Vec<Vector3<f64>>>| v.as_ref().and_then(|v| v.get(i).copied());
            let (p, e) = (at(&rec.position), at(&rec.euler));
            let tr = PoseTruth {
                p: p.unwrap_or_default(),
                v: Vector3::zeros(),
                a: Vector3::zeros(),
                euler: e.unwrap_or_default(),
                euler_rate: Vector3::zeros(),
                omega_body: Vector3::zeros(),
            };
            let fix = sensor.pose_fix(&tr);
            let present: Vec<bool> = (0..6).map(|r| if r < 3 { p.is_some() } else { e.is_some() }).collect();
            let z = present.iter().any(|p| *p).then(|| Measurement {
                // A channel the file lacks carries no value.
                z: DVector::from_fn(6, |r, _| if present[r] { fix[r] } else { 0.0 }),
                present,
            });
            return Sensed {
                imu: Some(sample),
                z,
                row: None,
            };
        }
        let Some(tr) = truth.motion_now() else {
            return Sensed::default();
        };
        let sample = sensor.imu(&tr);
        Sensed {
            imu: Some(sample),
            z: Some(Measurement::full(DVector::from_row_slice(&sensor.pose_fix(&tr)))),
            row: Some(ImuRow {
                t,
                sample,
                mag: None,
                position: tr.p,
                euler: tr.euler,
            }),
        }
    }
}

impl Manifold for Pose {
    fn angle_states(&self) -> Vec<bool> {
        (0..9).map(|i| i >= 6).collect()
    }
}

impl GroundTruth for Pose {
    fn kinematic_state(
        &self,
        p: Option<Vector3<f64>>,
        v: Option<Vector3<f64>>,
        e: Option<Vector3<f64>>,
    ) -> DVector<f64> {
        let nan = Vector3::repeat(f64::NAN);
        let (p, v, e) = (p.unwrap_or(nan), v.unwrap_or(nan), e.unwrap_or(nan));
        DVector::from_iterator(9, p.iter().chain(v.iter()).chain(e.iter()).copied())
    }

    /// The truth perturbed by N(0, P₀) (the "initial unfiltered estimate" of Sequeira (2023)); a recording without
    /// reference columns starts at the origin, at rest, level.
    fn initial(
        &self,
        truth: &DVector<f64>,
        _first: Option<(&ImuSample, Option<&Vector3<f64>>)>,
        rng: &mut Rng,
    ) -> Gaussian {
        let mut P = DMatrix::zeros(9, 9);
        for i in 0..3 {
            P[(i, i)] = self.p0_pos;
            P[(3 + i, 3 + i)] = self.p0_vel;
            P[(6 + i, 6 + i)] = self.p0_att;
        }
        let mut x = truth.clone();
        for i in 0..9 {
            let n: f64 = rand::Rng::sample(rng, rand_distr::StandardNormal);
            x[i] += n * P[(i, i)].sqrt();
        }
        wrap_rows(&mut x, &self.angle_states());
        x.iter_mut().filter(|v| !v.is_finite()).for_each(|v| *v = 0.0);
        Gaussian { x, P }
    }
}

impl Report for Pose {
    fn columns(&self) -> Vec<String> {
        ["x", "y", "z", "roll", "pitch", "yaw"]
            .iter()
            .map(|s| s.to_string())
            .collect()
    }

    fn reported(&self, state: &DVector<f64>) -> Vec<f64> {
        REPORTED.iter().map(|&i| state[i]).collect()
    }

    fn reported_var(&self, g: &Gaussian) -> Vec<f64> {
        REPORTED.iter().map(|&i| g.P[(i, i)]).collect()
    }

    fn fusion(&self) -> FusionLayout {
        FusionLayout {
            angle_states: self.angle_states(),
            error_rows: vec![0, 1, 2],
            median: true,
            quaternion: false,
        }
    }
}

/// f and its Jacobian F for the pose model: a trapezoid in the navigation frame, each sample rotated by the attitude
/// at its own end of the interval (second-order accurate; holding the start sample leaves a systematic O(Δt²) error
/// per step that the IMU noise model does not cover). Without samples the package is assumed unaccelerated.
pub fn step(x: &DVector<f64>, imu: Option<&ImuInterval>, dt: f64) -> (DVector<f64>, SMatrix<f64, 9, 9>) {
    let p = Vector3::new(x[0], x[1], x[2]);
    let v = Vector3::new(x[3], x[4], x[5]);
    let e0 = Vector3::new(x[6], x[7], x[8]);
    let g = Vector3::new(0.0, 0.0, GRAVITY);
    let (f0, f1, w) = match imu {
        Some(s) => (s.start.accel, s.end.accel, (s.start.gyro + s.end.gyro) * 0.5),
        None => {
            let f = rotation(&e0).transpose() * g;
            (f, f, Vector3::zeros())
        }
    };
    // θ̇ = E(θ)⁻¹ ω (eq. (3)) with the mean rate, integrated by the midpoint rule; a = ½ (R(θ₀) f₀ + R(θ₁) f₁) − g
    // (eq. (1)).
    let em = e0 + euler_rates(&e0, &w) * (0.5 * dt);
    let e1 = e0 + euler_rates(&em, &w) * dt;
    let dem = Matrix3::identity() + euler_rates_jacobian(&e0, &w) * (0.5 * dt);
    let a = (rotation(&e0) * f0 + rotation(&e1) * f1) * 0.5 - g;
    let pn = p + v * dt + a * (0.5 * dt * dt);
    let vn = v + a * dt;
    let mut xn = DVector::zeros(9);
    for i in 0..3 {
        xn[i] = pn[i];
        xn[3 + i] = vn[i];
        xn[6 + i] = if i == 2 { wrap_angle(e1[i]) } else { e1[i] };
    }
    // ∂θ₁/∂θ₀ = I + Δt J(θₘ) (I + ½ Δt J(θ₀)); ∂a/∂θ₀ = ½ (∂R(θ₀) f₀ + ∂R(θ₁) f₁ · ∂θ₁/∂θ₀).
    let de1 = Matrix3::identity() + euler_rates_jacobian(&em, &w) * dem * dt;
    let mut d0 = Matrix3::zeros();
    let mut d1 = Matrix3::zeros();
    for (i, (a0, a1)) in rotation_partials(&e0)
        .iter()
        .zip(rotation_partials(&e1).iter())
        .enumerate()
    {
        d0.set_column(i, &(a0 * f0));
        d1.set_column(i, &(a1 * f1));
    }
    let dA = (d0 + d1 * de1) * 0.5;
    let mut F = SMatrix::<f64, 9, 9>::identity();
    for r in 0..3 {
        F[(r, 3 + r)] = dt;
        for c in 0..3 {
            F[(r, 6 + c)] = 0.5 * dt * dt * dA[(r, c)];
            F[(3 + r, 6 + c)] = dt * dA[(r, c)];
            F[(6 + r, 6 + c)] = de1[(r, c)];
        }
    }
    (xn, F)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pose_jacobian_matches_differences() {
        let x = DVector::from_vec(vec![1.0, 2.0, 0.5, 0.3, -0.2, 0.1, 0.1, -0.15, 2.0]);
        let start = ImuSample {
            accel: Vector3::new(0.4, -0.3, 9.7),
            gyro: Vector3::new(0.05, -0.02, 0.6),
        };
        let end = ImuSample {
            accel: Vector3::new(0.5, -0.2, 9.8),
            gyro: Vector3::new(0.04, -0.01, 0.62),
        };
        let imu = ImuInterval { start, end };
        let (_, F) = step(&x, Some(&imu), 0.01);
        let h = 1e-6;
        for c in 0..9 {
            let (mut a, mut b) = (x.clone(), x.clone());
            a[c] += h;
            b[c] -= h;
            let (fa, _) = step(&a, Some(&imu), 0.01);
            let (fb, _) = step(&b, Some(&imu), 0.01);
            let col = (fa - fb) / (2.0 * h);
            assert!((col - F.column(c)).amax() < 1e-6, "column {c}");
        }
    }
}
