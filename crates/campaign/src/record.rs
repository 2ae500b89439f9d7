//! One run's result as a campaign keeps it: the network's figures and each estimator's, from its summary — the
//! columns of `runs.csv` and what `points.csv` takes statistics of.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use simnet_engine::Summary;

/// The figures of one estimator in one run.
pub const ESTIMATOR_METRICS: [&str; 11] = [
    "mean_error",
    "median_error",
    "ratio_to_centralized",
    "rms_error",
    "disagreement",
    "fused_error",
    "trace_p",
    "nees",
    "diverged",
    "messages",
    "bytes",
];

/// The figures of the whole network in one run.
pub const NETWORK_METRICS: [&str; 4] = ["loss_rate", "arrival_rate", "fused_error", "socket_losses"];

/// The figures of a radio channel in one run (a run over the pairwise medium has none, and a campaign of such runs
/// no column of them).
pub const RADIO_METRICS: [&str; 4] = ["channel_load", "airtime_s", "energy_j", "mean_power_mw"];

/// One run of a campaign: which, and what it found (`runs/KEY.json` in the store).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunRecord {
    /// [`super::RunSpec::key`].
    pub key: String,
    /// The point's index in the plan that ran it: a reader takes the index from its own plan by `key`, and checks
    /// `values` against that point's.
    pub point: usize,
    /// Every swept key's value at the run's point (records of simnet before 0.1 carry none).
    #[serde(default)]
    pub values: BTreeMap<String, toml::Value>,
    pub seed: u64,
    /// The simnet that ran it (version, and the commit when the build knew it).
    pub simnet: String,
    /// Steps run, and whether the run was cut short.
    pub steps: u64,
    pub interrupted: bool,
    /// [`NETWORK_METRICS`] by name (`None`: not measured, e.g. a network without links).
    pub network: BTreeMap<String, Option<f64>>,
    /// [`ESTIMATOR_METRICS`] of each estimator, by estimator name.
    pub estimators: BTreeMap<String, BTreeMap<String, Option<f64>>>,
}

impl RunRecord {
    pub fn of(key: &str, point: usize, values: BTreeMap<String, toml::Value>, seed: u64, s: &Summary) -> RunRecord {
        let sent: u64 = s.links.iter().map(|l| l.sent).sum();
        let lost: u64 = s.links.iter().map(|l| l.lost).sum();
        let arrival: Vec<f64> = s.links.iter().filter_map(|l| l.arrival_rate).collect();
        let mut network = BTreeMap::from([
            ("loss_rate".to_string(), (sent > 0).then(|| lost as f64 / sent as f64)),
            ("arrival_rate".to_string(), mean(&arrival)),
            ("fused_error".to_string(), s.fused.as_ref().and_then(|f| f.mean_error)),
            ("socket_losses".to_string(), Some(s.socket_losses as f64)),
        ]);
        if let Some(r) = &s.radio {
            let airtime: f64 = r.nodes.iter().map(|n| n.airtime_s).sum();
            let power: Vec<f64> = r.nodes.iter().map(|n| n.mean_power_mw).collect();
            network.extend([
                ("channel_load".to_string(), Some(r.channel_load)),
                ("airtime_s".to_string(), Some(airtime)),
                ("energy_j".to_string(), Some(r.energy_j)),
                ("mean_power_mw".to_string(), mean(&power)),
            ]);
        }
        let estimators = s
            .estimators
            .iter()
            .map(|(name, e)| {
                let over_nodes = |f: &dyn Fn(&simnet_engine::observe::metrics::FilterSummary) -> Option<f64>| {
                    let v: Vec<f64> = e.nodes.iter().filter_map(|n| f(&n.figures)).collect();
                    (v.len() == e.nodes.len()).then(|| mean(&v)).flatten()
                };
                let m = BTreeMap::from([
                    ("mean_error".to_string(), e.mean_error),
                    ("median_error".to_string(), e.median_error),
                    ("ratio_to_centralized".to_string(), e.ratio_to_centralized),
                    ("rms_error".to_string(), over_nodes(&|f| f.rms_error)),
                    ("disagreement".to_string(), e.disagreement),
                    ("fused_error".to_string(), e.fused_error),
                    ("trace_p".to_string(), over_nodes(&|f| f.mean_trace_p_post)),
                    ("nees".to_string(), over_nodes(&|f| f.nees_mean)),
                    ("diverged".to_string(), Some(e.diverged as f64)),
                    ("messages".to_string(), Some(e.messages as f64)),
                    ("bytes".to_string(), Some(e.bytes as f64)),
                ]);
                (name.clone(), m)
            })
            .collect();
        RunRecord {
            key: key.to_string(),
            point,
            values,
            seed,
            simnet: super::simnet_build(),
            steps: s.steps,
            interrupted: s.interrupted,
            network,
            estimators,
        }
    }

    /// This record, read back, checked to be `run` of `plan` (its key, its seed and, where it carries them, the
    /// swept values of the run's point by key) and filed under the point `plan` gives the run, whatever index the
    /// plan that wrote it used.
    pub fn file_under(&mut self, run: &super::RunSpec, plan: &super::PlanFile) -> Result<(), String> {
        if self.key != run.key {
            return Err(format!("it holds run {}", simnet_engine::input::quoted(&self.key)));
        }
        if self.seed != run.seed {
            return Err(format!(
                "it holds seed {}, run {} is seed {}",
                self.seed, run.key, run.seed
            ));
        }
        let values = plan.values(run.point);
        if !self.values.is_empty() && self.values != values {
            let shown = |v: &BTreeMap<String, toml::Value>| {
                v.iter()
                    .map(|(k, x)| format!("{k} = {}", super::cell(x)))
                    .collect::<Vec<_>>()
                    .join(", ")
            };
            // The record's side is the file's: quoted short.
            return Err(format!(
                "it was run at {}, but run {} is at {}",
                simnet_engine::input::quoted(&shown(&self.values)),
                run.key,
                shown(&values)
            ));
        }
        self.point = run.point;
        self.values = values;
        Ok(())
    }

    /// Whether the run was over a radio channel (its record carries [`RADIO_METRICS`]).
    pub fn on_radio(&self) -> bool {
        self.network.contains_key(RADIO_METRICS[0])
    }

    /// A figure by table name: `loss_rate`, or `icf.mean_error`.
    pub fn get(&self, column: &str) -> Option<f64> {
        match column.split_once('.') {
            Some((est, metric)) => self.estimators.get(est)?.get(metric).copied().flatten(),
            None => self.network.get(column).copied().flatten(),
        }
        .filter(|v| v.is_finite())
    }
}

fn mean(v: &[f64]) -> Option<f64> {
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}
