//! `simnet reproduce PAPER`: rerun a source document's experiments and write its claims table and plots.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;

use clap::{Args, Subcommand};

use super::{write_atomic, UsageError};
use crate::net::{self, RunOptions};
use crate::report::trace::TraceWriter;
use crate::reproduce::{self, lesecq, nieminen, rigid_pair, sequeira, RunResult};
use crate::scenario::Scenario;

#[derive(Subcommand, Debug, Clone)]
pub enum Paper {
    /// The consensus IMU network (Sequeira 2023): dead reckoning, independent nodes, both protocols, feasibility, drift,
    /// fusion.
    Sequeira(SequeiraArgs),
    /// Attitude with data loss (Lesecq 2009): the quaternion EKF, standard and square-root, in the slides' scenario.
    Lesecq(LesecqArgs),
    /// Two IMUs on one rigid body (the rigid-pair paper): the Monte Carlo of dead reckoning, averaged pair and constrained EKF.
    RigidPair(RigidPairArgs),
    /// Boundary-value reconstruction (Nieminen et al. 2010): the rate-table example, trapezoid against FEM against FEM with the
    /// sensor-error model.
    Nieminen(NieminenArgs),
}

#[derive(Args, Debug, Clone)]
pub struct NieminenArgs {
    /// Seed of the first simulated sensor noise (the table shows it; seed + 1, … are judged too).
    #[arg(allow_hyphen_values = true, long, default_value_t = 1)]
    pub seed: u64,
    /// Seeds the claims are judged on (a claim holds on at least 90 % of them).
    #[arg(allow_hyphen_values = true, long, default_value_t = 20, value_parser = clap::value_parser!(u64).range(1..=10_000))]
    pub seeds: u64,
    /// Where to write claims.md, claims.json and the plots.
    #[arg(long, default_value = "out/nieminen")]
    pub out: PathBuf,
}

#[derive(Args, Debug, Clone)]
pub struct RigidPairArgs {
    /// Runs per motion (the paper used 10,000).
    #[arg(allow_hyphen_values = true, long, default_value_t = 1000, value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
    pub runs: u64,
    /// Let the accelerometer's noise over this analogue bandwidth (Hz) reach each 50 Hz sample unfiltered (the
    /// MMA7361's is 400 Hz); default: noise band-limited to the sample rate.
    #[arg(allow_hyphen_values = true, long, value_parser = super::positive)]
    pub accel_bandwidth: Option<f64>,
    /// Seed of the first run (run i uses seed + i).
    #[arg(allow_hyphen_values = true, long, default_value_t = 1)]
    pub seed: u64,
    /// Where to write results.json (every motion's figures), claims.md and claims.json.
    #[arg(long, default_value = "out/rigid-pair")]
    pub out: PathBuf,
}

#[derive(Args, Debug, Clone)]
pub struct LesecqArgs {
    /// Seeds (1, 2, …); a claim holds when it holds on every seed. Plots show seed 1.
    #[arg(allow_hyphen_values = true, long, default_value_t = 5, value_parser = clap::value_parser!(u64).range(1..=1000))]
    pub seeds: u64,
    /// Loss probability of each accelerometer and magnetometer sample.
    #[arg(allow_hyphen_values = true, long, default_value_t = 0.2, value_parser = super::probability)]
    pub loss: f64,
    /// How long each reference attitude holds, s.
    #[arg(allow_hyphen_values = true, long, default_value_t = 3.0, value_parser = super::positive)]
    pub segment: f64,
    /// Where to write claims.md, claims.json and the plots.
    #[arg(long, default_value = "out/lesecq")]
    pub out: PathBuf,
}

