//! Two IMUs on one rigid body (the rigid-pair paper, IEEE Sensors 2011): stage one estimates the body's orientation (gyro integration, corrected
//! toward the accelerometer's tilt when quasi-static); stage two is an EKF over both sensors' positions and
//! velocities, driven by their accelerometers, whose observation is the known body-frame separation rotated into the
//! global frame, z = [R d; ‖d‖] = [p₂ − p₁; ‖p₂ − p₁‖], with the Jacobian of the norm.

use nalgebra::{Matrix3, Matrix4, SMatrix, SVector, Vector3, Vector4};

use super::attitude::{rotation, transition};
use super::EstimateError;
use crate::geom::GRAVITY;

/// Gravity in the global frame (z up).
pub fn gravity() -> Vector3<f64> {
    Vector3::new(0.0, 0.0, -GRAVITY)
}

/// Stage one: body orientation from the mean of the two gyros; when the body is quasi-static (specific force close
/// to g and little rotation) the attitude is pulled toward the accelerometer's tilt by `gain` per sample.
#[derive(Debug, Clone)]
pub struct Orientation {
    /// The attitude quaternion [w, x, y, z], body to navigation.
    pub q: Vector4<f64>,
    /// The fraction of the way to the accelerometer's tilt taken per quasi-static sample.
    pub gain: f64,
    /// Quasi-static when |‖f‖ − g| < this (m/s²) and ‖ω‖ < `rate_limit` (rad/s).
    pub accel_tolerance: f64,
    /// Largest rate for a quasi-static sample, rad/s.
    pub rate_limit: f64,
}

impl Orientation {
    /// A filter from attitude `q` with the default gain and limits.
    pub fn new(q: Vector4<f64>) -> Orientation {
        Orientation {
            q,
            gain: 0.02,
            accel_tolerance: 0.05 * GRAVITY,
            rate_limit: 0.1,
        }
    }

    /// Body-to-global rotation.
    pub fn rotation(&self) -> Matrix3<f64> {
        rotation(&self.q)
    }

    /// One sample: propagate by `gyro` over `dt`, correct toward gravity if quasi-static.
    pub fn step(&mut self, gyro: &Vector3<f64>, specific_force: &Vector3<f64>, dt: f64) {
        self.q = (transition(gyro, dt) * self.q).normalize();
        if (specific_force.norm() - GRAVITY).abs() < self.accel_tolerance && gyro.norm() < self.rate_limit {
            // The measured "up" in the global frame against the true up: rotate by a fraction of the angle between.
            let up_meas = (self.rotation() * specific_force).normalize();
            let up = Vector3::z();
            let axis = up_meas.cross(&up);
            let s = axis.norm();
            if s > 1e-12 {
                let angle = s.atan2(up_meas.dot(&up)) * self.gain;
                let half = 0.5 * angle;
                let a = axis / s * half.sin();
                // Left-multiply: a correction expressed in the global frame.
                let c = Vector4::new(half.cos(), a[0], a[1], a[2]);
                self.q = quat_mul(&c, &self.q).normalize();
            }
        }
    }
}

/// Hamilton product, scalar first.
pub fn quat_mul(a: &Vector4<f64>, b: &Vector4<f64>) -> Vector4<f64> {
    let (a0, av) = (a[0], Vector3::new(a[1], a[2], a[3]));
    let (b0, bv) = (b[0], Vector3::new(b[1], b[2], b[3]));
    let v = bv * a0 + av * b0 + av.cross(&bv);
    Vector4::new(a0 * b0 - av.dot(&bv), v[0], v[1], v[2])
}

/// One sensor's dead reckoning: global acceleration R f + g, integrated by the trapezoid rule.
#[derive(Debug, Clone)]
pub struct DeadReckoning {
    /// Position, m.
    pub p: Vector3<f64>,
    /// Velocity, m/s.
    pub v: Vector3<f64>,
    last_a: Option<Vector3<f64>>,
}

impl DeadReckoning {
    /// Dead reckoning from position `p` and velocity `v`.
    pub fn new(p: Vector3<f64>, v: Vector3<f64>) -> DeadReckoning {
        DeadReckoning { p, v, last_a: None }
    }

