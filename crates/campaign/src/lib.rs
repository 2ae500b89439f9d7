//! Campaigns (the crate `simnet-campaign`, shared by the CLI and the Python package): one scenario swept over any of its keys × seeds, run on every core, each run stored under the digest
//! of its resolved scenario and seed so that a campaign killed half-way runs only what is missing when started
//! again, and statistics with confidence intervals per point.
//!
//! # Layout
//!
//! | file | owns |
//! |---|---|
//! | `plan.rs` | the swept keys ([`Axis`]: `KEY=V1,V2` or `START:END:STEP`), their product ([`Point`]s), every point validated before a run starts, the runs ([`RunSpec`]) and shards |
//! | `record.rs` | one run's figures as stored ([`RunRecord`]): the network's and every estimator's |
//! | `points.rs` | per point, estimator and figure: mean, sd, n, Student-t 95 % interval ([`PointStat`]) |
//! | `store.rs` | the directory: `plan.json`, `runs/KEY.json`, writes that are whole or absent |
//! | `tables.rs` | `runs.csv` and `points.csv` |
//! | `outputs.rs` | the files a finished campaign writes from its records: tables, `sweep.svg`, `manifest.json`, `report.html` |
//! | `stack.rs` | a Docker Swarm stack that runs the shards of a campaign as the tasks of one service |
//!
//! A campaign is run by [`execute`] with a function that makes a run's [`Summary`] from its scenario (in memory
//! with [`in_memory`], or over sockets by the caller): the runs missing from the store ([`run_missing`]), then the
//! campaign's files once the store holds them all ([`finish`]).

mod outputs;
pub mod page;
mod plan;
mod points;
mod record;
mod stack;
mod store;
mod tables;

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};

use serde::{Deserialize, Serialize};

use simnet_engine::scenario::{Scenario, ScenarioError};
use simnet_engine::Summary;

pub use outputs::{figure, finish, record_shard, Finished, Manifest, ShardInfo};
pub use plan::{cell, parse_shard, shard, Axis, Plan, Point, RunSpec, MAX_RUNS, MAX_VALUES};
pub use points::{estimators_of, mean_error_table, points, PointStat, LEVEL, NETWORK};
pub use record::{RunRecord, ESTIMATOR_METRICS, NETWORK_METRICS, RADIO_METRICS};
pub use stack::{stack_file, StackOptions};
pub use store::{read_capped, write_atomic, Store};
pub use tables::{estimator_names, write_points, write_runs};

#[derive(Debug, thiserror::Error)]
pub enum CampaignError {
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    #[error("{}: {source}", path.display())]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{}: not a file this campaign wrote ({message})", path.display())]
    Damaged { path: PathBuf, message: String },
    #[error("{}: holds another campaign ({why}); choose another --out, or remove it", dir.display())]
    OtherCampaign { dir: PathBuf, why: String },
    #[error("{missing} of {total} runs are missing, first {first}")]
    Missing {
        missing: usize,
        total: usize,
        first: String,
    },
    #[error("{0}")]
    Plot(#[from] simnet_engine::report::plot::PlotError),
    #[error("writing a table: {0}")]
    Csv(#[from] csv::Error),
}

impl CampaignError {
    /// Bad input (exit 2): a scenario, a directory or a file that is not this campaign's.
    pub fn is_usage(&self) -> bool {
        matches!(
            self,
            CampaignError::Scenario(_) | CampaignError::Damaged { .. } | CampaignError::OtherCampaign { .. }
        )
    }
}

/// simnet's version, and the git commit it was built from when known.
pub fn simnet_build() -> String {
    match option_env!("SIMNET_GIT_COMMIT") {
        Some(c) => format!("{} ({c})", env!("CARGO_PKG_VERSION")),
        None => env!("CARGO_PKG_VERSION").to_string(),
    }
}

/// A point as `plan.json` keeps it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlanPoint {
    pub values: Vec<toml::Value>,
    /// [`Scenario::digest`] of the point's scenario.
    pub digest: String,
}

/// `plan.json`: what a campaign runs, enough to list its runs and name its points without the scenario (what
/// `sweep merge` reads).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlanFile {
    pub topology: String,
    /// The estimation model (the unit of the errors).
    pub model: simnet_engine::model::Kind,
    /// The base scenario as TOML, and its SHA-256.
    pub base: String,
    pub base_sha256: String,
    pub axes: Vec<Axis>,
    pub seeds: u64,
    pub points: Vec<PlanPoint>,
}

impl PlanFile {
    /// `plan.json` as read from a file, checked ([`PlanFile::check`]).
    pub fn parse(text: &str) -> Result<PlanFile, String> {
        let p: PlanFile = serde_json::from_str(text).map_err(|e| e.to_string())?;
        p.check()?;
        Ok(p)
    }

