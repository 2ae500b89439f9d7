//! `simnet compare`: every estimator on the same scenario over a grid of loss × rounds × seeds, in memory, and
//! the table of mean errors relative to the centralized reference (mean ± standard deviation over the seeds).

use super::*;
use crate::estimators::Kind;

#[derive(Args, Debug, Clone)]
pub struct CompareArgs {
    /// Built-in name or a path.
    #[arg(long, short = 't')]
    pub topology: String,
    /// Loss probabilities, comma-separated (Bernoulli on every link).
    #[arg(long, value_delimiter = ',', value_parser = probability, default_values_t = [0.0, 0.1, 0.3])]
    pub loss: Vec<f64>,
    /// Consensus rounds, comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [1u64, 3, 10],
          value_parser = clap::value_parser!(u64).range(1..=crate::scenario::MAX_ROUNDS as u64))]
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
}

struct Cell {
    loss: f64,
    rounds: u64,
    seed: u64,
}

pub(super) fn compare(args: &CompareArgs, quiet: bool) -> anyhow::Result<ExitCode> {
    let base = Scenario::resolve(&args.topology)?;
    let mut all = args
        .estimators
        .as_deref()
        .map_or_else(|| Kind::ALL.to_vec(), super::args::EstimatorChoice::kinds);
    if !all.contains(&Kind::Centralized) {
        all.push(Kind::Centralized);
        all.sort();
    }
    let cells: Vec<Cell> = args
        .loss
        .iter()
        .flat_map(|&loss| {
            args.rounds
                .iter()
                .flat_map(move |&rounds| (1..=args.seeds).map(move |seed| Cell { loss, rounds, seed }))
        })
        .collect();
    // Every cell's scenario is checked before any run starts.
    let scenarios: Vec<Scenario> = cells
        .iter()
        .map(|c| {
            base.with(&Overrides {
                loss: Some(LossModel::Bernoulli { p: c.loss }),
                seed: Some(c.seed),
                duration_s: args.duration,
                estimators: Some(all.clone()),
                rounds: Some(c.rounds),
                ..Default::default()
            })
        })
        .collect::<Result<_, _>>()?;
    let pb = (!quiet).then(|| {
        progress_bar_of(
            cells.len() as u64,
            "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} runs (eta {eta})",
        )
    });
    let tick = || {
        if let Some(p) = &pb {
            p.inc(1);
        }
    };
    let summaries = crate::par::map(
        &scenarios,
        |s| crate::sim::Sim::new(s).and_then(|sim| sim.run()).map(|r| r.summary()),
        &tick,
    );
    if let Some(p) = pb {
        p.finish_and_clear();
    }
    let mut out = std::io::stdout().lock();
    let names: Vec<&str> = all
        .iter()
        .filter(|k| **k != Kind::Centralized)
        .map(|k| k.name())
        .collect();
    writeln!(
        out,
        "{} ({} model), {} s per run, {} per cell: mean error / centralized's, mean ± sd over the seeds",
        base.name(),
        base.model().get().kind(),
        args.duration.unwrap_or(base.sim().duration_s),
        crate::scenario::count(args.seeds as usize, "seed")
    )?;
    writeln!(out)?;
    // One cell per column, header and rows alike (with no scheme beside the reference, too).
    let header: Vec<&str> = ["loss", "L", "centralized error"]
        .into_iter()
        .chain(names.iter().copied())
        .chain(["sequeira's rank"])
        .collect();
    writeln!(out, "| {} |", header.join(" | "))?;
    writeln!(out, "|{}", "---|".repeat(header.len()))?;
    let per_cell = args.seeds as usize;
    for (chunk, cs) in summaries.chunks(per_cell).zip(cells.chunks(per_cell)) {
        let ok: Vec<&crate::Summary> = chunk.iter().filter_map(|s| s.as_ref().ok()).collect();
        let stat = |v: Vec<f64>| {
            let n = v.len() as f64;
            let m = v.iter().sum::<f64>() / n;
            let sd = (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0).max(1.0)).sqrt();
            (m, sd, v.len())
        };
        let central = stat(
            ok.iter()
                .filter_map(|s| s.estimators.get("centralized")?.mean_error)
                .collect(),
        );
        let ratios: Vec<(f64, f64, usize)> = names
            .iter()
            .map(|n| {
                stat(
                    ok.iter()
                        .filter_map(|s| s.estimators.get(*n)?.ratio_to_centralized)
                        .collect(),
                )
            })
            .collect();
        let cell = |(m, sd, k): (f64, f64, usize)| {
            if k == 0 || !m.is_finite() {
                "diverged".to_string()
            } else if k < per_cell {
                format!("{m:.3} ± {sd:.3} ({k} of {per_cell})")
            } else {
                format!("{m:.3} ± {sd:.3}")
            }
        };
        let seq = names.iter().position(|n| *n == "sequeira").map(|i| ratios[i].0);
        let rank = seq.map_or("—".to_string(), |s| {
            let better = ratios.iter().filter(|r| r.0.is_finite() && r.0 < s).count();
            format!("{} of {}", better + 1, names.len())
        });
        let row: Vec<String> = [
            format!("{:.0} %", 100.0 * cs[0].loss),
            cs[0].rounds.to_string(),
            cell(central),
        ]
        .into_iter()
        .chain(ratios.iter().map(|r| cell(*r)))
        .chain([rank])
        .collect();
        writeln!(out, "| {} |", row.join(" | "))?;
        for (s, c) in chunk.iter().zip(cs) {
            if let Err(e) = s {
                eprintln!("warning: loss {} L {} seed {}: {e}", c.loss, c.rounds, c.seed);
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}
