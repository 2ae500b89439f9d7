//! Topology files: TOML in, a validated [`Topology`] out.
//!
//! Every problem is reported with the file, the key and what was expected; `validate` gathers all of them rather than
//! stopping at the first. Names resolve to a path, then `./topologies/NAME.toml`, then the copies compiled into the
//! binary ([`builtin`]).

pub mod builtin;
mod raw;

use std::collections::HashMap;
use std::fmt;
use std::path::Path;
use std::sync::Arc;

use nalgebra::{DMatrix, DVector};

use crate::imu_csv::ImuRecording;
use crate::link::{FaultSchedule, Jitter, LinkConfig, LossModel, ScheduledFault};
use crate::model::{Attitude, Linear, ModelConfig, Pose};
use crate::motion::Trajectory;
use crate::sensor::SensorProfile;
use raw::*;

/// One problem found in a topology file.
#[derive(Debug, Clone, PartialEq)]
pub struct Problem {
    /// Dotted key path, e.g. `edge[2].nodes`.
    pub key: String,
    pub message: String,
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "`{}`: {}", self.key, self.message)
    }
}

/// `./topologies/NAME.toml`, without doubling an extension the user gave.
fn in_topologies(name: &str) -> String {
    if name.ends_with(".toml") {
        format!("./topologies/{name}")
    } else {
        format!("./topologies/{name}.toml")
    }
}

/// "1 node", "3 nodes".
pub fn count(n: usize, what: &str) -> String {
    format!("{n} {what}{}", if n == 1 { "" } else { "s" })
}

#[derive(Debug, thiserror::Error)]
pub enum TopologyError {
    #[error(
        "topology `{name}` not found: not a file, not {}, not a built-in (see `simnet topologies`)",
        in_topologies(name)
    )]
    NotFound { name: String },
    #[error("{file}: cannot read: {source}")]
    Io { file: String, source: std::io::Error },
    #[error("{file}: {message}")]
    Parse { file: String, message: String },
    #[error("{file}: {}:\n{}", count(problems.len(), "problem"), problems.iter().map(|p| format!("  - {p}")).collect::<Vec<_>>().join("\n"))]
    Invalid { file: String, problems: Vec<Problem> },
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Role {
    /// Senses and estimates.
    Peer,
    /// Senses and sends; runs no filter.
    Sensor,
    /// Estimates from what it receives; has no sensor of its own.
    Estimator,
}

impl Role {
    pub fn senses(self) -> bool {
        !matches!(self, Role::Estimator)
    }
    pub fn estimates(self) -> bool {
        !matches!(self, Role::Sensor)
    }
    pub fn as_str(self) -> &'static str {
        match self {
            Role::Peer => "peer",
            Role::Sensor => "sensor",
            Role::Estimator => "estimator",
        }
    }
}

#[derive(Debug, Clone)]
pub struct SimConfig {
    pub rate_hz: f64,
    pub duration_s: f64,
    pub burn_in_s: f64,
    /// The burn-in the file asked for, where a shorter `--duration` halved it (see [`Topology::warnings`]).
    pub burn_in_shortened_from: Option<f64>,
    pub seed: u64,
    pub trajectory: Trajectory,
    /// Measurements of step k are used only if they arrive by t_k + deadline (Sinopoli's deadline model).
    pub deadline_s: f64,
    /// The pose fix travels as two datagrams (position, orientation) so that loss can be partial.
    pub split_channels: bool,
    /// A filter whose trace P exceeds this is marked diverged.
    pub divergence_trace: f64,
}

impl SimConfig {
    pub fn dt(&self) -> f64 {
        1.0 / self.rate_hz
    }
    pub fn steps(&self) -> u64 {
        (self.duration_s * self.rate_hz).round() as u64
    }
    pub fn burn_in_steps(&self) -> u64 {
        ((self.burn_in_s * self.rate_hz).round() as u64).min(self.steps())
    }
}

#[derive(Debug, Clone, Copy)]
pub struct LmiConfig {
    pub alpha: f64,
    pub gamma: f64,
    pub enabled: bool,
}

#[derive(Debug, Clone)]
pub struct ConsensusConfig {
    pub beta0: f64,
    /// `beta[i][j]`: weight node i gives the measurement of node j (row i = receiving node, by position in the file).
    pub beta: Vec<Vec<f64>>,
    pub lmi: LmiConfig,
    /// λ of the per-channel inflation R̄ᵢᵢ = λ² Rᵢᵢ for a channel no source delivered.
    pub inflation: f64,
}

#[derive(Debug, Clone)]
pub struct NodeConfig {
    /// The id written in the file; nodes are indexed by position everywhere else.
    pub id: u32,
    pub role: Role,
    pub addr: Option<String>,
    pub sensor: SensorProfile,
    /// A recorded IMU that replaces the simulated one (`imu_csv`).
    pub recording: Option<RecordedImu>,
}

/// A node's IMU file: the path as written, as resolved, and its rows.
#[derive(Debug, Clone)]
pub struct RecordedImu {
    pub given: String,
    pub path: String,
    pub data: Arc<ImuRecording>,
}

