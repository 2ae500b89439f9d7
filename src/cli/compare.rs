//! `simnet compare`: every estimator on the same scenario over a grid of loss × rounds × seeds, in memory, and
//! the table of mean errors relative to the centralized reference (mean ± standard deviation over the seeds). It is
//! a sweep over `loss` and `rounds`: with `--out DIR` its runs are a campaign's, resumable, with `runs.csv`,
//! `points.csv`, `sweep.svg` and `report.html`.

use super::*;
use crate::campaign::{self, Axis, Plan, PointStat, RunRecord};
use crate::estimators::Kind;
use crate::stats::MeanCi;

#[derive(Args, Debug, Clone)]
pub struct CompareArgs {
    /// Built-in name or a path.
    #[arg(long, short = 't')]
    pub topology: String,
    /// Loss probabilities, comma-separated (Bernoulli on every link).
    #[arg(long, value_delimiter = ',', value_parser = probability, default_values_t = [0.0, 0.1, 0.3])]
    pub loss: Vec<f64>,
    /// Consensus rounds, comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [1u64, 3, 10], value_parser = rounds)]
    pub rounds: Vec<u64>,
    /// Seeds per cell (1, 2, … N).
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u64).range(1..=10_000))]
    pub seeds: u64,
    /// Simulated duration of each run, s (unset: the topology's own).
    #[arg(long, value_parser = positive)]
    pub duration: Option<f64>,
    /// Estimators to compare, comma-separated, or `all`; `centralized`, the reference, is always run. Default: every
    /// one the model can run.
    #[arg(long, value_delimiter = ',', value_parser = super::args::estimator)]
    pub estimators: Option<Vec<super::args::EstimatorChoice>>,
    /// Keep the runs as a campaign in DIR (as `simnet sweep --out`: resumable, with runs.csv, points.csv,
    /// sweep.svg, report.html and manifest.json).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print the table as JSON instead of Markdown.
    #[arg(long)]
    pub json: bool,
    /// With --out, also write runs and points as Parquet (a build with the `parquet` feature).
    #[arg(long, value_enum, default_value = "csv", requires = "out")]
    pub format: Format,
}

/// One cell of the table: a figure's mean, standard deviation and number of seeds that gave it.
#[derive(serde::Serialize)]
struct Figure {
    mean: Option<f64>,
    sd: Option<f64>,
    n: usize,
}

impl Figure {
    fn of(s: Option<&MeanCi>) -> Figure {
        let finite = |v: f64| v.is_finite().then_some(v);
        s.map_or(
            Figure {
                mean: None,
                sd: None,
                n: 0,
            },
            |s| Figure {
                mean: finite(s.mean),
                sd: finite(s.sd),
                n: s.n,
            },
        )
    }

    fn text(&self, seeds: usize) -> String {
        match (self.mean, self.sd) {
            (None, _) => "diverged".to_string(),
            (Some(m), sd) => {
                let sd = sd.map_or(String::new(), |sd| format!(" ± {sd:.3}"));
                let of = if self.n < seeds {
                    format!(" ({} of {seeds})", self.n)
                } else {
                    String::new()
                };
                format!("{m:.3}{sd}{of}")
            }
        }
    }
}

/// One row: a loss and a number of rounds.
#[derive(serde::Serialize)]
struct Row {
    loss: f64,
    rounds: u64,
    centralized_error: Figure,
    /// Each estimator's mean error / centralized's.
    ratio_to_centralized: std::collections::BTreeMap<String, Figure>,
    /// Sequeira's place among the estimators by mean ratio (1 = best), when it ran.
    sequeira_rank: Option<usize>,
}

