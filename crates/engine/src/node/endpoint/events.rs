//! What a node reports: the datagrams it accepted, its counters and its end-of-run report (the rows of
//! `trace.csv`, the step estimates and the LMI terms are [`crate::observe`]'s).

use crate::imu_csv::ImuRow;
use crate::link::LinkCounters;
use crate::observe::metrics::{FilterMetrics, RxBySource};
use crate::observe::TraceRow;
use crate::scenario::Role;

/// A datagram the node accepted as coming from a neighbour (its shell learns addresses and step timing from it).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Arrival {
    pub src: usize,
    pub step: u64,
    pub measurement: bool,
    /// A hello's answer to a probe (0: none).
    pub answer: u64,
}

/// Datagram counters not tied to a link.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct NodeCounters {
    pub datagrams_in: u64,
    /// Undecodable datagrams other than checksum failures (garbage, wrong magic, unknown source, …).
    pub malformed: u64,
    /// Checksum failures of datagrams from known peers.
    pub corrupted: u64,
    /// Measurements for a step this node has not reached yet, held until it does.
    pub early: u64,
    pub restarts: u64,
    pub steps_down: u64,
    /// Networked updates whose LMI terms could not be computed for a protocol search (left out of it).
    #[serde(default)]
    pub lmi_failures: u64,
    /// The first step this node ran (0 unless it joined a running network late).
    pub first_step: u64,
    pub steps_run: u64,
    /// Datagrams refused by authentication, by cause.
    #[serde(default)]
    pub rejected: super::Rejections,
    /// Datagrams whose step lies outside the run, or further ahead of this node's own step than a neighbour can be.
    #[serde(default)]
    pub implausible_step: u64,
    /// Datagrams from an address that is not a neighbour's (one process per node): counted, never used.
    #[serde(default)]
    pub unknown_address: u64,
    /// Datagrams the kernel dropped on this node's socket, its receive buffer full: lost before any rule of the
    /// link layer could decide their fate.
    #[serde(default)]
    pub kernel_drops: u64,
    /// Neighbours' measurements left out of the networked update by the innovation gate.
    #[serde(default)]
    pub gated: u64,
}

/// Everything a node reports at the end of a run.
#[derive(Debug, Clone)]
pub struct NodeReport {
    pub index: usize,
    pub id: u32,
    pub role: Role,
    pub networked: Option<FilterMetrics>,
    pub independent: Option<FilterMetrics>,
    /// The distributed estimators' figures at this node, by kind (estimating nodes).
    pub schemes: Vec<(crate::estimators::Kind, FilterMetrics)>,
    /// What each distributed estimator sent from this node.
    pub traffic: Vec<(crate::estimators::Kind, super::Traffic)>,
    /// Round messages that came after their round closed.
    pub rounds_late: u64,
    /// Outgoing links (sender-side counters).
    pub links_out: Vec<(usize, LinkCounters)>,
    /// What its radio did, on a shared channel ([`crate::medium::Medium::radio`]).
    pub radio: Option<crate::medium::radio::RadioCounters>,
    /// Its frames at each receiver, on a shared channel ([`crate::medium::Medium::radio_links`]).
    pub radio_links: Vec<(usize, crate::medium::radio::LinkQuality)>,
    /// Per-source receive counters, indexed by node index.
    pub rx: RxBySource,
    pub counters: NodeCounters,
    pub trace: Vec<TraceRow>,
    /// The IMU samples with the true pose, when traces are recorded (pose model, sensing nodes).
    pub imu: Vec<ImuRow>,
    /// What became of the datagrams of each attack (by index in the scenario) this node was the target or the
    /// compromised source of.
    pub attacks: Vec<(usize, crate::attack::Tally)>,
}
