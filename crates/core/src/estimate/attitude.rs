//! Quaternion attitude EKF of Lesecq's slides (Lesecq 2009): prediction from the gyro with A_t = exp(½ Ω(ω) Tₑ) and
//! Q_t = (Tₑ²/4) Ξ(q̂) R_g Ξ(q̂)ᵀ + (Tₑ²/4) Y [R_g ⊗ P] Yᵀ; correction from the accelerometer b_a = C(q)(a − g) and
//! magnetometer b_m = C(q) h, with per-channel loss R̄ = M R M (M(i,i) = λ for a missing channel), in the standard
//! form and in the factorised (square-root, QR) form of the slides.
//!
//! Quaternions are scalar first, q = [q₀, q⃗], and rotate body to navigation frame; C(q) is navigation to body.

use nalgebra::{DMatrix, DVector, Matrix3, Matrix4, Vector3, Vector4};

use super::EstimateError;

/// ω* of the slides: the cross-product matrix.
pub fn skew(w: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -w[2], w[1], w[2], 0.0, -w[0], -w[1], w[0], 0.0)
}

/// Ω(ω) = [[0, −ωᵀ], [ω, −ω*]]: q̇ = ½ Ω(ω) q.
pub fn omega(w: &Vector3<f64>) -> Matrix4<f64> {
    let mut m = Matrix4::zeros();
    let s = skew(w);
    for i in 0..3 {
        m[(0, 1 + i)] = -w[i];
        m[(1 + i, 0)] = w[i];
        for j in 0..3 {
            m[(1 + i, 1 + j)] = -s[(i, j)];
        }
    }
    m
}

/// Ξ(q) = [−q⃗ᵀ; q₀ I + q⃗*]: q̇ = ½ Ξ(q) ω.
pub fn xi(q: &Vector4<f64>) -> nalgebra::Matrix4x3<f64> {
    let v = Vector3::new(q[1], q[2], q[3]);
    let lower = Matrix3::identity() * q[0] + skew(&v);
    let mut m = nalgebra::Matrix4x3::zeros();
    for j in 0..3 {
        m[(0, j)] = -v[j];
        for i in 0..3 {
            m[(1 + i, j)] = lower[(i, j)];
        }
    }
    m
}

/// A_t = exp(½ Ω(ω) Tₑ) in closed form: Ω² = −|ω|² I, so exp = cos(|ω|Tₑ/2) I + sin(|ω|Tₑ/2)/|ω| Ω.
pub fn transition(w: &Vector3<f64>, dt: f64) -> Matrix4<f64> {
    let n = w.norm();
    let half = 0.5 * n * dt;
    let s = if n > 1e-12 { half.sin() / n } else { 0.5 * dt };
    Matrix4::identity() * half.cos() + omega(w) * s
}

/// The attitude `q` turned by the angular rate `w` over `dt` (eq. of [`transition`]), renormalised against the
/// rounding that would otherwise accumulate over many steps.
pub fn turn(q: &Vector4<f64>, w: &Vector3<f64>, dt: f64) -> Vector4<f64> {
    (transition(w, dt) * q).normalize()
}

/// Body-to-navigation rotation of a unit quaternion.
pub fn rotation(q: &Vector4<f64>) -> Matrix3<f64> {
    let v = Vector3::new(q[1], q[2], q[3]);
    Matrix3::identity() * (q[0] * q[0] - v.norm_squared()) + v * v.transpose() * 2.0 + skew(&v) * (2.0 * q[0])
}

/// C(q) u (navigation to body) and its Jacobian with respect to q.
pub fn rotate_to_body(q: &Vector4<f64>, u: &Vector3<f64>) -> (Vector3<f64>, nalgebra::Matrix3x4<f64>) {
    let v = Vector3::new(q[1], q[2], q[3]);
    // C(q) u = (q₀² − |q⃗|²) u + 2 (q⃗·u) q⃗ − 2 q₀ (q⃗ × u).
    let y = u * (q[0] * q[0] - v.norm_squared()) + v * (2.0 * v.dot(u)) - v.cross(u) * (2.0 * q[0]);
    let d0 = u * (2.0 * q[0]) - v.cross(u) * 2.0;
    let dv = -(u * v.transpose()) * 2.0
        + Matrix3::identity() * (2.0 * v.dot(u))
        + v * u.transpose() * 2.0
        + skew(u) * (2.0 * q[0]);
    let mut j = nalgebra::Matrix3x4::zeros();
    for i in 0..3 {
        j[(i, 0)] = d0[i];
        for k in 0..3 {
            j[(i, 1 + k)] = dv[(i, k)];
        }
    }
    (y, j)
}

