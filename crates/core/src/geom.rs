//! Euler ZYX attitude: rotation matrix, its partial derivatives and the angle-rate kinematics of eq. (3) of the
//! Sequeira (2023). Angles are stored as [roll φ, pitch θ, yaw ψ] with R = Rz(ψ) Ry(θ) Rx(φ) (body to navigation).

use nalgebra::{Matrix3, Vector3};
use std::f64::consts::PI;

/// Gravity in the navigation frame (z up).
pub const GRAVITY: f64 = 9.81;

/// The rotation matrix of Euler angles [roll, pitch, yaw] (ZYX: R = Rz Ry Rx), body to navigation.
pub fn rotation(e: &Vector3<f64>) -> Matrix3<f64> {
    rz(e[2]) * ry(e[1]) * rx(e[0])
}

/// ∂R/∂φ, ∂R/∂θ, ∂R/∂ψ.
pub fn rotation_partials(e: &Vector3<f64>) -> [Matrix3<f64>; 3] {
    let (x, y, z) = (rx(e[0]), ry(e[1]), rz(e[2]));
    [z * y * drx(e[0]), z * dry(e[1]) * x, drz(e[2]) * y * x]
}

fn rx(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c)
}
fn ry(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c)
}
fn rz(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}
fn drx(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(0.0, 0.0, 0.0, 0.0, -s, -c, 0.0, c, -s)
}
fn dry(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(-s, 0.0, c, 0.0, 0.0, 0.0, -c, 0.0, -s)
}
fn drz(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(-s, -c, 0.0, c, -s, 0.0, 0.0, 0.0, 0.0)
}

/// Body rates from Euler-angle rates (the inverse of eq. (3)).
pub fn body_rates(e: &Vector3<f64>, de: &Vector3<f64>) -> Vector3<f64> {
    let (sf, cf) = e[0].sin_cos();
    let (st, ct) = e[1].sin_cos();
    Vector3::new(
        de[0] - de[2] * st,
        de[1] * cf + de[2] * sf * ct,
        -de[1] * sf + de[2] * cf * ct,
    )
}

/// Euler-angle rates from body rates ω = (p, q, r): eq. (3) of Sequeira (2023).
pub fn euler_rates(e: &Vector3<f64>, w: &Vector3<f64>) -> Vector3<f64> {
    let (sf, cf) = e[0].sin_cos();
    let (st, ct) = e[1].sin_cos();
    let k = w[1] * sf + w[2] * cf;
    Vector3::new(w[0] + k * st / ct, w[1] * cf - w[2] * sf, k / ct)
}

/// ∂(euler_rates)/∂(φ, θ, ψ) at fixed body rates: the attitude block of the EKF Jacobian.
pub fn euler_rates_jacobian(e: &Vector3<f64>, w: &Vector3<f64>) -> Matrix3<f64> {
    let (sf, cf) = e[0].sin_cos();
    let (st, ct) = e[1].sin_cos();
    let k = w[1] * sf + w[2] * cf;
    let dk = w[1] * cf - w[2] * sf;
    Matrix3::new(
        dk * st / ct,
        k / (ct * ct),
        0.0,
        -w[1] * sf - w[2] * cf,
        0.0,
        0.0,
        dk / ct,
        k * st / (ct * ct),
        0.0,
    )
}

/// Wrap to (−π, π].
pub fn wrap_angle(a: f64) -> f64 {
    // Most angles are in range already: returned as they are (no fmod, and no rounding through a + π − π).
    if a > -PI && a <= PI {
        return a;
    }
    let mut x = (a + PI).rem_euclid(2.0 * PI) - PI;
    if x <= -PI {
        x += 2.0 * PI;
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rates_round_trip_and_partials_match_differences() {
        let e = Vector3::new(0.1, -0.2, 2.5);
        let de = Vector3::new(0.3, -0.1, 0.7);
        let w = body_rates(&e, &de);
        assert!((euler_rates(&e, &w) - de).norm() < 1e-12);
        let h = 1e-6;
        let p = rotation_partials(&e);
        let j = euler_rates_jacobian(&e, &w);
        for i in 0..3 {
            let mut a = e;
            let mut b = e;
            a[i] += h;
            b[i] -= h;
            let num = (rotation(&a) - rotation(&b)) / (2.0 * h);
            assert!((num - p[i]).norm() < 1e-8);
            let numj = (euler_rates(&a, &w) - euler_rates(&b, &w)) / (2.0 * h);
            assert!((numj - j.column(i)).norm() < 1e-7);
        }
    }
}