#[derive(Debug, Clone)]
pub struct DirectedLink {
    pub from: usize,
    pub to: usize,
    pub config: LinkConfig,
}

#[derive(Debug, Clone)]
pub struct Topology {
    pub name: String,
    pub description: String,
    /// Where it came from: a path or `builtin:NAME`.
    pub source: String,
    pub sim: SimConfig,
    pub model: ModelConfig,
    pub consensus: ConsensusConfig,
    pub nodes: Vec<NodeConfig>,
    pub links: Vec<DirectedLink>,
    pub faults: FaultSchedule,
    /// The overrides applied since the file was read (the last value of each wins).
    pub applied: Overrides,
}

impl Topology {
    /// Index of the node whose file id is `id`.
    pub fn index_of(&self, id: u32) -> Option<usize> {
        self.nodes.iter().position(|n| n.id == id)
    }
    /// Directed links into node `i`.
    pub fn in_links(&self, i: usize) -> impl Iterator<Item = &DirectedLink> {
        self.links.iter().filter(move |l| l.to == i)
    }
    pub fn out_links(&self, i: usize) -> impl Iterator<Item = &DirectedLink> {
        self.links.iter().filter(move |l| l.from == i)
    }
    /// Parse and validate TOML text; `file` names the source in errors.
    pub fn from_toml(text: &str, file: &str) -> Result<Topology, TopologyError> {
        let raw: RawTopology = toml::from_str(text).map_err(|e| TopologyError::Parse {
            file: file.to_string(),
            message: e.to_string().trim_end().to_string(),
        })?;
        let mut v = Validator::default();
        let topo = v.topology(raw, file);
        if v.problems.is_empty() {
            Ok(topo.expect("no problems implies a topology"))
        } else {
            Err(TopologyError::Invalid {
                file: file.to_string(),
                problems: v.problems,
            })
        }
    }

    pub fn from_path(path: &Path) -> Result<Topology, TopologyError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| TopologyError::Io {
            file: file.clone(),
            source,
        })?;
        Topology::from_toml(&text, &file)
    }

    /// A path, then `./topologies/NAME.toml`, then a built-in.
    pub fn resolve(name_or_path: &str) -> Result<Topology, TopologyError> {
        let (text, file) = Topology::resolve_text(name_or_path)?;
        Topology::from_toml(&text, &file)
    }

    /// The TOML text [`Topology::resolve`] would parse, and the name it gives the file in errors.
    pub fn resolve_text(name_or_path: &str) -> Result<(String, String), TopologyError> {
        let read = |p: &Path| {
            let file = p.display().to_string();
            std::fs::read_to_string(p)
                .map(|t| (t, file.clone()))
                .map_err(|source| TopologyError::Io { file, source })
        };
        let p = Path::new(name_or_path);
        if p.is_file() {
            return read(p);
        }
        let local = Path::new("topologies").join(format!("{name_or_path}.toml"));
        if local.is_file() {
            return read(&local);
        }
        match builtin::get(name_or_path) {
            Some(text) => Ok((text.to_string(), format!("builtin:{name_or_path}"))),
            None => Err(TopologyError::NotFound {
                name: name_or_path.to_string(),
            }),
        }
    }
}

/// A recording that ends before the run does. Checked once the command-line overrides have set the duration and
/// the rate ([`Topology::check_recordings`]); a node runs past the end of its file without IMU samples.
fn recording_problems(sim: &SimConfig, nodes: &[NodeConfig]) -> Vec<Problem> {
    let need = sim.steps().saturating_sub(1) as f64 * sim.dt();
    nodes
        .iter()
        .enumerate()
        .filter_map(|(i, n)| {
            let r = n.recording.as_ref()?;
            let span = r.data.span();
            (span + 1e-6 * sim.dt() < need).then(|| Problem {
                key: format!("node[{i}].imu_csv"),
                message: format!(
                    "{} covers {span:.3} s, the run needs {need:.3} s (shorten sim.duration_s or --duration)",
                    r.path
                ),
            })
        })
        .collect()
}

impl Topology {
    /// After [`Topology::apply`]: every recorded IMU covers the run.
    /// Settings that are valid but probably not meant: a run no longer than its burn-in (no step counts in the
    /// means), faults that start after the run has ended.
    pub fn warnings(&self) -> Vec<String> {
        let mut w = Vec::new();
        let d = self.sim.duration_s;
        if let Some(asked) = self.sim.burn_in_shortened_from.filter(|b| d <= *b) {
            w.push(format!(
                "the run ({d} s) is shorter than the burn-in sim.burn_in_s = {asked} s: the means count from {} s",
                self.sim.burn_in_s
            ));
        }
        let late: Vec<f64> = self.faults.starts().filter(|t| *t >= d).collect();
        if !late.is_empty() {
            w.push(format!(
                "{} after the run ends at {d} s (at {}): never applied",
                if late.len() == 1 {
                    "1 fault starts".to_string()
                } else {
                    format!("{} faults start", late.len())
                },
                late.iter().map(|t| format!("{t} s")).collect::<Vec<_>>().join(", ")
            ));
        }
        w
    }

