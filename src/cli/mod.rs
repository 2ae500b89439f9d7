//! Command line: clap definitions, tracing setup, exit codes (0 success, 2 bad input, 1 failure while running).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;

use clap::{Args, Parser, Subcommand, ValueEnum};

use crate::link::LossModel;
use crate::net::{self, Clock, RunOptions};
use crate::report::trace::TraceRecorder;
use crate::report::{plot, summary};
use crate::scenario::{builtin, Overrides, Scenario, ScenarioError};

mod protocol;
mod reconstruct;
mod reproduce;

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
        /// Scenario files (TOML) to check.
        #[arg(required = true)]
        files: Vec<PathBuf>,
    },
    /// Run one node of a topology as its own process (realtime; one host of a multi-host network).
    Node(NodeArgs),
    /// Merge the parts written by `simnet node --out` into one summary, table and plots.
    Collect(CollectArgs),
    /// Print a docker compose file that runs a topology with one container per node.
    Compose(ComposeArgs),
    /// Covariance bounds of a linear model under intermittent observations (Sinopoli et al.): λ_min, λ̄, S̄, V̄.
    Bounds(BoundsArgs),
    /// Find β weights that keep (17) and (19) feasible along a run with the most useful exchange (Sequeira (2023) §5).
    Protocol(protocol::ProtocolArgs),
    /// Rerun a source document's experiments: a table of its claims with simnet's figures, and the plots.
    #[command(subcommand)]
    Reproduce(reproduce::Paper),
    /// Position from a recorded IMU file as a boundary value problem (FEM), beside the trapezoid rule.
    Reconstruct(reconstruct::ReconstructArgs),
}

#[derive(Args, Debug, Clone)]
pub struct BoundsArgs {
    /// A topology with a linear model (its A, C, Q, R; --measure runs it).
    #[arg(long, short = 't')]
    pub topology: Option<String>,
    /// A as a TOML array, e.g. '[[-1.25]]' (instead of a topology).
    #[arg(long, allow_hyphen_values = true)]
    pub a: Option<String>,
    /// C (outputs × states) as a TOML array, with --a.
    #[arg(long)]
    pub c: Option<String>,
    /// Q, the process noise covariance, as a TOML array, with --a.
    #[arg(long)]
    pub q: Option<String>,
    /// R, the measurement noise covariance, as a TOML array, with --a.
    #[arg(long)]
    pub r: Option<String>,
    /// Arrival rate λ at which to give S̄ and V̄ (default: 1 − the topology's link loss, or 0.5).
    #[arg(allow_hyphen_values = true, long, value_parser = probability)]
    pub lambda: Option<f64>,
    /// Also run the topology at that arrival rate and print the measured mean trace P_{k|k−1}.
    #[arg(long)]
    pub measure: bool,
    /// Bounds (and measurements, with --measure) over a grid of arrival rates, with a plot.
    #[arg(long)]
    pub sweep: bool,
    /// Where --sweep writes bounds.csv and bounds.svg.
    #[arg(long, default_value = "out/bounds")]
    pub out: PathBuf,
    /// Simulated duration of each --measure run, s.
    #[arg(allow_hyphen_values = true, long, value_parser = positive)]
    pub duration: Option<f64>,
    /// Seed of each --measure run (default: the topology's).
    #[arg(allow_hyphen_values = true, long)]
    pub seed: Option<u64>,
}

#[derive(Args, Debug, Clone)]
#[command(mut_arg("out", |a| a.help("Write this node's part here: node-ID.json, trace-ID.csv, estimates-ID.csv (for `simnet collect`)").long_help(None)))]
pub struct NodeArgs {
    /// This node's id in the topology.
    #[arg(long)]
    pub id: u32,
    /// Address to bind (default 0.0.0.0 and the port of the node's `addr`, or 7000).
    #[arg(long)]
    pub bind: Option<std::net::SocketAddr>,
    /// A neighbour's address, overriding the topology (`addr`, default `node<ID>:7000`). Repeatable.
    #[arg(allow_hyphen_values = true, long = "peer", value_name = "ID=HOST:PORT", value_parser = peer)]
    pub peers: Vec<(u32, String)>,
    /// Seconds to wait for every neighbour before starting alone.
    #[arg(allow_hyphen_values = true, long, default_value_t = 30.0, value_parser = positive)]
    pub handshake_timeout: f64,
    #[command(flatten)]
    pub run: RunArgs,
}

#[derive(Args, Debug, Clone)]
pub struct CollectArgs {
    /// Directories holding node-*.json parts.
    #[arg(required = true)]
    pub dirs: Vec<PathBuf>,
    /// Where to write the merged summary.json, trace.csv, links.csv and plots (default: the first directory).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print the merged summary.json instead of the table.
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug, Clone)]
pub struct ComposeArgs {
    /// Built-in name or path of the topology to run, one container per node.
    #[arg(long, short = 't')]
    pub topology: String,
    /// Image name of the simnet image.
    #[arg(long, default_value = "simnet:latest")]
    pub image: String,
}

