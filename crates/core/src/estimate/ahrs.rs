//! Two open attitude filters beside the quaternion EKF, for comparing on the same data: Madgwick's gradient-descent
//! filter (Madgwick, Harrison & Vaidyanathan 2011, "Estimation of IMU and MARG orientation using a gradient descent
//! algorithm"; report of 2010, eqs. 25–46) and Mahony's explicit complementary filter (Mahony, Hamel & Pflimlin 2008,
//! "Nonlinear complementary filters on the special orthogonal group", eq. 32/48), with their published gains.
//!
//! Both take the navigation-frame gravity `g` and field `h` of the model (not a fixed north-east-down frame), and
//! use the same quaternion convention as the EKF: scalar first, body to navigation. The magnetometer reference is
//! compensated as in Madgwick's eqs. 45–46: the measured field, rotated into the navigation frame, keeps its
//! vertical part and its horizontal magnitude and takes the reference's horizontal direction, so that a wrong dip
//! angle or field strength does not tilt the estimate.

use nalgebra::{Vector3, Vector4};

use super::attitude::{rotate_to_body, rotation};

/// Madgwick's β for a gyro, accelerometer and magnetometer (MARG) array, and for gyro and accelerometer only, as
/// published (report of 2010 §7: the β that minimised the error in the experiments).
pub const MADGWICK_BETA_MARG: f64 = 0.041;
/// Madgwick's β without a magnetometer (the same report's IMU figure).
pub const MADGWICK_BETA_IMU: f64 = 0.033;
/// Mahony's proportional and integral gains, rad/s (the defaults of the open `ahrs` implementation, after
/// Mahony et al. 2008 §VI).
pub const MAHONY_KP: f64 = 1.0;
/// Mahony's integral gain, rad/s (see [`MAHONY_KP`]).
pub const MAHONY_KI: f64 = 0.3;

/// A filter of this family: one sample at a time, the attitude as a unit quaternion.
pub trait Ahrs {
    /// One sample: gyro `w` (rad/s), specific force `f` (body), magnetometer `m` (body, any unit), over `dt`; `g` and
    /// `h` are the navigation-frame gravity and field.
    fn update(
        &mut self,
        w: &Vector3<f64>,
        f: Option<&Vector3<f64>>,
        m: Option<&Vector3<f64>>,
        g: &Vector3<f64>,
        h: &Vector3<f64>,
        dt: f64,
    );

    /// The attitude quaternion [w, x, y, z], body to navigation.
    fn attitude(&self) -> Vector4<f64>;
}

/// q ⊗ [0, ω]: the product the attitude kinematics q̇ = ½ q ⊗ [0, ω] need.
fn times_pure(q: &Vector4<f64>, w: &Vector3<f64>) -> Vector4<f64> {
    Vector4::new(
        -q[1] * w[0] - q[2] * w[1] - q[3] * w[2],
        q[0] * w[0] + q[2] * w[2] - q[3] * w[1],
        q[0] * w[1] - q[1] * w[2] + q[3] * w[0],
        q[0] * w[2] + q[1] * w[1] - q[2] * w[0],
    )
}

/// The field reference of Madgwick's eqs. 45–46: the measured field `m` (body) in the navigation frame, with the
/// reference `h`'s horizontal direction ("horizontal": orthogonal to `g`).
pub fn compensated_field(
    q: &Vector4<f64>,
    m: &Vector3<f64>,
    g: &Vector3<f64>,
    h: &Vector3<f64>,
) -> Option<Vector3<f64>> {
    let down = g.try_normalize(1e-12)?;
    let n = rotation(q) * m;
    let vertical = down * n.dot(&down);
    let horizontal = (n - vertical).norm();
    let dir = (h - down * h.dot(&down)).try_normalize(1e-12)?;
    Some(dir * horizontal + vertical)
}

/// The direction a body-frame reading should have (`C(q) u` normalised) and the measured one normalised: None for a
/// reading or reference too small to give a direction.
fn directions(q: &Vector4<f64>, u: &Vector3<f64>, reading: &Vector3<f64>) -> Option<(Vector3<f64>, Vector3<f64>)> {
    let r = reading.try_normalize(1e-12)?;
    let (p, _) = rotate_to_body(q, &u.try_normalize(1e-12)?);
    Some((p, r))
}

/// Madgwick's filter: the gyro's rate, less β times the normalised gradient of the misfit between the predicted and
/// measured directions of gravity and of the field.
#[derive(Debug, Clone)]
pub struct Madgwick {
    /// The attitude quaternion [w, x, y, z], body to navigation.
    pub q: Vector4<f64>,
    /// The gradient step's gain β, rad/s.
    pub beta: f64,
}

impl Madgwick {
    /// A filter from attitude `q` (normalised) with gain `beta`.
    pub fn new(q: Vector4<f64>, beta: f64) -> Madgwick {
        Madgwick { q: q.normalize(), beta }
    }
}