#[derive(Args, Debug, Clone)]
pub struct SequeiraArgs {
    /// Seeds per experiment (1, 2, …); a claim holds when it holds on every seed.
    #[arg(allow_hyphen_values = true, long, default_value_t = 5, value_parser = clap::value_parser!(u64).range(1..=100))]
    pub seeds: u64,
    /// Simulated duration of every run, s (default: the topologies' 30 s).
    #[arg(allow_hyphen_values = true, long, value_parser = super::positive)]
    pub duration: Option<f64>,
    /// Where to write claims.md, claims.json and the plots.
    #[arg(long, default_value = "out/sequeira")]
    pub out: PathBuf,
}

/// A whole run over UDP (virtual clock), with its trace rows when `record`.
fn run_over_udp(
    rt: &tokio::runtime::Runtime,
    topo: &Scenario,
    record: bool,
) -> Result<RunResult, crate::reproduce::ReproduceError> {
    let topo = Arc::new(topo.clone());
    let opts = RunOptions {
        trace: record.then(|| TraceWriter::for_topology(&topo).keep_all()),
        ..Default::default()
    };
    let out = rt
        .block_on(net::run(topo.clone(), opts, std::future::pending()))
        .map_err(|e| crate::reproduce::ReproduceError::Run(e.into()))?;
    let summary = out.summary();
    let (rows, fused) = match out.trace {
        Some(t) => t.finish()?,
        None => Default::default(),
    };
    Ok(RunResult { summary, rows, fused })
}

pub fn reproduce(paper: &Paper, quiet: bool) -> anyhow::Result<ExitCode> {
    super::check_out(match paper {
        Paper::Sequeira(a) => &a.out,
        Paper::Lesecq(a) => &a.out,
        Paper::RigidPair(a) => &a.out,
        Paper::Nieminen(a) => &a.out,
    })?;
    let args = match paper {
        Paper::Sequeira(a) => a,
        Paper::Lesecq(a) => return lesecq(a),
        Paper::RigidPair(a) => return rigid_pair(a, quiet),
        Paper::Nieminen(a) => return nieminen(a),
    };
    if let Some(d) = args.duration {
        if d * 100.0 > crate::scenario::MAX_STEPS {
            return Err(UsageError::Option(format!(
                "--duration {d} s is more than {:e} steps",
                crate::scenario::MAX_STEPS
            ))
            .into());
        }
    }
    let rt = tokio::runtime::Builder::new_multi_thread().enable_all().build()?;
    let runner = |t: &Scenario, record: bool| run_over_udp(&rt, t, record);
    let pb = (!quiet).then(|| {
        let pb = indicatif::ProgressBar::new_spinner();
        pb.enable_steady_tick(std::time::Duration::from_millis(200));
        pb
    });
    let tick = |what: &str| {
        if let Some(pb) = &pb {
            pb.set_message(what.to_string());
        }
    };
    let cfg = sequeira::Config {
        seeds: (1..=args.seeds).collect(),
        duration_s: args.duration,
    };
    let out = sequeira::run(&cfg, &runner, &tick)?;
    if let Some(pb) = &pb {
        pb.finish_and_clear();
    }
    let title = format!(
        "Sequeira et al., networks of IMUs (Sequeira 2023): claims and simnet's figures ({} seeds)",
        cfg.seeds.len()
    );
    finish(&args.out, &title, &out.claims, &out.plots, &[])
}

fn lesecq(args: &LesecqArgs) -> anyhow::Result<ExitCode> {
    if args.segment > 1e5 {
        return Err(UsageError::Option(format!("--segment {} s is too long (at most 1e5 s)", args.segment)).into());
    }
    let cfg = lesecq::Config {
        loss: args.loss,
        segment_s: args.segment,
        ..Default::default()
    };
    let seeds: Vec<u64> = (1..=args.seeds).collect();
    let out = lesecq::run(&cfg, &seeds)?;
    let title = format!(
        "Lesecq, sensor fusion with intermittent data (Lesecq 2009): attitude with {:.0} % loss ({} seeds)",
        args.loss * 100.0,
        seeds.len()
    );
    finish(&args.out, &title, &out.claims, &out.plots, &[])
}

