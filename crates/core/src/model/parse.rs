//! The `[model]` table: its kind and the keys that belong to it.

use nalgebra::{DMatrix, DVector};

use super::{Attitude, Kind, Linear, ModelConfig, Observed, Pose, Ranges};
use serde::{Deserialize, Serialize};

use crate::checks::Checks;

/// The `[model]` table as written (`deny_unknown_fields`: a misspelt key is an error naming it).
#[derive(Debug, Serialize, Deserialize, Default, Clone)]
#[serde(deny_unknown_fields)]
pub struct RawModel {
    /// `pose`, `attitude`, `linear` or a model a program registered.
    pub kind: Option<String>,
    /// A registered model's own keys (`[model.params]`).
    pub params: Option<toml::Table>,
    // pose
    /// Pose: position process noise, m² per step.
    pub q_pos: Option<f64>,
    /// Pose: velocity process noise, (m/s)² per step.
    pub q_vel: Option<f64>,
    /// Pose: attitude process noise, rad² per step.
    pub q_att: Option<f64>,
    /// Pose: position-fix noise variance, m².
    pub r_pos: Option<f64>,
    /// Pose: attitude-fix noise variance, rad².
    pub r_att: Option<f64>,
    /// Pose: initial position variance, m².
    pub p0_pos: Option<f64>,
    /// Pose: initial velocity variance, (m/s)².
    pub p0_vel: Option<f64>,
    /// Pose: initial attitude variance, rad².
    pub p0_att: Option<f64>,
    // attitude
    /// Attitude: accelerometer noise variance, (m/s²)².
    pub r_acc: Option<f64>,
    /// Attitude: magnetometer noise variance.
    pub r_mag: Option<f64>,
    /// Attitude: Earth's field in the navigation frame.
    pub mag_field: Option<[f64; 3]>,
    // linear
    /// Linear: A, row by row.
    pub a: Option<Vec<Vec<f64>>>,
    /// Linear: C, row by row.
    pub c: Option<Vec<Vec<f64>>>,
    /// Linear: Q, row by row.
    pub q: Option<Vec<Vec<f64>>>,
    /// Linear: R, row by row.
    pub r: Option<Vec<Vec<f64>>>,
    /// Linear: x₀.
    pub x0: Option<Vec<f64>>,
    /// Linear: P₀, row by row.
    pub p0: Option<Vec<Vec<f64>>>,
    /// Linear: what the nodes measure, `state` (y = C x + v) or `ranges` (each node's range to the body the first
    /// two state rows place, from where the node stands).
    pub observe: Option<String>,
}

