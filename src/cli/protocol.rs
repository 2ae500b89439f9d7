//! `simnet protocol`: the β search of [`crate::protocol`], its table, plot and topology file, and a fresh run of the
//! result over UDP beside the topology's own protocol.

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;

use clap::{Args, ValueEnum};

use super::{progress_bar_of, write_atomic, Format, RunArgs, UsageError};
use crate::net::{self, RunOptions};
use crate::protocol::{self, Boundary, Evaluation, Objective, SearchConfig, SearchResult};
use crate::report::plot;
use crate::scenario::{Overrides, Scenario};

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ObjectiveArg {
    /// Lowest mean error among feasible protocols (ties within 1 %: the most exchange).
    Error,
    /// Most weight to the neighbours among feasible protocols.
    Exchange,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SolverArg {
    /// The paper's one-parameter family, bisection with the direct checks (pure Rust).
    Family,
    /// All β by Clarabel's PSD cones, most exchanged weight (needs a build with `--features sdp`).
    Sdp,
}

#[derive(Args, Debug, Clone)]
#[command(mut_arg("out", |a| a.help("Write NAME-protocol.toml, protocol.csv/json/svg here (default out/protocol-NAME)").long_help(None)))]
pub struct ProtocolArgs {
    /// Scenario, link options, duration and seed of the scoring runs; --out (default out/protocol-NAME) and --json.
    #[command(flatten)]
    pub run: RunArgs,
    /// Scoring runs per protocol (seeds SEED, SEED+1, …).
    #[arg(allow_hyphen_values = true, long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..=64))]
    pub seeds: u64,
    /// Points of the family scored on [0, u_max].
    #[arg(allow_hyphen_values = true, long, default_value_t = 13, value_parser = clap::value_parser!(u64).range(2..=500))]
    pub grid: u64,
    /// Bisection steps on the feasibility boundary (when the family crosses it).
    #[arg(allow_hyphen_values = true, long, default_value_t = 6, value_parser = clap::value_parser!(u64).range(0..=40))]
    pub bisect: u64,
    /// Largest row sum Σⱼ βᵢⱼ the family reaches. Up to 1 (19) holds on any data; past 1 it binds, and the search
    /// finds where.
    #[arg(allow_hyphen_values = true, long, default_value_t = 1.0, value_parser = row_sum)]
    pub max_row_sum: f64,
    /// What the choice optimises: the lowest mean error, or the most exchange that stays feasible.
    #[arg(long, value_enum, default_value = "error")]
    pub objective: ObjectiveArg,
    /// Past row sum 1, keep the chosen u this fraction inside the boundary the scoring runs found.
    #[arg(allow_hyphen_values = true, long, default_value_t = 0.05, value_parser = super::probability)]
    pub margin: f64,
    /// The search: bisection along the one-parameter family, or an SDP over all β (feature `sdp`).
    #[arg(long, value_enum, default_value = "family")]
    pub solver: SolverArg,
    /// Seed of the fresh verification run (default: the run seed + 1000).
    #[arg(long)]
    pub verify_seed: Option<u64>,
}

fn row_sum(s: &str) -> Result<f64, String> {
    let v = super::parse_f64(s)?;
    if (1.0..=100.0).contains(&v) {
        Ok(v)
    } else {
        Err(format!(
            "must be in [1, 100] (independent nodes have row sum 1), got {v}"
        ))
    }
}

pub fn protocol(args: &ProtocolArgs, quiet: bool) -> anyhow::Result<ExitCode> {
    if args.run.realtime {
        return Err(UsageError::Option("protocol scores whole runs in virtual time: drop --realtime".into()).into());
    }
    if args.run.format != Format::Csv {
        return Err(UsageError::Option("protocol writes protocol.csv only: drop --format".into()).into());
    }
    if args.solver == SolverArg::Sdp && !cfg!(feature = "sdp") {
        return Err(UsageError::Option(
            "--solver sdp needs a build with the `sdp` feature: `cargo build --release --features sdp` \
             (Debian: apt-get install libopenblas-dev gfortran)"
                .into(),
        )
        .into());
    }
    let topo = args.run.topology()?;
    let name = args.run.topology.clone().unwrap_or_default();
    let (base_text, _) = Scenario::resolve_text(&name).map_err(UsageError::from)?;
    let cfg = SearchConfig {
        seeds: (0..args.seeds).map(|s| topo.sim().seed + s).collect(),
        grid: args.grid as usize,
        bisect: args.bisect as usize,
        max_row_sum: args.max_row_sum,
        objective: match args.objective {
            ObjectiveArg::Error => Objective::Error,
            ObjectiveArg::Exchange => Objective::Exchange,
        },
        margin: args.margin,
    };
    let out_dir = args
        .run
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("out/protocol-{}", topo.name())));
    super::check_out(&out_dir)?;
    let pb = (!quiet && !args.run.json).then(|| {
        progress_bar_of(
            protocol::planned_evaluations(&cfg),
            "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} protocols scored (eta {eta})",
        )
    });
    let tick = || {
        if let Some(pb) = &pb {
            pb.inc(1);
        }
    };
    // Every search error is about the input: options, a topology without exchange, or α too small.
    let result = protocol::search(&topo, &cfg, &tick).map_err(|e| UsageError::Option(e.to_string()))?;
    if let Some(pb) = &pb {
        pb.finish_and_clear();
    }
    let (beta, found, sdp_note) = choose(&topo, &cfg, &result, args.solver)?;

    let found_name = format!("{}-protocol", topo.name());
    let description = format!(
        "β found by `simnet protocol` on {} ({}, σ = {}, {} seeds): exchange {:.3}",
        topo.name(),
        match args.solver {
            SolverArg::Family => "family",
            SolverArg::Sdp => "sdp",
        },
        cfg.max_row_sum,
        cfg.seeds.len(),
        found.exchange
    );
    // Recorded IMU files by absolute path: the written topology lives in the output folder.
    let imu_files: Vec<Option<String>> = topo
        .nodes()
        .iter()
        .map(|n| {
            let r = n.recording.as_ref()?;
            let path = std::path::absolute(&r.path).unwrap_or_else(|_| PathBuf::from(&r.path));
            Some(path.display().to_string())
        })
        .collect();
    let text = protocol::topology_text(&base_text, &found_name, &description, &beta, &imu_files)
        .map_err(|e| anyhow::anyhow!("writing the protocol topology: {e}"))?;
    // The command-line options (--loss, --duration, …) are not in the file: say which ones the search ran under.
    let command: Vec<String> = std::env::args().skip(1).collect();
    let text = format!(
        "# Written by `simnet {}`.\n# Options given there (--loss, --duration, …) are not part of this file:\n\
         # pass them again to run under the search's conditions.\n{text}",
        command.join(" ")
    );
    // The file must load as it is written: the verification run below uses it.
    let found_topo = Scenario::from_toml(&text, &found_name)?;

    // Print first: whatever happens to the files, the result is not lost.
    if !args.run.json {
        print_table(&topo, &cfg, &result, &found, sdp_note.as_deref())?;
    }
    std::fs::create_dir_all(&out_dir)?;
    let toml_path = out_dir.join(format!("{found_name}.toml"));
    write_atomic(&toml_path, text.as_bytes())?;
    write_atomic(&out_dir.join("protocol.csv"), csv(&result).as_bytes())?;
    let boundary_exchange = match result.boundary {
        Boundary::Between { feasible, .. } => Some(protocol::exchange(
            &topo,
            &protocol::family(&topo, feasible, cfg.max_row_sum),
        )),
        Boundary::NotReached { .. } => None,
    };
    let points: Vec<plot::ProtocolPoint> = result
        .curve
        .iter()
        .map(|e| (e.exchange, e.mean_error, e.worst_error, e.feasible()))
        .collect();
    let svg = plot::protocol_curve(
        &points,
        result.reference.independent_error,
        (result.reference.exchange, result.reference.mean_error),
        (found.exchange, found.mean_error),
        boundary_exchange,
        topo.model().kind().error_text().label,
        &format!("{}: mean error against exchanged weight", topo.name()),
    )?;
    write_atomic(&out_dir.join("protocol.svg"), svg.as_bytes())?;

    // A fresh run over UDP with a seed the search never saw: the found protocol and the topology's own.
    let verify_seed = args.verify_seed.unwrap_or(topo.sim().seed + 1000);
    let over = Overrides {
        seed: Some(verify_seed),
        ..args.run.overrides()?
    };
    let found_topo = found_topo.with(&over).map_err(UsageError::from)?;
    let seed_only = Overrides {
        seed: Some(verify_seed),
        ..Default::default()
    };
    let own = topo
        .with(&seed_only)
        .and_then(|t| t.with_guard(true))
        .map_err(UsageError::from)?;
    let rt = tokio::runtime::Builder::new_multi_thread().enable_all().build()?;
    let verify = |t: Scenario| -> anyhow::Result<crate::report::summary::Summary> {
        let t = Arc::new(t);
        let out = rt.block_on(net::run(t.clone(), RunOptions::default(), std::future::pending()))?;
        Ok(out.summary())
    };
    let fresh_found = verify(found_topo)?;
    let fresh_own = verify(own)?;
    let json = serde_json::json!({
        "topology": topo.name(),
        "objective": cfg.objective,
        "solver": match args.solver { SolverArg::Family => "family", SolverArg::Sdp => "sdp" },
        "max_row_sum": cfg.max_row_sum,
        "seeds": cfg.seeds,
        "alpha": topo.consensus().lmi.alpha,
        "gamma": topo.consensus().lmi.gamma,
        "search": result,
        "found": { "beta": beta, "evaluation": found, "file": toml_path },
        "fresh_run": {
            "seed": verify_seed,
            "found": fresh_figures(&fresh_found),
            "own": fresh_figures(&fresh_own),
        },
    });
    write_atomic(
        &out_dir.join("protocol.json"),
        serde_json::to_string_pretty(&json)?.as_bytes(),
    )?;
    let mut stdout = std::io::stdout().lock();
    if args.run.json {
        writeln!(stdout, "{}", serde_json::to_string_pretty(&json)?)?;
    } else {
        let f = fresh_figures(&fresh_found);
        let o = fresh_figures(&fresh_own);
        writeln!(
            stdout,
            "fresh run over UDP (seed {verify_seed}): found protocol mean error {:.5}{u}, {} infeasible steps; \
             the topology's own protocol {:.5}{u}, {} infeasible steps; independent nodes {:.5}{u}",
            f.mean_error,
            f.infeasible_steps,
            o.mean_error,
            o.infeasible_steps,
            f.independent_error,
            u = topo.model().kind().error_text().unit
        )?;
        writeln!(
            stdout,
            "wrote {}/{{{found_name}.toml, protocol.csv, protocol.json, protocol.svg}}",
            out_dir.display()
        )?;
    }
    Ok(ExitCode::SUCCESS)
}

