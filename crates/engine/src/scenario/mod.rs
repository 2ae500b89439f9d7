//! Scenarios: everything one run needs, validated. A scenario comes from a topology file (TOML) and
//! command-line [`Overrides`] (`resolve.rs`); every problem is reported with the file, the key and what was expected, all of them
//! at once rather than the first.
//!
//! | file | owns |
//! |---|---|
//! | `toml.rs` | the file as written: serde mirrors with `deny_unknown_fields` |
//! | `validate/` | raw → typed: sim, nodes, links, consensus (`mod.rs`), loss, link settings and faults (`link.rs`) |
//! | `resolve.rs` | names → paths → built-ins: the only place a topology file is read |
//! | `load.rs` | recorded IMU files named by `imu_csv` |
//! | `overrides.rs` | command-line overrides, applied and validated again |
//! | `flags.rs` | `simnet run`'s options as plain values ([`Flags`]), for the command line and the Python package |
//! | `builtin.rs` | the topologies compiled into the binary |

pub mod builder;
pub mod builtin;
mod flags;
pub mod graph;
mod keys;
mod load;
mod medium;
pub mod options;
mod overrides;
mod resolve;
pub mod schema;
pub(crate) mod toml;
mod validate;
pub use validate::check_addr;

use std::fmt;
use std::sync::Arc;
use std::time::Duration;

use crate::estimators::weight_in;
use crate::imu_csv::ImuRecording;
use crate::link::{FaultSchedule, LinkConfig};
use crate::model::ModelConfig;
use crate::motion::Trajectory;
use crate::sensor::SensorProfile;
use crate::time::Time;

pub use crate::checks::{Checks, Problem};

/// The validator of a topology: the shared [`Checks`] (its problems, the recordings read) and the scenario's own
/// checks as methods on it (`validate/`, `graph.rs`, `load.rs`).
#[derive(Debug, Default)]
pub(crate) struct Validator(pub(crate) Checks);

impl std::ops::Deref for Validator {
    type Target = Checks;
    fn deref(&self) -> &Checks {
        &self.0
    }
}

impl std::ops::DerefMut for Validator {
    fn deref_mut(&mut self) -> &mut Checks {
        &mut self.0
    }
}
pub use builder::{LinkSpec, ScenarioBuilder};
pub use flags::{parse_set, FlagError, Flags, LossKind, MAX_STEPS};
pub use keys::parse_value;
pub use options::{RunOption, RUN_OPTIONS};
pub use overrides::Overrides;

/// "1 node", "3 nodes".
pub fn count(n: usize, what: &str) -> String {
    format!("{n} {what}{}", if n == 1 { "" } else { "s" })
}

#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    #[error(
        "topology `{name}` not found: not a file, not {}, not a built-in (see `simnet topologies`)",
        resolve::in_topologies(name)
    )]
    NotFound { name: String },
    #[error("{file}: cannot read: {source}")]
    Io { file: String, source: std::io::Error },
    #[error("{file}: {message}")]
    Parse { file: String, message: String },
    #[error("{file}: {}:\n{}", count(problems.len(), "problem"), problems.iter().map(|p| format!("  - {p}")).collect::<Vec<_>>().join("\n"))]
    Invalid { file: String, problems: Vec<Problem> },
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Role {
    /// Senses and estimates.
    Peer,
    /// Senses and sends; runs no filter.
    Sensor,
    /// Estimates from what it receives; has no sensor of its own.
    Estimator,
}

impl fmt::Display for Role {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.pad(self.as_str())
    }
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

#[derive(Debug, Clone, PartialEq)]
pub struct SimConfig {
    pub rate_hz: f64,
    pub duration_s: f64,
    pub burn_in_s: f64,
    /// The burn-in the file asked for, where a shorter `--duration` halved it (see [`Scenario::warnings`]).
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

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmiConfig {
    pub alpha: f64,
    pub gamma: f64,
    pub enabled: bool,
}

/// The consensus weights β, sparse: row i holds the weights node i gives to the measurements it uses (row i =
/// receiving node, by position in the file), so memory grows with the links, not with the square of the nodes.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Beta {
    /// Per row, the non-zero (column, weight), by column.
    rows: Vec<Vec<(usize, f64)>>,
}

