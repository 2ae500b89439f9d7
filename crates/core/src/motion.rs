//! Ground-truth trajectories shared by every node: all IMUs ride the same rigid package.
//! Each is analytic in t, so position, velocity, acceleration, attitude and body rates agree exactly.

use nalgebra::Vector3;
use std::f64::consts::PI;
use std::str::FromStr;

use crate::geom::body_rates;

/// An analytic ground-truth trajectory: position, velocity, acceleration and attitude at any time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Trajectory {
    /// Helix: radius 2 m, one turn per 10 s, climbing 0.1 m/s (the paper's spiral).
    Spiral,
    /// The helix without the climb.
    Circle,
    /// Along x at 1 m/s with a gentle speed oscillation.
    Line,
    /// Still.
    Rest,
    /// Two straight trunks joined by a 2 s blend (the paper's piecewise-linear trajectory, §6).
    Piecewise,
    /// Lissajous figure-8, 6 m × 3 m, 20 s per lap.
    Figure8,
    /// Turning in place: roll ±35°, pitch ±25°, yaw ±90°, periods of 9–21 s (for the attitude model, whose
    /// accelerometer channel assumes no linear acceleration).
    Tumble,
}

/// Every trajectory's name, for errors and `--help`.
pub const TRAJECTORIES: &[&str] = &["spiral", "circle", "line", "rest", "piecewise", "figure8", "tumble"];

/// A trajectory name that is not one of [`TRAJECTORIES`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("expected one of {all}, got `{0}`", all = TRAJECTORIES.join(" | "))]
pub struct UnknownTrajectory(pub String);

impl FromStr for Trajectory {
    type Err = UnknownTrajectory;
    fn from_str(s: &str) -> Result<Self, UnknownTrajectory> {
        Ok(match s {
            "spiral" => Trajectory::Spiral,
            "circle" => Trajectory::Circle,
            "line" => Trajectory::Line,
            "rest" => Trajectory::Rest,
            "piecewise" => Trajectory::Piecewise,
            "figure8" => Trajectory::Figure8,
            "tumble" => Trajectory::Tumble,
            other => return Err(UnknownTrajectory(other.to_string())),
        })
    }
}

impl std::fmt::Display for Trajectory {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let all = [
            Trajectory::Spiral,
            Trajectory::Circle,
            Trajectory::Line,
            Trajectory::Rest,
            Trajectory::Piecewise,
            Trajectory::Figure8,
            Trajectory::Tumble,
        ];
        let i = all.iter().position(|t| t == self).unwrap_or(0);
        f.write_str(TRAJECTORIES[i])
    }
}

/// The true state of the package at one instant.
#[derive(Debug, Clone, Copy)]
pub struct PoseTruth {
    /// Position, m.
    pub p: Vector3<f64>,
    /// Velocity, m/s.
    pub v: Vector3<f64>,
    /// Acceleration, m/s².
    pub a: Vector3<f64>,
    /// [roll, pitch, yaw], Euler ZYX.
    pub euler: Vector3<f64>,
    /// The Euler angles' rates, rad/s.
    pub euler_rate: Vector3<f64>,
    /// Body-frame angular rate: what an ideal gyro reads.
    pub omega_body: Vector3<f64>,
}

impl Trajectory {
    /// Whether it stays where it starts, turned as it starts.
    pub fn is_still(self) -> bool {
        self == Trajectory::Rest
    }