    pub fn of(plan: &Plan) -> PlanFile {
        PlanFile {
            topology: plan.base.name().to_string(),
            model: plan.base.model().kind(),
            base: plan.base.to_toml(),
            base_sha256: plan.base.digest(),
            axes: plan.axes.clone(),
            seeds: plan.seeds,
            points: plan
                .points
                .iter()
                .map(|p| PlanPoint {
                    values: p.values.clone(),
                    digest: p.digest.clone(),
                })
                .collect(),
        }
    }

    /// Whether this plan (as read from a file) is one simnet writes: seeds and runs within the bounds a campaign
    /// has, each point the product of the axes at its index, each digest a SHA-256 — checked before anything is
    /// allocated by its size, so that a crafted `plan.json` is an error naming what is wrong.
    pub fn check(&self) -> Result<(), String> {
        if self.seeds == 0 {
            return Err("`seeds` is 0".into());
        }
        let mut points: usize = 1;
        for (i, a) in self.axes.iter().enumerate() {
            if a.values.is_empty() || a.values.len() > MAX_VALUES {
                return Err(format!(
                    "axis `{}` has {} values (1 to {MAX_VALUES})",
                    a.key,
                    a.values.len()
                ));
            }
            if self.axes[..i].iter().any(|b| b.key == a.key) {
                return Err(format!("axis `{}` is given twice", a.key));
            }
            points = points.saturating_mul(a.values.len());
        }
        if points != self.points.len() {
            return Err(format!(
                "its axes make {points} points, but it lists {}",
                self.points.len()
            ));
        }
        if (points as u128) * (self.seeds as u128) > MAX_RUNS as u128 {
            return Err(format!(
                "{points} points × {} seeds is more than {MAX_RUNS} runs",
                self.seeds
            ));
        }
        for (i, p) in self.points.iter().enumerate() {
            if p.values != plan::combination(&self.axes, i) {
                return Err(format!("point {i} does not hold the axes' values at its index"));
            }
            if p.digest.len() != 64 || !p.digest.bytes().all(|b| b.is_ascii_hexdigit()) {
                return Err(format!("point {i}'s digest is not a SHA-256"));
            }
        }
        Ok(())
    }

    /// Every swept key's value at point `i`.
    pub fn values(&self, i: usize) -> std::collections::BTreeMap<String, toml::Value> {
        plan::values_by_key(&self.axes, &self.points[i].values)
    }

    /// Every run, point-major and seed-minor (the list [`Plan::runs`] gives).
    pub fn runs(&self) -> Vec<RunSpec> {
        plan::runs_of(self.points.iter().map(|p| p.digest.as_str()), self.seeds)
    }