/// Print the claims table, then write it with the plots; `written`: files the caller wrote into `dir` already.
fn finish(
    dir: &Path,
    title: &str,
    claims: &[reproduce::Claim],
    plots: &[(String, String)],
    written: &[&str],
) -> anyhow::Result<ExitCode> {
    let md = reproduce::markdown(title, claims);
    // Print first: whatever happens to the files, the result is not lost.
    let mut out = std::io::stdout().lock();
    writeln!(out, "{md}")?;
    std::fs::create_dir_all(dir)?;
    write_atomic(&dir.join("claims.md"), md.as_bytes())?;
    write_atomic(
        &dir.join("claims.json"),
        serde_json::to_string_pretty(claims)?.as_bytes(),
    )?;
    for (name, svg) in plots {
        write_atomic(&dir.join(name), svg.as_bytes())?;
    }
    let files: String = written
        .iter()
        .map(|w| format!("{w}, "))
        .chain(["claims.md, claims.json".to_string()])
        .chain(plots.iter().map(|p| format!(", {}", p.0)))
        .collect();
    writeln!(out, "wrote {}/{{{files}}}", dir.display())?;
    Ok(ExitCode::SUCCESS)
}

fn rigid_pair(args: &RigidPairArgs, quiet: bool) -> anyhow::Result<ExitCode> {
    let cfg = rigid_pair::Config {
        runs: args.runs as usize,
        seed: args.seed,
        accel_bandwidth_hz: args.accel_bandwidth,
        ..Default::default()
    };
    let pb = (!quiet).then(|| {
        super::progress_bar_of(
            3 * args.runs,
            "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} runs ({per_sec}, eta {eta})",
        )
    });
    let tick = || {
        if let Some(pb) = &pb {
            pb.inc(1);
        }
    };
    let started = std::time::Instant::now();
    let results = rigid_pair::monte_carlo(&cfg, &tick)?;
    if let Some(pb) = &pb {
        pb.finish_and_clear();
    }
    let mut out = std::io::stdout().lock();
    writeln!(
        out,
        "{} runs per motion, 30 s at 2 m/s, 50 Hz, in {:.1} s on {} cores; mean position error over each run\n",
        args.runs,
        started.elapsed().as_secs_f64(),
        std::thread::available_parallelism().map_or(1, |n| n.get())
    )?;
    writeln!(out, "{}", rigid_pair::table(&results, &cfg))?;
    writeln!(out)?;
    drop(out);
    std::fs::create_dir_all(&args.out)?;
    write_atomic(
        &args.out.join("results.json"),
        serde_json::to_string_pretty(&results)?.as_bytes(),
    )?;
    let title = "Two IMUs on a rigid body (the rigid-pair paper): claims and simnet's figures";
    finish(&args.out, title, &rigid_pair::claims(&results), &[], &["results.json"])
}

fn nieminen(args: &NieminenArgs) -> anyhow::Result<ExitCode> {
    let sensor = nieminen::Sensor {
        seed: args.seed,
        ..Default::default()
    };
    let out = nieminen::run(&sensor, args.seeds)?;
    let mut stdout = std::io::stdout().lock();
    writeln!(
        stdout,
        "Rate table, r = {} m, {} Hz; sensor bias {} m/s², scale {}, noise {} m/s²; P1, P2, P3 at ¼, ½, ¾ of the record\n",
        sensor.radius, sensor.rate_hz, sensor.bias, sensor.scale, sensor.noise
    )?;
    writeln!(stdout, "{}", out.table)?;
    drop(stdout);
    std::fs::create_dir_all(&args.out)?;
    write_atomic(&args.out.join("table.md"), out.table.as_bytes())?;
    write_atomic(
        &args.out.join("results.json"),
        serde_json::to_string_pretty(&out.results)?.as_bytes(),
    )?;
    let title = "Nieminen et al., boundary conditions for inertial navigation (Nieminen et al. 2010): claims and simnet's figures";
    finish(&args.out, title, &out.claims, &out.plots, &[])
}
