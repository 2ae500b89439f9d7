//! Position from a recorded IMU file as a boundary value problem (Nieminen et al., Nieminen et al. (2010) §4–5): the specific
//! force is rotated into the navigation frame (with the file's reference attitude when it has one, as the paper
//! assumes; otherwise by integrating the gyro), gravity is added, and each axis is solved by FEM with the given ends.
//! The trapezoid rule from the start is the comparison. The optional error model fits a scale and a bias per body
//! axis and a gravity correction (nine parameters, §5.3) from additional constraints.

use nalgebra::{Matrix3, Vector3};

use simnet_engine::estimate::attitude::{from_euler, rotation as quat_rotation, turn};
use simnet_engine::estimate::bvp::{self, BvpError, Constraint, End};
use simnet_engine::geom::{rotation, GRAVITY};
use simnet_engine::imu_csv::ImuRecording;

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Known {
    Position(Vector3<f64>),
    Velocity(Vector3<f64>),
}

#[derive(Debug, Clone, Default)]
pub struct Options {
    pub start: Option<Known>,
    pub end: Option<Known>,
    /// The start velocity for the trapezoid rule when `start` is a position.
    pub start_velocity: Option<Vector3<f64>>,
    /// Additional constraints: (time, known value).
    pub constraints: Vec<(f64, Known)>,
    pub error_model: bool,
    /// Initial attitude (Euler ZYX, rad) when the file has no reference attitude.
    pub initial_euler: Option<Vector3<f64>>,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReconstructError {
    #[error("give the position at one end at least (--start-position or --end-position, or --from-reference)")]
    NoPosition,
    #[error("a boundary value problem needs one condition at each end: a position or a velocity at the start and at the end")]
    Ends,
    #[error("the error model needs additional constraints (--velocity-at/--position-at): 9 parameters, {0} equations")]
    FewConstraints(usize),
    #[error(transparent)]
    Bvp(#[from] BvpError),
}

#[derive(Debug, Clone)]
pub struct Reconstruction {
    pub t: Vec<f64>,
    /// Trapezoid rule from the start (when the start position and velocity are known).
    pub trapezoid: Option<Vec<Vector3<f64>>>,
    pub fem: Vec<Vector3<f64>>,
    /// FEM with the fitted error model, and its parameters: scale corrections (3), biases (3), gravity correction (3).
    pub model: Option<(Vec<Vector3<f64>>, [f64; 9])>,
}

/// Body-to-navigation rotations at every sample.
pub fn attitudes(rec: &ImuRecording, initial: Option<Vector3<f64>>) -> Vec<Matrix3<f64>> {
    if let Some(e) = &rec.euler {
        return e.iter().map(rotation).collect();
    }
    if let Some(q) = &rec.quat {
        return q.iter().map(quat_rotation).collect();
    }
    let mut q = from_euler(&initial.unwrap_or_else(Vector3::zeros));
    let mut out = vec![quat_rotation(&q)];
    for k in 1..rec.t.len() {
        let w = (rec.gyro[k - 1] + rec.gyro[k]) * 0.5;
        q = turn(&q, &w, rec.t[k] - rec.t[k - 1]);
        out.push(quat_rotation(&q));
    }
    out
}

fn axis(v: &[Vector3<f64>], k: usize) -> Vec<f64> {
    v.iter().map(|x| x[k]).collect()
}

pub fn reconstruct(rec: &ImuRecording, o: &Options) -> Result<Reconstruction, ReconstructError> {
    let t = &rec.t;
    let r = attitudes(rec, o.initial_euler);
    let g = Vector3::new(0.0, 0.0, -GRAVITY);
    let a: Vec<Vector3<f64>> = r.iter().zip(&rec.accel).map(|(r, f)| r * f + g).collect();
    let end_of = |k: usize, known: Option<Known>| match known {
        Some(Known::Position(p)) => Some(End::Position(p[k])),
        Some(Known::Velocity(v)) => Some(End::Velocity(v[k])),
        None => None,
    };
    let ends: Vec<(End, End)> = (0..3)
        .map(|k| match (end_of(k, o.start), end_of(k, o.end)) {
            (Some(s), Some(e)) => Ok((s, e)),
            _ => Err(ReconstructError::Ends),
        })
        .collect::<Result<_, _>>()?;
    if ends
        .iter()
        .all(|(s, e)| !matches!(s, End::Position(_)) && !matches!(e, End::Position(_)))
    {
        return Err(ReconstructError::NoPosition);
    }
    let mut fem = vec![Vector3::zeros(); t.len()];
    for (k, &(s, e)) in ends.iter().enumerate() {
        for (p, x) in fem.iter_mut().zip(bvp::solve(t, &axis(&a, k), s, e)?) {
            p[k] = x;
        }
    }
    let trapezoid = match (o.start, o.start_velocity) {
        (Some(Known::Position(p0)), Some(v0)) => {
            let mut out = vec![Vector3::zeros(); t.len()];
            for k in 0..3 {
                for (p, x) in out.iter_mut().zip(bvp::trapezoid(t, &axis(&a, k), p0[k], v0[k])) {
                    p[k] = x;
                }
            }
            Some(out)
        }
        _ => None,
    };
    let model = if o.error_model {
        let equations = 3 * o.constraints.len();
        if equations < 9 {
            return Err(ReconstructError::FewConstraints(equations));
        }
        // a_k = Σ_m R_km ((1 + s_m) f_m + b_m) + g_k + δg_k: signals R_km f_m (scale), R_km (bias), δ_kj (gravity).
        let bases: Vec<Vec<f64>> = (0..3).map(|k| axis(&a, k)).collect();
        let signals: Vec<Vec<Vec<f64>>> = (0..3)
            .map(|k| {
                let mut s = Vec::with_capacity(9);
                for m in 0..3 {
                    s.push(r.iter().zip(&rec.accel).map(|(r, f)| r[(k, m)] * f[m]).collect());
                }
                for m in 0..3 {
                    s.push(r.iter().map(|r| r[(k, m)]).collect());
                }
                for j in 0..3 {
                    s.push(vec![if j == k { 1.0 } else { 0.0 }; t.len()]);
                }
                s
            })
            .collect();
        let constraints: Vec<(usize, Constraint)> = o
            .constraints
            .iter()
            .flat_map(|&(tc, known)| {
                (0..3).map(move |k| {
                    (
                        k,
                        match known {
                            Known::Position(p) => Constraint::Position { t: tc, value: p[k] },
                            Known::Velocity(v) => Constraint::Velocity { t: tc, value: v[k] },
                        },
                    )
                })
            })
            .collect();
        let (theta, xs) = bvp::fit_error_model_axes(t, &bases, &signals, &ends, &constraints)?;
        let pos = (0..t.len())
            .map(|i| Vector3::new(xs[0][i], xs[1][i], xs[2][i]))
            .collect();
        let mut p = [0.0; 9];
        p.copy_from_slice(&theta);
        Some((pos, p))
    } else {
        None
    };
    Ok(Reconstruction {
        t: t.clone(),
        trapezoid,
        fem,
        model,
    })
}

/// Velocity of a reference track by three-point differences.
pub fn reference_velocity(t: &[f64], p: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
    let v: Vec<Vec<f64>> = (0..3).map(|k| bvp::velocity(t, &axis(p, k))).collect();
    (0..t.len()).map(|i| Vector3::new(v[0][i], v[1][i], v[2][i])).collect()
}
