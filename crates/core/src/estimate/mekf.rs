//! The multiplicative (error-state) EKF of attitude, with shaping states for the coloured disturbances a real
//! recording carries: the textbook alternative to the additive quaternion EKF of [`super::attitude`].
//!
//! - **Attitude error.** The estimate is a unit quaternion q̂; the filter's state is the small rotation δθ that takes
//!   it to the truth in the navigation frame, q = exp(δθ) ⊗ q̂, reset into q̂ after every correction (Markley 2003,
//!   "Attitude error representations for Kalman filtering", JGCD 26(2); Markley & Crassidis 2014, §6.2). Tilt and
//!   heading are then separate coordinates: the accelerometer's Jacobian has a zero heading column, so gravity can
//!   never turn heading, whatever the covariance holds.
//! - **Linear acceleration** is a first-order Gauss–Markov state in the body frame, a_{k+1} = φ_a Δᵀ a_k + w
//!   (Luinge & Veltink 2005, "Measuring orientation of human body segments using miniature gyroscopes and
//!   accelerometers", Med. Biol. Eng. Comput. 43): the accelerometer reads C(q)(−g) + a + v.
//! - **The field's disturbance** across the field is a scalar Gauss–Markov state d (Roetenberg, Luinge, Baten &
//!   Veltink 2005, "Compensation of magnetic disturbances improves inertial and magnetic sensing of human body
//!   segment orientation", IEEE TNSRE 13(3)). The magnetometer is referred to the compensated field b of Madgwick's
//!   eqs. 45–46 (the measured dip and strength, the estimated north), whose misfit with the reading lies along one
//!   direction alone, u = up × b, horizontal and across the field: the filter takes that one component,
//!   y = (C(q̂)u)ᵀ m = d + uᵀ \[b\]× δθ + v. The other two components are zero by construction and carry nothing.
//! - The gyro drives the prediction: q̂ ← q̂ ⊗ exp(ω Tₑ), δθ ← δθ − C(q̂)ᵀ δω Tₑ, so Q_θ = σ_g² Tₑ² I.
//!
//! State x = [δθ (3, navigation frame); a (3, body frame); d (1)], P its 7 × 7 covariance. Every correction returns
//! its normalised innovation squared, the filter-consistency statistic (Bar-Shalom, Li & Kirubarajan 2001, §5.4).

use nalgebra::{Matrix3, SMatrix, SVector, UnitQuaternion, Vector3, Vector4};

use super::attitude::skew;
use super::EstimateError;

const N: usize = 7;
type Mat = SMatrix<f64, N, N>;
type Vec7 = SVector<f64, N>;

/// A first-order Gauss–Markov process: stationary variance and correlation time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GaussMarkov {
    /// Stationary variance per axis.
    pub var: f64,
    /// Correlation time, s.
    pub tau: f64,
}

impl GaussMarkov {
    /// φ = exp(−Tₑ/τ): what of the process survives a step.
    pub fn phi(&self, dt: f64) -> f64 {
        (-dt / self.tau.max(1e-9)).exp()
    }
}

/// What the filter knows of its sensors.
#[derive(Debug, Clone, PartialEq)]
pub struct MekfModel {
    /// Gravity in the navigation frame (z up: [0, 0, −|g|]).
    pub g: Vector3<f64>,
    /// The earth field in the navigation frame; None without a magnetometer.
    pub h: Option<Vector3<f64>>,
    /// Gyro white noise per axis, (rad/s)².
    pub gyro_var: f64,
    /// Accelerometer and magnetometer white noise per axis.
    pub accel_var: f64,
    /// Magnetometer white noise per axis.
    pub mag_var: f64,
    /// Linear acceleration, horizontal (per axis) and vertical; one correlation time for both (the vertical's `tau`
    /// is not used).
    pub accel_horizontal: GaussMarkov,
    /// The vertical component (its `tau` not used).
    pub accel_vertical: GaussMarkov,
    /// The field's disturbance across it, horizontal (the component that turns heading).
    pub field: GaussMarkov,
}