pub(super) fn compare(args: &CompareArgs, quiet: bool) -> anyhow::Result<ExitCode> {
    let format = args.format.check()?;
    let base = Scenario::resolve(&args.topology)?;
    let mut all = args
        .estimators
        .as_deref()
        .map_or_else(Kind::all, super::args::EstimatorChoice::kinds);
    if !all.contains(&Kind::Centralized) {
        all.push(Kind::Centralized);
        all.sort();
    }
    let list = |v: Vec<String>| v.join(",");
    let axes = [
        format!("loss={}", list(args.loss.iter().map(f64::to_string).collect())),
        format!("rounds={}", list(args.rounds.iter().map(u64::to_string).collect())),
    ]
    .iter()
    .map(|a| Axis::parse(a).map_err(|e| UsageError::Option(format!("--loss/--rounds: {e}"))))
    .collect::<Result<Vec<_>, _>>()?;
    let start = campaign::sweep_base(&base, Some(all), None, args.duration)?;
    // The schemes as validated: "all" is all the model can run.
    let all = start.estimators().run.clone();
    // Every cell's scenario is checked before any run starts.
    let plan = Plan::new(start, axes, args.seeds)?;
    let stats = match &args.out {
        Some(dir) => match super::sweep::run_campaign(&plan, dir, None, super::sweep::Transport::Memory, quiet)? {
            super::sweep::Campaign::Finished(_, done) => {
                let files = super::sweep::files_of(dir, &done, format)?;
                if !quiet {
                    eprintln!("{}", super::sweep::wrote_line(dir, &files, done.runs));
                }
                done.stats
            }
            super::sweep::Campaign::Ended(code) => return Ok(code),
        },
        None => in_memory(&plan, quiet),
    };
    let names: Vec<&str> = all
        .iter()
        .filter(|k| **k != Kind::Centralized)
        .map(|k| k.name())
        .collect();
    let rows = rows(args, &names, &stats);
    let mut out = std::io::stdout().lock();
    if args.json {
        let v = serde_json::json!({
            "topology": base.name(),
            "model": base.model().kind(),
            "duration_s": args.duration.unwrap_or(base.sim().duration_s),
            "seeds": args.seeds,
            "rows": rows,
        });
        writeln!(out, "{}", serde_json::to_string_pretty(&v)?)?;
        return Ok(ExitCode::SUCCESS);
    }
    writeln!(
        out,
        "{} ({} model), {} s per run, {} per cell: mean error / centralized's, mean ± sd over the seeds",
        base.name(),
        base.model().kind(),
        args.duration.unwrap_or(base.sim().duration_s),
        crate::scenario::count(args.seeds as usize, "seed")
    )?;
    writeln!(out)?;
    // One cell per column, header and rows alike (with no scheme beside the reference, too); a rank only where
    // sequeira ran.
    let ranked = names.contains(&"sequeira");
    let header: Vec<&str> = ["loss", "L", "centralized error"]
        .into_iter()
        .chain(names.iter().copied())
        .chain(ranked.then_some("sequeira's rank"))
        .collect();
    writeln!(out, "| {} |", header.join(" | "))?;
    writeln!(out, "|{}", "---|".repeat(header.len()))?;
    let seeds = args.seeds as usize;
    for r in &rows {
        let cells: Vec<String> = [
            format!("{:.0} %", 100.0 * r.loss),
            r.rounds.to_string(),
            r.centralized_error.text(seeds),
        ]
        .into_iter()
        .chain(names.iter().map(|n| r.ratio_to_centralized[*n].text(seeds)))
        .chain(ranked.then(|| {
            r.sequeira_rank
                .map_or("—".to_string(), |k| format!("{k} of {}", names.len()))
        }))
        .collect();
        writeln!(out, "| {} |", cells.join(" | "))?;
    }
    Ok(ExitCode::SUCCESS)
}

/// Every run of the plan in memory, on every core, and the statistics of its points (a campaign's, without a store).
fn in_memory(plan: &Plan, quiet: bool) -> Vec<PointStat> {
    let runs = plan.runs();
    let pb = (!quiet).then(|| {
        progress_bar_of(
            runs.len() as u64,
            "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} runs (eta {eta})",
        )
    });
    let tick = || {
        if let Some(p) = &pb {
            p.inc(1);
        }
    };
    let summaries = crate::par::map(
        &runs,
        |r| {
            plan.scenario(r)
                .map_err(|e| e.to_string())
                .and_then(|s| campaign::in_memory(&s))
        },
        &tick,
    );
    if let Some(p) = pb {
        p.finish_and_clear();
    }
    let mut records = Vec::new();
    for (r, s) in runs.iter().zip(summaries) {
        match s {
            Ok(s) => records.push(RunRecord::of(&r.key, r.point, plan.values(r.point), r.seed, &s)),
            Err(e) => eprintln!("warning: {} seed {}: {e}", plan.describe(r.point), r.seed),
        }
    }
    campaign::points(&records, plan.points.len())
}

/// The table's rows from the points' statistics, loss outermost as the plan orders its points.
fn rows(args: &CompareArgs, names: &[&str], stats: &[PointStat]) -> Vec<Row> {
    let stat = |point: usize, est: &str, metric: &str| {
        stats
            .iter()
            .find(|s| s.point == point && s.estimator == est && s.metric == metric)
            .map(|s| &s.stat)
    };
    let cells = args
        .loss
        .iter()
        .flat_map(|&loss| args.rounds.iter().map(move |&rounds| (loss, rounds)));
    cells
        .enumerate()
        .map(|(point, (loss, rounds))| {
            let ratio_to_centralized: std::collections::BTreeMap<String, Figure> = names
                .iter()
                .map(|n| (n.to_string(), Figure::of(stat(point, n, "ratio_to_centralized"))))
                .collect();
            let mean = |n: &str| ratio_to_centralized[n].mean;
            let sequeira_rank = names.contains(&"sequeira").then(|| {
                let s = mean("sequeira").unwrap_or(f64::INFINITY);
                1 + names.iter().filter(|n| mean(n).is_some_and(|m| m < s)).count()
            });
            Row {
                loss,
                rounds,
                centralized_error: Figure::of(stat(point, "centralized", "mean_error")),
                ratio_to_centralized,
                sequeira_rank,
            }
        })
        .collect()
}