impl Beta {
    /// From non-zero (column, weight) per row; zeros are dropped, columns sorted.
    pub fn from_rows(rows: Vec<Vec<(usize, f64)>>) -> Beta {
        let rows = rows
            .into_iter()
            .map(|mut r| {
                r.retain(|(_, b)| *b != 0.0);
                r.sort_by_key(|(j, _)| *j);
                r
            })
            .collect();
        Beta { rows }
    }

    pub fn from_dense(m: &[Vec<f64>]) -> Beta {
        Beta::from_rows(m.iter().map(|r| r.iter().copied().enumerate().collect()).collect())
    }

    /// The n×n matrix (for a protocol search over small networks).
    pub fn to_dense(&self) -> Vec<Vec<f64>> {
        let n = self.rows.len();
        self.rows
            .iter()
            .map(|r| {
                let mut d = vec![0.0; n];
                for &(j, b) in r {
                    d[j] = b;
                }
                d
            })
            .collect()
    }

    /// βᵢⱼ (0 where node i gives node j's measurement no weight).
    pub fn get(&self, i: usize, j: usize) -> f64 {
        self.rows.get(i).map_or(0.0, |r| weight_in(r, j))
    }

    /// Row i's non-zero (column, weight), by column.
    pub fn row(&self, i: usize) -> &[(usize, f64)] {
        self.rows.get(i).map_or(&[], Vec::as_slice)
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct ConsensusConfig {
    pub beta0: f64,
    /// βᵢⱼ: the weight node i gives the measurement of node j.
    pub beta: Beta,
    pub lmi: LmiConfig,
    /// λ of the per-channel inflation R̄ᵢᵢ = λ² Rᵢᵢ for a channel no source delivered.
    pub inflation: f64,
    /// The innovation gate's probability: a neighbour's measurement whose normalised innovation squared exceeds the
    /// χ² quantile of it (degrees of freedom: its rows) is left out of the networked update. None: no gate.
    pub gate: Option<f64>,
}

/// The distributed estimators a run holds beside the node's two filters, and their consensus rounds.
#[derive(Debug, Clone, PartialEq)]
pub struct EstimatorsConfig {
    /// Sorted; empty: only the two filters (`networked` = sequeira and `independent`).
    pub run: Vec<crate::estimators::Kind>,
    /// Message exchanges per step, each with its sub-deadline t_k + D(r+1)/L inside the step.
    pub rounds: usize,
    pub params: crate::estimators::Params,
    /// The schemes a program registered, each set up from its own table (`[estimators.<name>]`, empty when the
    /// file has none): every one the run holds, and any the file gives a table.
    pub configured: std::collections::BTreeMap<crate::estimators::Kind, crate::estimators::Configured>,
    /// The fusion center of `centralized` and `centralized-net` (a sensing node); none without one.
    pub sink: Option<usize>,
    /// The faults of centralized-net's link to the sink from a node the scenario does not link to it.
    pub star_link: LinkConfig,
    /// Each node's Metropolis weights to the nodes it hears from, and to itself ([`crate::estimators::metropolis`]);
    /// empty unless a node runs a scheme.
    pub weights: Arc<Vec<crate::estimators::Weights>>,
}

impl EstimatorsConfig {
    /// A scheme the nodes run over the rounds (not only the two filters or the observer's reference).
    pub fn any_in_node(&self) -> bool {
        self.run.iter().any(|k| k.in_node())
    }
}

/// `[security]`: whether datagrams are authenticated, and with which key.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SecurityConfig {
    /// Every datagram sealed with this key ([`crate::wire::secure`]); none: unauthenticated.
    pub key: Option<crate::wire::secure::Key>,
    /// Where the key came from: the key file, or `seed` (an in-process run's own key, from the run seed).
    pub key_source: Option<String>,
}

/// `[medium]`: what carries the nodes' datagrams.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MediumConfig {
    /// Every directed link decides alone, by its `[link]` and `[[edge]]` rules ([`Scenario::pairwise_medium`]).
    Pairwise,
    /// One shared IEEE 802.15.4 channel between the nodes where the world places them ([`Scenario::radio_medium`]).
    Radio(crate::medium::radio::Radio),
}