impl MekfModel {
    /// Σ_a in the body frame at attitude `q`: C(q) diag(σ_h², σ_h², σ_v²) C(q)ᵀ.
    fn accel_cov(&self, q: &UnitQuaternion<f64>) -> Matrix3<f64> {
        let c = q.to_rotation_matrix().matrix().transpose();
        let up = self.up();
        let v = self.accel_vertical.var;
        let h = self.accel_horizontal.var;
        // diag(h, h, v) about the vertical `up`, whichever way the model's g points.
        let nav = Matrix3::identity() * h + up * up.transpose() * (v - h);
        c * nav * c.transpose()
    }

    fn up(&self) -> Vector3<f64> {
        (-self.g).try_normalize(1e-12).unwrap_or_else(Vector3::z)
    }
}

/// One correction's normalised innovation squared, and its degrees of freedom.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Nis {
    /// The normalised innovation squared νᵀ S⁻¹ ν.
    pub value: f64,
    /// Degrees of freedom (the rows of the innovation).
    pub dof: usize,
}

/// The multiplicative attitude EKF: a quaternion and a 7-state error (δθ, linear acceleration, field disturbance).
#[derive(Debug, Clone)]
pub struct Mekf {
    q: UnitQuaternion<f64>,
    /// a (body) and d; δθ is zero between corrections.
    x: Vec7,
    P: Mat,
    model: MekfModel,
}

impl Mekf {
    /// Start at `q0`, levelled on one accelerometer sample (and one magnetometer sample): its tilt is off by what
    /// the linear acceleration and the noise of that sample give, (σ_h² + σ_a²)/|g|² per axis, its heading by the
    /// field's disturbance across it over the horizontal field, (σ_d² + σ_m²)/|h_h|² (π² at most, and without a
    /// magnetometer); the shaping states start at zero with their stationary variance.
    pub fn new(q0: Vector4<f64>, model: MekfModel) -> Result<Mekf, EstimateError> {
        let q = unit(&q0).ok_or(EstimateError::NonFinite { what: "MEKF start" })?;
        let g2 = model.g.norm_squared();
        let tilt = (model.accel_horizontal.var + model.accel_var) / g2.max(1e-12);
        let up = model.up();
        let heading = match model.h {
            Some(h) => {
                let hh2 = (h - up * h.dot(&up)).norm_squared();
                ((model.field.var + model.mag_var) / hh2.max(1e-300)).min(std::f64::consts::PI.powi(2))
            }
            None => std::f64::consts::PI.powi(2),
        };
        let mut P = Mat::zeros();
        // δθ is in the navigation frame: tilt about the two horizontal axes, heading about `up`.
        let theta = Matrix3::identity() * tilt + up * up.transpose() * (heading - tilt);
        P.fixed_view_mut::<3, 3>(0, 0).copy_from(&theta);
        P.fixed_view_mut::<3, 3>(3, 3).copy_from(&model.accel_cov(&q));
        P[(6, 6)] = model.field.var;
        let m = Mekf {
            q,
            x: Vec7::zeros(),
            P,
            model,
        };
        m.check()?;
        Ok(m)
    }

    /// The attitude, scalar first, body to navigation.
    pub fn q(&self) -> Vector4<f64> {
        Vector4::new(self.q.w, self.q.i, self.q.j, self.q.k)
    }

    /// The error state's covariance.
    pub fn P(&self) -> &SMatrix<f64, 7, 7> {
        &self.P
    }

    /// The linear acceleration (body frame) and the field's disturbance the filter holds.
    pub fn disturbances(&self) -> (Vector3<f64>, f64) {
        (Vector3::new(self.x[3], self.x[4], self.x[5]), self.x[6])
    }

