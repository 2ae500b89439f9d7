//! Prediction (eq. (4) of Sequeira (2023)): x_{k|k−1} = f(x_{k−1|k−1}), P_{k|k−1} = F P Fᵀ + Q.

use nalgebra::{DMatrix, DVector, Matrix3, Vector3, Vector4};

use super::attitude::{process_noise, transition};

use super::{symmetrize, Gaussian};
use crate::geom::{euler_rates, euler_rates_jacobian, rotation, rotation_partials, wrap_angle, GRAVITY};
use crate::sensor::ImuSample;

#[derive(Debug, Clone)]
pub enum Process {
    /// x⁺ = A x + w, w ~ N(0, Q).
    Linear { A: DMatrix<f64>, Q: DMatrix<f64> },
    /// x = [p, v, θ]; driven by the node's own IMU (accelerometer rotated to the navigation frame, gyro through the
    /// Euler-rate kinematics of eq. (3)).
    Pose { dt: f64, Q: DMatrix<f64> },
    /// x = q (unit quaternion, scalar first), driven by the gyro: q⁺ = A_t q, A_t = exp(½ Ω(ω) Tₑ), and the Q_t of
    /// Lesecq's slides built from Ξ(q̂) and the gyro noise covariance R_g.
    Attitude { dt: f64, Rg: Matrix3<f64> },
}

impl Process {
    /// Pose process noise from the IMU noise densities (n_a: velocity random walk, n_g: angle random walk) plus the
    /// topology's extra per-step variances.
    pub fn pose(dt: f64, accel_noise: f64, gyro_noise: f64, q_pos: f64, q_vel: f64, q_att: f64) -> Process {
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
        Process::Pose { dt, Q }
    }

    pub fn state_dim(&self) -> usize {
        match self {
            Process::Linear { A, .. } => A.nrows(),
            Process::Pose { .. } => 9,
            Process::Attitude { .. } => 4,
        }
    }

    /// State rows that are angles.
    pub fn angle_states(&self) -> Vec<bool> {
        match self {
            Process::Linear { A, .. } => vec![false; A.nrows()],
            Process::Pose { .. } => (0..9).map(|i| i >= 6).collect(),
            Process::Attitude { .. } => vec![false; 4],
        }
    }

    /// One prediction step; `imu` holds the samples at both ends of the interval (ignored by the linear model).
    pub fn predict(&self, g: &Gaussian, imu: Option<&ImuInterval>) -> Gaussian {
        match self {
            Process::Linear { A, Q } => {
                let mut P = A * &g.P * A.transpose() + Q;
                symmetrize(&mut P);
                Gaussian { x: A * &g.x, P }
            }
            Process::Pose { dt, Q } => {
                let (x, F) = pose_step(&g.x, imu, *dt);
                let mut P = &F * &g.P * F.transpose() + Q;
                symmetrize(&mut P);
                Gaussian { x, P }
            }
            Process::Attitude { dt, Rg } => {
                // The mean rate over the interval; without a gyro the body is assumed not to turn.
                let w = imu.map_or(Vector3::zeros(), |s| (s.start.gyro + s.end.gyro) * 0.5);
                let q = Vector4::new(g.x[0], g.x[1], g.x[2], g.x[3]);
                let At = transition(&w, *dt);
                let A = DMatrix::from_column_slice(4, 4, At.as_slice());
                let mut P = &A * &g.P * A.transpose() + process_noise(&q, &g.P, Rg, *dt);
                symmetrize(&mut P);
                let qn = (At * q).normalize();
                Gaussian {
                    x: DVector::from_column_slice(qn.as_slice()),
                    P,
                }
            }
        }
    }

    /// Bring an updated state back onto its manifold: the attitude quaternion to unit norm (the slides' EKF
    /// normalises after each correction).
    pub fn normalize(&self, g: &mut Gaussian) {
        if let Process::Attitude { .. } = self {
            let n = g.x.norm();
            if n > 0.0 && n.is_finite() {
                g.x /= n;
            }
        }
    }
}

/// IMU samples at the start and the end of one prediction interval.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuInterval {
    pub start: ImuSample,
    pub end: ImuSample,
}

/// f and its Jacobian F for the pose model: a trapezoid in the navigation frame, each sample rotated by the attitude
/// at its own end of the interval (second-order accurate; holding the start sample leaves a systematic O(Δt²) error
/// per step that the IMU noise model does not cover). Without samples the package is assumed unaccelerated.
fn pose_step(x: &DVector<f64>, imu: Option<&ImuInterval>, dt: f64) -> (DVector<f64>, DMatrix<f64>) {
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
    let mut F = DMatrix::identity(9, 9);
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
        let (_, F) = pose_step(&x, Some(&imu), 0.01);
        let h = 1e-6;
        for c in 0..9 {
            let (mut a, mut b) = (x.clone(), x.clone());
            a[c] += h;
            b[c] -= h;
            let (fa, _) = pose_step(&a, Some(&imu), 0.01);
            let (fb, _) = pose_step(&b, Some(&imu), 0.01);
            let col = (fa - fb) / (2.0 * h);
            assert!((col - F.column(c)).amax() < 1e-6, "column {c}");
        }
    }
}