/// Quaternion of Euler ZYX angles [roll φ, pitch θ, yaw ψ] (rad).
pub fn from_euler(e: &Vector3<f64>) -> Vector4<f64> {
    let (cr, sr) = ((0.5 * e[0]).cos(), (0.5 * e[0]).sin());
    let (cp, sp) = ((0.5 * e[1]).cos(), (0.5 * e[1]).sin());
    let (cy, sy) = ((0.5 * e[2]).cos(), (0.5 * e[2]).sin());
    Vector4::new(
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    )
}

/// Euler ZYX angles [φ, θ, ψ] of a unit quaternion.
pub fn to_euler(q: &Vector4<f64>) -> Vector3<f64> {
    let (w, x, y, z) = (q[0], q[1], q[2], q[3]);
    Vector3::new(
        (2.0 * (w * x + y * z)).atan2(1.0 - 2.0 * (x * x + y * y)),
        (2.0 * (w * y - z * x)).clamp(-1.0, 1.0).asin(),
        (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z)),
    )
}

/// Euler angles of a body at rest from one accelerometer sample (roll, pitch: the measured specific force is
/// C(q)(−g)) and, when there is one, a magnetometer sample (yaw: the levelled reading against the field h).
pub fn level(accel: &Vector3<f64>, mag: Option<&Vector3<f64>>, g: &Vector3<f64>, h: &Vector3<f64>) -> Vector3<f64> {
    // For z-up navigation with g = [0, 0, −|g|], f_b = |g| [−sin θ, sin φ cos θ, cos φ cos θ].
    let up = if g[2] < 0.0 { 1.0 } else { -1.0 };
    let f = accel * up;
    let roll = f[1].atan2(f[2]);
    let pitch = (-f[0]).atan2((f[1] * f[1] + f[2] * f[2]).sqrt());
    let yaw = mag.map_or(0.0, |m| {
        // Undo roll and pitch: Ry(θ) Rx(φ) m_b = Rz(ψ)ᵀ h.
        let l = crate::geom::rotation(&Vector3::new(roll, pitch, 0.0)) * m;
        crate::geom::wrap_angle(h[1].atan2(h[0]) - l[1].atan2(l[0]))
    });
    Vector3::new(roll, pitch, yaw)
}

/// Angle of the rotation between two attitudes, rad.
pub fn angle_between(a: &Vector4<f64>, b: &Vector4<f64>) -> f64 {
    let d = (a.dot(b) / (a.norm() * b.norm())).abs().min(1.0);
    2.0 * d.acos()
}

/// Q_t of the slides: the gyro noise through Ξ(q̂), and through the uncertainty of q,
/// Q_t = (Tₑ²/4) Ξ(q̂) R_g Ξ(q̂)ᵀ + (Tₑ²/4) Y [R_g ⊗ P] Yᵀ.
pub fn process_noise(q: &Vector4<f64>, P: &DMatrix<f64>, Rg: &Matrix3<f64>, dt: f64) -> DMatrix<f64> {
    let X = DMatrix::from_column_slice(4, 3, xi(q).as_slice());
    let Rg = DMatrix::from_column_slice(3, 3, Rg.as_slice());
    let mut Y = DMatrix::zeros(4, 12);
    for (k, e) in [Vector3::x(), Vector3::y(), Vector3::z()].iter().enumerate() {
        Y.view_mut((0, 4 * k), (4, 4)).copy_from(&omega(e));
    }
    let c = dt * dt / 4.0;
    (&X * &Rg * X.transpose()) * c + (&Y * Rg.kronecker(P) * Y.transpose()) * c
}

/// The EKF prediction with the gyro reading ω over Tₑ: q⁺ = A_t q (renormalised), P⁺ = A_t P A_tᵀ + Q_t.
pub fn predict(
    q: &Vector4<f64>,
    P: &DMatrix<f64>,
    w: &Vector3<f64>,
    dt: f64,
    Rg: &Matrix3<f64>,
) -> (Vector4<f64>, DMatrix<f64>) {
    let At = transition(w, dt);
    let A = DMatrix::from_column_slice(4, 4, At.as_slice());
    let mut Pn = &A * P * A.transpose() + process_noise(q, P, Rg, dt);
    super::symmetrize(&mut Pn);
    ((At * q).normalize(), Pn)
}

/// The predicted measurement h(q) = [C(q)(−g); C(q) h] (accelerometer, magnetometer) and its Jacobian (6 × 4).
pub fn measurement(q: &Vector4<f64>, g: &Vector3<f64>, h: &Vector3<f64>) -> (DVector<f64>, DMatrix<f64>) {
    let (ya, ja) = rotate_to_body(q, &(-g));
    let (ym, jm) = rotate_to_body(q, h);
    let mut C = DMatrix::zeros(6, 4);
    C.view_mut((0, 0), (3, 4)).copy_from(&ja);
    C.view_mut((3, 0), (3, 4)).copy_from(&jm);
    (DVector::from_iterator(6, ya.iter().chain(ym.iter()).copied()), C)
}