/// Most consensus rounds per step.
pub const MAX_ROUNDS: usize = 100;
/// The fastest step rate: a period of a microsecond.
pub const MAX_RATE_HZ: f64 = 1e6;

#[derive(Debug, Clone)]
pub struct NodeConfig {
    /// The id written in the file; nodes are indexed by position everywhere else.
    pub id: u32,
    pub role: Role,
    pub addr: Option<String>,
    pub sensor: SensorProfile,
    /// A recorded IMU that replaces the simulated one (`imu_csv`).
    pub recording: Option<RecordedImu>,
    /// Where it is in the world ([`Scenario::world`]).
    pub place: crate::world::Place,
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

/// A validated scenario. Its fields are read through accessors and changed only through `with*`, which validate the
/// result again: a `Scenario` value is valid by construction.
#[derive(Debug, Clone)]
pub struct Scenario {
    name: String,
    description: String,
    /// Where it came from: a path or `builtin:NAME`.
    source: String,
    sim: SimConfig,
    model: ModelConfig,
    consensus: ConsensusConfig,
    estimators: EstimatorsConfig,
    security: SecurityConfig,
    medium: MediumConfig,
    nodes: Vec<NodeConfig>,
    links: Vec<DirectedLink>,
    /// Indices into `links` of each node's incoming and outgoing links.
    ins: Vec<Vec<usize>>,
    outs: Vec<Vec<usize>>,
    /// Node index by file id.
    by_id: std::collections::HashMap<u32, usize>,
    faults: FaultSchedule,
    /// The adversaries (`[[attack]]`).
    attacks: Vec<crate::attack::Attack>,
    /// The overrides applied since the file was read (the last value of each wins).
    applied: Overrides,
    /// The file as written, with every change since: what a change validates again.
    raw: toml::RawTopology,
}

impl Scenario {
    pub fn name(&self) -> &str {
        &self.name
    }
    pub fn description(&self) -> &str {
        &self.description
    }
    /// Where it came from: a path or `builtin:NAME`.
    pub fn source(&self) -> &str {
        &self.source
    }
    pub fn sim(&self) -> &SimConfig {
        &self.sim
    }
    pub fn model(&self) -> &ModelConfig {
        &self.model
    }
    pub fn consensus(&self) -> &ConsensusConfig {
        &self.consensus
    }
    pub fn estimators(&self) -> &EstimatorsConfig {
        &self.estimators
    }
    pub fn security(&self) -> &SecurityConfig {
        &self.security
    }
    /// What carries the datagrams (`[medium]`).
    pub fn medium(&self) -> &MediumConfig {
        &self.medium
    }
    /// Where every node is at every time: an IMU network's nodes on one body following `sim.trajectory`, each at
    /// its lever arm; a linear system's nodes still at their positions.
    pub fn world(&self) -> crate::world::World {
        let mut w = crate::world::World::new();
        if self.model().get().imu_driven() {
            w.add_body(self.sim().trajectory);
        }
        for n in &self.nodes {
            w.place(n.place);
        }
        w
    }

    /// The nodes in file order; a node's index is its position here.
    pub fn nodes(&self) -> &[NodeConfig] {
        &self.nodes
    }
    pub fn links(&self) -> &[DirectedLink] {
        &self.links
    }
    pub fn faults(&self) -> &FaultSchedule {
        &self.faults
    }
    pub fn attacks(&self) -> &[crate::attack::Attack] {
        &self.attacks
    }
    /// The same scenario without its attacks: the clean run an attacked run is compared with.
    pub fn without_attacks(&self) -> Scenario {
        let mut s = self.clone();
        s.attacks.clear();
        s.raw.attack.clear();
        s
    }
    /// The overrides applied since the file was read (the last value of each wins).
    pub fn applied(&self) -> &Overrides {
        &self.applied
    }
}

impl Scenario {
    /// The time of step k, t_k = k·Δt.
    pub fn step_time(&self, k: u64) -> Time {
        Time::at_step(k, self.sim().dt())
    }