    pub fn check_recordings(&self) -> Result<(), TopologyError> {
        let problems = recording_problems(&self.sim, &self.nodes);
        if problems.is_empty() {
            Ok(())
        } else {
            Err(TopologyError::Invalid {
                file: self.source.clone(),
                problems,
            })
        }
    }
}

/// Command-line overrides applied on top of a file (as `summary.json` records them: unset ones left out).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct Overrides {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub loss: Option<LossModel>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub delay_ms: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub jitter_ms: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub duplicate: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub corrupt: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub duration_s: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rate_hz: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
}

impl Topology {
    /// CLI link options replace the value on every link (file defaults and per-edge overrides alike).
    pub fn apply(&mut self, o: &Overrides) {
        let a = &mut self.applied;
        macro_rules! keep {
            ($($f:ident),*) => { $( if o.$f.is_some() { a.$f = o.$f; } )* };
        }
        keep!(loss, delay_ms, jitter_ms, duplicate, corrupt, duration_s, rate_hz, seed);
        for l in &mut self.links {
            if let Some(loss) = o.loss {
                l.config.loss = loss;
            }
            if let Some(d) = o.delay_ms {
                l.config.delay_ms = d;
            }
            if let Some(j) = o.jitter_ms {
                l.config.jitter_ms = j;
            }
            if let Some(d) = o.duplicate {
                l.config.duplicate = d;
            }
            if let Some(c) = o.corrupt {
                l.config.corrupt = c;
            }
        }
        if let Some(d) = o.duration_s {
            self.sim.duration_s = d;
            if self.sim.burn_in_s > d / 2.0 {
                let asked = self.sim.burn_in_shortened_from.unwrap_or(self.sim.burn_in_s);
                self.sim.burn_in_shortened_from = Some(asked);
                self.sim.burn_in_s = d / 2.0;
            }
        }
        if let Some(r) = o.rate_hz {
            let old_dt = self.sim.dt();
            self.sim.rate_hz = r;
            if (self.sim.deadline_s - old_dt).abs() < 1e-12 || self.sim.deadline_s > self.sim.dt() {
                self.sim.deadline_s = self.sim.dt();
            }
        }
        if let Some(s) = o.seed {
            self.sim.seed = s;
        }
    }
}

/// Checks a probability, a positive number, … and records a problem naming the key.
#[derive(Default)]
struct Validator {
    problems: Vec<Problem>,
}

impl Validator {
    fn bad(&mut self, key: impl Into<String>, message: impl Into<String>) {
        self.problems.push(Problem {
            key: key.into(),
            message: message.into(),
        });
    }

    /// Read `imu_csv`: relative to the topology file's folder, or to the working directory for a built-in.
    fn recording(&mut self, key: &str, path: &str, topology_file: &str) -> Option<RecordedImu> {
        let base = Path::new(topology_file);
        let resolved = match base.parent() {
            Some(dir) if base.is_file() && Path::new(path).is_relative() => dir.join(path),
            _ => Path::new(path).to_path_buf(),
        };
        let shown = resolved.display().to_string();
        let text = match std::fs::read_to_string(&resolved) {
            Ok(t) => t,
            Err(e) => {
                self.bad(key, format!("cannot read {shown}: {e}"));
                return None;
            }
        };
        match crate::imu_csv::parse(&text, &shown) {
            Ok(data) => Some(RecordedImu {
                given: path.to_string(),
                path: shown,
                data: Arc::new(data),
            }),
            Err(e) => {
                self.bad(key, e.to_string());
                None
            }
        }
    }

    fn prob(&mut self, key: &str, v: Option<f64>, default: f64) -> f64 {
        match v {
            Some(x) if !(0.0..=1.0).contains(&x) || !x.is_finite() => {
                self.bad(key, format!("must be a probability in [0, 1], got {x}"));
                default
            }
            Some(x) => x,
            None => default,
        }
    }

    fn positive(&mut self, key: &str, v: Option<f64>, default: f64) -> f64 {
        match v {
            Some(x) if !(x > 0.0 && x.is_finite()) => {
                self.bad(key, format!("must be a positive finite number, got {x}"));
                default
            }
            Some(x) => x,
            None => default,
        }
    }

    fn non_negative(&mut self, key: &str, v: Option<f64>, default: f64) -> f64 {
        match v {
            Some(x) if !(x >= 0.0 && x.is_finite()) => {
                self.bad(key, format!("must be a non-negative finite number, got {x}"));
                default
            }
            Some(x) => x,
            None => default,
        }
    }

