//! What a finished campaign writes from its stored records — `runs.csv`, `points.csv`, `sweep.svg`,
//! `manifest.json` and `report.html` — each written whole or not at all. The records are read back from the store every time, so that
//! a campaign run at once and one resumed after a kill write the same bytes.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::points::{points, PointStat, NETWORK};
use super::record::RunRecord;
use super::store::{read_capped, write_atomic, Store};
use super::{cell, Axis, CampaignError, PlanFile};
use simnet_engine::report::plot::{SweepLine, SweepPanel};

/// How a campaign (or one shard of it) was made.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShardInfo {
    /// `I/N`, or `all` for an unsharded campaign.
    pub shard: String,
    pub simnet: String,
    pub command: Vec<String>,
    pub transport: String,
    /// RFC 3339.
    pub started: String,
    pub finished: String,
    /// The cores of the machine that ran it.
    pub cores: usize,
    /// Runs made by it (the rest were in the store already).
    pub ran: usize,
}

/// `manifest.json`: what the campaign is, how and by what it was made.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// simnet's version and, when known, the commit it was built from, of the process that wrote the files.
    pub simnet: String,
    /// The command line that wrote these files.
    pub command: Vec<String>,
    pub topology: String,
    /// The resolved base scenario (TOML) and its SHA-256.
    pub base_scenario: String,
    pub base_sha256: String,
    pub axes: Vec<Axis>,
    pub seeds: u64,
    pub points: usize,
    pub runs: usize,
    pub estimators: Vec<String>,
    /// The earliest start and the latest end of the processes that made the runs.
    pub started: String,
    pub finished: String,
    /// Those processes: this one, or every shard.
    pub made_by: Vec<ShardInfo>,
}

/// The files a finished campaign wrote.
#[derive(Debug)]
pub struct Finished {
    pub runs: usize,
    pub files: Vec<String>,
    pub stats: Vec<PointStat>,
}

/// Where a process that made runs of a campaign leaves its [`ShardInfo`]: a file of its own (a random name), so that
/// every process of a campaign resumed after a kill, or of a shard run twice, stays listed.
fn shard_file(dir: &Path, shard: &str) -> std::path::PathBuf {
    let token = simnet_engine::fresh::token();
    dir.join("shards")
        .join(format!("{}.{token}.json", shard.replace('/', "-of-")))
}

/// Record how this process took part (`shards/I-of-N.RANDOM.json`, `shards/all.RANDOM.json`).
pub fn record_shard(dir: &Path, info: &ShardInfo) -> Result<(), CampaignError> {
    let path = shard_file(dir, &info.shard);
    std::fs::create_dir_all(path.parent().unwrap_or(dir)).map_err(|source| CampaignError::Io {
        path: path.clone(),
        source,
    })?;
    write_atomic(
        &path,
        serde_json::to_string_pretty(info).expect("serialises").as_bytes(),
    )
}

/// Every record of `plan`'s runs in `store`; the files written from them into `store.dir`, or the runs still missing.
/// `me` is this process: recorded in the directory when it made runs, and listed in `manifest.json` with every
/// process recorded there before it.
pub fn finish(store: &Store, plan: &PlanFile, me: &ShardInfo) -> Result<Finished, CampaignError> {
    if me.ran > 0 {
        record_shard(&store.dir, me)?;
    }
    let runs = plan.runs();
    let mut records: Vec<RunRecord> = Vec::with_capacity(runs.len());
    let mut missing = Vec::new();
    for r in &runs {
        match store.get(r, plan)? {
            Some(rec) => records.push(rec),
            None => missing.push(r),
        }
    }
    if let Some(first) = missing.first() {
        return Err(CampaignError::Missing {
            missing: missing.len(),
            total: runs.len(),
            first: format!("{}, seed {}", plan.describe(first.point), first.seed),
        });
    }
    let dir = &store.dir;
    let stats = points(&records, plan.points.len());
    let mut files = Vec::new();
    let mut put = |name: &str, bytes: Vec<u8>| -> Result<(), CampaignError> {
        write_atomic(&dir.join(name), &bytes)?;
        files.push(name.to_string());
        Ok(())
    };
    let mut buf = Vec::new();
    super::write_runs(&mut buf, plan, &records)?;
    put("runs.csv", buf)?;
    let mut buf = Vec::new();
    super::write_points(&mut buf, plan, &stats)?;
    put("points.csv", buf)?;
    let svg = figure(plan, &stats)?;
    put("sweep.svg", svg.clone().into_bytes())?;
    let mut made_by = shards(dir)?;
    if !made_by.contains(me) {
        made_by.push(me.clone());
    }
    let manifest = Manifest {
        simnet: me.simnet.clone(),
        command: me.command.clone(),
        topology: plan.topology.clone(),
        base_scenario: plan.base.clone(),
        base_sha256: plan.base_sha256.clone(),
        axes: plan.axes.clone(),
        seeds: plan.seeds,
        points: plan.points.len(),
        runs: runs.len(),
        estimators: super::estimator_names(&records),
        // RFC 3339 in UTC sorts as text.
        started: made_by.iter().map(|s| s.started.clone()).min().unwrap_or_default(),
        finished: made_by.iter().map(|s| s.finished.clone()).max().unwrap_or_default(),
        made_by,
    };
    put(
        "manifest.json",
        (serde_json::to_string_pretty(&manifest).expect("serialises") + "\n").into_bytes(),
    )?;
    put(
        "report.html",
        super::page::sweep_page(plan, &manifest, &stats, &svg).into_bytes(),
    )?;
    Ok(Finished {
        runs: runs.len(),
        files,
        stats,
    })
}