    /// Why `other` is not the same campaign, if it is not.
    pub fn differs(&self, other: &PlanFile) -> Option<String> {
        if self.base_sha256 != other.base_sha256 {
            Some(format!(
                "its base scenario is {} {}, not {} {}",
                self.topology,
                &self.base_sha256[..12.min(self.base_sha256.len())],
                other.topology,
                &other.base_sha256[..12.min(other.base_sha256.len())]
            ))
        } else if self.axes != other.axes {
            let keys = |p: &PlanFile| p.axes.iter().map(|a| a.key.as_str()).collect::<Vec<_>>().join(", ");
            Some(format!(
                "it sweeps [{}] with other values than [{}]",
                keys(self),
                keys(other)
            ))
        } else if self.seeds != other.seeds {
            Some(format!("it runs {} seeds per point, not {}", self.seeds, other.seeds))
        } else if self.points != other.points {
            Some("its points name other scenarios".into())
        } else {
            None
        }
    }

    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a plan always serialises")
    }

    /// The key the plots run along: the first swept over more than one value (else the first).
    pub fn x_axis(&self) -> Option<&Axis> {
        self.axes.iter().find(|a| a.values.len() > 1).or(self.axes.first())
    }

    /// `key = value, …` of point `i`.
    pub fn describe(&self, i: usize) -> String {
        self.axes
            .iter()
            .zip(&self.points[i].values)
            .map(|(a, v)| format!("{} = {}", a.key, cell(v)))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// The scenario a sweep's runs start from: `base` with the sweep's estimators (unset: the topology's, else
/// independent and sequeira, the node's two filters), rounds and duration.
pub fn sweep_base(
    base: &Scenario,
    estimators: Option<Vec<simnet_engine::estimators::Kind>>,
    rounds: Option<u64>,
    duration_s: Option<f64>,
) -> Result<Scenario, ScenarioError> {
    use simnet_engine::estimators::Kind;
    let estimators = match estimators {
        None if base.estimators().run.is_empty() => Some(vec![Kind::Independent, Kind::Sequeira]),
        e => e,
    };
    base.with(&simnet_engine::Overrides {
        estimators,
        rounds,
        duration_s,
        ..Default::default()
    })
}

/// One run in memory ([`simnet_engine::Sim`]).
pub fn in_memory(s: &Scenario) -> Result<Summary, String> {
    simnet_engine::Sim::new(s)
        .and_then(|sim| sim.run())
        .map(|r| r.summary())
        .map_err(|e| e.to_string())
}

/// Who runs a campaign, as its manifest records it.
#[derive(Debug, Clone)]
pub struct Runner {
    /// `I/N` for shard I of N, `all` for a whole campaign.
    pub shard: String,
    /// The command that ran it (`simnet sweep …`, or the Python call).
    pub command: Vec<String>,
    /// `memory` or `udp`.
    pub transport: String,
}

/// What [`execute`] did: the runs, and the campaign's files once the store holds every run of the plan
/// ([`CampaignError::Missing`] while some are not there: stopped, failed, or another shard's).
#[derive(Debug)]
pub struct Executed {
    pub ran: Ran,
    pub finished: Result<Finished, CampaignError>,
}

/// A campaign, as `simnet sweep` and Python's `simnet.sweep` both run it: the runs of `runs` (the plan's, or one
/// shard's) missing from `store`, on every core ([`run_missing`]), then its files when it is whole ([`finish`]),
/// with who ran it, when, on how many cores and how many runs in the manifest.
#[allow(clippy::too_many_arguments)]
pub fn execute(
    plan: &Plan,
    runs: &[RunSpec],
    store: &Store,
    who: Runner,
    run: &(dyn Fn(&Scenario) -> Result<Summary, String> + Sync),
    tick: &(dyn Fn() + Sync),
    stop: &AtomicBool,
) -> Executed {
    let started = now();
    let ran = run_missing(plan, runs, store, run, tick, stop);
    let me = ShardInfo::of(who, started, ran.ran);
    let finished = finish(store, &PlanFile::of(plan), &me);
    Executed { ran, finished }
}

impl ShardInfo {
    /// The record of this process: `who` ran `ran` runs from `started` ([`now`]) until now, with this build of
    /// simnet, on this machine's cores.
    pub fn of(who: Runner, started: String, ran: usize) -> ShardInfo {
        ShardInfo {
            shard: who.shard,
            simnet: simnet_build(),
            command: who.command,
            transport: who.transport,
            started,
            finished: now(),
            cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
            ran,
        }
    }
}

/// The wall clock's time, RFC 3339 to the second: when a shard started and finished (provenance, never a figure).
pub fn now() -> String {
    humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string()
}

/// What [`run_missing`] did.
#[derive(Debug, Default)]
pub struct Ran {
    /// Runs made and stored now.
    pub ran: usize,
    /// Runs whose record was there already.
    pub kept: usize,
    /// Runs not started because `stop` was set.
    pub stopped: usize,
    /// Runs that failed, with why (no record stored: a rerun tries them again).
    pub failed: Vec<(RunSpec, String)>,
}

/// Every run of `runs` whose record `store` lacks, over every core: `run` makes its summary from its scenario,
/// `tick` is called once per run of `runs` (kept ones at once), and once `stop` is set no further run starts.
pub fn run_missing(
    plan: &Plan,
    runs: &[RunSpec],
    store: &Store,
    run: &(dyn Fn(&Scenario) -> Result<Summary, String> + Sync),
    tick: &(dyn Fn() + Sync),
    stop: &AtomicBool,
) -> Ran {
    let (kept, todo): (Vec<&RunSpec>, Vec<&RunSpec>) = runs.iter().partition(|r| store.has(&r.key));
    kept.iter().for_each(|_| tick());
    enum Outcome {
        Ran,
        Stopped,
        Failed(String),
    }
    let outcomes = simnet_engine::par::map(
        &todo,
        |r| {
            if stop.load(Ordering::Relaxed) {
                return Outcome::Stopped;
            }
            let summary = plan.scenario(r).map_err(|e| e.to_string()).and_then(|s| run(&s));
            match summary {
                // A run cut short by a stop is not a result: it is not stored.
                Ok(s) if s.interrupted => Outcome::Stopped,
                Ok(s) => match store.put(&RunRecord::of(&r.key, r.point, plan.values(r.point), r.seed, &s)) {
                    Ok(()) => Outcome::Ran,
                    Err(e) => Outcome::Failed(e.to_string()),
                },
                Err(e) => Outcome::Failed(e),
            }
        },
        tick,
    );
    let mut out = Ran {
        kept: kept.len(),
        ..Default::default()
    };
    for (r, o) in todo.into_iter().zip(outcomes) {
        match o {
            Outcome::Ran => out.ran += 1,
            Outcome::Stopped => out.stopped += 1,
            Outcome::Failed(e) => out.failed.push((r.clone(), e)),
        }
    }
    out
}
