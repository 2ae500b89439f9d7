//! `runs.csv` (one row per run: the swept values, the seed, the network's figures and every estimator's) and
//! `points.csv` (one row per point, estimator and figure: mean, sd, n, 95 % confidence interval). Numbers are
//! written as Rust writes an f64 (the shortest text that reads back the same), a missing figure as an empty cell:
//! the same records give the same bytes.

use std::io::Write;

use super::plan::cell;
use super::points::PointStat;
use super::record::{RunRecord, ESTIMATOR_METRICS, NETWORK_METRICS, RADIO_METRICS};
use super::PlanFile;

/// The estimators of `records`, in the order `simnet estimators` lists them (unknown names after, by name).
pub fn estimator_names(records: &[RunRecord]) -> Vec<String> {
    let mut names: Vec<&String> = records.iter().flat_map(|r| r.estimators.keys()).collect();
    names.sort_by_key(|n| (simnet_engine::estimators::Kind::rank(n), *n));
    names.dedup();
    names.into_iter().cloned().collect()
}

fn num(v: Option<f64>) -> String {
    v.filter(|x| x.is_finite()).map_or(String::new(), |x| x.to_string())
}

/// The columns of `runs.csv` after the swept keys and the seed (the radio's where a run had one).
pub fn run_columns(estimators: &[String], radio: bool) -> Vec<String> {
    let mut cols: Vec<String> = NETWORK_METRICS.iter().map(|m| m.to_string()).collect();
    if radio {
        cols.extend(RADIO_METRICS.iter().map(|m| m.to_string()));
    }
    for e in estimators {
        cols.extend(ESTIMATOR_METRICS.iter().map(|m| format!("{e}.{m}")));
    }
    cols
}

/// `runs.csv`, `records` sorted by point and seed.
pub fn write_runs(w: impl Write, plan: &PlanFile, records: &[RunRecord]) -> csv::Result<()> {
    let mut out = csv::Writer::from_writer(w);
    let estimators = estimator_names(records);
    let radio = records.iter().any(RunRecord::on_radio);
    let cols = run_columns(&estimators, radio);
    let mut head = vec!["point".to_string()];
    head.extend(plan.axes.iter().map(|a| a.key.clone()));
    head.extend(["seed".to_string(), "run".to_string(), "steps".to_string()]);
    head.extend(cols.iter().cloned());
    out.write_record(&head)?;
    let mut sorted: Vec<&RunRecord> = records.iter().collect();
    sorted.sort_by_key(|r| (r.point, r.seed));
    for r in sorted {
        let mut row = vec![r.point.to_string()];
        row.extend(plan.points[r.point].values.iter().map(cell));
        row.extend([r.seed.to_string(), r.key.clone(), r.steps.to_string()]);
        row.extend(cols.iter().map(|c| num(r.get(c))));
        out.write_record(&row)?;
    }
    out.flush()?;
    Ok(())
}

/// `points.csv`.
pub fn write_points(w: impl Write, plan: &PlanFile, stats: &[PointStat]) -> csv::Result<()> {
    let mut out = csv::Writer::from_writer(w);
    let mut head = vec!["point".to_string()];
    head.extend(plan.axes.iter().map(|a| a.key.clone()));
    head.extend(
        ["estimator", "metric", "n", "mean", "sd", "ci95_low", "ci95_high"]
            .iter()
            .map(|s| s.to_string()),
    );
    out.write_record(&head)?;
    for s in stats {
        let mut row = vec![s.point.to_string()];
        row.extend(plan.points[s.point].values.iter().map(cell));
        row.extend([s.estimator.clone(), s.metric.clone(), s.stat.n.to_string()]);
        row.extend([s.stat.mean, s.stat.sd, s.stat.low, s.stat.high].map(|v| num(Some(v))));
        out.write_record(&row)?;
    }
    out.flush()?;
    Ok(())
}