    /// Prediction with the gyro reading ω (bias removed) over Tₑ.
    pub fn predict(&mut self, w: &Vector3<f64>, dt: f64) -> Result<(), EstimateError> {
        let step = UnitQuaternion::from_scaled_axis(w * dt);
        self.q *= step;
        let (fa, fd) = (self.model.accel_horizontal.phi(dt), self.model.field.phi(dt));
        let mut F = Mat::identity();
        // A linear acceleration fixed in the navigation frame turns in the body frame against the body's turn.
        let turn = step.to_rotation_matrix().matrix().transpose() * fa;
        F.fixed_view_mut::<3, 3>(3, 3).copy_from(&turn);
        F[(6, 6)] = fd;
        let mut Q = Mat::zeros();
        Q.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(Matrix3::identity() * (self.model.gyro_var * dt * dt)));
        Q.fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&(self.model.accel_cov(&self.q) * (1.0 - fa * fa)));
        Q[(6, 6)] = self.model.field.var * (1.0 - fd * fd);
        self.P = F * self.P * F.transpose() + Q;
        self.P = (self.P + self.P.transpose()) * 0.5;
        let a = turn * Vector3::new(self.x[3], self.x[4], self.x[5]);
        self.x.fixed_rows_mut::<3>(3).copy_from(&a);
        self.x[6] *= fd;
        self.check()
    }

    /// Correction with the specific force f (body frame): y = C(q̂)(−g) + a, H = [C(q̂)[−g]×, I, 0].
    pub fn update_accel(&mut self, f: &Vector3<f64>) -> Result<Nis, EstimateError> {
        let c = self.c();
        let u = -self.model.g;
        let a = Vector3::new(self.x[3], self.x[4], self.x[5]);
        let nu = f - (c * u + a);
        let mut H = SMatrix::<f64, 3, N>::zeros();
        H.fixed_view_mut::<3, 3>(0, 0).copy_from(&(c * skew(&u)));
        H.fixed_view_mut::<3, 3>(0, 3).copy_from(&Matrix3::identity());
        let R = Matrix3::identity() * self.model.accel_var;
        self.correct(&H, &nu, &R)
    }

    /// Correction with the magnetometer reading m (body frame), through the compensated field: None when there is
    /// no field model or the reading gives no horizontal direction.
    pub fn update_field(&mut self, m: &Vector3<f64>) -> Result<Option<Nis>, EstimateError> {
        let Some(h) = self.model.h else {
            return Ok(None);
        };
        let q = self.q();
        let Some(b) = super::ahrs::compensated_field(&q, m, &self.model.g, &h) else {
            return Ok(None);
        };
        let Some(u) = self.model.up().cross(&b).try_normalize(1e-12) else {
            return Ok(None);
        };
        let c = self.c();
        // uᵀ b = 0, so the predicted reading is d alone.
        let nu = SVector::<f64, 1>::new((c * u).dot(m) - self.x[6]);
        let mut H = SMatrix::<f64, 1, N>::zeros();
        let row = skew(&b).transpose() * u;
        for j in 0..3 {
            H[(0, j)] = row[j];
        }
        H[(0, 6)] = 1.0;
        let R = SMatrix::<f64, 1, 1>::new(self.model.mag_var);
        self.correct(&H, &nu, &R).map(Some)
    }

    /// C(q̂), navigation to body.
    fn c(&self) -> Matrix3<f64> {
        self.q.to_rotation_matrix().matrix().transpose()
    }

    /// The Kalman correction in Joseph form, then the reset of δθ into q̂.
    fn correct<const M: usize>(
        &mut self,
        H: &SMatrix<f64, M, N>,
        nu: &SVector<f64, M>,
        R: &SMatrix<f64, M, M>,
    ) -> Result<Nis, EstimateError> {
        let S = H * self.P * H.transpose() + R;
        let chol = S.cholesky().ok_or(EstimateError::NotPositiveDefinite {
            what: "MEKF innovation covariance",
        })?;
        let nis = nu.dot(&chol.solve(nu));
        let K = chol.solve(&(H * self.P)).transpose();
        let IKH = Mat::identity() - K * H;
        self.P = IKH * self.P * IKH.transpose() + K * R * K.transpose();
        self.P = (self.P + self.P.transpose()) * 0.5;
        let dx = K * nu;
        self.q = UnitQuaternion::from_scaled_axis(Vector3::new(dx[0], dx[1], dx[2])) * self.q;
        for j in 3..N {
            self.x[j] += dx[j];
        }
        self.check()?;
        Ok(Nis { value: nis, dof: M })
    }

    fn check(&self) -> Result<(), EstimateError> {
        let finite =
            self.P.iter().chain(self.x.iter()).all(|v| v.is_finite()) && self.q.coords.iter().all(|v| v.is_finite());
        if finite {
            Ok(())
        } else {
            Err(EstimateError::NonFinite { what: "MEKF estimate" })
        }
    }
}