/// The validated model of a `[model]` table; problems go to `ck` with their keys.
pub fn parse(m: RawModel, ck: &mut Checks) -> ModelConfig {
    let kind = m.kind.as_deref().unwrap_or("pose");
    // Keys that belong to some kinds only.
    let owned: [(&str, bool, &[&str]); 19] = [
        ("q_pos", m.q_pos.is_some(), &["pose"]),
        ("q_vel", m.q_vel.is_some(), &["pose"]),
        ("q_att", m.q_att.is_some(), &["pose"]),
        ("r_pos", m.r_pos.is_some(), &["pose"]),
        ("r_att", m.r_att.is_some(), &["pose"]),
        ("p0_pos", m.p0_pos.is_some(), &["pose"]),
        ("p0_vel", m.p0_vel.is_some(), &["pose"]),
        ("p0_att", m.p0_att.is_some(), &["pose", "attitude"]),
        ("r_acc", m.r_acc.is_some(), &["attitude"]),
        ("r_mag", m.r_mag.is_some(), &["attitude"]),
        ("mag_field", m.mag_field.is_some(), &["attitude"]),
        ("a", m.a.is_some(), &["linear"]),
        ("c", m.c.is_some(), &["linear"]),
        ("q", m.q.is_some(), &["linear"]),
        ("r", m.r.is_some(), &["linear"]),
        ("x0", m.x0.is_some(), &["linear"]),
        ("p0", m.p0.is_some(), &["linear"]),
        ("observe", m.observe.is_some(), &["linear"]),
        ("params", m.params.is_some(), &[]),
    ];
    let known = Kind::from_name(kind);
    let registered = known.and_then(|k| Some((k, k.registration().build?)));
    if known.is_some() {
        for (key, given, owners) in owned {
            if key == "params" && registered.is_some() {
                continue;
            }
            if given && !owners.contains(&kind) {
                let kinds: Vec<String> = owners.iter().map(|o| format!("\"{o}\"")).collect();
                let whom = match kinds.is_empty() {
                    true => "a model a program registered".to_string(),
                    false => format!("kind = {}", kinds.join(" or ")),
                };
                ck.bad(format!("model.{key}"), format!("only for {whom}"));
            }
        }
    }
    if let Some((kind, build)) = registered {
        let params = m.params.unwrap_or_default();
        let model = build(&params, ck);
        return ModelConfig::Registered { kind, params, model };
    }
    match kind {
        "pose" => ModelConfig::Pose(Pose {
            q_pos: ck.non_negative("model.q_pos", m.q_pos, 0.0),
            q_vel: ck.non_negative("model.q_vel", m.q_vel, 0.0),
            q_att: ck.non_negative("model.q_att", m.q_att, 0.0),
            r_pos: ck.positive("model.r_pos", m.r_pos, 0.01),
            r_att: ck.positive("model.r_att", m.r_att, 0.001),
            p0_pos: ck.positive("model.p0_pos", m.p0_pos, 0.25),
            p0_vel: ck.positive("model.p0_vel", m.p0_vel, 0.01),
            p0_att: ck.positive("model.p0_att", m.p0_att, 0.003),
        }),
        "attitude" => {
            let field = m.mag_field.unwrap_or([0.25, 0.0, -0.433]);
            let norm = field.iter().map(|v| v * v).sum::<f64>().sqrt();
            if !(norm > 0.0 && norm.is_finite()) {
                ck.bad("model.mag_field", "must be a finite non-zero vector");
            } else if (field[0] * field[0] + field[1] * field[1]).sqrt() < 1e-3 * norm {
                ck.bad(
                    "model.mag_field",
                    "must have a horizontal component: a vertical field leaves yaw unobservable",
                );
            }
            ModelConfig::Attitude(Attitude {
                r_acc: ck.positive("model.r_acc", m.r_acc, 0.01),
                r_mag: ck.positive("model.r_mag", m.r_mag, 1e-5),
                mag_field: field,
                p0_att: ck.positive("model.p0_att", m.p0_att, 0.003),
            })
        }
        "linear" => {
            let ranges = match m.observe.as_deref() {
                None | Some("state") => false,
                Some("ranges") => true,
                Some(other) => {
                    ck.bad("model.observe", format!("expected state | ranges, got `{other}`"));
                    false
                }
            };
            let a = ck.matrix("model.a", &m.a);
            let q = ck.matrix("model.q", &m.q);
            let r = ck.matrix("model.r", &m.r);
            // A range is linearised at the node's site: there is no C to give.
            let c = match (ranges, &m.c) {
                (true, Some(_)) => {
                    ck.bad(
                        "model.c",
                        "not with observe = \"ranges\": each node's range is linearised where the node stands",
                    );
                    None
                }
                (true, None) => a.as_ref().map(|a| DMatrix::zeros(1, a.nrows())),
                (false, _) => ck.matrix("model.c", &m.c),
            };
            for (k, v) in [("a", &a), ("c", &c), ("q", &q), ("r", &r)] {
                if v.is_none() && m.kind.is_some() && ck.problems.iter().all(|p| p.key != format!("model.{k}")) {
                    ck.bad(format!("model.{k}"), "required for kind = \"linear\"");
                }
            }
            let (Some(a), Some(c), Some(q), Some(r)) = (a, c, q, r) else {
                return ModelConfig::Linear(Linear::new(
                    DMatrix::identity(1, 1),
                    DMatrix::identity(1, 1),
                    DMatrix::identity(1, 1),
                    DMatrix::identity(1, 1),
                    DVector::zeros(1),
                    DMatrix::identity(1, 1),
                ));
            };
            let n = a.nrows();
            if a.ncols() != n {
                ck.bad("model.a", format!("must be square, got {}×{}", a.nrows(), a.ncols()));
            }
            if c.ncols() != n {
                ck.bad(
                    "model.c",
                    format!("must have {n} columns (the state size of model.a), got {}", c.ncols()),
                );
            }
            if c.nrows() > 64 {
                ck.bad("model.c", "at most 64 measurement rows fit in one datagram");
            }
            ck.spd("model.q", &q, n, true);
            ck.spd("model.r", &r, c.nrows(), false);
            let x0 = match &m.x0 {
                Some(v) if v.len() != n => {
                    ck.bad("model.x0", format!("must have {n} entries, got {}", v.len()));
                    DVector::zeros(n)
                }
                Some(v) => DVector::from_column_slice(v),
                None => DVector::zeros(n),
            };
            let p0 = match ck.matrix("model.p0", &m.p0) {
                Some(p) => {
                    ck.spd("model.p0", &p, n, false);
                    p
                }
                None => DMatrix::identity(n, n),
            };
            let linear = Linear::new(a, c, q, r, x0, p0);
            if !ranges {
                return ModelConfig::Linear(linear);
            }
            if n < 2 {
                ck.bad(
                    "model.a",
                    "observe = \"ranges\" places the body by the first two state rows: at least 2 states",
                );
            }
            // The sites are the nodes' positions, which the scenario gives after the model ([`ModelConfig::stand_at`]).
            match Ranges::planar(Vec::new(), n, linear.R()[(0, 0)]) {
                Some(sensing) => ModelConfig::Ranged {
                    model: Observed {
                        base: std::sync::Arc::new(linear.clone()),
                        sensing,
                    },
                    linear,
                },
                None => ModelConfig::Linear(linear),
            }
        }
        other => {
            ck.bad("model.kind", format!("expected {}, got `{other}`", Kind::names()));
            ModelConfig::Pose(Pose::default())
        }
    }
}

