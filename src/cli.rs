//! Command line: clap definitions, tracing setup, exit codes (0 success, 2 bad input, 1 failure while running).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;

use clap::{Args, Parser, Subcommand, ValueEnum};

use crate::link::LossModel;
use crate::net::{self, Clock, RunOptions};
use crate::node::Truth;
use crate::report::{plot, summary};
use crate::topology::{builtin, ModelConfig, Overrides, Topology, TopologyError};

#[derive(Parser, Debug)]
#[command(
    name = "simnet",
    version,
    about = "Networked IMU sensor-network simulator with fault injection over real UDP sockets"
)]
#[command(args_conflicts_with_subcommands = true)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
    #[command(flatten)]
    pub run: RunArgs,
    /// More log output (-v info, -vv debug, -vvv trace); RUST_LOG overrides.
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    pub verbose: u8,
    /// Only errors.
    #[arg(short, long, global = true, conflicts_with = "verbose")]
    pub quiet: bool,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Run a topology (the default command).
    Run(RunArgs),
    /// List the built-in topologies.
    Topologies,
    /// Check topology files and explain every problem.
    Validate {
        #[arg(required = true)]
        files: Vec<PathBuf>,
    },
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum LossKind {
    Bernoulli,
    GilbertElliott,
}

#[derive(Args, Debug, Clone, Default)]
pub struct RunArgs {
    /// Built-in name, `./topologies/NAME.toml`, or a path.
    #[arg(long, short = 't')]
    pub topology: Option<String>,
    /// Packet loss probability on every link (stationary loss for Gilbert–Elliott).
    #[arg(long, value_parser = probability)]
    pub loss: Option<f64>,
    /// Loss process for --loss.
    #[arg(long, value_enum, requires = "loss")]
    pub loss_model: Option<LossKind>,
    /// Mean loss run in packets (Gilbert–Elliott: r = 1/B, p = L·r/(1−L)).
    #[arg(long, value_parser = at_least_one)]
    pub burst: Option<f64>,
    /// Constant one-way delay on every link, ms.
    #[arg(long, value_parser = non_negative)]
    pub delay: Option<f64>,
    /// Jitter on every link, ms (uniform ± unless the topology says normal).
    #[arg(long, value_parser = non_negative)]
    pub jitter: Option<f64>,
    /// Probability that a link delivers a datagram twice.
    #[arg(long, value_parser = probability)]
    pub duplicate: Option<f64>,
    /// Probability that a link flips one bit of a datagram (the receiver's checksum must catch it).
    #[arg(long, value_parser = probability)]
    pub corrupt: Option<f64>,
    /// Simulated duration, s.
    #[arg(long, value_parser = positive)]
    pub duration: Option<f64>,
    /// Step rate, Hz.
    #[arg(long, value_parser = positive)]
    pub rate: Option<f64>,
    /// Run seed (every random stream derives from it).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Pace steps by the wall clock instead of the virtual lockstep clock.
    #[arg(long)]
    pub realtime: bool,
    /// Write summary.json, trace.csv, links.csv and SVG plots here.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print summary.json on stdout instead of the table.
    #[arg(long)]
    pub json: bool,
}

fn parse_f64(s: &str) -> Result<f64, String> {
    s.parse::<f64>().map_err(|_| format!("`{s}` is not a number"))
}
fn probability(s: &str) -> Result<f64, String> {
    let v = parse_f64(s)?;
    if (0.0..=1.0).contains(&v) {
        Ok(v)
    } else {
        Err(format!("must be a probability in [0, 1], got {v}"))
    }
}
fn positive(s: &str) -> Result<f64, String> {
    let v = parse_f64(s)?;
    if v > 0.0 && v.is_finite() {
        Ok(v)
    } else {
        Err(format!("must be a positive number, got {v}"))
    }
}
fn non_negative(s: &str) -> Result<f64, String> {
    let v = parse_f64(s)?;
    if v >= 0.0 && v.is_finite() {
        Ok(v)
    } else {
        Err(format!("must be a non-negative number, got {v}"))
    }
}
fn at_least_one(s: &str) -> Result<f64, String> {
    let v = parse_f64(s)?;
    if v >= 1.0 && v.is_finite() {
        Ok(v)
    } else {
        Err(format!("a mean loss run is at least 1 packet, got {v}"))
    }
}