/// The shards that recorded themselves in `dir`, by shard.
fn shards(dir: &Path) -> Result<Vec<ShardInfo>, CampaignError> {
    let Ok(entries) = std::fs::read_dir(dir.join("shards")) else {
        return Ok(Vec::new());
    };
    let mut out = Vec::new();
    for e in entries.flatten() {
        let path = e.path();
        if path.extension().is_some_and(|x| x == "json") {
            let info: ShardInfo = serde_json::from_str(&read_capped(&path)?).map_err(|err| CampaignError::Damaged {
                path: path.clone(),
                message: err.to_string(),
            })?;
            out.push(info);
        }
    }
    out.sort_by(|a, b| (&a.shard, &a.started).cmp(&(&b.shard, &b.started)));
    Ok(out)
}

/// The figures drawn, with their axis labels.
const FIGURES: [(&str, &str); 3] = [
    ("mean_error", ""),
    ("ratio_to_centralized", "mean error / centralized's"),
    ("disagreement", "disagreement across nodes"),
];

/// `sweep.svg`: each figure against the first key swept over more than one value (one row of panels per combination
/// of the other such keys), one line per estimator with its 95 % band.
pub fn figure(plan: &PlanFile, stats: &[PointStat]) -> Result<String, CampaignError> {
    let Some(xi) = plan
        .x_axis()
        .and_then(|x| plan.axes.iter().position(|a| a.key == x.key))
    else {
        return Ok(simnet_engine::report::plot::sweep(&[], 1, "", None, "no swept key")?);
    };
    let first = &plan.axes[xi];
    let number = |v: &toml::Value| v.as_float().or(v.as_integer().map(|i| i as f64));
    let numeric = first.values.iter().all(|v| number(v).is_some());
    let x_of = |point: usize| -> f64 {
        let v = &plan.points[point].values[xi];
        if numeric {
            number(v).unwrap_or(f64::NAN)
        } else {
            first.values.iter().position(|w| w == v).map_or(f64::NAN, |i| i as f64)
        }
    };
    // Rows: the combinations of the other keys that vary, in point order.
    let others: Vec<usize> = (0..plan.axes.len())
        .filter(|&i| i != xi && plan.axes[i].values.len() > 1)
        .collect();
    let rest =
        |point: usize| -> Vec<toml::Value> { others.iter().map(|&i| plan.points[point].values[i].clone()).collect() };
    let mut combos: Vec<Vec<toml::Value>> = Vec::new();
    for p in 0..plan.points.len() {
        let r = rest(p);
        if !combos.contains(&r) {
            combos.push(r);
        }
    }
    let estimators = super::estimators_of(stats);
    let shown: Vec<(&str, &str)> = FIGURES
        .iter()
        .copied()
        .filter(|(m, _)| {
            stats
                .iter()
                .any(|s| s.metric == *m && s.estimator != NETWORK && s.stat.mean.is_finite())
        })
        .collect();
    let mut panels = Vec::new();
    for combo in combos.iter().take(simnet_engine::report::plot::MAX_SWEEP_ROWS) {
        let at: String = others
            .iter()
            .zip(combo)
            .map(|(&i, v)| format!("{} = {}", plan.axes[i].key, cell(v)))
            .collect::<Vec<_>>()
            .join(", ");
        for (metric, label) in &shown {
            let label = if label.is_empty() {
                plan.model.error_text().label
            } else {
                label
            };
            let lines = estimators
                .iter()
                .filter(|e| !(*metric == "ratio_to_centralized" && e.as_str() == "centralized"))
                .map(|e| SweepLine {
                    label: e.clone(),
                    reference: e == "centralized",
                    // Its place in the registry: an estimator keeps its colour in every plot.
                    colour: simnet_engine::estimators::Kind::rank(e),
                    points: stats
                        .iter()
                        .filter(|s| s.estimator == *e && s.metric == *metric)
                        .filter(|s| rest(s.point) == *combo)
                        .map(|s| (x_of(s.point), s.stat.mean, s.stat.low, s.stat.high))
                        .collect(),
                })
                .filter(|l| l.points.iter().any(|p| p.1.is_finite()))
                .collect();
            panels.push(SweepPanel {
                title: if at.is_empty() {
                    label.to_string()
                } else {
                    format!("{label} · {at}")
                },
                y_desc: format!("{label} (mean over seeds)"),
                lines,
            });
        }
    }
    let names: Vec<String> = first.values.iter().map(cell).collect();
    // Keys held at one value are said in the title.
    let fixed: String = plan
        .axes
        .iter()
        .filter(|a| a.values.len() == 1)
        .map(|a| format!(", {} = {}", a.key, cell(&a.values[0])))
        .collect();
    let more = if combos.len() > simnet_engine::report::plot::MAX_SWEEP_ROWS {
        format!(
            " — first {} of {} combinations",
            simnet_engine::report::plot::MAX_SWEEP_ROWS,
            combos.len()
        )
    } else {
        String::new()
    };
    Ok(simnet_engine::report::plot::sweep(
        &panels,
        shown.len().max(1),
        &first.key,
        (!numeric).then_some(&names[..]),
        &format!(
            "{}{fixed}: against {} ({} seeds per point, 95 % confidence bands){more}",
            plan.topology, first.key, plan.seeds
        ),
    )?)
}