    /// One sample of acceleration in the navigation frame over `dt` (trapezoid).
    pub fn step(&mut self, a_global: &Vector3<f64>, dt: f64) {
        let a0 = self.last_a.unwrap_or(*a_global);
        let v_new = self.v + (a0 + a_global) * (0.5 * dt);
        self.p += (self.v + v_new) * (0.5 * dt);
        self.v = v_new;
        self.last_a = Some(*a_global);
    }
}

/// Stage two: x = [p₁, v₁, p₂, v₂] (12 states), each sensor's acceleration in the global frame as the input.
#[derive(Debug, Clone)]
pub struct SeparationEkf {
    /// Both sensors' position and velocity, 6 states each.
    pub x: SVector<f64, 12>,
    /// The state covariance.
    pub P: SMatrix<f64, 12, 12>,
    last_a: Option<[Vector3<f64>; 2]>,
    /// Accelerometer noise variance per sample, (m/s²)².
    pub accel_var: f64,
    /// Variance of the rotated separation's components (orientation error × ‖d‖), m².
    pub vector_var: f64,
    /// Variance of the norm row, m² (the norm is a physical constant).
    pub norm_var: f64,
}

impl SeparationEkf {
    /// The filter from both sensors' positions and velocities; noise variances of the acceleration, the separation vector and its norm.
    pub fn new(p: [Vector3<f64>; 2], v: [Vector3<f64>; 2], accel_var: f64, vector_var: f64, norm_var: f64) -> Self {
        let mut x = SVector::<f64, 12>::zeros();
        for s in 0..2 {
            x.fixed_rows_mut::<3>(6 * s).copy_from(&p[s]);
            x.fixed_rows_mut::<3>(6 * s + 3).copy_from(&v[s]);
        }
        SeparationEkf {
            x,
            P: SMatrix::<f64, 12, 12>::identity() * 1e-8,
            last_a: None,
            accel_var,
            vector_var,
            norm_var,
        }
    }

    /// Sensor `s`'s position (0 or 1).
    pub fn position(&self, s: usize) -> Vector3<f64> {
        self.x.fixed_rows::<3>(6 * s).into_owned()
    }

    /// Predict with both sensors' global accelerations (trapezoid in the mean, white acceleration noise in P).
    pub fn predict(&mut self, a: [Vector3<f64>; 2], dt: f64) {
        let a0 = self.last_a.unwrap_or(a);
        let mut F = SMatrix::<f64, 12, 12>::identity();
        let mut Q = SMatrix::<f64, 12, 12>::zeros();
        // Per axis: p += v dt + a dt²/2, v += a dt; a carries the accelerometer's noise.
        let (q11, q12, q22) = (dt.powi(4) / 4.0, dt.powi(3) / 2.0, dt * dt);
        for s in 0..2 {
            let (ip, iv) = (6 * s, 6 * s + 3);
            let am = (a0[s] + a[s]) * 0.5;
            let v = self.x.fixed_rows::<3>(iv).into_owned();
            let p = self.x.fixed_rows::<3>(ip).into_owned() + v * dt + am * (0.5 * dt * dt);
            self.x.fixed_rows_mut::<3>(ip).copy_from(&p);
            self.x.fixed_rows_mut::<3>(iv).copy_from(&(v + am * dt));
            for k in 0..3 {
                F[(ip + k, iv + k)] = dt;
                Q[(ip + k, ip + k)] = q11 * self.accel_var;
                Q[(ip + k, iv + k)] = q12 * self.accel_var;
                Q[(iv + k, ip + k)] = q12 * self.accel_var;
                Q[(iv + k, iv + k)] = q22 * self.accel_var;
            }
        }
        self.last_a = Some(a);
        self.P = F * self.P * F.transpose() + Q;
    }