/// The protocol to write: the family's choice, or the SDP's (started from it).
fn choose(
    topo: &Scenario,
    cfg: &SearchConfig,
    result: &SearchResult,
    solver: SolverArg,
) -> anyhow::Result<(Vec<Vec<f64>>, Evaluation, Option<String>)> {
    match solver {
        SolverArg::Family => {
            // Score the rounded β the file will carry, not the unrounded family point.
            let mut e = protocol::evaluate(topo, &result.beta, result.chosen.u, &cfg.seeds)?;
            e.u = result.chosen.u;
            Ok((result.beta.clone(), e, None))
        }
        #[cfg(feature = "sdp")]
        SolverArg::Sdp => {
            let r = protocol::sdp::search(topo, cfg, &result.beta, 5)?;
            let note = format!(
                "SDP over all β (Clarabel, {} round(s), {} steps as PSD cones): exchange {:.4}, mean error \
                 {:.5}{}, {} infeasible steps",
                r.rounds,
                r.steps_as_cones,
                r.evaluation.exchange,
                r.evaluation.mean_error,
                topo.model().kind().error_text().unit,
                r.evaluation.infeasible_steps
            );
            Ok((r.beta, r.evaluation, Some(note)))
        }
        #[cfg(not(feature = "sdp"))]
        SolverArg::Sdp => unreachable!("rejected before the search"),
    }
}