    fn topology(&mut self, raw: RawTopology, file: &str) -> Option<Topology> {
        let name = raw.name.clone().unwrap_or_else(|| {
            Path::new(file)
                .file_stem()
                .map(|s| s.to_string_lossy().trim_start_matches("builtin:").to_string())
                .unwrap_or_default()
        });
        let description = raw.description.clone().unwrap_or_default();
        let sim = self.sim(raw.sim.unwrap_or_default());
        let model = self.model(raw.model.unwrap_or_default());

        // Nodes.
        if raw.node.is_empty() {
            self.bad("node", "at least one [[node]] is required");
        }
        let mut ids: HashMap<i64, usize> = HashMap::new();
        let sensor_defaults = self.sensor("sensor", raw.sensor.as_ref(), &SensorProfile::default());
        let mut nodes = Vec::new();
        for (i, n) in raw.node.iter().enumerate() {
            let key = format!("node[{i}]");
            let id = n.id.unwrap_or(i as i64);
            if !(0..=u32::MAX as i64).contains(&id) {
                self.bad(format!("{key}.id"), format!("must be a non-negative integer, got {id}"));
            }
            if ids.insert(id, i).is_some() {
                self.bad(format!("{key}.id"), format!("id {id} is used by more than one node"));
            }
            let role = match n.role.as_deref().unwrap_or("peer") {
                "peer" => Role::Peer,
                "sensor" => Role::Sensor,
                "estimator" => Role::Estimator,
                other => {
                    self.bad(
                        format!("{key}.role"),
                        format!("expected peer | sensor | estimator, got `{other}`"),
                    );
                    Role::Peer
                }
            };
            let sensor = self.sensor(&format!("{key}.sensor"), n.sensor.as_ref(), &sensor_defaults);
            let recording = n
                .imu_csv
                .as_deref()
                .and_then(|f| self.recording(&format!("{key}.imu_csv"), f, file));
            if recording.is_some() {
                if role == Role::Estimator {
                    self.bad(format!("{key}.imu_csv"), "an estimator has no IMU to replace");
                }
                if !model.get().imu_driven() {
                    self.bad(
                        format!("{key}.imu_csv"),
                        format!("a {} model has no IMU: only for kind = pose or attitude", model.get().kind()),
                    );
                }
            }
            nodes.push(NodeConfig {
                id: id.clamp(0, u32::MAX as i64) as u32,
                role,
                addr: n.addr.clone(),
                sensor,
                recording,
            });
        }
        let n = nodes.len();
        let index = |v: &mut Validator, key: &str, id: i64| -> Option<usize> {
            let r = ids.get(&id).copied();
            if r.is_none() {
                v.bad(key, format!("no [[node]] has id {id}"));
            }
            r
        };

        // Links: [link] defaults, then one or two directed links per [[edge]].
        let default_link = self.link("link", raw.link.clone().unwrap_or_default(), &LinkConfig::default());
        let mut links: Vec<DirectedLink> = Vec::new();
        for (e, edge) in raw.edge.iter().enumerate() {
            let key = format!("edge[{e}]");
            if edge.nodes.len() != 2 {
                self.bad(
                    format!("{key}.nodes"),
                    format!("must list exactly two node ids, got {}", edge.nodes.len()),
                );
                continue;
            }
            let a = index(self, &format!("{key}.nodes"), edge.nodes[0]);
            let b = index(self, &format!("{key}.nodes"), edge.nodes[1]);
            let (Some(a), Some(b)) = (a, b) else { continue };
            if a == b {
                self.bad(format!("{key}.nodes"), "an edge must join two different nodes");
                continue;
            }
            let over = RawLink {
                loss: edge.loss.clone(),
                delay_ms: edge.delay_ms,
                jitter_ms: edge.jitter_ms,
                jitter: edge.jitter.clone(),
                duplicate: edge.duplicate,
                corrupt: edge.corrupt,
            };
            let cfg = self.link(&key, over, &default_link);
            let mut add = |v: &mut Validator, from: usize, to: usize| {
                if links.iter().any(|l| l.from == from && l.to == to) {
                    v.bad(
                        format!("{key}.nodes"),
                        format!("link {} -> {} is given twice", nodes[from].id, nodes[to].id),
                    );
                } else {
                    links.push(DirectedLink { from, to, config: cfg });
                }
            };
            add(self, a, b);
            if !edge.directed.unwrap_or(false) {
                add(self, b, a);
            }
        }

        // Roles must make sense on the graph.
        for (i, node) in nodes.iter().enumerate() {
            let key = format!("node[{i}].role");
            if node.role == Role::Estimator && !links.iter().any(|l| l.to == i) {
                self.bad(key, "an estimator with no incoming edge never receives a measurement");
            } else if node.role == Role::Sensor && !links.iter().any(|l| l.from == i) {
                self.bad(key, "a sensor with no outgoing edge sends to nobody");
            }
        }

        let consensus = self.consensus(raw.consensus.unwrap_or_default(), &nodes, &links);
        let faults = self.faults(&raw.fault, &ids, n);

        if sim.split_channels && model.get().observation().channels() < 2 {
            self.bad(
                "sim.split_channels",
                "only the pose and attitude models have separate channels",
            );
        }
        Some(Topology {
            name,
            description,
            source: file.to_string(),
            sim,
            model,
            consensus,
            applied: Overrides::default(),
            nodes,
            links,
            faults,
        })
    }