    /// The truth at time `t` (s).
    pub fn at(self, t: f64) -> PoseTruth {
        let (p, v, a) = self.translation(t);
        let (euler, euler_rate) = if self == Trajectory::Rest {
            (Vector3::zeros(), Vector3::zeros())
        } else if self == Trajectory::Tumble {
            let (ar, wr) = (0.6, 2.0 * PI / 9.0);
            let (ap, wp) = (0.45, 2.0 * PI / 13.0);
            let (ay, wy) = (PI / 2.0, 2.0 * PI / 21.0);
            (
                Vector3::new(ar * (wr * t).sin(), ap * (wp * t + 0.5).sin(), ay * (wy * t).sin()),
                Vector3::new(
                    ar * wr * (wr * t).cos(),
                    ap * wp * (wp * t + 0.5).cos(),
                    ay * wy * (wy * t).cos(),
                ),
            )
        } else {
            // Yaw follows the horizontal heading; roll and pitch sway so that every axis is excited.
            let h2 = v.x * v.x + v.y * v.y;
            let (yaw, dyaw) = if h2 > 1e-6 {
                (v.y.atan2(v.x), (v.x * a.y - v.y * a.x) / h2)
            } else {
                (0.0, 0.0)
            };
            let roll = 0.08 * (1.3 * t).sin();
            let pitch = 0.06 * (0.9 * t + 0.4).sin();
            (
                Vector3::new(roll, pitch, yaw),
                Vector3::new(0.08 * 1.3 * (1.3 * t).cos(), 0.06 * 0.9 * (0.9 * t + 0.4).cos(), dyaw),
            )
        };
        PoseTruth {
            p,
            v,
            a,
            euler,
            euler_rate,
            omega_body: body_rates(&euler, &euler_rate),
        }
    }

    fn translation(self, t: f64) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
        match self {
            Trajectory::Spiral | Trajectory::Circle => {
                let (r, w) = (2.0, 2.0 * PI / 10.0);
                let climb = if self == Trajectory::Spiral { 0.1 } else { 0.0 };
                let (s, c) = (w * t).sin_cos();
                (
                    Vector3::new(r * c, r * s, climb * t),
                    Vector3::new(-r * w * s, r * w * c, climb),
                    Vector3::new(-r * w * w * c, -r * w * w * s, 0.0),
                )
            }
            Trajectory::Line => {
                let w = 0.5;
                (
                    Vector3::new(t + 0.5 * (w * t).sin(), 0.0, 0.0),
                    Vector3::new(1.0 + 0.5 * w * (w * t).cos(), 0.0, 0.0),
                    Vector3::new(-0.5 * w * w * (w * t).sin(), 0.0, 0.0),
                )
            }
            Trajectory::Rest | Trajectory::Tumble => (Vector3::zeros(), Vector3::zeros(), Vector3::zeros()),
            Trajectory::Piecewise => {
                let v1 = Vector3::new(1.0, 0.0, 0.0);
                let v2 = Vector3::new(0.0, 1.0, 0.1);
                let (tc, width) = (12.0, 2.0);
                let u = ((t - tc) / width).max(0.0);
                // s(u) = 3u² − 2u³ blends v1 into v2; S(u) = ∫s integrates it into position.
                let (s, ds, big_s) = if u < 1.0 {
                    (
                        3.0 * u * u - 2.0 * u * u * u,
                        6.0 * u - 6.0 * u * u,
                        u * u * u - 0.5 * u * u * u * u,
                    )
                } else {
                    (1.0, 0.0, u - 0.5)
                };
                (
                    v1 * t + (v2 - v1) * width * big_s,
                    v1 + (v2 - v1) * s,
                    (v2 - v1) * ds / width,
                )
            }
            Trajectory::Figure8 => {
                let (amp, w) = (3.0, 2.0 * PI / 20.0);
                let (s1, c1) = (w * t).sin_cos();
                let (s2, c2) = (2.0 * w * t).sin_cos();
                (
                    Vector3::new(amp * s1, 0.5 * amp * s2, 0.0),
                    Vector3::new(amp * w * c1, amp * w * c2, 0.0),
                    Vector3::new(-amp * w * w * s1, -2.0 * amp * w * w * s2, 0.0),
                )
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derivatives_are_consistent() {
        for name in TRAJECTORIES {
            let tr: Trajectory = name.parse().unwrap();
            for &t in &[0.5, 11.0, 13.0, 17.3] {
                let h = 1e-5;
                let (a, b) = (tr.at(t + h), tr.at(t - h));
                let x = tr.at(t);
                assert!(((a.p - b.p) / (2.0 * h) - x.v).norm() < 1e-6, "{name} v at {t}");
                assert!(((a.v - b.v) / (2.0 * h) - x.a).norm() < 1e-6, "{name} a at {t}");
                let de = (a.euler - b.euler).map(crate::geom::wrap_angle) / (2.0 * h);
                assert!((de - x.euler_rate).norm() < 1e-5, "{name} euler rate at {t}");
            }
        }
    }
}
