//! The topology file as written: serde mirrors of the TOML with `deny_unknown_fields`, so a misspelt key is an
//! error that names it. `super::validate` turns these into the typed [`super::Scenario`].

use serde::{Deserialize, Serialize};

pub use crate::model::RawModel;

#[derive(Debug, Serialize, Deserialize, Clone, Default)]
#[serde(deny_unknown_fields)]
pub struct RawTopology {
    pub name: Option<String>,
    pub description: Option<String>,
    pub sim: Option<RawSim>,
    pub model: Option<RawModel>,
    pub consensus: Option<RawConsensus>,
    pub link: Option<RawLink>,
    pub sensor: Option<RawSensor>,
    pub estimators: Option<RawEstimators>,
    /// Nodes and edges from a graph generator instead of `[[node]]`/`[[edge]]`.
    pub generate: Option<RawGenerate>,
    pub security: Option<RawSecurity>,
    pub medium: Option<RawMedium>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub node: Vec<RawNode>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub edge: Vec<RawEdge>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub fault: Vec<RawFault>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub attack: Vec<RawAttack>,
}

#[derive(Debug, Serialize, Deserialize, Default, Clone)]
#[serde(deny_unknown_fields)]
pub struct RawSim {
    pub rate_hz: Option<f64>,
    pub duration_s: Option<f64>,
    pub burn_in_s: Option<f64>,
    pub seed: Option<u64>,
    pub trajectory: Option<String>,
    pub deadline_ms: Option<f64>,
    pub split_channels: Option<bool>,
    pub divergence_trace: Option<f64>,
}

#[derive(Debug, Serialize, Deserialize, Default, Clone)]
#[serde(deny_unknown_fields)]
pub struct RawConsensus {
    pub beta0: Option<f64>,
    #[serde(rename = "self")]
    pub self_weight: Option<f64>,
    pub neighbor: Option<f64>,
    pub matrix: Option<Vec<Vec<f64>>>,
    /// A rule for β instead of `matrix` or `self`/`neighbor`: "metropolis".
    pub weights: Option<String>,
    pub lmi: Option<RawLmi>,
    pub inflation: Option<f64>,
    /// The innovation gate: a neighbour's measurement whose normalised innovation squared exceeds the χ² quantile of
    /// this probability is left out of the update.
    pub gate: Option<f64>,
}

/// `[estimators]`: the distributed schemes run beside the node's two filters.
#[derive(Debug, Serialize, Default, Clone)]
pub struct RawEstimators {
    /// Names from `simnet estimators`, or "all".
    pub run: Option<Vec<String>>,
    pub rounds: Option<u64>,
    pub kcf_gamma: Option<f64>,
    pub hcmci_omega: Option<f64>,
    /// The node id of both centralized schemes' fusion center.
    pub sink: Option<i64>,
    /// `[estimators.<name>]`: the own table of a scheme a program registered (the validator names a table of any
    /// other name).
    #[serde(flatten)]
    pub schemes: std::collections::BTreeMap<String, toml::Table>,
}

/// `[estimators]`'s own keys, unknown ones refused as in every other table.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct EstimatorKeys {
    run: Option<Vec<String>>,
    rounds: Option<u64>,
    kcf_gamma: Option<f64>,
    hcmci_omega: Option<f64>,
    sink: Option<i64>,
}

/// Its keys as every table's (a misspelt one refused, naming those it takes), its sub-tables as the schemes'.
impl<'de> Deserialize<'de> for RawEstimators {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<RawEstimators, D::Error> {
        let mut table = toml::Table::deserialize(d)?;
        let names: Vec<String> = table
            .iter()
            .filter(|(_, v)| v.is_table())
            .map(|(k, _)| k.clone())
            .collect();
        let mut schemes = std::collections::BTreeMap::new();
        for name in names {
            if let Some(toml::Value::Table(t)) = table.remove(&name) {
                schemes.insert(name, t);
            }
        }
        let keys = EstimatorKeys::deserialize(toml::Value::Table(table)).map_err(serde::de::Error::custom)?;
        Ok(RawEstimators {
            run: keys.run,
            rounds: keys.rounds,
            kcf_gamma: keys.kcf_gamma,
            hcmci_omega: keys.hcmci_omega,
            sink: keys.sink,
            schemes,
        })
    }
}

#[derive(Debug, Serialize, Deserialize, Default, Clone)]
#[serde(deny_unknown_fields)]
pub struct RawLmi {
    pub alpha: Option<f64>,
    pub gamma: Option<f64>,
    pub enabled: Option<bool>,
}

#[derive(Debug, Serialize, Deserialize, Default, Clone)]
#[serde(deny_unknown_fields)]
pub struct RawLink {
    pub loss: Option<RawLoss>,
    pub delay_ms: Option<f64>,
    pub jitter_ms: Option<f64>,
    pub jitter: Option<String>,
    pub duplicate: Option<f64>,
    pub corrupt: Option<f64>,
}

#[derive(Debug, Serialize, Deserialize, Clone)]
#[serde(deny_unknown_fields)]
pub struct RawLoss {
    /// "bernoulli" or "gilbert-elliott"; left out, Gilbert–Elliott when a key only it has is given, else Bernoulli.
    pub model: Option<String>,
    pub p: Option<f64>,
    pub r: Option<f64>,
    pub one_minus_h: Option<f64>,
    pub one_minus_k: Option<f64>,
    /// Friendly Gilbert–Elliott form: target loss and mean burst.
    pub rate: Option<f64>,
    pub burst: Option<f64>,
}