/// An error for the user: exit code 2.
#[derive(Debug, thiserror::Error)]
pub enum UsageError {
    #[error(transparent)]
    Topology(#[from] TopologyError),
    #[error("{0}")]
    Option(String),
}

impl RunArgs {
    pub fn overrides(&self) -> Result<Overrides, UsageError> {
        let loss = match (self.loss, self.loss_model.unwrap_or(LossKind::Bernoulli), self.burst) {
            (None, _, Some(_)) => {
                return Err(UsageError::Option(
                    "--burst needs --loss (and --loss-model gilbert-elliott)".into(),
                ))
            }
            (None, _, None) => None,
            (Some(p), LossKind::Bernoulli, None) => Some(LossModel::Bernoulli { p }),
            (Some(_), LossKind::Bernoulli, Some(_)) => {
                return Err(UsageError::Option(
                    "--burst applies to --loss-model gilbert-elliott only".into(),
                ))
            }
            (Some(l), LossKind::GilbertElliott, burst) => {
                let b = burst.ok_or_else(|| {
                    UsageError::Option("--loss-model gilbert-elliott needs --burst B (mean loss run)".into())
                })?;
                Some(
                    LossModel::gilbert_elliott_from(l, b)
                        .map_err(|e| UsageError::Option(format!("--loss/--burst: {e}")))?,
                )
            }
        };
        Ok(Overrides {
            loss,
            delay_ms: self.delay,
            jitter_ms: self.jitter,
            duplicate: self.duplicate,
            corrupt: self.corrupt,
            duration_s: self.duration,
            rate_hz: self.rate,
            seed: self.seed,
        })
    }

    /// The topology with the command-line overrides applied.
    pub fn topology(&self) -> Result<Topology, UsageError> {
        let name = self
            .topology
            .as_deref()
            .ok_or_else(|| UsageError::Option("--topology NAME|PATH is required (see `simnet topologies`)".into()))?;
        let mut t = Topology::resolve(name)?;
        t.apply(&self.overrides()?);
        Ok(t)
    }
}

fn init_tracing(verbose: u8, quiet: bool) {
    use tracing_subscriber::EnvFilter;
    let level = if quiet {
        "error"
    } else {
        match verbose {
            0 => "warn",
            1 => "info",
            2 => "debug",
            _ => "trace",
        }
    };
    let filter = EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new(level));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .try_init();
}

pub fn main() -> ExitCode {
    let cli = Cli::parse();
    init_tracing(cli.verbose, cli.quiet);
    let result = match cli.command {
        Some(Command::Topologies) => {
            list_topologies();
            Ok(ExitCode::SUCCESS)
        }
        Some(Command::Validate { files }) => Ok(validate(&files)),
        Some(Command::Run(args)) => run(&args, cli.quiet),
        None if cli.run.topology.is_some() => run(&cli.run, cli.quiet),
        None => {
            use clap::CommandFactory;
            let _ = Cli::command().print_help();
            return ExitCode::from(2);
        }
    };
    match result {
        Ok(code) => code,
        Err(e)
            if e.downcast_ref::<std::io::Error>()
                .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe) =>
        {
            // stdout closed by the reader (`| head`): nothing left to say.
            ExitCode::SUCCESS
        }
        Err(e) => {
            let usage = e.downcast_ref::<UsageError>().is_some();
            eprintln!("error: {e:#}");
            ExitCode::from(if usage { 2 } else { 1 })
        }
    }
}

fn list_topologies() {
    for (name, text) in builtin::ALL {
        let d = Topology::from_toml(text, name)
            .map(|t| t.description)
            .unwrap_or_else(|e| format!("(invalid: {e})"));
        println!("{name:<16} {d}");
    }
}

fn validate(files: &[PathBuf]) -> ExitCode {
    let mut bad = false;
    for f in files {
        match Topology::from_path(f) {
            Ok(t) => println!(
                "{}: ok — `{}`, {} nodes, {} directed links, {} model, {} steps",
                f.display(),
                t.name,
                t.nodes.len(),
                t.links.len(),
                t.model.kind(),
                t.sim.steps()
            ),
            Err(e) => {
                bad = true;
                eprintln!("{e}");
            }
        }
    }
    if bad {
        ExitCode::from(2)
    } else {
        ExitCode::SUCCESS
    }
}

