//! The `summary.json` schema. `build.rs` makes a summary from a run, `table.rs` prints it, `csv.rs` writes
//! `links.csv`.

mod attacks;
mod build;
mod csv;
mod estimators;
mod radio;
mod table;

pub use attacks::{AttackEffect, AttackSummary};
pub use csv::write_links;
pub use estimators::{EstimatorNode, EstimatorSummary};
pub use radio::{LinkRadio, NodeRadio, RadioSummary};
pub(crate) use table::{figure, trace_figure};

use serde::{Deserialize, Serialize};

use crate::observe::fusion::FusedSummary;
use crate::observe::metrics::FilterSummary;

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct NodeSummary {
    pub id: u32,
    pub role: crate::scenario::Role,
    pub networked: Option<FilterSummary>,
    pub independent: Option<FilterSummary>,
    /// networked mean error / independent mean error.
    pub error_ratio: Option<f64>,
    pub malformed: u64,
    pub corrupted: u64,
    pub restarts: u64,
    pub steps_down: u64,
    /// Datagrams refused by authentication, by cause.
    #[serde(default)]
    pub rejected: crate::node::Rejections,
    /// Datagrams claiming a step outside the run, or further ahead of this node's than a neighbour can be.
    #[serde(default)]
    pub implausible_step: u64,
    /// Datagrams from an address that is no neighbour's, not authenticated (one process per node).
    #[serde(default)]
    pub unknown_address: u64,
    /// Neighbours' measurements the innovation gate left out of the networked update.
    #[serde(default)]
    pub gated: u64,
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct LinkSummary {
    pub from: u32,
    pub to: u32,
    pub sent: u64,
    pub delivered: u64,
    /// Never usable: dropped by the loss model or a scheduled fault, or lost in the socket layer.
    pub lost: u64,
    pub lost_random: u64,
    pub lost_down: u64,
    pub late: u64,
    pub duplicated: u64,
    pub corrupted: u64,
    pub loss_rate: Option<f64>,
    pub delivered_fraction: Option<f64>,
    /// γ: the fraction of the receiver's steps in which a measurement from the sender arrived in time (Sinopoli's
    /// arrival rate).
    pub arrival_rate: Option<f64>,
    pub mean_loss_run: f64,
    pub longest_loss_run: u64,
    /// The sender's measurements the receiver's innovation gate left out.
    #[serde(default)]
    pub gated: u64,
    /// Datagrams the sender numbered for the receiver that never came intact, as the receiver counts them from
    /// the gaps in their sequence numbers (every datagram, measurements, rounds and hellos, where `sent` counts
    /// transmissions; without estimators and hellos, `lost + corrupted`).
    #[serde(default)]
    pub seq_gaps: u64,
    /// On a radio channel: the sender's frames at the receiver (distance, RSSI, SINR, PRR).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub radio: Option<LinkRadio>,
}

/// How a run was set up, so that a result file says how it was made.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Settings {
    pub duration_s: f64,
    pub burn_in_s: f64,
    pub deadline_s: f64,
    pub trajectory: crate::motion::Trajectory,
    pub split_channels: bool,
    /// Consensus rounds per step (1 unless the run holds distributed estimators).
    #[serde(default = "one")]
    pub rounds: usize,
    /// The command-line (or environment) overrides applied to the file.
    pub overrides: crate::scenario::Overrides,
    /// Every directed link's resolved settings (loss model, delay, jitter, duplication, corruption).
    pub links: Vec<LinkSetting>,
    /// The resolved scenario: the TOML that reproduces this run (`simnet -t FILE`), overrides included.
    #[serde(default)]
    pub scenario: String,
    /// Its SHA-256 ([`crate::Scenario::digest`]).
    #[serde(default)]
    pub scenario_sha256: String,
    /// The `[[fault]]` windows (crashes, links down, partitions) by node id; absent from runs without one.
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub faults: Vec<crate::link::FaultWindow>,
}

fn one() -> usize {
    1
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct LinkSetting {
    pub from: u32,
    pub to: u32,
    #[serde(flatten)]
    pub config: crate::link::LinkConfig,
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Summary {
    /// The simnet version that made this file.
    #[serde(default)]
    pub simnet_version: String,
    pub topology: String,
    pub source: String,
    pub model: crate::model::Kind,
    pub seed: u64,
    pub clock: Clock,
    pub rate_hz: f64,
    pub steps: u64,
    pub burn_in_steps: u64,
    pub interrupted: bool,
    /// What the machine and its load decided, not the run: left out of every comparison of two runs.
    #[serde(default)]
    pub transport: Transport,
    /// Frames of the virtual clock lost in the socket layer (each carries one step's datagrams on one link).
    pub socket_losses: u64,
    pub nodes: Vec<NodeSummary>,
    pub links: Vec<LinkSummary>,
    pub fused: Option<FusedSummary>,
    /// Every estimator the run held (`[estimators] run`, `--estimators`), by name; absent when it held none.
    #[serde(skip_serializing_if = "std::collections::BTreeMap::is_empty", default)]
    pub estimators: std::collections::BTreeMap<String, EstimatorSummary>,
    #[serde(default)]
    pub settings: Option<Settings>,
    /// Set in the part a `simnet node` writes; absent from whole-run summaries.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub part: Option<PartInfo>,
    /// Authenticated datagrams: where the key came from and what was refused; absent from unauthenticated runs.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub security: Option<SecuritySummary>,
    /// What each `[[attack]]` did; absent from runs without one.
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub attacks: Vec<AttackSummary>,
    /// Each estimating node's error beside the same seed's clean run (set by [`Summary::compare_clean`]).
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub attack_effect: Vec<AttackEffect>,
    /// The radio channel: per node its frames, airtime and energy; absent from runs over the pairwise medium.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub radio: Option<RadioSummary>,
}

/// How a run's datagrams were authenticated.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct SecuritySummary {
    /// AES-128-CCM, 8-byte tags.
    pub aead: String,
    /// The key file, or `seed` (an in-process run's own key).
    pub key: String,
    /// Datagrams refused by authentication at every node, by cause.
    pub rejected: crate::node::Rejections,
}

/// How far a wall-clock run fell behind its schedule: each node step's start against t₀ + k·Δt.
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize, PartialEq)]
pub struct Schedule {
    /// The largest lag of a step's start behind its scheduled time, ms.
    pub max_lag_ms: f64,
    /// Node-steps that started more than one period late (their deadline had passed).
    pub late_steps: u64,
    /// Node-steps measured.
    pub steps: u64,
}

