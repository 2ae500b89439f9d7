//! `simnet compare`: every estimator on the same scenario over a grid of loss × rounds × seeds, in memory, and
//! the table of mean errors relative to the centralized reference (mean ± standard deviation over the seeds). It is
//! a sweep over `loss` and `rounds`: with `--out DIR` its runs are a campaign's, resumable, with `runs.csv`,
//! `points.csv`, `sweep.svg` and `report.html`. On a radio channel ([`radio`]) each estimator runs alone and pays
//! its airtime and energy; `--plot` draws error against what each one spends.

mod radio;

use super::*;
use crate::campaign::{self, Axis, Plan, PointStat, RunRecord};
use crate::estimators::Kind;
use crate::scenario::MediumConfig;
use crate::stats::MeanCi;

#[derive(Args, Debug, Clone)]
pub struct CompareArgs {
    /// Built-in name or a path.
    #[arg(long, short = 't')]
    pub topology: String,
    /// Loss probabilities, comma-separated (Bernoulli on every link) [default: 0,0.1,0.3]; not on a radio channel,
    /// which decides loss itself.
    #[arg(long, value_delimiter = ',', value_parser = probability)]
    pub loss: Option<Vec<f64>>,
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
    /// Write error against what each estimator spends as SVG: the channel's load on a radio, the kB a node sends a
    /// second otherwise (one --loss value); each estimator × rounds a point.
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

/// The loss values of a comparison over the pairwise medium.
const LOSS: [f64; 3] = [0.0, 0.1, 0.3];

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
        self.text_as(seeds, 3, 1.0, "")
    }

    /// The figure times `scale`, to `digits` decimals, followed by `unit`.
    fn text_as(&self, seeds: usize, digits: usize, scale: f64, unit: &str) -> String {
        match (self.mean, self.sd) {
            (None, _) => "diverged".to_string(),
            (Some(m), sd) => {
                let m = m * scale;
                let sd = sd.map_or(String::new(), |sd| format!(" ± {:.digits$}", sd * scale));
                let of = if self.n < seeds {
                    format!(" ({} of {seeds})", self.n)
                } else {
                    String::new()
                };
                format!("{m:.digits$}{sd}{unit}{of}")
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
    let radio = matches!(base.medium(), MediumConfig::Radio(_));
    let start = campaign::sweep_base(&base, Some(all), None, args.duration)?;
    // The schemes as validated: "all" is all the model can run.
    let all = start.estimators().run.clone();
    let names: Vec<&str> = all
        .iter()
        .filter(|k| **k != Kind::Centralized)
        .map(|k| k.name())
        .collect();
    let axes = if radio {
        radio::axes(args, &names)?
    } else {
        let list = |v: Vec<String>| v.join(",");
        [
            format!("loss={}", list(losses(args).iter().map(f64::to_string).collect())),
            format!("rounds={}", list(args.rounds.iter().map(u64::to_string).collect())),
        ]
        .iter()
        .map(|a| Axis::parse(a).map_err(|e| UsageError::Option(format!("--loss/--rounds: {e}"))))
        .collect::<Result<Vec<_>, _>>()?
    };
    if let Some(dir) = args.plot.as_deref().and_then(Path::parent) {
        if !dir.as_os_str().is_empty() && !dir.is_dir() {
            return Err(UsageError::Option(format!("--plot: {} is not a directory", dir.display())).into());
        }
    }
    if !radio && args.plot.is_some() && losses(args).len() != 1 {
        return Err(UsageError::Option(
            "--plot: give one --loss value (the plot is error against kB sent at that loss)".into(),
        )
        .into());
    }
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
    if radio {
        return radio::report(args, &base, &names, &stats, quiet);
    }
    let rows = rows(args, &names, &stats);
    let mut svg = None;
    if args.plot.is_some() {
        let kb = |point: usize, n: &str| {
            let nodes = base.nodes().len() as f64;
            let s = stat(&stats, point, n, "bytes")?;
            Some(s.mean / nodes / duration(args, &base) / 1e3)
        };
        // One loss value: the plan's points are the rounds, every estimator in each run.
        let points = budget_points(&names, &args.rounds, &stats, |ri, _| ri, kb);
        let title = format!(
            "{} — error against kB sent, loss {:.0} %, {} per point",
            base.name(),
            100.0 * losses(args)[0],
            crate::scenario::count(args.seeds as usize, "seed")
        );
        svg = Some(plot::budget(&points, "kB a node sends a second", &title)?);
    }
    let mut out = std::io::stdout().lock();
    if args.json {
        json(&mut out, args, &base, None, &rows)?;
        return finish(args, svg, quiet);
    }
    writeln!(
        out,
        "{} ({} model), {} s per run, {} per cell: mean error / centralized's, mean ± sd over the seeds",
        base.name(),
        base.model().kind(),
        duration(args, &base),
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
    finish(args, svg, quiet)
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

/// The loss values compared over the pairwise medium.
fn losses(args: &CompareArgs) -> Vec<f64> {
    args.loss.clone().unwrap_or_else(|| LOSS.to_vec())
}

/// Each run's simulated duration, s.
fn duration(args: &CompareArgs, base: &Scenario) -> f64 {
    args.duration.unwrap_or(base.sim().duration_s)
}

/// A figure of an estimator (or of `network`) at a point.
fn stat<'a>(stats: &'a [PointStat], point: usize, est: &str, metric: &str) -> Option<&'a MeanCi> {
    stats
        .iter()
        .find(|s| s.point == point && s.estimator == est && s.metric == metric)
        .map(|s| &s.stat)
}

/// Each estimator × rounds a point of the budget plot: `point_of(rounds index, estimator index)` is the plan's
/// point that ran it, `spent` its x there.
fn budget_points(
    names: &[&str],
    rounds: &[u64],
    stats: &[PointStat],
    point_of: impl Fn(usize, usize) -> usize,
    spent: impl Fn(usize, &str) -> Option<f64>,
) -> Vec<plot::BudgetPoint> {
    let mut points = Vec::new();
    for (ri, &l) in rounds.iter().enumerate() {
        for (ki, name) in names.iter().enumerate() {
            let point = point_of(ri, ki);
            let ratio = stat(stats, point, name, "ratio_to_centralized");
            let (Some(kind), Some(r), Some(x)) = (Kind::from_name(name), ratio, spent(point, name)) else {
                continue;
            };
            points.push(plot::BudgetPoint {
                kind,
                rounds: l,
                x,
                y: r.mean,
                y_low: r.low,
                y_high: r.high,
            });
        }
    }
    points
}

/// The table's rows from the points' statistics, loss outermost as the plan orders its points.
fn rows(args: &CompareArgs, names: &[&str], stats: &[PointStat]) -> Vec<Row> {
    let stat = |point: usize, est: &str, metric: &str| stat(stats, point, est, metric);
    let cells = losses(args)
        .into_iter()
        .flat_map(|loss| args.rounds.iter().map(move |&rounds| (loss, rounds)));
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

/// The comparison as JSON: the scenario, the medium where it is not the pairwise one, and the rows.
fn json(
    out: &mut impl Write,
    args: &CompareArgs,
    base: &Scenario,
    medium: Option<&str>,
    rows: &impl serde::Serialize,
) -> anyhow::Result<ExitCode> {
    let mut v = serde_json::json!({
        "topology": base.name(),
        "model": base.model().kind(),
        "duration_s": duration(args, base),
        "seeds": args.seeds,
        "rows": rows,
    });
    if let Some(m) = medium {
        v["medium"] = m.into();
    }
    writeln!(out, "{}", serde_json::to_string_pretty(&v)?)?;
    Ok(ExitCode::SUCCESS)
}

/// The plot written to `--plot` (atomically, after the table: a plot that cannot be written loses no figure), and
/// said.
fn finish(args: &CompareArgs, svg: Option<String>, quiet: bool) -> anyhow::Result<ExitCode> {
    if let (Some(path), Some(svg)) = (&args.plot, svg) {
        anyhow::Context::with_context(crate::report::write_atomic(path, svg.as_bytes()), || {
            format!("writing {}", path.display())
        })?;
        if !quiet {
            eprintln!("wrote {}", path.display());
        }
    }
    Ok(ExitCode::SUCCESS)
}