/// Which form carries the covariance.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Form {
    /// P itself; correction P = P − K C P, evaluated in Joseph form.
    Standard,
    /// An upper-triangular S with Sᵀ S = P, propagated by QR (slides: "square root form (factorized)").
    SquareRoot,
}

/// Sensor constants of the measurement model.
#[derive(Debug, Clone)]
pub struct AttitudeModel {
    /// Gravity in the navigation frame, m/s² (z up: [0, 0, −9.81]).
    pub g: Vector3<f64>,
    /// Earth's field in the navigation frame (any unit; the magnetometer noise is in the same unit).
    pub h: Vector3<f64>,
    /// Gyro noise covariance R_g, (rad/s)².
    pub Rg: Matrix3<f64>,
    /// Accelerometer and magnetometer noise covariance (6 × 6, diagonal for the per-channel inflation).
    pub R: DMatrix<f64>,
    /// λ of M(i, i) for a channel that did not arrive.
    pub lambda: f64,
}

/// The quaternion attitude EKF: state q, covariance P or its square root, one [`Form`].
#[derive(Debug, Clone)]
pub struct AttitudeEkf {
    /// The attitude quaternion [w, x, y, z], body to navigation.
    pub q: Vector4<f64>,
    form: Form,
    /// P (standard) or its upper-triangular square root S, Sᵀ S = P.
    cov: DMatrix<f64>,
}

/// Upper-triangular S with Sᵀ S = M for a positive semidefinite M (via its eigen-decomposition and a QR, so a
/// rank-deficient Q is fine).
fn sqrt_upper(m: &DMatrix<f64>) -> Result<DMatrix<f64>, EstimateError> {
    let e = m
        .clone()
        .try_symmetric_eigen(f64::EPSILON, 10_000)
        .ok_or(EstimateError::NonFinite {
            what: "covariance square root",
        })?;
    let n = m.nrows();
    // F = Λ^{1/2} Vᵀ has Fᵀ F = M; its QR's R factor has the same Gram matrix.
    let mut f = e.eigenvectors.transpose();
    for i in 0..n {
        let s = e.eigenvalues[i].max(0.0).sqrt();
        for j in 0..n {
            f[(i, j)] *= s;
        }
    }
    Ok(f.qr().r())
}

/// The R factor of a tall matrix's QR (the triangularisation the square-root filter performs).
fn triangularise(pre: DMatrix<f64>) -> DMatrix<f64> {
    pre.qr().r()
}

impl AttitudeEkf {
    /// A filter from attitude `q` and covariance `P` (4 × 4), propagated in `form`.
    pub fn new(q: Vector4<f64>, P: &DMatrix<f64>, form: Form) -> Result<AttitudeEkf, EstimateError> {
        let cov = match form {
            Form::Standard => P.clone(),
            Form::SquareRoot => sqrt_upper(P)?,
        };
        Ok(AttitudeEkf {
            q: q.normalize(),
            form,
            cov,
        })
    }

    /// The covariance P (from its square root in the square-root form).
    pub fn P(&self) -> DMatrix<f64> {
        match self.form {
            Form::Standard => self.cov.clone(),
            Form::SquareRoot => self.cov.transpose() * &self.cov,
        }
    }

    /// Prediction with the gyro reading ω_g over Tₑ.
    pub fn predict(&mut self, w: &Vector3<f64>, dt: f64, m: &AttitudeModel) -> Result<(), EstimateError> {
        if self.form == Form::Standard {
            (self.q, self.cov) = predict(&self.q, &self.cov, w, dt, &m.Rg);
            return Ok(());
        }
        let At = transition(w, dt);
        let A = DMatrix::from_column_slice(4, 4, At.as_slice());
        let Q = process_noise(&self.q, &self.P(), &m.Rg, dt);
        self.q = (At * self.q).normalize();
        // QR of [Q^{1/2}; P^{1/2} Aᵀ] = [P_{t+1/t}^{1/2}; 0].
        let mut pre = DMatrix::zeros(8, 4);
        pre.view_mut((0, 0), (4, 4)).copy_from(&sqrt_upper(&Q)?);
        pre.view_mut((4, 0), (4, 4)).copy_from(&(&self.cov * A.transpose()));
        self.cov = triangularise(pre);
        Ok(())
    }