    /// Update with the separation d (body frame) rotated by the stage-one orientation.
    pub fn update(&mut self, rotation: &Matrix3<f64>, d_body: &Vector3<f64>) -> Result<(), EstimateError> {
        let d = rotation * d_body;
        let delta = self.position(1) - self.position(0);
        let n = delta.norm();
        if n < 1e-9 {
            return Err(EstimateError::NonFinite {
                what: "separation of the two sensors",
            });
        }
        let u = delta / n;
        let z = Vector4::new(d[0], d[1], d[2], d_body.norm());
        let h = Vector4::new(delta[0], delta[1], delta[2], n);
        // H: ∂(p₂ − p₁)/∂x and ∂‖p₂ − p₁‖/∂x = [−uᵀ, 0, uᵀ, 0]. Static sizes: no allocation per update.
        let mut H = SMatrix::<f64, 4, 12>::zeros();
        for k in 0..3 {
            H[(k, k)] = -1.0;
            H[(k, 6 + k)] = 1.0;
            H[(3, k)] = -u[k];
            H[(3, 6 + k)] = u[k];
        }
        let R = Matrix4::from_diagonal(&Vector4::new(
            self.vector_var,
            self.vector_var,
            self.vector_var,
            self.norm_var,
        ));
        let P = &self.P;
        let S = H * P * H.transpose() + R;
        const WHAT: &str = "separation innovation covariance";
        if S.iter().any(|v| !v.is_finite()) {
            return Err(EstimateError::NonFinite { what: WHAT });
        }
        let chol = nalgebra::Cholesky::new(S).ok_or(EstimateError::NotPositiveDefinite { what: WHAT })?;
        let K = chol.solve(&(H * P)).transpose();
        let dx = K * (z - h);
        // Joseph form keeps P symmetric positive definite with the nearly redundant norm row.
        let IKH = SMatrix::<f64, 12, 12>::identity() - K * H;
        let mut Pn = IKH * P * IKH.transpose() + K * R * K.transpose();
        for i in 0..12 {
            for j in (i + 1)..12 {
                let a = 0.5 * (Pn[(i, j)] + Pn[(j, i)]);
                Pn[(i, j)] = a;
                Pn[(j, i)] = a;
            }
        }
        self.x += dx;
        self.P = Pn;
        if self.x.iter().any(|v| !v.is_finite()) {
            return Err(EstimateError::NonFinite {
                what: "rigid-pair state",
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_separation_leaves_consistent_estimates_unchanged() {
        let p = [Vector3::new(1.0, 2.0, 0.0), Vector3::new(1.5, 2.0, 0.0)];
        let mut f = SeparationEkf::new(p, [Vector3::zeros(); 2], 1e-4, 1e-4, 1e-6);
        f.P = SMatrix::identity() * 0.01;
        f.update(&Matrix3::identity(), &Vector3::new(0.5, 0.0, 0.0)).unwrap();
        assert!((f.position(0) - p[0]).norm() < 1e-12 && (f.position(1) - p[1]).norm() < 1e-12);
        // Opposite errors along the separation are pulled back toward it, symmetrically.
        let q = [Vector3::new(0.9, 2.0, 0.0), Vector3::new(1.6, 2.0, 0.0)];
        let mut g = SeparationEkf::new(q, [Vector3::zeros(); 2], 1e-4, 1e-4, 1e-6);
        g.P = SMatrix::identity() * 0.01;
        g.update(&Matrix3::identity(), &Vector3::new(0.5, 0.0, 0.0)).unwrap();
        let sep = g.position(1) - g.position(0);
        assert!((sep.norm() - 0.5).abs() < 1e-3, "{sep}");
        assert!(((g.position(0) + g.position(1)) / 2.0 - Vector3::new(1.25, 2.0, 0.0)).norm() < 1e-9);
    }

    #[test]
    fn dead_reckoning_integrates_constant_acceleration_exactly() {
        let mut d = DeadReckoning::new(Vector3::zeros(), Vector3::new(1.0, 0.0, 0.0));
        for _ in 0..100 {
            d.step(&Vector3::new(0.0, 2.0, 0.0), 0.01);
        }
        assert!((d.p - Vector3::new(1.0, 1.0, 0.0)).norm() < 1e-12, "{}", d.p);
    }
}