/// `[security]`: authenticated datagrams.
#[derive(Debug, Serialize, Deserialize, Default, Clone)]
#[serde(deny_unknown_fields)]
pub struct RawSecurity {
    /// The network's key file (`simnet keygen`), relative to the topology file.
    pub key_file: Option<String>,
    /// Authenticate with a key of the run's own (from its seed) where no key file is given: what an in-process run
    /// needs to measure the cost of authentication.
    pub auth: Option<bool>,
}

/// `[medium]`: what carries the datagrams, the independent links of `[link]` and `[[edge]]` or one shared radio
/// channel.
#[derive(Debug, Serialize, Deserialize, Default, Clone)]
#[serde(deny_unknown_fields)]
pub struct RawMedium {
    /// "pairwise" | "radio".
    pub kind: Option<String>,
    pub tx_dbm: Option<f64>,
    pub path_loss_exponent: Option<f64>,
    pub reference_loss_db: Option<f64>,
    pub reference_m: Option<f64>,
    pub sensitivity_dbm: Option<f64>,
    pub ack: Option<bool>,
    pub max_frame_retries: Option<i64>,
    pub shadowing_db: Option<f64>,
    pub shadowing_decorrelation_m: Option<f64>,
}

/// `[generate]`: a graph of `nodes` nodes (ids 0 … n−1) and its undirected edges.
#[derive(Debug, Serialize, Deserialize, Default, Clone)]
#[serde(deny_unknown_fields)]
pub struct RawGenerate {
    /// "ring" | "grid" | "complete" | "random-geometric".
    pub graph: String,
    pub nodes: Option<i64>,
    /// Grid width (default: the nearest square).
    pub columns: Option<i64>,
    /// The random geometric graph's own seed (default 1: the graph stays as the run seed changes).
    pub seed: Option<u64>,
    /// Every k-th node (ids k−1, 2k−1, …) is naive: an estimator without a sensor.
    pub naive_every: Option<i64>,
}

#[derive(Debug, Serialize, Deserialize, Default, Clone)]
#[serde(deny_unknown_fields)]
pub struct RawSensor {
    pub accel_noise: Option<f64>,
    pub gyro_noise: Option<f64>,
    pub accel_bias: Option<[f64; 3]>,
    pub gyro_bias: Option<[f64; 3]>,
    pub accel_drift: Option<[f64; 3]>,
    pub gyro_drift: Option<[f64; 3]>,
    pub pos_noise: Option<f64>,
    pub att_noise: Option<f64>,
    pub mag_noise: Option<f64>,
}

#[derive(Debug, Serialize, Deserialize, Clone)]
#[serde(deny_unknown_fields)]
pub struct RawNode {
    pub id: Option<i64>,
    pub role: Option<String>,
    pub addr: Option<String>,
    pub sensor: Option<RawSensor>,
    pub imu_csv: Option<String>,
    pub position_m: Option<Vec<f64>>,
    pub lever_arm_m: Option<Vec<f64>>,
}

#[derive(Debug, Serialize, Deserialize, Clone)]
#[serde(deny_unknown_fields)]
pub struct RawEdge {
    pub nodes: Vec<i64>,
    pub directed: Option<bool>,
    pub loss: Option<RawLoss>,
    pub delay_ms: Option<f64>,
    pub jitter_ms: Option<f64>,
    pub jitter: Option<String>,
    pub duplicate: Option<f64>,
    pub corrupt: Option<f64>,
}

#[derive(Debug, Serialize, Deserialize, Clone, Default)]
#[serde(deny_unknown_fields)]
pub struct RawFault {
    pub kind: String,
    pub link: Option<Vec<i64>>,
    pub directed: Option<bool>,
    pub nodes: Option<Vec<i64>>,
    pub node: Option<i64>,
    pub start_s: Option<f64>,
    pub end_s: Option<f64>,
    pub at_s: Option<f64>,
    pub restart_s: Option<f64>,
}

/// `[[attack]]`: one adversary (see [`crate::attack`]).
#[derive(Debug, Serialize, Deserialize, Clone, Default)]
#[serde(deny_unknown_fields)]
pub struct RawAttack {
    /// forge | tamper | replay | flood | false-data
    pub kind: String,
    pub target: Option<i64>,
    pub claim: Option<i64>,
    pub node: Option<i64>,
    pub start_s: Option<f64>,
    pub end_s: Option<f64>,
    pub bias: Option<Vec<f64>>,
    pub ramp: Option<Vec<f64>>,
    pub delay_s: Option<f64>,
    pub rate_hz: Option<f64>,
}

impl From<crate::link::LossModel> for RawLoss {
    fn from(l: crate::link::LossModel) -> RawLoss {
        use crate::link::LossModel;
        let none = RawLoss {
            model: None,
            p: None,
            r: None,
            one_minus_h: None,
            one_minus_k: None,
            rate: None,
            burst: None,
        };
        match l {
            LossModel::Bernoulli { p } => RawLoss {
                model: Some("bernoulli".into()),
                p: Some(p),
                ..none
            },
            LossModel::GilbertElliott {
                p,
                r,
                one_minus_h,
                one_minus_k,
            } => RawLoss {
                model: Some("gilbert-elliott".into()),
                p: Some(p),
                r: Some(r),
                one_minus_h: Some(one_minus_h),
                one_minus_k: Some(one_minus_k),
                ..none
            },
        }
    }
}

impl From<&crate::sensor::SensorProfile> for RawSensor {
    fn from(p: &crate::sensor::SensorProfile) -> RawSensor {
        RawSensor {
            accel_noise: Some(p.accel_noise),
            gyro_noise: Some(p.gyro_noise),
            accel_bias: Some(p.accel_bias),
            gyro_bias: Some(p.gyro_bias),
            accel_drift: Some(p.accel_drift),
            gyro_drift: Some(p.gyro_drift),
            pos_noise: Some(p.pos_noise),
            att_noise: Some(p.att_noise),
            mag_noise: Some(p.mag_noise),
        }
    }
}