    fn sim(&mut self, s: RawSim) -> SimConfig {
        let rate_hz = self.positive("sim.rate_hz", s.rate_hz, 100.0);
        let duration_s = self.positive("sim.duration_s", s.duration_s, 30.0);
        let burn_in_s = self.non_negative("sim.burn_in_s", s.burn_in_s, 3.0_f64.min(duration_s / 10.0));
        if burn_in_s >= duration_s {
            self.bad(
                "sim.burn_in_s",
                format!("must be shorter than sim.duration_s ({duration_s} s), got {burn_in_s}"),
            );
        }
        let trajectory = match s.trajectory.as_deref().unwrap_or("spiral").parse::<Trajectory>() {
            Ok(t) => t,
            Err(e) => {
                self.bad("sim.trajectory", e);
                Trajectory::Spiral
            }
        };
        let period_ms = 1000.0 / rate_hz;
        let deadline_ms = self.positive("sim.deadline_ms", s.deadline_ms, period_ms);
        if deadline_ms > period_ms + 1e-9 {
            self.bad(
                "sim.deadline_ms",
                format!("must not exceed one step period ({period_ms} ms): a measurement is used only in its own step"),
            );
        }
        let divergence_trace = self.positive("sim.divergence_trace", s.divergence_trace, 1e6);
        if duration_s * rate_hz > 1e8 {
            self.bad("sim.duration_s", "more than 1e8 steps");
        }
        SimConfig {
            rate_hz,
            duration_s,
            burn_in_s,
            burn_in_shortened_from: None,
            seed: s.seed.unwrap_or(1),
            trajectory,
            deadline_s: deadline_ms.min(period_ms) / 1000.0,
            split_channels: s.split_channels.unwrap_or(false),
            divergence_trace,
        }
    }

    fn matrix(&mut self, key: &str, rows: &Option<Vec<Vec<f64>>>) -> Option<DMatrix<f64>> {
        let rows = rows.as_ref()?;
        let r = rows.len();
        let c = rows.first().map_or(0, |x| x.len());
        if r == 0 || c == 0 {
            self.bad(key, "must be a non-empty array of rows");
            return None;
        }
        if rows.iter().any(|x| x.len() != c) {
            self.bad(key, format!("rows must all have {c} entries"));
            return None;
        }
        if rows.iter().flatten().any(|x| !x.is_finite()) {
            self.bad(key, "entries must be finite");
            return None;
        }
        Some(DMatrix::from_fn(r, c, |i, j| rows[i][j]))
    }

    fn spd(&mut self, key: &str, m: &DMatrix<f64>, n: usize, semi: bool) {
        if m.nrows() != n || m.ncols() != n {
            self.bad(key, format!("must be {n}×{n}, got {}×{}", m.nrows(), m.ncols()));
            return;
        }
        if (m - m.transpose()).amax() > 1e-9 * (1.0 + m.amax()) {
            self.bad(key, "must be symmetric");
            return;
        }
        let min = m.clone().symmetric_eigenvalues().min();
        if (semi && min < -1e-12) || (!semi && min <= 0.0) {
            let what = if semi {
                "positive semidefinite"
            } else {
                "positive definite"
            };
            self.bad(key, format!("must be {what} (smallest eigenvalue {min:.3e})"));
        }
    }