fn unit(q: &Vector4<f64>) -> Option<UnitQuaternion<f64>> {
    let v = nalgebra::Quaternion::new(q[0], q[1], q[2], q[3]);
    (v.norm() > 1e-12 && v.coords.iter().all(|x| x.is_finite())).then(|| UnitQuaternion::from_quaternion(v))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimate::attitude::{from_euler, rotate_to_body, turn};
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    const G: Vector3<f64> = Vector3::new(0.0, 0.0, -9.81);

    fn model(h: Option<Vector3<f64>>) -> MekfModel {
        MekfModel {
            g: G,
            h,
            gyro_var: 1e-4,
            accel_var: 0.01,
            mag_var: 1e-4,
            accel_horizontal: GaussMarkov { var: 0.5, tau: 0.1 },
            accel_vertical: GaussMarkov { var: 1.0, tau: 0.1 },
            field: GaussMarkov { var: 1e-3, tau: 1.0 },
        }
    }

    fn field() -> Vector3<f64> {
        let dip = 60f64.to_radians();
        Vector3::new(dip.cos(), 0.0, -dip.sin()) * 0.5
    }

    fn symmetric_positive_definite(P: &Mat) -> bool {
        (P - P.transpose()).amax() < 1e-12 && P.symmetric_eigenvalues().min() > 0.0
    }

    /// The navigation-frame rotation δθ from the estimate to the truth, q = exp(δθ) ⊗ q̂.
    fn error(f: &Mekf, truth: &Vector4<f64>) -> Vector3<f64> {
        (unit(truth).unwrap() * f.q.inverse()).scaled_axis()
    }

    /// A start off the truth by `off` (navigation frame), as a levelling on one sample would be.
    fn start(truth: &Vector4<f64>, off: Vector3<f64>) -> Vector4<f64> {
        let q = UnitQuaternion::from_scaled_axis(-off) * unit(truth).unwrap();
        Vector4::new(q.w, q.i, q.j, q.k)
    }

    /// The filter's own standard deviation of δθ per navigation axis.
    fn sigma(f: &Mekf) -> Vector3<f64> {
        Vector3::new(f.P[(0, 0)], f.P[(1, 1)], f.P[(2, 2)]).map(f64::sqrt)
    }

    /// Gravity cannot turn heading: every accelerometer correction, from a start off in tilt by the levelling's σ
    /// and 1 rad in heading, through noise, rotates the estimate about a horizontal axis alone (no twist about the
    /// vertical, to rounding); tilt converges, its error within 3σ of the filter's own covariance.
    #[test]
    fn the_accelerometer_never_turns_heading() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let m = model(None);
        let noise = Normal::new(0.0, m.accel_var.sqrt()).unwrap();
        let truth = from_euler(&Vector3::new(0.4, -0.3, 0.9));
        let s0 = Mekf::new(truth, m.clone()).map(|f| sigma(&f)).unwrap();
        let mut f = Mekf::new(start(&truth, Vector3::new(s0.x, -s0.y, 1.0)), m).unwrap();
        for _ in 0..2000 {
            // At rest: the prediction lets the linear-acceleration state decay, so a steady tilt misfit is the tilt's.
            f.predict(&Vector3::zeros(), 0.01).unwrap();
            let a = rotate_to_body(&truth, &-G).0 + Vector3::from_fn(|_, _| noise.sample(&mut rng));
            let before = f.q;
            f.update_accel(&a).unwrap();
            let d = f.q * before.inverse();
            let twist = 2.0 * d.k.atan2(d.w);
            assert!(twist.abs() < 1e-12, "a correction turned heading by {twist} rad");
            assert!(symmetric_positive_definite(&f.P));
        }
        let (e, s) = (error(&f, &truth), sigma(&f));
        for i in 0..2 {
            assert!(s[i] < s0[i] / 2.0, "tilt σ {s} from {s0}");
            assert!(e[i].abs() < 3.0 * s[i], "tilt error {e} against σ {s}");
        }
    }

    /// Noise-free readings at rest, from a start off by the levelling's σ on every axis: heading from the field,
    /// tilt from gravity, the error within 3σ of the filter's covariance, every σ at least halved; P stays
    /// symmetric positive definite.
    #[test]
    fn a_clean_field_and_gravity_find_the_attitude() {
        let truth = from_euler(&Vector3::new(0.3, -0.5, 1.1));
        let m = model(Some(field()));
        let s0 = Mekf::new(truth, m.clone()).map(|f| sigma(&f)).unwrap();
        let mut f = Mekf::new(start(&truth, s0), m).unwrap();
        let a = rotate_to_body(&truth, &-G).0;
        let h = rotate_to_body(&truth, &field()).0;
        for _ in 0..2000 {
            f.predict(&Vector3::zeros(), 0.01).unwrap();
            f.update_accel(&a).unwrap();
            f.update_field(&h).unwrap().expect("a horizontal field");
            assert!(symmetric_positive_definite(&f.P));
        }
        let (e, s) = (error(&f, &truth), sigma(&f));
        for i in 0..3 {
            assert!(s[i] < s0[i] / 2.0, "σ {s} from {s0}");
            assert!(e[i].abs() < 3.0 * s[i], "error {e} against σ {s}");
        }
    }

    /// Against a simulation that draws its noise and disturbances from the filter's own model, the filter is
    /// consistent: the mean normalised innovation squared per degree of freedom lies within the 99 % band of its
    /// χ² distribution (the innovations of a consistent filter are white, so the sum of N NIS values is χ²).
    #[test]
    fn on_its_own_model_the_filter_is_consistent() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let m = model(Some(field()));
        let dt = 0.01;
        let std = Normal::new(0.0, 1.0).unwrap();
        let mut draw = |s: f64| s * std.sample(&mut rng);
        let mut q = from_euler(&Vector3::new(0.1, 0.2, 0.3));
        let mut f = Mekf::new(q, m.clone()).unwrap();
        let (mut a_nav, mut d) = (Vector3::zeros(), 0.0);
        let (fa, fd) = (m.accel_horizontal.phi(dt), m.field.phi(dt));
        let (mut sum, mut dof) = (0.0, 0usize);
        for k in 0..20_000 {
            let t = k as f64 * dt;
            let w = Vector3::new(0.5 * (0.3 * t).sin(), 0.4 * (0.2 * t).cos(), 0.3);
            // The linear acceleration held in the navigation frame, horizontal and vertical apart.
            a_nav = a_nav * fa
                + Vector3::new(
                    draw((m.accel_horizontal.var * (1.0 - fa * fa)).sqrt()),
                    draw((m.accel_horizontal.var * (1.0 - fa * fa)).sqrt()),
                    draw((m.accel_vertical.var * (1.0 - fa * fa)).sqrt()),
                );
            d = d * fd + draw((m.field.var * (1.0 - fd * fd)).sqrt());
            let measured_w = w + Vector3::from_fn(|_, _| draw(m.gyro_var.sqrt()));
            q = turn(&q, &w, dt);
            f.predict(&measured_w, dt).unwrap();
            let acc = rotate_to_body(&q, &(a_nav - G)).0 + Vector3::from_fn(|_, _| draw(m.accel_var.sqrt()));
            // The disturbance across the field, horizontal: along up × h.
            let across = Vector3::z().cross(&field()).normalize();
            let mag = rotate_to_body(&q, &(field() + across * d)).0 + Vector3::from_fn(|_, _| draw(m.mag_var.sqrt()));
            for nis in [f.update_accel(&acc).unwrap(), f.update_field(&mag).unwrap().unwrap()] {
                if k >= 1000 {
                    sum += nis.value;
                    dof += nis.dof;
                }
            }
        }
        let mean = sum / dof as f64;
        let n = dof as f64;
        let band = (
            crate::stats::chi2_quantile(0.005, n) / n,
            crate::stats::chi2_quantile(0.995, n) / n,
        );
        assert!(
            mean > band.0 && mean < band.1,
            "mean NIS per dof {mean} outside {band:?}"
        );
    }
}