    /// The deadline of step k, t_k + D: what arrives by then is used in step k.
    pub fn deadline(&self, k: u64) -> Time {
        self.step_time(k) + self.deadline_delay()
    }

    /// The sub-deadline of round r of step k, t_k + D(r+1)/L (to the nanosecond below; the last round's is the
    /// step's deadline).
    pub fn round_end(&self, k: u64, r: usize) -> Time {
        let rounds = self.estimators().rounds.max(1) as u64;
        let d = self.deadline_delay().as_nanos() * (r as u128 + 1) / u128::from(rounds);
        self.step_time(k) + Duration::from_nanos(u64::try_from(d).unwrap_or(u64::MAX))
    }

    /// D, from a step's time to its deadline (to the nanosecond).
    pub fn deadline_delay(&self) -> Duration {
        crate::time::nanos(self.sim().deadline_s * 1e9)
    }

    /// Index of the node whose file id is `id`.
    pub fn index_of(&self, id: u32) -> Option<usize> {
        // Most networks number their nodes by index: found without hashing.
        if self.nodes.get(id as usize).is_some_and(|n| n.id == id) {
            return Some(id as usize);
        }
        self.by_id.get(&id).copied()
    }
    /// Directed links into node `i`.
    pub fn in_links(&self, i: usize) -> impl Iterator<Item = &DirectedLink> {
        self.ins.get(i).into_iter().flatten().map(|&li| &self.links[li])
    }
    pub fn out_links(&self, i: usize) -> impl Iterator<Item = &DirectedLink> {
        self.outs.get(i).into_iter().flatten().map(|&li| &self.links[li])
    }
}

impl Scenario {
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
        for n in &self.nodes {
            if let Some(a) = n
                .addr
                .as_deref()
                .filter(|a| a.starts_with("0.0.0.0:") || a.starts_with("[::]:"))
            {
                w.push(format!(
                    "node {}'s addr {a} binds every interface of its host: name the address its peers reach",
                    n.id
                ));
            }
        }
        let late: Vec<f64> = self.faults.starts().map(Time::as_secs).filter(|t| *t >= d).collect();
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
        let late: Vec<usize> = (0..self.attacks.len())
            .filter(|&i| self.attacks[i].start_s >= d)
            .collect();
        if !late.is_empty() {
            let which: Vec<String> = late.iter().map(|i| format!("attack[{i}]")).collect();
            w.push(format!(
                "{} after the run ends at {d} s: never under way",
                which.join(", ") + " start"
            ));
        }
        w
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sparse weights are the dense matrix: round trip, lookups, rows without zeros.
    #[test]
    fn sparse_beta_is_the_dense_matrix() {
        let dense = vec![vec![0.6, 0.2, 0.0], vec![0.0, 1.0, 0.0], vec![0.3, 0.0, 0.7]];
        let b = Beta::from_dense(&dense);
        assert_eq!(b.to_dense(), dense);
        assert_eq!(
            (b.get(0, 1), b.get(1, 0), b.get(2, 2), b.get(9, 9)),
            (0.2, 0.0, 0.7, 0.0)
        );
        assert_eq!(b.row(2), &[(0, 0.3), (2, 0.7)]);
        assert_eq!(
            Beta::from_rows(vec![vec![(2, 0.5), (0, 0.0), (1, 0.25)]]).row(0),
            &[(1, 0.25), (2, 0.5)]
        );
        // A built-in's weights: self and neighbours on every ring node, nothing else.
        let ring = Scenario::resolve("ring3").unwrap();
        for i in 0..3 {
            let row = ring.consensus().beta.row(i);
            assert_eq!(row.len(), 3);
            assert!(row.iter().all(|(_, w)| *w > 0.0));
        }
    }
}