#[derive(serde::Serialize)]
struct Fresh {
    mean_error: f64,
    independent_error: f64,
    infeasible_steps: u64,
}

/// Mean over estimating nodes with a known truth of the networked and independent mean errors, and the guard's
/// rejections.
fn fresh_figures(s: &crate::report::summary::Summary) -> Fresh {
    let pairs = s.scored_errors();
    let n = pairs.len().max(1) as f64;
    Fresh {
        mean_error: pairs.iter().map(|p| p.0).sum::<f64>() / n,
        independent_error: pairs.iter().map(|p| p.1).sum::<f64>() / n,
        infeasible_steps: s
            .nodes
            .iter()
            .filter_map(|node| node.networked.as_ref()?.lmi_infeasible_steps)
            .sum(),
    }
}

fn print_table(
    topo: &Scenario,
    cfg: &SearchConfig,
    r: &SearchResult,
    found: &Evaluation,
    sdp_note: Option<&str>,
) -> std::io::Result<()> {
    let mut o = std::io::stdout().lock();
    writeln!(
        o,
        "protocol search on {} ({}; α = {}, γ = {}; σ = {}; seeds {}..{}; objective {:?})",
        topo.name(),
        crate::scenario::count(topo.nodes().len(), "node"),
        topo.consensus().lmi.alpha,
        topo.consensus().lmi.gamma,
        cfg.max_row_sum,
        cfg.seeds[0],
        cfg.seeds[cfg.seeds.len() - 1],
        cfg.objective
    )?;
    writeln!(
        o,
        "{:>8} {:>9} {:>11} {:>11} {:>12} {:>11}",
        "u",
        "exchange",
        format!("mean err{}", topo.model().kind().error_text().unit),
        "worst seed",
        "independent",
        "infeasible"
    )?;
    for e in &r.curve {
        let mark = if e.u == r.chosen.u { "  ← chosen" } else { "" };
        writeln!(
            o,
            "{:>8.4} {:>9.4} {:>11.5} {:>11.5} {:>12.5} {:>11}{}{mark}",
            e.u,
            e.exchange,
            e.mean_error,
            e.worst_error,
            e.independent_error,
            e.infeasible_steps,
            if e.diverged { " diverged" } else { "" }
        )?;
    }
    match r.boundary {
        Boundary::NotReached { u_max } => writeln!(
            o,
            "(17) and (19) held at every step of every run up to u = {u_max:.4}: the family never crosses them"
        )?,
        Boundary::Between { feasible, infeasible } => writeln!(
            o,
            "(17)/(19) boundary: feasible at u = {feasible:.5}, violated at u = {infeasible:.5} (bisection)"
        )?,
    }
    let pct = |a: f64, b: f64| 100.0 * (1.0 - a / b);
    writeln!(
        o,
        "topology's own protocol: exchange {:.4}, mean error {:.5}{} ({} infeasible steps)",
        r.reference.exchange,
        r.reference.mean_error,
        topo.model().kind().error_text().unit,
        r.reference.infeasible_steps
    )?;
    if let Some(n) = sdp_note {
        writeln!(o, "{n}")?;
    }
    writeln!(
        o,
        "found: exchange {:.4}, mean error {:.5}{} — {:.1} % below the own protocol, {:.1} % below independent nodes",
        found.exchange,
        found.mean_error,
        topo.model().kind().error_text().unit,
        pct(found.mean_error, r.reference.mean_error),
        pct(found.mean_error, found.independent_error)
    )
}

fn csv(r: &SearchResult) -> String {
    let mut s = String::from("u,exchange,mean_error,worst_error,independent_error,infeasible_steps,diverged\n");
    for e in &r.curve {
        s.push_str(&format!(
            "{},{},{},{},{},{},{}\n",
            e.u, e.exchange, e.mean_error, e.worst_error, e.independent_error, e.infeasible_steps, e.diverged
        ));
    }
    s
}
