//! Statistics per point: for every figure of every estimator (and of the network), the mean over the seeds, its
//! standard deviation, n, and the 95 % confidence interval of the mean from Student's t.

use serde::{Deserialize, Serialize};

use super::record::{RunRecord, ESTIMATOR_METRICS, NETWORK_METRICS, RADIO_METRICS};
use simnet_engine::stats::MeanCi;

/// The confidence level of every interval.
pub const LEVEL: f64 = 0.95;

/// The estimator column of the network's own figures.
pub const NETWORK: &str = "network";

/// One row of `points.csv`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointStat {
    pub point: usize,
    /// An estimator's name, or [`NETWORK`].
    pub estimator: String,
    pub metric: String,
    #[serde(flatten)]
    pub stat: MeanCi,
}

/// The statistics of every point, in point order, then estimator (the network first), then metric; `records` in
/// any order. A figure that is missing or not finite in a run (a diverged filter) is left out of its n.
pub fn points(records: &[RunRecord], points: usize) -> Vec<PointStat> {
    let mut by_point: Vec<Vec<&RunRecord>> = vec![Vec::new(); points];
    for r in records {
        if let Some(v) = by_point.get_mut(r.point) {
            v.push(r);
        }
    }
    let mut out = Vec::new();
    for (point, runs) in by_point.iter().enumerate() {
        if runs.is_empty() {
            continue;
        }
        let mut estimators: Vec<&str> = runs
            .iter()
            .flat_map(|r| r.estimators.keys())
            .map(String::as_str)
            .collect();
        estimators.sort();
        estimators.dedup();
        let network: Vec<&str> = if runs.iter().any(|r| r.on_radio()) {
            NETWORK_METRICS.iter().chain(&RADIO_METRICS).copied().collect()
        } else {
            NETWORK_METRICS.to_vec()
        };
        let groups =
            std::iter::once((NETWORK, &network[..])).chain(estimators.iter().map(|e| (*e, &ESTIMATOR_METRICS[..])));
        for (estimator, metrics) in groups {
            for metric in metrics {
                let column = if estimator == NETWORK {
                    metric.to_string()
                } else {
                    format!("{estimator}.{metric}")
                };
                let v: Vec<f64> = runs.iter().filter_map(|r| r.get(&column)).collect();
                out.push(PointStat {
                    point,
                    estimator: estimator.to_string(),
                    metric: metric.to_string(),
                    stat: MeanCi::of(&v, LEVEL),
                });
            }
        }
    }
    out
}

/// The estimators of `stats` (not the network), in the order `simnet estimators` lists them.
pub fn estimators_of(stats: &[PointStat]) -> Vec<String> {
    let mut names: Vec<&str> = stats
        .iter()
        .filter(|s| s.estimator != NETWORK)
        .map(|s| s.estimator.as_str())
        .collect();
    names.sort_by_key(|n| (simnet_engine::estimators::Kind::rank(n), *n));
    names.dedup();
    names.into_iter().map(String::from).collect()
}

/// The table a campaign prints and its report shows: per point, the swept values, the measured loss (%) and each
/// estimator's mean error, every figure `mean ± half its 95 % interval`. (header, rows).
pub fn mean_error_table(plan: &super::PlanFile, stats: &[PointStat]) -> (Vec<String>, Vec<Vec<String>>) {
    let names = estimators_of(stats);
    let mut header: Vec<String> = plan.axes.iter().map(|a| a.key.clone()).collect();
    header.push("loss".into());
    header.extend(names.iter().cloned());
    let get = |point: usize, est: &str, metric: &str| {
        stats
            .iter()
            .find(|s| s.point == point && s.estimator == est && s.metric == metric)
            .map_or("—".to_string(), |s| s.stat.text())
    };
    let rows = plan
        .points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let mut r: Vec<String> = p.values.iter().map(super::cell).collect();
            r.push(
                stats
                    .iter()
                    .find(|s| s.point == i && s.estimator == NETWORK && s.metric == "loss_rate")
                    .map_or("—".to_string(), |s| format!("{} %", s.stat.scaled(100.0).text())),
            );
            r.extend(names.iter().map(|n| get(i, n, "mean_error")));
            r
        })
        .collect();
    (header, rows)
}