impl Ahrs for Madgwick {
    fn attitude(&self) -> Vector4<f64> {
        self.q
    }

    fn update(
        &mut self,
        w: &Vector3<f64>,
        f: Option<&Vector3<f64>>,
        m: Option<&Vector3<f64>>,
        g: &Vector3<f64>,
        h: &Vector3<f64>,
        dt: f64,
    ) {
        let q = self.q;
        let mut grad = Vector4::zeros();
        // At rest the accelerometer reads C(q)(−g): its reference direction is "up".
        let mut add = |u: &Vector3<f64>, reading: &Vector3<f64>| {
            if let (Some(u), Some(r)) = (u.try_normalize(1e-12), reading.try_normalize(1e-12)) {
                let (p, j) = rotate_to_body(&q, &u);
                // ∇ ½|C(q)u − r|² = Jᵀ (C(q)u − r) (eq. 20).
                grad += j.transpose() * (p - r);
            }
        };
        if let Some(f) = f {
            add(&-g, f);
        }
        if let (Some(m), Some(b)) = (m, m.and_then(|m| compensated_field(&q, m, g, h))) {
            add(&b, m);
        }
        let mut qdot = times_pure(&q, w) * 0.5;
        if let Some(n) = grad.try_normalize(1e-15) {
            qdot -= n * self.beta; // eq. 42
        }
        self.q = (q + qdot * dt).normalize();
    }
}

/// Mahony's explicit complementary filter: the gyro's rate corrected by k_P ω_mes, and its bias estimated by the
/// integral term, ω_mes = Σ v_i × v̂_i over the measured (v) and predicted (v̂) directions.
#[derive(Debug, Clone)]
pub struct Mahony {
    /// The attitude quaternion [w, x, y, z], body to navigation.
    pub q: Vector4<f64>,
    /// The gyro bias estimate b̂, rad/s.
    pub bias: Vector3<f64>,
    /// Proportional gain k_P, rad/s.
    pub kp: f64,
    /// Integral gain k_I, rad/s.
    pub ki: f64,
}

impl Mahony {
    /// A filter from attitude `q` (normalised), zero bias, gains `kp` and `ki`.
    pub fn new(q: Vector4<f64>, kp: f64, ki: f64) -> Mahony {
        Mahony {
            q: q.normalize(),
            bias: Vector3::zeros(),
            kp,
            ki,
        }
    }
}

impl Ahrs for Mahony {
    fn attitude(&self) -> Vector4<f64> {
        self.q
    }