impl Schedule {
    /// One step that started `lag_s` behind its schedule, with period `dt`.
    pub fn record(&mut self, lag_s: f64, dt: f64) {
        self.max_lag_ms = self.max_lag_ms.max(lag_s * 1e3);
        self.late_steps += u64::from(lag_s > dt);
        self.steps += 1;
    }

    pub fn merge(&mut self, o: &Schedule) {
        self.max_lag_ms = self.max_lag_ms.max(o.max_lag_ms);
        self.late_steps = self.late_steps.saturating_add(o.late_steps);
        self.steps = self.steps.saturating_add(o.steps);
    }
}

/// The `transport` section of `summary.json`: what depends on the machine and its load, not on the run — the wall
/// time, frames the kernel dropped on a full socket buffer and the virtual clock sent again, and how far a
/// wall-clock run fell behind its schedule. A resent frame leaves every result unchanged, so two runs of one scenario
/// and seed agree on everything outside this section ([`Summary::reproducible`]). `socket_losses` is not in it: a
/// frame lost for good changes what the nodes estimate.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct Transport {
    pub wall_s: f64,
    /// Frames of the virtual clock sent again because a receiver asked for them (the kernel had dropped them).
    #[serde(default)]
    pub frames_resent: u64,
    /// Datagrams the kernel dropped on each node's socket (its receive buffer full), by node id; nodes without a
    /// drop are left out.
    #[serde(default)]
    pub kernel_drops: std::collections::BTreeMap<u32, u64>,
    /// How far the wall-clock runs fell behind their schedule; absent from virtual-clock runs.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub schedule: Option<Schedule>,
}

impl Transport {
    /// Every node's kernel drops.
    pub fn kernel_drops_total(&self) -> u64 {
        self.kernel_drops.values().sum()
    }
}

/// The key of `summary.json` that [`Summary::reproducible`] clears: the [`Transport`] section.
pub const LOAD_DEPENDENT: &str = "transport";

impl Summary {
    /// This summary with its [`Transport`] section cleared: what two runs of one scenario and seed give alike, in
    /// memory or over UDP on the virtual clock, on a quiet machine or a loaded one.
    pub fn reproducible(&self) -> Summary {
        Summary {
            transport: Transport::default(),
            ..self.clone()
        }
    }

    /// (networked, independent) scored errors of every estimating node whose error was measured
    /// ([`FilterSummary::scored_error`]).
    pub fn scored_errors(&self) -> Vec<(f64, f64)> {
        self.nodes
            .iter()
            .filter_map(|n| {
                let (a, b) = (n.networked.as_ref()?, n.independent.as_ref()?);
                Some((a.scored_error()?, b.scored_error()?))
            })
            .collect()
    }

    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a summary always serialises")
    }
}

/// What a part adds to the summary schema.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct PartInfo {
    pub node: u32,
    pub first_step: u64,
    pub steps_done: u64,
    /// Sender-side counters of each outgoing link, by destination id.
    pub links_out: Vec<(u32, crate::link::LinkCounters)>,
    /// Receiver-side counters, by source id.
    pub rx: Vec<(u32, crate::observe::metrics::RxCounters)>,
    /// How the observer fuses this run's estimates.
    pub fusion: crate::model::FusionLayout,
    /// The run the node took part in (the smallest boot epoch its neighbours agreed on): parts of one run share it.
    #[serde(default)]
    pub run: Option<u64>,
}

/// How a run's steps were clocked.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Clock {
    /// Lockstep: each step's datagrams are exchanged before it closes (in memory or over sockets).
    Virtual,
    /// Every node paces itself on the wall clock; delay and jitter are real waits.
    Realtime,
    /// One node per process, each on its own wall clock (`simnet node`, merged by `simnet collect`).
    MultiHost,
}

impl Clock {
    pub fn as_str(self) -> &'static str {
        match self {
            Clock::Virtual => "virtual",
            Clock::Realtime => "realtime",
            Clock::MultiHost => "multi-host",
        }
    }
}

impl std::fmt::Display for Clock {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.pad(self.as_str())
    }
}