    /// Correction with y = [b_a; b_m]; `present[c]` says whether channel c (0 accelerometer, 1 magnetometer)
    /// arrived. Nothing arrived: no correction.
    pub fn update(&mut self, y: &DVector<f64>, present: [bool; 2], m: &AttitudeModel) -> Result<(), EstimateError> {
        if !present.iter().any(|p| *p) {
            return Ok(());
        }
        let (predicted, C) = measurement(&self.q, &m.g, &m.h);
        // R̄ = M R M with M(i, i) = λ on the rows of a missing channel.
        let mut Rb = m.R.clone();
        for i in 0..6 {
            for j in 0..6 {
                let mi = if present[i / 3] { 1.0 } else { m.lambda };
                let mj = if present[j / 3] { 1.0 } else { m.lambda };
                Rb[(i, j)] *= mi * mj;
            }
        }
        let innovation = y - predicted;
        let K = match self.form {
            Form::Standard => {
                let P = &self.cov;
                let S = &C * P * C.transpose() + &Rb;
                let chol = super::cholesky(&S, "attitude innovation covariance")?;
                let K = chol.solve(&(&C * P)).transpose();
                // Joseph form: the same P − K C P, without its cancellation once P is small.
                let IKC = DMatrix::identity(4, 4) - &K * &C;
                let mut Pn = &IKC * P * IKC.transpose() + &K * &Rb * K.transpose();
                super::symmetrize(&mut Pn);
                self.cov = Pn;
                K
            }
            Form::SquareRoot => {
                // QR of [[R̄^{1/2}, 0], [P^{1/2} Cᵀ, P^{1/2}]] = [[U, Z], [0, P_{t+1/t+1}^{1/2}]]; U Kᵀ = Z.
                let mut pre = DMatrix::zeros(10, 10);
                pre.view_mut((0, 0), (6, 6)).copy_from(&sqrt_upper(&Rb)?);
                pre.view_mut((6, 0), (4, 6)).copy_from(&(&self.cov * C.transpose()));
                pre.view_mut((6, 6), (4, 4)).copy_from(&self.cov);
                let post = triangularise(pre);
                let U = post.view((0, 0), (6, 6)).into_owned();
                let Z = post.view((0, 6), (6, 4)).into_owned();
                let Kt = U
                    .solve_upper_triangular(&Z)
                    .ok_or(EstimateError::NotPositiveDefinite { what: "factor U of S" })?;
                self.cov = post.view((6, 6), (4, 4)).into_owned();
                Kt.transpose()
            }
        };
        let dq = &K * innovation;
        self.q = (self.q + Vector4::new(dq[0], dq[1], dq[2], dq[3])).normalize();
        if self.q.iter().chain(self.cov.iter()).any(|v| !v.is_finite()) {
            return Err(EstimateError::NonFinite {
                what: "attitude estimate",
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jacobian_of_the_rotation_matches_finite_differences() {
        let q = from_euler(&Vector3::new(0.3, -0.5, 1.1));
        let u = Vector3::new(0.2, -0.4, 0.9);
        let (_, j) = rotate_to_body(&q, &u);
        for k in 0..4 {
            let mut dq = Vector4::zeros();
            dq[k] = 1e-6;
            let num = (rotate_to_body(&(q + dq), &u).0 - rotate_to_body(&(q - dq), &u).0) / 2e-6;
            for i in 0..3 {
                assert!((num[i] - j[(i, k)]).abs() < 1e-8, "∂/∂q{k}: {num} vs {}", j.column(k));
            }
        }
        // C(q) is the transpose of the body-to-navigation rotation.
        assert!((rotate_to_body(&q, &u).0 - rotation(&q).transpose() * u).norm() < 1e-12);
    }

    #[test]
    fn levelling_recovers_the_attitude_of_a_body_at_rest() {
        let g = Vector3::new(0.0, 0.0, -9.81);
        let h = Vector3::new(0.25, 0.0, -0.433);
        for e in [
            Vector3::new(0.3, -0.5, 1.1),
            Vector3::new(-1.0, 0.7, -2.9),
            Vector3::zeros(),
        ] {
            let q = from_euler(&e);
            let a = rotate_to_body(&q, &(-g)).0;
            let m = rotate_to_body(&q, &h).0;
            assert!((level(&a, Some(&m), &g, &h) - e).norm() < 1e-12, "{e}");
        }
    }

    #[test]
    fn euler_round_trip_and_transition_integrate_a_constant_rate() {
        let e = Vector3::new(-0.4, 0.2, 2.5);
        assert!((to_euler(&from_euler(&e)) - e).norm() < 1e-12);
        // 100 steps of a constant yaw rate 0.5 rad/s over 0.01 s turn yaw by 0.5 rad.
        let mut q = from_euler(&Vector3::zeros());
        let w = Vector3::new(0.0, 0.0, 0.5);
        for _ in 0..100 {
            q = transition(&w, 0.01) * q;
        }
        assert!((to_euler(&q)[2] - 0.5).abs() < 1e-12);
    }
}