    fn update(
        &mut self,
        w: &Vector3<f64>,
        f: Option<&Vector3<f64>>,
        m: Option<&Vector3<f64>>,
        g: &Vector3<f64>,
        h: &Vector3<f64>,
        dt: f64,
    ) {
        let q = self.q;
        let mut mes = Vector3::zeros();
        if let Some((p, r)) = f.and_then(|f| directions(&q, &-g, f)) {
            mes += r.cross(&p);
        }
        if let Some((p, r)) = m.and_then(|m| compensated_field(&q, m, g, h).and_then(|b| directions(&q, &b, m))) {
            mes += r.cross(&p);
        }
        // Eq. 32: ḃ = −k_I ω_mes, q̇ = ½ q ⊗ p(Ω − b̂ + k_P ω_mes).
        self.bias -= mes * (self.ki * dt);
        let rate = w - self.bias + mes * self.kp;
        self.q = (q + times_pure(&q, &rate) * (0.5 * dt)).normalize();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimate::attitude::{angle_between, from_euler, turn};

    const G: Vector3<f64> = Vector3::new(0.0, 0.0, -9.81);

    /// A field of 0.5 with a 60° dip, pointing along x.
    fn field() -> Vector3<f64> {
        let dip = 60f64.to_radians();
        Vector3::new(dip.cos(), 0.0, -dip.sin()) * 0.5
    }

    /// A body turning at a constant rate about a tilted axis from a tilted start: (true attitudes, gyro, accel, mag)
    /// at `rate` Hz for `secs`, without noise; the gyro reads `bias` on top.
    fn motion(secs: f64, rate: f64, bias: Vector3<f64>) -> Vec<(Vector4<f64>, [Vector3<f64>; 3])> {
        let w = Vector3::new(0.2, -0.1, 0.5);
        let dt = 1.0 / rate;
        let mut q = from_euler(&Vector3::new(0.3, -0.2, 1.0));
        let mut out = Vec::new();
        for _ in 0..(secs * rate) as usize {
            let (f, _) = rotate_to_body(&q, &-G);
            let (m, _) = rotate_to_body(&q, &field());
            out.push((q, [w + bias, f, m]));
            q = turn(&q, &w, dt);
        }
        out
    }

    fn start_off(q: &Vector4<f64>) -> Vector4<f64> {
        // 20° off about x.
        let e = from_euler(&Vector3::new(20f64.to_radians(), 0.0, 0.0));
        let r = rotation(q) * rotation(&e);
        let u = nalgebra::UnitQuaternion::from_matrix(&r);
        Vector4::new(u.w, u.i, u.j, u.k)
    }

    #[test]
    fn both_filters_leave_a_wrong_start_for_the_true_attitude() {
        let data = motion(60.0, 100.0, Vector3::zeros());
        let q0 = start_off(&data[0].0);
        assert!((angle_between(&q0, &data[0].0).to_degrees() - 20.0).abs() < 1e-6);
        let mut mad = Madgwick::new(q0, 0.1);
        let mut mah = Mahony::new(q0, MAHONY_KP, MAHONY_KI);
        for (_, [w, f, m]) in &data {
            mad.update(w, Some(f), Some(m), &G, &field(), 0.01);
            mah.update(w, Some(f), Some(m), &G, &field(), 0.01);
        }
        let last = data.last().unwrap().0;
        // The last sample's update moved the estimate one step past `last`.
        let w = data.last().unwrap().1[0];
        let next = turn(&last, &w, 0.01);
        for (name, q) in [("madgwick", mad.q), ("mahony", mah.q)] {
            let e = angle_between(&q, &next).to_degrees();
            assert!(e < 0.5, "{name}: {e}° after 60 s");
        }
    }

    #[test]
    fn mahony_learns_a_gyro_bias_and_madgwick_holds_it_down() {
        let bias = Vector3::new(0.02, -0.015, 0.01);
        let data = motion(120.0, 100.0, bias);
        let mut mad = Madgwick::new(data[0].0, MADGWICK_BETA_MARG);
        let mut mah = Mahony::new(data[0].0, MAHONY_KP, MAHONY_KI);
        let mut worst = [0f64; 2];
        for (i, (truth, [w, f, m])) in data.iter().enumerate() {
            let true_w = w - bias;
            let next = turn(truth, &true_w, 0.01);
            mad.update(w, Some(f), Some(m), &G, &field(), 0.01);
            mah.update(w, Some(f), Some(m), &G, &field(), 0.01);
            if i > 3000 {
                worst[0] = worst[0].max(angle_between(&mad.q, &next).to_degrees());
                worst[1] = worst[1].max(angle_between(&mah.q, &next).to_degrees());
            }
        }
        assert!((mah.bias - bias).norm() < 0.1 * bias.norm(), "b̂ = {:?}", mah.bias);
        assert!(worst[1] < 0.2, "mahony: {}°", worst[1]);
        // Madgwick has no bias state: a 1.5 °/s bias, below β, leaves a steady error that β bounds.
        assert!(worst[0] < 0.5, "madgwick: {}°", worst[0]);
    }

    #[test]
    fn a_wrong_dip_or_strength_of_the_reference_field_does_not_tilt_the_estimate() {
        let data = motion(60.0, 100.0, Vector3::zeros());
        // The reference field 30° off in dip and twice as strong; its horizontal direction right.
        let dip = 30f64.to_radians();
        let wrong = Vector3::new(dip.cos(), 0.0, -dip.sin());
        let mut mad = Madgwick::new(data[0].0, MADGWICK_BETA_MARG);
        let mut mah = Mahony::new(data[0].0, MAHONY_KP, MAHONY_KI);
        let mut worst = [0f64; 2];
        for (truth, [w, f, m]) in &data {
            let next = turn(truth, w, 0.01);
            mad.update(w, Some(f), Some(m), &G, &wrong, 0.01);
            mah.update(w, Some(f), Some(m), &G, &wrong, 0.01);
            worst[0] = worst[0].max(angle_between(&mad.q, &next).to_degrees());
            worst[1] = worst[1].max(angle_between(&mah.q, &next).to_degrees());
        }
        assert!(worst[0] < 0.1 && worst[1] < 0.1, "{worst:?}");
    }

    #[test]
    fn without_a_magnetometer_tilt_still_converges() {
        let data = motion(60.0, 100.0, Vector3::zeros());
        let q0 = start_off(&data[0].0);
        let mut mad = Madgwick::new(q0, 0.1);
        let mut mah = Mahony::new(q0, MAHONY_KP, 0.0);
        for (_, [w, f, _]) in &data {
            mad.update(w, Some(f), None, &G, &field(), 0.01);
            mah.update(w, Some(f), None, &G, &field(), 0.01);
        }
        let (last, [w, _, _]) = data.last().unwrap();
        let next = turn(last, w, 0.01);
        for (name, q) in [("madgwick", mad.q), ("mahony", mah.q)] {
            // Tilt: the angle between the predicted and true "up" in the body frame.
            let up = |q: &Vector4<f64>| rotate_to_body(q, &Vector3::z()).0;
            let tilt = up(&q).angle(&up(&next)).to_degrees();
            assert!(tilt < 0.5, "{name}: tilt {tilt}°");
        }
    }
}
