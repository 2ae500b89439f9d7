//! The ground truth as each node computes it for itself: the analytic trajectory (pose, attitude), the reference
//! columns of its recorded IMU file, or the linear system driven by its own seeded process noise. Every node derives
//! the same truth from the run seed, so no truth crosses the network and separate processes agree on it.
#![allow(non_snake_case)]

use std::sync::Arc;

use nalgebra::{DMatrix, DVector, Vector3, Vector4};
use rand::Rng as _;
use rand_distr::StandardNormal;

use crate::estimate::attitude::{angle_between, from_euler, to_euler};
use crate::imu_csv::StepRecording;
use crate::motion::{PoseTruth, Trajectory};
use crate::rng::Rng;
use crate::topology::{ModelConfig, Topology};

#[derive(Debug, Clone)]
#[allow(clippy::large_enum_variant)] // one per node
pub enum Truth {
    Pose {
        trajectory: Trajectory,
        dt: f64,
        k: u64,
    },
    /// The trajectory's attitude as a unit quaternion (scalar first).
    Attitude {
        trajectory: Trajectory,
        dt: f64,
        k: u64,
    },
    /// A recording's reference columns; a missing column is NaN, and its errors are not computed.
    Recorded {
        rec: Arc<StepRecording>,
        k: u64,
        attitude: bool,
    },
    Linear {
        x: DVector<f64>,
        A: DMatrix<f64>,
        Q_sqrt: DMatrix<f64>,
        rng: Rng,
        k: u64,
        /// Shift of coordinates not yet applied to the estimates (see `REBASE_LIMIT`).
        shift: Option<DVector<f64>>,
        /// Number of shifts so far: states of different frames must not be mixed (e.g. in a median).
        frame: u64,
    },
}

/// An unstable A makes the true state grow like ρ(A)ᵏ until it overflows (Sinopoli's scalar example: 1.25ᵏ). When
/// it passes this size, truth, estimates and later measurements move to coordinates centred on the current truth.
/// The Kalman filter is affine-equivariant, so errors, gains and covariances are unchanged; only the origin of the
/// reported states moves.
pub const REBASE_LIMIT: f64 = 1e6;

/// A square root of a symmetric positive semidefinite matrix (eigen-decomposition; Q may be singular).
pub fn psd_sqrt(m: &DMatrix<f64>) -> DMatrix<f64> {
    // Validated finite and symmetric PSD before it gets here.
    let e = m.clone().symmetric_eigen();
    let d = e.eigenvalues.map(|v| v.max(0.0).sqrt());
    &e.eigenvectors * DMatrix::from_diagonal(&d)
}

fn randn(rng: &mut Rng, n: usize) -> DVector<f64> {
    DVector::from_fn(n, |_, _| rng.sample(StandardNormal))
}

impl Truth {
    /// The truth of a node whose IMU is `recorded` (else the topology's own).
    pub fn of_node(topo: &Topology, recorded: Option<Arc<StepRecording>>) -> Truth {
        match recorded {
            Some(rec) => Truth::Recorded {
                rec,
                k: 0,
                attitude: matches!(topo.model, ModelConfig::Attitude(_)),
            },
            None => Truth::new(topo),
        }
    }

    pub fn new(topo: &Topology) -> Truth {
        match &topo.model {
            ModelConfig::Pose(_) => Truth::Pose {
                trajectory: topo.sim.trajectory,
                dt: topo.sim.dt(),
                k: 0,
            },
            ModelConfig::Attitude(_) => Truth::Attitude {
                trajectory: topo.sim.trajectory,
                dt: topo.sim.dt(),
                k: 0,
            },
            ModelConfig::Linear(m) => {
                let mut rng = crate::rng::stream(topo.sim.seed, "truth", 0, 0);
                // x₀ ~ N(x̂₀, P₀), so that the filter's prior is consistent with the truth.
                let x = &m.x0 + psd_sqrt(&m.P0) * randn(&mut rng, m.x0.len());
                Truth::Linear {
                    x,
                    A: m.A.clone(),
                    Q_sqrt: psd_sqrt(&m.Q),
                    rng,
                    k: 0,
                    shift: None,
                    frame: 0,
                }
            }
        }
    }

    pub fn advance_to(&mut self, target: u64) {
        match self {
            Truth::Pose { k, .. } | Truth::Attitude { k, .. } | Truth::Recorded { k, .. } => *k = target,
            Truth::Linear {
                x,
                A,
                Q_sqrt,
                rng,
                k,
                shift,
                frame,
            } => {
                while *k < target {
                    let w = &*Q_sqrt * randn(rng, x.len());
                    *x = &*A * &*x + w;
                    *shift = shift.take().map(|s| &*A * s);
                    if x.amax() > REBASE_LIMIT {
                        *shift = Some(shift.take().unwrap_or_else(|| DVector::zeros(x.len())) - &*x);
                        x.fill(0.0);
                        *frame += 1;
                    }
                    *k += 1;
                }
            }
        }
    }

    /// Which coordinate frame the current states are in (changes at each re-basing).
    pub fn frame(&self) -> u64 {
        match self {
            Truth::Linear { frame, .. } => *frame,
            _ => 0,
        }
    }