/// A matrix as the rows a `[model]` table writes.
pub fn matrix_rows(m: &DMatrix<f64>) -> Vec<Vec<f64>> {
    (0..m.nrows()).map(|i| m.row(i).iter().copied().collect()).collect()
}

/// The `[model]` table that [`parse`] turns back into `m` (a scenario built in code goes through the same checks as
/// a file).
pub fn to_raw(m: &ModelConfig) -> RawModel {
    let rows = |m: &DMatrix<f64>| Some(matrix_rows(m));
    match m {
        ModelConfig::Pose(p) => RawModel {
            kind: Some("pose".into()),
            q_pos: Some(p.q_pos),
            q_vel: Some(p.q_vel),
            q_att: Some(p.q_att),
            r_pos: Some(p.r_pos),
            r_att: Some(p.r_att),
            p0_pos: Some(p.p0_pos),
            p0_vel: Some(p.p0_vel),
            p0_att: Some(p.p0_att),
            ..Default::default()
        },
        ModelConfig::Attitude(a) => RawModel {
            kind: Some("attitude".into()),
            r_acc: Some(a.r_acc),
            r_mag: Some(a.r_mag),
            mag_field: Some(a.mag_field),
            p0_att: Some(a.p0_att),
            ..Default::default()
        },
        ModelConfig::Linear(l) => RawModel {
            kind: Some("linear".into()),
            a: rows(l.A()),
            c: rows(l.C()),
            q: rows(l.Q()),
            r: rows(l.R()),
            x0: Some(l.x0().iter().copied().collect()),
            p0: rows(l.P0()),
            ..Default::default()
        },
        ModelConfig::Ranged { linear: l, .. } => RawModel {
            kind: Some("linear".into()),
            observe: Some("ranges".into()),
            a: rows(l.A()),
            q: rows(l.Q()),
            r: rows(l.R()),
            x0: Some(l.x0().iter().copied().collect()),
            p0: rows(l.P0()),
            ..Default::default()
        },
        ModelConfig::Registered { kind, params, .. } => RawModel {
            kind: Some(kind.as_str().into()),
            params: Some(params.clone()),
            ..Default::default()
        },
    }
}

impl From<Pose> for ModelConfig {
    fn from(m: Pose) -> ModelConfig {
        ModelConfig::Pose(m)
    }
}

impl From<Attitude> for ModelConfig {
    fn from(m: Attitude) -> ModelConfig {
        ModelConfig::Attitude(m)
    }
}

impl From<Linear> for ModelConfig {
    fn from(m: Linear) -> ModelConfig {
        ModelConfig::Linear(m)
    }
}
