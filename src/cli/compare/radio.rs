//! `simnet compare` on a radio channel: each estimator runs alone on the channel, so that what one sends takes no
//! air from another's (a deployment runs one scheme), beside the nodes' own measurement broadcasts, which every run
//! carries. A row per rounds × estimator: its error relative to the centralized reference, the channel's load, the
//! radios' mean power and the messages lost. The channel decides loss itself: `--loss` is refused.

use super::*;

/// The plan's axes: the rounds, then the estimator that runs (with the reference, which sends nothing).
pub(super) fn axes(args: &CompareArgs, names: &[&str]) -> Result<Vec<Axis>, UsageError> {
    if args.loss.is_some() {
        return Err(UsageError::Option(
            "--loss: a radio channel decides every frame's fate from distance, noise and contention; --loss sets the \
             pairwise medium's links"
                .into(),
        ));
    }
    if names.is_empty() {
        return Err(UsageError::Option(
            "--estimators: nothing to compare beside the centralized reference".into(),
        ));
    }
    let rounds: Vec<String> = args.rounds.iter().map(u64::to_string).collect();
    let rounds = Axis::parse(&format!("rounds={}", rounds.join(",")))
        .map_err(|e| UsageError::Option(format!("--rounds: {e}")))?;
    let run = Axis {
        key: "estimators.run".into(),
        values: names
            .iter()
            .map(|n| toml::Value::Array(vec![(*n).into(), Kind::Centralized.name().into()]))
            .collect(),
    };
    Ok(vec![rounds, run])
}

/// One row: an estimator at a number of rounds, alone on the channel.
#[derive(serde::Serialize)]
struct Row {
    rounds: u64,
    estimator: String,
    /// Its mean error / centralized's.
    ratio_to_centralized: Figure,
    centralized_error: Figure,
    /// The senders' airtime over the run's span.
    channel_load: Figure,
    /// Every node's airtime, s.
    airtime_s: Figure,
    /// A node's mean radio power, mW.
    mean_power_mw: Figure,
    /// The measured fraction of messages lost over every link.
    loss_rate: Figure,
}

/// The table (or JSON) of `stats`, and the budget plot with `--plot`.
pub(super) fn report(
    args: &CompareArgs,
    base: &Scenario,
    names: &[&str],
    stats: &[PointStat],
    quiet: bool,
) -> anyhow::Result<ExitCode> {
    let point_of = |ri: usize, ki: usize| ri * names.len() + ki;
    let rows: Vec<Row> = args
        .rounds
        .iter()
        .enumerate()
        .flat_map(|(ri, &rounds)| {
            names.iter().enumerate().map(move |(ki, n)| {
                let point = point_of(ri, ki);
                let net = |m: &str| Figure::of(stat(stats, point, campaign::NETWORK, m));
                Row {
                    rounds,
                    estimator: n.to_string(),
                    ratio_to_centralized: Figure::of(stat(stats, point, n, "ratio_to_centralized")),
                    centralized_error: Figure::of(stat(stats, point, "centralized", "mean_error")),
                    channel_load: net("channel_load"),
                    airtime_s: net("airtime_s"),
                    mean_power_mw: net("mean_power_mw"),
                    loss_rate: net("loss_rate"),
                }
            })
        })
        .collect();
    let mut svg = None;
    if args.plot.is_some() {
        let load = |point: usize, _: &str| stat(stats, point, campaign::NETWORK, "channel_load").map(|s| s.mean);
        let points = budget_points(names, &args.rounds, stats, point_of, load);
        let title = format!(
            "{} — error against the channel's load, each estimator alone, {} per point",
            base.name(),
            crate::scenario::count(args.seeds as usize, "seed")
        );
        svg = Some(plot::budget(&points, "channel load (airtime / time)", &title)?);
    }
    let mut out = std::io::stdout().lock();
    if args.json {
        json(&mut out, args, base, Some("radio"), &rows)?;
        return finish(args, svg, quiet);
    }
    writeln!(
        out,
        "{} ({} model) over one IEEE 802.15.4 channel, {} s per run, {} per cell: each estimator alone on the channel \
         beside the nodes' measurement broadcasts; its mean error / centralized's, the channel's load (airtime / time), \
         a radio's mean power and the messages lost, mean ± sd over the seeds",
        base.name(),
        base.model().kind(),
        duration(args, base),
        crate::scenario::count(args.seeds as usize, "seed")
    )?;
    writeln!(out)?;
    let header = [
        "L",
        "estimator",
        "error / centralized",
        "channel load",
        "power per node",
        "messages lost",
    ];
    writeln!(out, "| {} |", header.join(" | "))?;
    writeln!(out, "|{}", "---|".repeat(header.len()))?;
    let seeds = args.seeds as usize;
    for r in &rows {
        let cells = [
            r.rounds.to_string(),
            r.estimator.clone(),
            r.ratio_to_centralized.text(seeds),
            r.channel_load.text_as(seeds, 1, 100.0, " %"),
            r.mean_power_mw.text_as(seeds, 2, 1.0, " mW"),
            r.loss_rate.text_as(seeds, 1, 100.0, " %"),
        ];
        writeln!(out, "| {} |", cells.join(" | "))?;
    }
    if let Some(c) = rows.first().and_then(|r| r.centralized_error.mean) {
        writeln!(out)?;
        writeln!(
            out,
            "centralized (every measurement at one center, no radio): mean error {c:.4}"
        )?;
    }
    finish(args, svg, quiet)
}