    fn model(&mut self, m: RawModel) -> ModelConfig {
        let kind = m.kind.as_deref().unwrap_or("pose");
        // Keys that belong to some kinds only.
        let owned: [(&str, bool, &[&str]); 17] = [
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
        ];
        if ["pose", "attitude", "linear"].contains(&kind) {
            for (key, given, owners) in owned {
                if given && !owners.contains(&kind) {
                    let kinds: Vec<String> = owners.iter().map(|o| format!("\"{o}\"")).collect();
                    self.bad(
                        format!("model.{key}"),
                        format!("only for kind = {}", kinds.join(" or ")),
                    );
                }
            }
        }
        match kind {
            "pose" => ModelConfig::Pose(Pose {
                q_pos: self.non_negative("model.q_pos", m.q_pos, 0.0),
                q_vel: self.non_negative("model.q_vel", m.q_vel, 0.0),
                q_att: self.non_negative("model.q_att", m.q_att, 0.0),
                r_pos: self.positive("model.r_pos", m.r_pos, 0.01),
                r_att: self.positive("model.r_att", m.r_att, 0.001),
                p0_pos: self.positive("model.p0_pos", m.p0_pos, 0.25),
                p0_vel: self.positive("model.p0_vel", m.p0_vel, 0.01),
                p0_att: self.positive("model.p0_att", m.p0_att, 0.003),
            }),
            "attitude" => {
                let field = m.mag_field.unwrap_or([0.25, 0.0, -0.433]);
                let norm = field.iter().map(|v| v * v).sum::<f64>().sqrt();
                if !(norm > 0.0 && norm.is_finite()) {
                    self.bad("model.mag_field", "must be a finite non-zero vector");
                } else if (field[0] * field[0] + field[1] * field[1]).sqrt() < 1e-3 * norm {
                    self.bad(
                        "model.mag_field",
                        "must have a horizontal component: a vertical field leaves yaw unobservable",
                    );
                }
                ModelConfig::Attitude(Attitude {
                    r_acc: self.positive("model.r_acc", m.r_acc, 0.01),
                    r_mag: self.positive("model.r_mag", m.r_mag, 1e-5),
                    mag_field: field,
                    p0_att: self.positive("model.p0_att", m.p0_att, 0.003),
                })
            }
            "linear" => {
                let a = self.matrix("model.a", &m.a);
                let c = self.matrix("model.c", &m.c);
                let q = self.matrix("model.q", &m.q);
                let r = self.matrix("model.r", &m.r);
                for (k, v) in [("a", &a), ("c", &c), ("q", &q), ("r", &r)] {
                    if v.is_none() && m.kind.is_some() && self.problems.iter().all(|p| p.key != format!("model.{k}")) {
                        self.bad(format!("model.{k}"), "required for kind = \"linear\"");
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
                    self.bad("model.a", format!("must be square, got {}×{}", a.nrows(), a.ncols()));
                }
                if c.ncols() != n {
                    self.bad(
                        "model.c",
                        format!("must have {n} columns (the state size of model.a), got {}", c.ncols()),
                    );
                }
                if c.nrows() > 64 {
                    self.bad("model.c", "at most 64 measurement rows fit in one datagram");
                }
                self.spd("model.q", &q, n, true);
                self.spd("model.r", &r, c.nrows(), false);
                let x0 = match &m.x0 {
                    Some(v) if v.len() != n => {
                        self.bad("model.x0", format!("must have {n} entries, got {}", v.len()));
                        DVector::zeros(n)
                    }
                    Some(v) => DVector::from_column_slice(v),
                    None => DVector::zeros(n),
                };
                let p0 = match self.matrix("model.p0", &m.p0) {
                    Some(p) => {
                        self.spd("model.p0", &p, n, false);
                        p
                    }
                    None => DMatrix::identity(n, n),
                };
                ModelConfig::Linear(Linear::new(a, c, q, r, x0, p0))
            }
            other => {
                self.bad(
                    "model.kind",
                    format!("expected pose | attitude | linear, got `{other}`"),
                );
                ModelConfig::Pose(Pose::default())
            }
        }
    }

    fn loss(&mut self, key: &str, l: &RawLoss) -> LossModel {
        match l.model.as_str() {
            "bernoulli" => {
                for (k, v) in [
                    ("r", l.r),
                    ("one_minus_h", l.one_minus_h),
                    ("one_minus_k", l.one_minus_k),
                    ("burst", l.burst),
                ] {
                    if v.is_some() {
                        self.bad(format!("{key}.{k}"), "only for model = \"gilbert-elliott\"");
                    }
                }
                let p = self.prob(&format!("{key}.p"), l.p.or(l.rate), 0.0);
                LossModel::Bernoulli { p }
            }
            "gilbert-elliott" => {
                if let (Some(rate), Some(burst)) = (l.rate, l.burst) {
                    let rate = self.prob(&format!("{key}.rate"), Some(rate), 0.0);
                    if burst.is_nan() || burst < 1.0 {
                        self.bad(
                            format!("{key}.burst"),
                            format!("mean loss run must be at least 1 packet, got {burst}"),
                        );
                        return LossModel::Bernoulli { p: 0.0 };
                    }
                    return match LossModel::gilbert_elliott_from(rate, burst) {
                        Ok(m) => m,
                        Err(e) => {
                            self.bad(format!("{key}.rate"), e);
                            LossModel::Bernoulli { p: 0.0 }
                        }
                    };
                }
                let p = self.prob(&format!("{key}.p"), l.p, 0.0);
                let r = self.prob(&format!("{key}.r"), l.r, 1.0);
                if l.p.is_none() || l.r.is_none() {
                    self.bad(
                        key,
                        "gilbert-elliott needs p and r (netem's `loss gemodel p r 1-h 1-k`), or rate and burst",
                    );
                }
                if p + r == 0.0 {
                    self.bad(format!("{key}.r"), "p and r cannot both be 0");
                }
                LossModel::GilbertElliott {
                    p,
                    r,
                    one_minus_h: self.prob(&format!("{key}.one_minus_h"), l.one_minus_h, 1.0),
                    one_minus_k: self.prob(&format!("{key}.one_minus_k"), l.one_minus_k, 0.0),
                }
            }
            other => {
                self.bad(
                    format!("{key}.model"),
                    format!("expected bernoulli | gilbert-elliott, got `{other}`"),
                );
                LossModel::Bernoulli { p: 0.0 }
            }
        }
    }

    fn link(&mut self, key: &str, raw: RawLink, base: &LinkConfig) -> LinkConfig {
        let loss = match &raw.loss {
            Some(l) => self.loss(&format!("{key}.loss"), l),
            None => base.loss,
        };
        let jitter = match raw.jitter.as_deref() {
            None => base.jitter,
            Some("uniform") => Jitter::Uniform,
            Some("normal") => Jitter::Normal,
            Some(other) => {
                self.bad(
                    format!("{key}.jitter"),
                    format!("expected uniform | normal, got `{other}`"),
                );
                base.jitter
            }
        };
        LinkConfig {
            loss,
            delay_ms: self.non_negative(&format!("{key}.delay_ms"), raw.delay_ms, base.delay_ms),
            jitter_ms: self.non_negative(&format!("{key}.jitter_ms"), raw.jitter_ms, base.jitter_ms),
            jitter,
            duplicate: self.prob(&format!("{key}.duplicate"), raw.duplicate, base.duplicate),
            corrupt: self.prob(&format!("{key}.corrupt"), raw.corrupt, base.corrupt),
        }
    }

    fn sensor(&mut self, key: &str, raw: Option<&RawSensor>, base: &SensorProfile) -> SensorProfile {
        let Some(s) = raw else { return base.clone() };
        let vec3 = |v: &mut Validator, k: &str, x: Option<[f64; 3]>, d: [f64; 3]| -> [f64; 3] {
            match x {
                Some(a) if a.iter().any(|e| !e.is_finite()) => {
                    v.bad(format!("{key}.{k}"), "entries must be finite");
                    d
                }
                Some(a) => a,
                None => d,
            }
        };
        let non_neg3 = |v: &mut Validator, k: &str, x: Option<[f64; 3]>, d: [f64; 3]| -> [f64; 3] {
            let a = vec3(v, k, x, d);
            if a.iter().any(|e| *e < 0.0) {
                v.bad(format!("{key}.{k}"), "standard deviations must be non-negative");
            }
            a
        };
        SensorProfile {
            accel_noise: self.non_negative(&format!("{key}.accel_noise"), s.accel_noise, base.accel_noise),
            gyro_noise: self.non_negative(&format!("{key}.gyro_noise"), s.gyro_noise, base.gyro_noise),
            accel_bias: vec3(self, "accel_bias", s.accel_bias, base.accel_bias),
            gyro_bias: vec3(self, "gyro_bias", s.gyro_bias, base.gyro_bias),
            accel_drift: non_neg3(self, "accel_drift", s.accel_drift, base.accel_drift),
            gyro_drift: non_neg3(self, "gyro_drift", s.gyro_drift, base.gyro_drift),
            pos_noise: self.non_negative(&format!("{key}.pos_noise"), s.pos_noise, base.pos_noise),
            att_noise: self.non_negative(&format!("{key}.att_noise"), s.att_noise, base.att_noise),
            mag_noise: self.non_negative(&format!("{key}.mag_noise"), s.mag_noise, base.mag_noise),
        }
    }

    fn consensus(&mut self, c: RawConsensus, nodes: &[NodeConfig], links: &[DirectedLink]) -> ConsensusConfig {
        let n = nodes.len();
        let beta0 = self.prob("consensus.beta0", c.beta0, 0.0);
        if c.matrix.is_some() && (c.self_weight.is_some() || c.neighbor.is_some()) {
            self.bad(
                "consensus.matrix",
                "give either `matrix` or `self`/`neighbor`, not both",
            );
        }
        let beta = match &c.matrix {
            Some(m) => {
                if m.len() != n || m.iter().any(|r| r.len() != n) {
                    self.bad(
                        "consensus.matrix",
                        format!("must be {n}×{n} (one row and column per [[node]])"),
                    );
                    vec![vec![0.0; n]; n]
                } else {
                    for (i, row) in m.iter().enumerate() {
                        for (j, &b) in row.iter().enumerate() {
                            if !(b >= 0.0 && b.is_finite()) {
                                self.bad(
                                    format!("consensus.matrix[{i}][{j}]"),
                                    format!("weights must be ≥ 0, got {b}"),
                                );
                            } else if b > 0.0 && i != j && !links.iter().any(|l| l.from == j && l.to == i) {
                                self.bad(
                                    format!("consensus.matrix[{i}][{j}]"),
                                    format!(
                                        "weight {b} but no link carries node {}'s measurement to node {}",
                                        nodes[j].id, nodes[i].id
                                    ),
                                );
                            }
                        }
                    }
                    m.clone()
                }
            }
            None => {
                let s = self.non_negative("consensus.self", c.self_weight, 1.0);
                let nb = self.non_negative("consensus.neighbor", c.neighbor, 0.0);
                (0..n)
                    .map(|i| {
                        (0..n)
                            .map(|j| {
                                if i == j {
                                    if nodes[i].role.senses() {
                                        s
                                    } else {
                                        0.0
                                    }
                                } else if links.iter().any(|l| l.from == j && l.to == i) && nodes[j].role.senses() {
                                    // An estimator without a sensor of its own gives its sources the whole weight.
                                    if nodes[i].role == Role::Estimator && c.neighbor.is_none() {
                                        1.0
                                    } else {
                                        nb
                                    }
                                } else {
                                    0.0
                                }
                            })
                            .collect()
                    })
                    .collect()
            }
        };
        for (i, node) in nodes.iter().enumerate() {
            if node.role.estimates() && beta[i].iter().all(|&b| b == 0.0) && c.matrix.is_some() {
                self.bad(
                    format!("consensus.matrix[{i}]"),
                    format!("node {} estimates but gives every measurement weight 0", node.id),
                );
            }
        }
        let l = c.lmi.unwrap_or_default();
        let lmi = LmiConfig {
            alpha: self.positive("consensus.lmi.alpha", l.alpha, 1000.0),
            gamma: self.non_negative("consensus.lmi.gamma", l.gamma, 1e-5),
            enabled: l.enabled.unwrap_or(true),
        };
        let inflation = self.positive("consensus.inflation", c.inflation, 1e3);
        if inflation < 1.0 {
            self.bad(
                "consensus.inflation",
                format!("λ inflates a missing channel and must be ≥ 1, got {inflation}"),
            );
        }
        ConsensusConfig {
            beta0,
            beta,
            lmi,
            inflation,
        }
    }

    fn faults(&mut self, raw: &[RawFault], ids: &HashMap<i64, usize>, n: usize) -> FaultSchedule {
        let mut out = Vec::new();
        for (f, r) in raw.iter().enumerate() {
            let key = format!("fault[{f}]");
            let idx = |v: &mut Validator, k: &str, id: i64| -> Option<usize> {
                let r = ids.get(&id).copied();
                if r.is_none() {
                    v.bad(format!("{key}.{k}"), format!("no [[node]] has id {id}"));
                }
                r
            };
            let window = |v: &mut Validator| -> Option<(f64, f64)> {
                let (Some(s), Some(e)) = (r.start_s, r.end_s) else {
                    v.bad(key.clone(), "needs start_s and end_s");
                    return None;
                };
                if !(s >= 0.0 && e > s && e.is_finite()) {
                    v.bad(
                        format!("{key}.end_s"),
                        format!("need 0 ≤ start_s < end_s, got {s}..{e}"),
                    );
                    return None;
                }
                Some((s, e))
            };
            match r.kind.as_str() {
                "link-down" => {
                    let Some(link) = &r.link else {
                        self.bad(format!("{key}.link"), "link-down needs link = [from, to]");
                        continue;
                    };
                    if link.len() != 2 {
                        self.bad(format!("{key}.link"), "must list two node ids");
                        continue;
                    }
                    let (a, b) = (idx(self, "link", link[0]), idx(self, "link", link[1]));
                    let (Some(a), Some(b), Some((s, e))) = (a, b, window(self)) else {
                        continue;
                    };
                    out.push(ScheduledFault::LinkDown {
                        from: a,
                        to: b,
                        both_ways: !r.directed.unwrap_or(false),
                        start: s,
                        end: e,
                    });
                }
                "partition" => {
                    let Some(ns) = &r.nodes else {
                        self.bad(
                            format!("{key}.nodes"),
                            "partition needs nodes = [ids cut off from the rest]",
                        );
                        continue;
                    };
                    let set: Vec<usize> = ns.iter().filter_map(|&id| idx(self, "nodes", id)).collect();
                    if set.is_empty() || set.len() >= n {
                        self.bad(format!("{key}.nodes"), "must name some but not all nodes");
                    }
                    let Some((s, e)) = window(self) else { continue };
                    out.push(ScheduledFault::Partition {
                        nodes: set,
                        start: s,
                        end: e,
                    });
                }
                "crash" => {
                    let Some(id) = r.node else {
                        self.bad(format!("{key}.node"), "crash needs node = ID");
                        continue;
                    };
                    let Some(node) = idx(self, "node", id) else { continue };
                    let Some(at) = r.at_s.filter(|a| *a >= 0.0 && a.is_finite()) else {
                        self.bad(format!("{key}.at_s"), "crash needs at_s ≥ 0");
                        continue;
                    };
                    if let Some(rs) = r.restart_s {
                        if rs.is_nan() || rs <= at {
                            self.bad(
                                format!("{key}.restart_s"),
                                format!("must be after at_s ({at}), got {rs}"),
                            );
                            continue;
                        }
                    }
                    out.push(ScheduledFault::Crash {
                        node,
                        at,
                        restart: r.restart_s,
                    });
                }
                other => self.bad(
                    format!("{key}.kind"),
                    format!("expected link-down | partition | crash, got `{other}`"),
                ),
            }
        }
        FaultSchedule::new(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_builtin_validates() {
        for (name, _) in builtin::ALL {
            let t = Topology::resolve(name).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(t.name, *name);
        }
    }

    #[test]
    fn problems_name_the_key() {
        let err = Topology::from_toml("[sim]\nrate_hz = -1\n[[node]]\nid=0\nrole='boss'\n", "x.toml").unwrap_err();
        let s = err.to_string();
        assert!(s.contains("sim.rate_hz") && s.contains("node[0].role"), "{s}");
        let err = Topology::from_toml("[sim]\nrat_hz = 1\n", "x.toml").unwrap_err();
        assert!(err.to_string().contains("rat_hz"), "{err}");
    }
}