    /// A change of origin to add to every estimate predicted to the current step, once.
    pub fn take_shift(&mut self) -> Option<DVector<f64>> {
        match self {
            Truth::Linear { shift, .. } => shift.take(),
            _ => None,
        }
    }

    /// The analytic motion at the current step (not for recorded or linear truths).
    pub fn motion(&self) -> Option<PoseTruth> {
        match self {
            Truth::Pose { trajectory, dt, k } | Truth::Attitude { trajectory, dt, k } => {
                Some(trajectory.at(*k as f64 * dt))
            }
            _ => None,
        }
    }

    /// The true state in the filter's coordinates: [p, v, θ], q or x. A recording has no velocity (NaN).
    pub fn state(&self) -> DVector<f64> {
        let nan = Vector3::repeat(f64::NAN);
        match self {
            Truth::Pose { trajectory, dt, k } => {
                let s = trajectory.at(*k as f64 * dt);
                DVector::from_iterator(9, s.p.iter().chain(s.v.iter()).chain(s.euler.iter()).copied())
            }
            Truth::Attitude { trajectory, dt, k } => quaternion(&trajectory.at(*k as f64 * dt).euler),
            Truth::Recorded { rec, k, attitude } => {
                let at = |v: &Option<Vec<Vector3<f64>>>| v.as_ref().and_then(|v| v.get(*k as usize).copied());
                let euler = at(&rec.euler).unwrap_or(nan);
                if *attitude {
                    quaternion(&euler)
                } else {
                    let p = at(&rec.position).unwrap_or(nan);
                    DVector::from_iterator(9, p.iter().chain(nan.iter()).chain(euler.iter()).copied())
                }
            }
            Truth::Linear { x, .. } => x.clone(),
        }
    }

    fn is_attitude(&self) -> bool {
        matches!(self, Truth::Attitude { .. } | Truth::Recorded { attitude: true, .. })
    }

    /// The columns written to `trace.csv`: position and attitude for pose, Euler angles for attitude, the whole
    /// state for linear.
    pub fn reported(&self, state: &DVector<f64>) -> Vec<f64> {
        match self {
            Truth::Linear { .. } => state.iter().copied().collect(),
            _ if self.is_attitude() => {
                let q = Vector4::new(state[0], state[1], state[2], state[3]);
                to_euler(&q).iter().copied().collect()
            }
            _ => [0, 1, 2, 6, 7, 8].iter().map(|&i| state[i]).collect(),
        }
    }

    /// The variances of the reported columns: the diagonal of P for pose and linear; for attitude the diagonal of
    /// J P Jᵀ, J the Jacobian of the Euler angles with respect to q (central differences).
    pub fn reported_var(&self, g: &crate::estimate::Gaussian) -> Vec<f64> {
        match self {
            Truth::Linear { .. } => g.P.diagonal().iter().copied().collect(),
            _ if self.is_attitude() => {
                let q = Vector4::new(g.x[0], g.x[1], g.x[2], g.x[3]);
                let h = 1e-6;
                let J = DMatrix::from_fn(3, 4, |i, j| {
                    let mut e = Vector4::zeros();
                    e[j] = h;
                    let d = to_euler(&(q + e)) - to_euler(&(q - e));
                    // Yaw and roll wrap at ±π: take the shorter way round.
                    let d =
                        d.map(|a| (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI);
                    d[i] / (2.0 * h)
                });
                (&J * &g.P * J.transpose()).diagonal().iter().copied().collect()
            }
            _ => [0, 1, 2, 6, 7, 8].iter().map(|&i| g.P[(i, i)]).collect(),
        }
    }

    /// Names of the reported columns.
    pub fn columns(&self) -> Vec<String> {
        let names: &[&str] = match self {
            Truth::Linear { x, .. } => return (0..x.len()).map(|i| format!("x{i}")).collect(),
            _ if self.is_attitude() => &["roll", "pitch", "yaw"],
            _ => &["x", "y", "z", "roll", "pitch", "yaw"],
        };
        names.iter().map(|s| s.to_string()).collect()
    }

    /// The truth with the sign of `est` for the attitude model (q and −q are the same attitude), as a NEES needs.
    pub fn aligned(&self, truth: &DVector<f64>, est: &DVector<f64>) -> DVector<f64> {
        if self.is_attitude() && truth.dot(est) < 0.0 {
            -truth
        } else {
            truth.clone()
        }
    }

    /// The error figure of an estimate: position error (m) for pose, rotation angle (degrees) for attitude, state
    /// error norm for linear; `None` where the truth is not known.
    pub fn error(&self, truth: &DVector<f64>, est: &DVector<f64>) -> Option<f64> {
        let q = |v: &DVector<f64>| Vector4::new(v[0], v[1], v[2], v[3]);
        let (known, e) = match self {
            Truth::Linear { .. } => (true, (truth - est).norm()),
            _ if self.is_attitude() => (
                truth.iter().all(|v| v.is_finite()),
                angle_between(&q(truth), &q(est)).to_degrees(),
            ),
            _ => (
                truth.rows(0, 3).iter().all(|v| v.is_finite()),
                (truth.rows(0, 3) - est.rows(0, 3)).norm(),
            ),
        };
        known.then_some(e)
    }
}

fn quaternion(euler: &Vector3<f64>) -> DVector<f64> {
    DVector::from_column_slice(from_euler(euler).as_slice())
}