fn run(args: &RunArgs, quiet: bool) -> anyhow::Result<ExitCode> {
    let topo = Arc::new(args.topology()?);
    let steps = topo.sim.steps();
    tracing::info!(topology = %topo.name, seed = topo.sim.seed, steps, "starting");
    let progress = (!quiet && !args.json).then(|| progress_bar(steps));
    let opts = RunOptions {
        clock: if args.realtime { Clock::Realtime } else { Clock::Virtual },
        record_trace: args.out.is_some(),
        progress: progress
            .clone()
            .map(|pb| -> net::Progress { Arc::new(move |d, _| pb.set_position(d)) }),
        ..Default::default()
    };
    let rt = tokio::runtime::Builder::new_multi_thread().enable_all().build()?;
    let shutdown = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    let mut out = rt.block_on(net::run(topo.clone(), opts, shutdown))?;
    if let Some(pb) = progress {
        pb.finish_and_clear();
    }
    let clock = if args.realtime { Clock::Realtime } else { Clock::Virtual };
    let s = summary::Summary::build(
        &topo,
        clock.as_str(),
        &out.reports,
        out.observer.summary(),
        out.steps_done,
        out.interrupted,
        out.wall_s,
        out.socket_losses,
    );
    // Print first: whatever happens to the files, the result is not lost.
    let mut stdout = std::io::stdout().lock();
    if args.json {
        writeln!(stdout, "{}", s.to_json())?;
    } else {
        s.write_table(&mut stdout)?;
    }
    drop(stdout);
    if let Some(dir) = &args.out {
        let mut rows = Vec::new();
        for r in &mut out.reports {
            rows.append(&mut r.trace);
        }
        rows.sort_by_key(|r| (r.step, r.node, !r.networked));
        let fused = out.observer.plot_rows();
        write_outputs(dir, &topo, &s, &rows, &fused)?;
        if !args.json {
            println!(
                "\nwrote {}/{{summary.json, trace.csv, links.csv, trajectory.svg, error.svg, trace_p.svg}}",
                dir.display()
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}

fn progress_bar(steps: u64) -> indicatif::ProgressBar {
    let pb = indicatif::ProgressBar::new(steps);
    pb.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} steps ({per_sec}, eta {eta})",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    pb
}

/// Write to a temporary name, then rename: a reader never sees a half-written file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let tmp = path.with_extension(format!(
        "{}.tmp",
        path.extension().and_then(|e| e.to_str()).unwrap_or("")
    ));
    std::fs::write(&tmp, bytes)?;
    std::fs::rename(&tmp, path)
}

fn write_outputs(
    dir: &Path,
    topo: &Topology,
    s: &summary::Summary,
    rows: &[crate::node::TraceRow],
    fused: &[crate::report::observer::FusedRow],
) -> anyhow::Result<()> {
    use anyhow::Context;
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let put = |name: &str, bytes: &[u8]| {
        write_atomic(&dir.join(name), bytes).with_context(|| format!("cannot write {}", dir.join(name).display()))
    };
    put("summary.json", s.to_json().as_bytes())?;
    let mut buf = Vec::new();
    summary::write_trace(&mut buf, &Truth::new(topo).columns(), topo.sim.rate_hz, rows)?;
    put("trace.csv", &buf)?;
    let mut buf = Vec::new();
    summary::write_links(&mut buf, &s.links)?;
    put("links.csv", &buf)?;
    let pose = matches!(topo.model, ModelConfig::Pose(_));
    let title = |what: &str| format!("{} — {what} (seed {})", topo.name, topo.sim.seed);
    put(
        "trajectory.svg",
        plot::trajectory(rows, fused, pose, &title("trajectories"))?.as_bytes(),
    )?;
    put(
        "error.svg",
        plot::error(
            rows,
            fused,
            topo.sim.dt(),
            pose,
            &title("error, networked vs independent"),
        )?
        .as_bytes(),
    )?;
    put(
        "trace_p.svg",
        plot::trace_p(rows, topo.sim.dt(), &title("trace P, networked vs independent"))?.as_bytes(),
    )?;
    Ok(())
}