fn peer(s: &str) -> Result<(u32, String), String> {
    let (id, addr) = s
        .split_once('=')
        .ok_or_else(|| format!("expected ID=HOST:PORT, got `{s}`"))?;
    let id = id.parse::<u32>().map_err(|_| format!("`{id}` is not a node id"))?;
    if !addr.contains(':') {
        return Err(format!("`{addr}` needs a port (HOST:PORT)"));
    }
    Ok((id, addr.to_string()))
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
    /// Packet loss probability on every link (stationary loss for Gilbert–Elliott); unset: the topology's own.
    #[arg(long, env = "SIMNET_LOSS", allow_hyphen_values = true, value_parser = probability)]
    pub loss: Option<f64>,
    /// Loss process for --loss.
    #[arg(long, env = "SIMNET_LOSS_MODEL", value_enum, requires = "loss")]
    pub loss_model: Option<LossKind>,
    /// Mean loss run in packets (Gilbert–Elliott: r = 1/B, p = L·r/(1−L)).
    #[arg(long, env = "SIMNET_BURST", allow_hyphen_values = true, value_parser = at_least_one)]
    pub burst: Option<f64>,
    /// Constant one-way delay on every link, ms.
    #[arg(long, env = "SIMNET_DELAY", allow_hyphen_values = true, value_parser = non_negative)]
    pub delay: Option<f64>,
    /// Jitter on every link, ms (uniform ± unless the topology says normal).
    #[arg(long, env = "SIMNET_JITTER", allow_hyphen_values = true, value_parser = non_negative)]
    pub jitter: Option<f64>,
    /// Probability that a link delivers a datagram twice.
    #[arg(long, env = "SIMNET_DUPLICATE", allow_hyphen_values = true, value_parser = probability)]
    pub duplicate: Option<f64>,
    /// Probability that a link flips one bit of a datagram (the receiver's checksum must catch it).
    #[arg(long, env = "SIMNET_CORRUPT", allow_hyphen_values = true, value_parser = probability)]
    pub corrupt: Option<f64>,
    /// Simulated duration, s.
    #[arg(long, env = "SIMNET_DURATION", allow_hyphen_values = true, value_parser = positive)]
    pub duration: Option<f64>,
    /// Step rate, Hz.
    #[arg(long, env = "SIMNET_RATE", allow_hyphen_values = true, value_parser = positive)]
    pub rate: Option<f64>,
    /// Run seed (every random stream derives from it).
    #[arg(allow_hyphen_values = true, long, env = "SIMNET_SEED")]
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

/// The longest run accepted (as for `sim.duration_s` in a topology file).
const MAX_STEPS: f64 = 1e8;

/// An error for the user: exit code 2.
#[derive(Debug, thiserror::Error)]
pub enum UsageError {
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
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
    pub fn topology(&self) -> Result<Scenario, UsageError> {
        let name = self
            .topology
            .as_deref()
            .ok_or_else(|| UsageError::Option("--topology NAME|PATH is required (see `simnet topologies`)".into()))?;
        let t = Scenario::resolve(name)?.with(&self.overrides()?)?;
        for w in t.warnings() {
            tracing::warn!("{}: {w}", t.name);
        }
        if t.sim.duration_s * t.sim.rate_hz > MAX_STEPS {
            return Err(UsageError::Option(format!(
                "--duration/--rate: {} s at {} Hz is more than {MAX_STEPS:e} steps",
                t.sim.duration_s, t.sim.rate_hz
            )));
        }
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
    use std::io::IsTerminal;
    let fmt = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::stderr().is_terminal());
    // Without -v only warnings and errors show: a plain `WARN message` line reads best.
    let _ = if verbose == 0 {
        fmt.without_time().with_target(false).try_init()
    } else {
        fmt.try_init()
    };
}

pub fn main() -> ExitCode {
    // An empty override (compose passes `${SIMNET_LOSS:-}`) means unset: the topology's own setting.
    for v in crate::compose::ENV {
        if std::env::var_os(v).is_some_and(|x| x.is_empty()) {
            std::env::remove_var(v);
        }
    }
    let cli = Cli::parse();
    init_tracing(cli.verbose, cli.quiet);
    let result = match cli.command {
        Some(Command::Topologies) => {
            list_topologies();
            Ok(ExitCode::SUCCESS)
        }
        Some(Command::Validate { files }) => Ok(validate(&files)),
        Some(Command::Run(args)) => run(&args, cli.quiet),
        Some(Command::Node(args)) => run_node(&args, cli.quiet),
        Some(Command::Collect(args)) => collect(&args),
        Some(Command::Compose(args)) => compose(&args),
        Some(Command::Bounds(args)) => bounds(&args),
        Some(Command::Protocol(args)) => protocol::protocol(&args, cli.quiet),
        Some(Command::Reproduce(paper)) => reproduce::reproduce(&paper, cli.quiet),
        Some(Command::Reconstruct(args)) => reconstruct::reconstruct(&args),
        None if cli.run.topology.is_some() => run(&cli.run, cli.quiet),
        None if std::env::args_os().len() > 1 => Err(UsageError::Option(
            "a run needs --topology NAME|PATH (`simnet topologies` lists the built-ins)".into(),
        )
        .into()),
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
            // stdout closed by the reader (`| head`): the files are written, but what was printed is cut short,
            // which a shell reports as 128 + SIGPIPE.
            ExitCode::from(141)
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
        let d = Scenario::from_toml(text, name)
            .map(|t| t.description)
            .unwrap_or_else(|e| format!("(invalid: {e})"));
        println!("{name:<16} {d}");
    }
}

fn validate(files: &[PathBuf]) -> ExitCode {
    let mut bad = false;
    for f in files {
        match Scenario::from_path(f).and_then(|t| t.check_recordings().map(|_| t)) {
            Ok(t) => println!(
                "{}: ok — `{}`, {}, {}, {} model, {} steps",
                f.display(),
                t.name,
                crate::scenario::count(t.nodes.len(), "node"),
                crate::scenario::count(t.links.len(), "directed link"),
                t.model.get().kind(),
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
    // A bad --out fails now, not after the run.
    let out_dir = args.out.as_deref().map(OutDir::prepare).transpose()?;
    let steps = topo.sim.steps();
    tracing::info!(topology = %topo.name, seed = topo.sim.seed, steps, "starting");
    let progress = (!quiet && !args.json).then(|| progress_bar(steps));
    let opts = RunOptions {
        clock: if args.realtime { Clock::Realtime } else { Clock::Virtual },
        trace: out_dir
            .as_ref()
            .map(|d| d.trace(&topo).map(|t| t.with_imu(d.imu_opener())))
            .transpose()?,
        progress: progress
            .clone()
            .map(|pb| -> net::Progress { Arc::new(move |d, _| pb.set_position(d)) }),
        ..Default::default()
    };
    let rt = tokio::runtime::Builder::new_multi_thread().enable_all().build()?;
    let mut out = rt.block_on(net::run(topo.clone(), opts, shutdown_signal()))?;
    if let Some(pb) = progress {
        pb.finish_and_clear();
    }
    let s = out.summary();
    // Files first: a reader that closes stdout early (`| head`) loses nothing.
    let mut wrote = Vec::new();
    if let Some(d) = &out_dir {
        // Each sensing node's IMU samples with the true pose (input for `simnet reconstruct`), streamed too.
        let imu = out.trace.as_ref().map(|t| t.imu_nodes()).unwrap_or_default();
        let (rows, fused) = d.finish_trace(out.trace.take())?;
        wrote = write_files(&d.dir, &s, topo.sim.dt(), &rows, &fused)?;
        for id in imu {
            let name = format!("imu-{id}.csv");
            d.rename_tmp(&name)?;
            wrote.push(name);
        }
    }
    print_summary(&s, args.json, None)?;
    if let (Some(d), false) = (&out_dir, args.json) {
        println!("\nwrote {}/{{{}}}", d.dir.display(), wrote.join(", "));
    }
    Ok(exit_code(s.interrupted))
}

/// For a run stopped early by a signal, whose partial results were still written: 128 + the signal, as a shell
/// reports it (130 for Ctrl-C, 143 for SIGTERM).
fn exit_code(interrupted: bool) -> ExitCode {
    match STOPPED_BY.load(std::sync::atomic::Ordering::SeqCst) {
        0 if !interrupted => ExitCode::SUCCESS,
        0 => ExitCode::from(130),
        sig => ExitCode::from(128 + sig),
    }
}

/// An output directory checked before the run: it exists (or was made) and can be written.
struct OutDir {
    dir: PathBuf,
}

const TRACE_TMP: &str = "trace.csv.tmp";

/// A bad output directory is a usage error found before any work (exit 2), for every command that writes one.
pub(crate) fn check_out(dir: &Path) -> Result<(), UsageError> {
    OutDir::prepare(dir).map(|_| ())
}

impl OutDir {
    fn prepare(dir: &Path) -> Result<OutDir, UsageError> {
        let bad = |what: String| UsageError::Option(format!("--out {}: {what}", dir.display()));
        if dir.exists() && !dir.is_dir() {
            return Err(bad("exists and is not a directory".into()));
        }
        std::fs::create_dir_all(dir).map_err(|e| bad(format!("cannot create it: {e}")))?;
        let probe = dir.join(".simnet-write-check");
        std::fs::write(&probe, b"").map_err(|e| bad(format!("cannot write in it: {e}")))?;
        let _ = std::fs::remove_file(&probe);
        Ok(OutDir { dir: dir.to_path_buf() })
    }

    /// The recorder that streams `trace.csv` into this directory (under a temporary name until the run ends).
    fn trace(&self, topo: &Scenario) -> Result<TraceRecorder, UsageError> {
        let path = self.dir.join(TRACE_TMP);
        let f = std::fs::File::create(&path)
            .map_err(|e| UsageError::Option(format!("--out: cannot write {}: {e}", path.display())))?;
        Ok(TraceRecorder::for_topology(topo).to_writer(Box::new(std::io::BufWriter::new(f))))
    }

    /// Close the streamed `trace.csv`; the plot sample it kept.
    fn finish_trace(
        &self,
        rec: Option<TraceRecorder>,
    ) -> anyhow::Result<(Vec<crate::node::TraceRow>, Vec<crate::report::observer::FusedRow>)> {
        use anyhow::Context;
        let path = self.dir.join("trace.csv");
        let sample = rec
            .map(TraceRecorder::finish)
            .transpose()
            .with_context(|| format!("cannot write {}", path.display()))?
            .unwrap_or_default();
        std::fs::rename(self.dir.join(TRACE_TMP), &path).with_context(|| format!("cannot write {}", path.display()))?;
        Ok(sample)
    }

    /// Opens `imu-ID.csv.tmp` for the recorder ([`OutDir::rename_tmp`] gives it its name at the end).
    fn imu_opener(&self) -> crate::report::trace::ImuOpener {
        let dir = self.dir.clone();
        Box::new(move |id| {
            let f = std::fs::File::create(dir.join(format!("imu-{id}.csv.tmp")))?;
            Ok(Box::new(std::io::BufWriter::new(f)) as Box<dyn Write + Send>)
        })
    }

    fn rename_tmp(&self, name: &str) -> anyhow::Result<()> {
        use anyhow::Context;
        let path = self.dir.join(name);
        std::fs::rename(self.dir.join(format!("{name}.tmp")), &path)
            .with_context(|| format!("cannot write {}", path.display()))
    }

    fn put(&self, name: &str, bytes: &[u8]) -> anyhow::Result<()> {
        use anyhow::Context;
        let path = self.dir.join(name);
        write_atomic(&path, bytes).with_context(|| format!("cannot write {}", path.display()))
    }
}

/// summary.json or the table (with an optional note under it) on stdout.
fn print_summary(s: &summary::Summary, json: bool, note: Option<&str>) -> std::io::Result<()> {
    let mut stdout = std::io::stdout().lock();
    if json {
        writeln!(stdout, "{}", s.to_json())
    } else {
        s.write_table(&mut stdout)?;
        note.map_or(Ok(()), |n| writeln!(stdout, "{n}"))
    }
}

fn progress_bar(steps: u64) -> indicatif::ProgressBar {
    progress_bar_of(
        steps,
        "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} steps ({per_sec}, eta {eta})",
    )
}

fn progress_bar_of(len: u64, template: &str) -> indicatif::ProgressBar {
    let pb = indicatif::ProgressBar::new(len);
    pb.set_style(
        indicatif::ProgressStyle::with_template(template).unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
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

/// summary.json, links.csv and the three plots, each written atomically; the names written.
fn write_files(
    dir: &Path,
    s: &summary::Summary,
    dt: f64,
    rows: &[crate::node::TraceRow],
    fused: &[crate::report::observer::FusedRow],
) -> anyhow::Result<Vec<String>> {
    let d = OutDir { dir: dir.to_path_buf() };
    d.put("summary.json", s.to_json().as_bytes())?;
    let mut buf = Vec::new();
    summary::write_links(&mut buf, &s.links)?;
    d.put("links.csv", &buf)?;
    let title = |what: &str| format!("{} — {what} (seed {})", s.topology, s.seed);
    d.put(
        "trajectory.svg",
        plot::trajectory(rows, fused, s.model.trajectory_view(), &title("trajectories"))?.as_bytes(),
    )?;
    d.put(
        "error.svg",
        plot::error(rows, fused, dt, s.model, &title("error, networked vs independent"))?.as_bytes(),
    )?;
    d.put(
        "trace_p.svg",
        plot::trace_p(rows, dt, &title("trace P, networked vs independent"))?.as_bytes(),
    )?;
    Ok([
        "trace.csv",
        "summary.json",
        "links.csv",
        "trajectory.svg",
        "error.svg",
        "trace_p.svg",
    ]
    .map(String::from)
    .to_vec())
}

fn run_node(args: &NodeArgs, quiet: bool) -> anyhow::Result<ExitCode> {
    use crate::net::host::{run_node, HostConfig};
    use std::collections::HashMap;
    let topo = Arc::new(args.run.topology()?);
    let index = topo
        .index_of(args.id)
        .ok_or_else(|| UsageError::Option(format!("--id {}: no [[node]] has this id in `{}`", args.id, topo.name)))?;
    let mut peers: HashMap<usize, String> = HashMap::new();
    for l in &topo.links {
        for j in [l.from, l.to] {
            if (l.from == index || l.to == index) && j != index {
                peers.insert(j, crate::compose::node_addr(&topo, j));
            }
        }
    }
    for (id, addr) in &args.peers {
        let j = topo
            .index_of(*id)
            .ok_or_else(|| UsageError::Option(format!("--peer {id}=…: no [[node]] has id {id}")))?;
        if !peers.contains_key(&j) {
            return Err(UsageError::Option(format!(
                "--peer {id}=…: node {id} is not a neighbour of node {}",
                args.id
            ))
            .into());
        }
        peers.insert(j, addr.clone());
    }
    let own = crate::compose::node_addr(&topo, index);
    let port = own
        .rsplit_once(':')
        .and_then(|(_, p)| p.parse::<u16>().ok())
        .ok_or_else(|| UsageError::Option(format!("node {}: address `{own}` has no port", args.id)))?;
    let bind = args
        .bind
        .unwrap_or_else(|| std::net::SocketAddr::from(([0, 0, 0, 0], port)));
    let out_dir = args.run.out.as_deref().map(OutDir::prepare).transpose()?;
    let steps = topo.sim.steps();
    let progress = (!quiet && !args.run.json).then(|| progress_bar(steps));
    let cfg = HostConfig {
        bind,
        peers,
        handshake_timeout: std::time::Duration::from_secs_f64(args.handshake_timeout),
        record_trace: args.run.out.is_some(),
        progress: progress
            .clone()
            .map(|pb| -> net::Progress { Arc::new(move |d, _| pb.set_position(d)) }),
    };
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()?;
    let out = rt.block_on(run_node(topo.clone(), index, cfg, shutdown_signal()))?;
    if let Some(pb) = progress {
        pb.finish_and_clear();
    }
    let mut s = summary::Summary::build(
        &topo,
        "realtime",
        std::slice::from_ref(&out.report),
        None,
        out.steps_done,
        out.interrupted,
        out.wall_s,
        0,
    );
    let id_of = |j: usize| topo.nodes[j].id;
    s.part = Some(crate::report::parts::PartInfo {
        node: args.id,
        first_step: out.report.counters.first_step,
        steps_done: out.steps_done,
        links_out: out.report.links_out.iter().map(|(to, c)| (id_of(*to), *c)).collect(),
        rx: topo
            .in_links(index)
            .map(|l| (id_of(l.from), out.report.rx[l.from]))
            .collect(),
        fusion: topo.model.get().fusion(),
    });
    // One end of a link cannot tell its loss: the per-link figures come from `simnet collect`.
    s.links.clear();
    if let Some(d) = &out_dir {
        let mut buf = Vec::new();
        crate::report::trace::write_trace(&mut buf, &topo.model.get().columns(), &out.report.trace)?;
        d.put(&format!("trace-{}.csv", args.id), &buf)?;
        let mut buf = Vec::new();
        crate::report::parts::write_estimates(&mut buf, &out.estimates)?;
        d.put(&format!("estimates-{}.csv", args.id), &buf)?;
        // The part last: its presence means the node finished writing.
        d.put(&format!("node-{}.json", args.id), s.to_json().as_bytes())?;
    }
    print_summary(
        &s,
        args.run.json,
        Some("(per-link figures: `simnet collect` on the parts of every node)"),
    )?;
    Ok(exit_code(s.interrupted))
}

/// The signal that stopped the run, for its exit code (0 while none did).
static STOPPED_BY: std::sync::atomic::AtomicU8 = std::sync::atomic::AtomicU8::new(0);

/// Ctrl-C (SIGINT) or SIGTERM (what `docker stop` sends); which one is kept for [`exit_code`].
async fn shutdown_signal() {
    use std::sync::atomic::Ordering;
    #[cfg(unix)]
    {
        use tokio::signal::unix::{signal, SignalKind};
        match signal(SignalKind::terminate()) {
            Ok(mut term) => {
                tokio::select! {
                    _ = tokio::signal::ctrl_c() => STOPPED_BY.store(2, Ordering::SeqCst),
                    _ = term.recv() => STOPPED_BY.store(15, Ordering::SeqCst),
                }
            }
            Err(_) => {
                let _ = tokio::signal::ctrl_c().await;
                STOPPED_BY.store(2, Ordering::SeqCst);
            }
        }
    }
    #[cfg(not(unix))]
    {
        let _ = tokio::signal::ctrl_c().await;
        STOPPED_BY.store(2, Ordering::SeqCst);
    }
}

fn collect(args: &CollectArgs) -> anyhow::Result<ExitCode> {
    use crate::report::parts::{merge, read_estimates, read_trace, PartError};
    use anyhow::Context;
    use std::collections::BTreeMap;
    let mut parts = Vec::new();
    let mut estimates = BTreeMap::new();
    let mut rows = Vec::new();
    let mut columns = Vec::new();
    for dir in &args.dirs {
        let entries = std::fs::read_dir(dir).map_err(|e| UsageError::Option(format!("{}: {e}", dir.display())))?;
        let mut names: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
        names.sort();
        for p in names {
            let name = p.file_name().and_then(|n| n.to_str()).unwrap_or_default().to_string();
            let Some(id) = name.strip_prefix("node-").and_then(|n| n.strip_suffix(".json")) else {
                continue;
            };
            let text = std::fs::read_to_string(&p).with_context(|| format!("cannot read {}", p.display()))?;
            let s: summary::Summary = serde_json::from_str(&text)
                .map_err(|e| UsageError::Option(format!("{}: not a node part: {e}", p.display())))?;
            let node_index = parts.len();
            parts.push(s);
            let est = dir.join(format!("estimates-{id}.csv"));
            if let Ok(f) = std::fs::File::open(&est) {
                let es = read_estimates(std::io::BufReader::new(f), node_index, &est.display().to_string())
                    .map_err(|e| UsageError::Option(e.to_string()))?;
                estimates.insert(id.parse::<u32>().unwrap_or(u32::MAX), es);
            }
            let tr = dir.join(format!("trace-{id}.csv"));
            if let Ok(f) = std::fs::File::open(&tr) {
                let (names, r) = read_trace(std::io::BufReader::new(f), &tr.display().to_string())
                    .map_err(|e| UsageError::Option(e.to_string()))?;
                if columns.is_empty() {
                    columns = names;
                }
                rows.extend(r);
            }
        }
    }
    if parts.is_empty() {
        let dirs: Vec<String> = args.dirs.iter().map(|d| d.display().to_string()).collect();
        return Err(UsageError::Option(PartError::Empty(dirs.join(", ")).to_string()).into());
    }
    let (s, mut observer) = merge(&parts, &estimates).map_err(|e| UsageError::Option(e.to_string()))?;
    let d = OutDir::prepare(args.out.as_deref().unwrap_or(&args.dirs[0]))?;
    rows.sort_by_key(|r| (r.step, r.node, !r.networked));
    let dt = 1.0 / s.rate_hz;
    let path = d.dir.join(TRACE_TMP);
    let f = std::fs::File::create(&path)
        .map_err(|e| UsageError::Option(format!("cannot write {}: {e}", path.display())))?;
    let mut rec =
        TraceRecorder::new(columns, observer.layout(), dt, s.steps).to_writer(Box::new(std::io::BufWriter::new(f)));
    // Fused rows go after the node rows of their step.
    let mut fused = observer.drain_rows().into_iter().peekable();
    for chunk in rows.chunk_by(|a, b| a.step == b.step) {
        rec.rows(chunk.to_vec());
        let step = chunk[0].step;
        let mut now = Vec::new();
        while let Some(f) = fused.next_if(|f| f.step <= step) {
            now.push(f);
        }
        rec.fused(now);
    }
    rec.fused(fused.collect());
    let (rows, fused) = d.finish_trace(Some(rec))?;
    let wrote = write_files(&d.dir, &s, dt, &rows, &fused)?;
    print_summary(&s, args.json, None)?;
    if !args.json {
        println!("\nwrote {}/{{{}}}", d.dir.display(), wrote.join(", "));
    }
    Ok(ExitCode::SUCCESS)
}

fn compose(args: &ComposeArgs) -> anyhow::Result<ExitCode> {
    let topo = Scenario::resolve(&args.topology).map_err(UsageError::from)?;
    let builtin = builtin::get(&args.topology).is_some();
    print!(
        "{}",
        crate::compose::compose_file(&topo, &args.topology, builtin, &args.image)
    );
    Ok(ExitCode::SUCCESS)
}

fn matrix_arg(name: &str, text: &str) -> Result<nalgebra::DMatrix<f64>, UsageError> {
    #[derive(serde::Deserialize)]
    struct M {
        m: Vec<Vec<f64>>,
    }
    let rows = toml::from_str::<M>(&format!("m = {text}"))
        .map_err(|e| {
            UsageError::Option(format!(
                "--{name}: expected a TOML array of rows such as [[1.0, 0.1], [0.0, 1.0]]: {e}"
            ))
        })?
        .m;
    let c = rows.first().map_or(0, |r| r.len());
    if rows.is_empty() || c == 0 || rows.iter().any(|r| r.len() != c) {
        return Err(UsageError::Option(format!(
            "--{name}: rows must be non-empty and of equal length"
        )));
    }
    Ok(nalgebra::DMatrix::from_fn(rows.len(), c, |i, j| rows[i][j]))
}

#[allow(non_snake_case)] // the textbook names A, C, Q, R
fn bounds(args: &BoundsArgs) -> anyhow::Result<ExitCode> {
    use crate::estimate::bounds::{
        critical_upper, lambda_min, lower_bound, markov_condition, spectral_radius, upper_bound,
    };
    use crate::link::LossModel;
    let topo = match &args.topology {
        Some(t) => {
            let topo = Scenario::resolve(t)
                .and_then(|t| {
                    t.with(&Overrides {
                        duration_s: args.duration,
                        seed: args.seed,
                        ..Default::default()
                    })
                })
                .map_err(UsageError::from)?;
            Some(topo)
        }
        None => None,
    };
    let (A, C, Q, R) = match (&topo, &args.a, &args.c, &args.q, &args.r) {
        (Some(t), None, None, None, None) => match t.model.as_linear() {
            Some(m) => (m.A().clone(), m.C().clone(), m.Q().clone(), m.R().clone()),
            None => {
                return Err(UsageError::Option(format!(
                    "`{}` has a {} model: bounds need kind = \"linear\"",
                    t.name,
                    t.model.get().kind()
                ))
                .into())
            }
        },
        (None, Some(a), Some(c), Some(q), Some(r)) => (
            matrix_arg("a", a)?,
            matrix_arg("c", c)?,
            matrix_arg("q", q)?,
            matrix_arg("r", r)?,
        ),
        _ => return Err(UsageError::Option("give --topology (linear model), or all of --a --c --q --r".into()).into()),
    };
    // The same checks as a topology's [model].
    let text = format!(
        "[model]\nkind = \"linear\"\na = {}\nc = {}\nq = {}\nr = {}\n[[node]]\nid = 0\n",
        toml_matrix(&A),
        toml_matrix(&C),
        toml_matrix(&Q),
        toml_matrix(&R)
    );
    Scenario::from_toml(&text, "--a/--c/--q/--r").map_err(UsageError::from)?;
    if args.sweep {
        check_out(&args.out)?;
    }
    if args.measure && topo.is_none() {
        return Err(UsageError::Option("--measure runs a topology: give --topology".into()).into());
    }
    let link_loss = topo.as_ref().and_then(|t| t.links.first().map(|l| l.config.loss));
    let lambda = args
        .lambda
        .unwrap_or_else(|| link_loss.map_or(0.5, |l| 1.0 - l.stationary_loss()));
    let rho = spectral_radius(&A).ok_or_else(|| anyhow::anyhow!("the eigenvalues of A did not converge"))?;
    let lmin = lambda_min(&A).unwrap_or(f64::NAN);
    let crit = critical_upper(&A, &C, &Q, &R, 1e-6)?;
    let lbar = crit.value();
    println!("system: {} states, {} outputs; ρ(A) = {rho:.6}", A.nrows(), C.nrows());
    println!("λ_min = {lmin:.6}   (1 − 1/ρ(A)²: below it the expected covariance diverges)");
    if !lbar.is_finite() {
        println!("λ̄     = ∞   (even without loss the filter is unstable: an undetectable unstable mode)");
    } else if crit.lo == crit.hi {
        println!("λ̄     = {lbar:.6}   (C is invertible: λ̄ = λ_min exactly, Sinopoli et al. Thm. 6)");
    } else if crit.to_tolerance {
        println!(
            "λ̄     ∈ ({:.7}, {:.7}]   (bisection: the MARE iteration from 0 diverges at the left end, converges at the right)",
            crit.lo, crit.hi
        );
    } else {
        println!(
            "λ̄     ∈ ({:.7}, {:.7}]   (bisection stopped where the MARE iteration neither converged nor diverged in {:.0e} steps: this is the precision reached)",
            crit.lo, crit.hi, crate::estimate::bounds::MAX_ITER as f64
        );
    }
    let measure = |l: f64| -> anyhow::Result<Option<f64>> {
        let Some(t) = &topo else { return Ok(None) };
        let t = Arc::new(t.with(&Overrides {
            loss: Some(LossModel::Bernoulli { p: 1.0 - l }),
            ..Default::default()
        })?);
        let estimators: Vec<u32> = t
            .nodes
            .iter()
            .filter(|n| n.role == crate::scenario::Role::Estimator)
            .map(|n| n.id)
            .collect();
        if estimators.is_empty() {
            return Err(UsageError::Option(format!(
                "--measure: `{}` has no estimator node fed over the network",
                t.name
            ))
            .into());
        }
        let rt = tokio::runtime::Builder::new_multi_thread().enable_all().build()?;
        let out = rt.block_on(net::run(t.clone(), RunOptions::default(), std::future::pending()))?;
        let s = out.summary();
        let v: Vec<f64> = s
            .nodes
            .iter()
            .filter(|n| estimators.contains(&n.id))
            .filter_map(|n| n.networked.as_ref().and_then(|f| f.mean_trace_p_prior))
            .collect();
        Ok((!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64))
    };
    use crate::estimate::bounds::FixedPoint;
    let at = |l: f64| -> anyhow::Result<(FixedPoint, FixedPoint)> {
        Ok((lower_bound(&A, &Q, l)?, upper_bound(&A, &C, &Q, &R, l)?))
    };
    let fmt = |v: Option<f64>| v.map_or("—".to_string(), |x| format!("{x:.4}"));
    let fmt_fp = |v: &FixedPoint| match v {
        FixedPoint::Converged(m) => format!("{:.4}", m.trace()),
        FixedPoint::Diverged => "∞ (no fixed point)".into(),
        FixedPoint::Undecided => "not reached (the iteration still creeps: at the edge of stability)".into(),
    };
    let trace_of = |v: &FixedPoint| v.matrix().map(|m| m.trace());
    let (sf, vf) = at(lambda)?;
    let (s, v) = (trace_of(&sf), trace_of(&vf));
    let bursty = matches!(link_loss, Some(LossModel::GilbertElliott { .. }));
    print!(
        "λ = {lambda}{}: trace S̄ = {}, trace V̄ = {}",
        if bursty {
            " (i.i.d. arrivals at the link's mean rate: NOT bounds for its bursty loss)"
        } else {
            ""
        },
        fmt_fp(&sf),
        fmt_fp(&vf)
    );
    if args.measure && !args.sweep {
        let m = measure(lambda)?;
        print!(", measured mean trace P_(k|k−1) = {}", fmt(m));
        if let (Some(s), Some(v), Some(m), false) = (s, v, m, bursty) {
            print!(
                " ({})",
                if s <= m && m <= v {
                    "within the bounds"
                } else {
                    "OUTSIDE the bounds"
                }
            );
        }
    }
    println!();
    if let Some(LossModel::GilbertElliott {
        p,
        r,
        one_minus_h,
        one_minus_k,
    }) = link_loss
    {
        if let Some((lhs, decay, ok)) = markov_condition(&A, p, r, one_minus_h, one_minus_k) {
            let exact = A.nrows() == 1 || (C.is_square() && C.clone().try_inverse().is_some());
            println!(
                "Gilbert–Elliott link (p = {p}, r = {r}, 1−h = {one_minus_h}, 1−k = {one_minus_k}): loss runs decay at ρ(T·diag(1−k, 1−h)) = {decay:.4} per step; ρ(A)²·{decay:.4} = {lhs:.4} {} 1 → {}",
                if ok { "<" } else { "≥" },
                match (ok, exact) {
                    (true, true) => "satisfied: the expected covariance stays bounded (necessary and sufficient here: scalar or C invertible; You, Fu & Xie 2011)",
                    (true, false) => "satisfied, but only necessary for this system (Huang & Dey 2007): boundedness is not shown",
                    (false, _) => "NOT satisfied: the expected covariance diverges (Huang & Dey 2007)",
                }
            );
        }
    }
    if args.sweep {
        use anyhow::Context;
        let start = if lbar.is_finite() { lbar } else { lmin };
        let grid: Vec<f64> = (1..=12)
            .map(|i| start + (1.0 - start) * i as f64 / 12.0)
            .filter(|l| *l < 1.0 + 1e-12)
            .collect();
        let mut rows = Vec::new();
        println!("\n{:>8} {:>12} {:>12} {:>12}", "λ", "trace S̄", "trace V̄", "measured");
        for l in grid {
            let (sf, vf) = at(l)?;
            let (s, v) = (trace_of(&sf), trace_of(&vf));
            let m = if args.measure { measure(l)? } else { None };
            let cell = |f: &FixedPoint| match f {
                FixedPoint::Converged(m) => format!("{:.4}", m.trace()),
                FixedPoint::Diverged => "∞".into(),
                FixedPoint::Undecided => "not reached".into(),
            };
            println!(
                "{:>8.4} {:>12} {:>12} {:>12}",
                l,
                cell(&sf),
                cell(&vf),
                m.map_or("—".into(), |x| format!("{x:.4}"))
            );
            rows.push((l, s, v, m));
        }
        std::fs::create_dir_all(&args.out).with_context(|| format!("cannot create {}", args.out.display()))?;
        let mut csv = String::from("lambda,trace_s_bar,trace_v_bar,measured_trace_p_prior\n");
        let o = |v: Option<f64>| v.map_or(String::new(), |x| format!("{x}"));
        for (l, s, v, m) in &rows {
            csv += &format!("{l},{},{},{}\n", o(*s), o(*v), o(*m));
        }
        write_atomic(&args.out.join("bounds.csv"), csv.as_bytes())?;
        let svg = plot::covariance_bounds(
            &rows,
            lmin,
            lbar,
            &format!(
                "covariance bounds against the arrival rate{}",
                topo.as_ref().map_or(String::new(), |t| format!(" — {}", t.name))
            ),
        )?;
        write_atomic(&args.out.join("bounds.svg"), svg.as_bytes())?;
        println!("\nwrote {}/{{bounds.csv, bounds.svg}}", args.out.display());
    }
    Ok(ExitCode::SUCCESS)
}

fn toml_matrix(m: &nalgebra::DMatrix<f64>) -> String {
    let rows: Vec<String> = (0..m.nrows())
        .map(|i| {
            format!(
                "[{}]",
                (0..m.ncols())
                    .map(|j| format!("{:?}", m[(i, j)]))
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        })
        .collect();
    format!("[{}]", rows.join(", "))
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    /// Every argument of every subcommand says what it is for, and `node`/`protocol` explain their own `--out`.
    #[test]
    fn every_argument_has_a_help_line() {
        fn walk(cmd: &clap::Command, path: &str, missing: &mut Vec<String>, outs: &mut Vec<(String, String)>) {
            for a in cmd.get_arguments() {
                let id = a.get_id().as_str();
                if id == "help" || id == "version" {
                    continue;
                }
                match a.get_help() {
                    Some(h) if !h.to_string().trim().is_empty() => {
                        if id == "out" {
                            outs.push((path.to_string(), h.to_string()));
                        }
                    }
                    _ => missing.push(format!("{path} {id}")),
                }
            }
            for sub in cmd.get_subcommands() {
                walk(sub, &format!("{path} {}", sub.get_name()), missing, outs);
            }
        }
        let (mut missing, mut outs) = (Vec::new(), Vec::new());
        walk(&Cli::command(), "simnet", &mut missing, &mut outs);
        assert!(missing.is_empty(), "arguments without help: {missing:?}");
        let text = |p: &str| outs.iter().find(|(q, _)| q == p).map(|o| o.1.clone()).unwrap();
        assert_ne!(text("simnet node"), text("simnet run"), "node reuses run's --out help");
        assert_ne!(text("simnet protocol"), text("simnet run"));
    }
}
