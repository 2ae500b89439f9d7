//! `simnet sweep`: a campaign over any scenario keys × seeds on every core, resumable, with confidence intervals;
//! `--shard I/N` runs a 1/N of it, `sweep merge` joins shards, `--emit stack` prints a Docker Swarm stack for it.

use std::sync::atomic::{AtomicBool, Ordering};

use super::*;
use crate::campaign::{self, Axis, CampaignError, Plan, PlanFile, ShardInfo, Store};

#[derive(Args, Debug)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct SweepArgs {
    #[command(subcommand)]
    pub command: Option<SweepCommand>,
    /// Built-in name, `./topologies/NAME.toml`, or a path.
    #[arg(long, short = 't', required = true)]
    pub topology: Option<String>,
    /// A scenario key (its path in the file) and its values: KEY=V1,V2,... or KEY=START:END:STEP (END included).
    /// Repeat for the cartesian product (the first varies slowest).
    #[arg(long = "set", value_name = "KEY=VALUES", required = true)]
    pub set: Vec<String>,
    /// Seeds 1 … N at every point.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u64).range(1..=100_000))]
    pub seeds: u64,
    /// Estimators every run holds, comma-separated, or `all` (default: the topology's, else sequeira and
    /// independent, the node's two filters).
    #[arg(long, value_delimiter = ',', value_parser = super::args::estimator)]
    pub estimators: Option<Vec<super::args::EstimatorChoice>>,
    /// Consensus rounds per step (1 to 100).
    #[arg(long, value_parser = super::args::rounds)]
    pub rounds: Option<u64>,
    /// Simulated duration of every run, s.
    #[arg(long, allow_hyphen_values = true, value_parser = super::args::positive)]
    pub duration: Option<f64>,
    /// The campaign's directory: its plan, one record per run, and the tables, plot and manifest.
    #[arg(long, required_unless_present = "emit")]
    pub out: Option<PathBuf>,
    /// How every run moves its datagrams: in memory (`Sim`), or over UDP sockets on loopback.
    #[arg(long, value_enum, default_value = "memory")]
    pub transport: Transport,
    /// Run shard I of N (1-based): the runs whose index is I−1 modulo N.
    #[arg(long, env = "SIMNET_SHARD", value_parser = campaign::parse_shard)]
    pub shard: Option<(usize, usize)>,
    /// Also write runs and points as Parquet (zstd; needs a build with the `parquet` feature).
    #[arg(long, value_enum, default_value = "csv")]
    pub format: Format,
    /// Print a Docker Swarm stack file that runs the campaign as --replicas shards, instead of running it.
    #[arg(long, value_enum)]
    pub emit: Option<Emit>,
    /// The simnet image of the stack.
    #[arg(long, default_value = "simnet:latest")]
    pub image: String,
    /// Shards (tasks) of the stack.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..=10_000))]
    pub replicas: u64,
}

#[derive(Subcommand, Debug)]
pub enum SweepCommand {
    /// Join the runs of shards (the --out directories of `sweep --shard`) into the files one sweep writes.
    Merge {
        /// The shards' directories.
        #[arg(required = true)]
        dirs: Vec<PathBuf>,
        /// Where the joined campaign goes (default: the first directory).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Also write runs and points as Parquet.
        #[arg(long, value_enum, default_value = "csv")]
        format: Format,
    },
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Transport {
    Memory,
    Udp,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Emit {
    Stack,
}

impl Transport {
    fn name(self) -> &'static str {
        match self {
            Transport::Memory => "memory",
            Transport::Udp => "udp",
        }
    }
}

fn usage_or_run(e: CampaignError) -> anyhow::Error {
    if e.is_usage() {
        UsageError::Option(e.to_string()).into()
    } else {
        e.into()
    }
}

pub(super) fn sweep(args: &SweepArgs, quiet: bool) -> anyhow::Result<ExitCode> {
    if let Some(SweepCommand::Merge { dirs, out, format }) = &args.command {
        return merge(dirs, out.as_deref(), format.check()?, quiet);
    }
    let format = args.format.check()?;
    let topology = args.topology.as_deref().unwrap_or_default();
    let axes: Vec<Axis> = args
        .set
        .iter()
        .map(|s| Axis::parse(s).map_err(|e| UsageError::Option(format!("--set {e}"))))
        .collect::<Result<_, _>>()?;
    let base = campaign::sweep_base(
        &Scenario::resolve(topology).map_err(UsageError::from)?,
        args.estimators.as_deref().map(super::args::EstimatorChoice::kinds),
        args.rounds,
        args.duration,
    )
    .map_err(UsageError::from)?;
    // Every point is validated before the first run starts.
    let plan = Plan::new(base, axes, args.seeds).map_err(UsageError::from)?;
    if args.emit == Some(Emit::Stack) {
        crate::compose::check_image(&args.image).map_err(UsageError::Option)?;
        out!("{}", stack(args, topology));
        return Ok(ExitCode::SUCCESS);
    }
    let dir = args.out.as_deref().unwrap_or(Path::new("."));
    match run_campaign(&plan, dir, args.shard, args.transport, quiet)? {
        Campaign::Finished(file, done) => wrote(dir, &file, done, format),
        Campaign::Ended(code) => Ok(code),
    }
}

/// How [`run_campaign`] ended.
pub(super) enum Campaign {
    /// Every run is in the store: its files are written.
    Finished(PlanFile, campaign::Finished),
    /// A shard that is done while others are not, or runs missing (stopped or failed): the exit code.
    Ended(ExitCode),
}

/// The runs of `plan` (of shard I of N) missing from the store in `dir`, on every core, with a progress bar; then,
/// when the campaign is whole, its files. Ctrl-C or SIGTERM stops it with every finished run kept.
pub(super) fn run_campaign(
    plan: &Plan,
    dir: &Path,
    shard: Option<(usize, usize)>,
    transport: Transport,
    quiet: bool,
) -> anyhow::Result<Campaign> {
    super::out::check_out(dir)?;
    let file = PlanFile::of(plan);
    let store = Store::open(dir, &file).map_err(usage_or_run)?;
    let all = plan.runs();
    let (mine, shard_name) = match shard {
        Some((i, n)) => (campaign::shard(&all, i, n), format!("{i}/{n}")),
        None => (all.clone(), "all".to_string()),
    };
    if !quiet {
        eprintln!(
            "{}: {} × {} = {} runs{} into {}",
            plan.base.name(),
            crate::scenario::count(plan.points.len(), "point"),
            crate::scenario::count(plan.seeds as usize, "seed"),
            all.len(),
            if shard_name == "all" {
                String::new()
            } else {
                format!(", shard {shard_name}: {}", mine.len())
            },
            dir.display()
        );
    }
    let stop = Arc::new(AtomicBool::new(false));
    watch_signals(stop.clone());
    let pb = (!quiet).then(|| {
        progress_bar_of(
            mine.len() as u64,
            "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} runs ({per_sec}, eta {eta})",
        )
    });
    let tick = || {
        if let Some(p) = &pb {
            p.inc(1);
        }
    };
    let run_one = |s: &Scenario| match transport {
        Transport::Memory => campaign::in_memory(s),
        Transport::Udp => over_udp(s, &stop),
    };
    let who = campaign::Runner {
        shard: shard_name.clone(),
        command: std::env::args().collect(),
        transport: transport.name().into(),
    };
    let campaign::Executed { ran, finished } = campaign::execute(plan, &mine, &store, who, &run_one, &tick, &stop);
    if let Some(p) = pb {
        p.finish_and_clear();
    }
    for (r, why) in ran.failed.iter().take(5) {
        eprintln!(
            "error: run {} ({}, seed {}): {why}",
            r.key,
            plan.describe(r.point),
            r.seed
        );
    }
    if ran.failed.len() > 5 {
        eprintln!("error: … and {} more failed runs", ran.failed.len() - 5);
    }
    if !quiet {
        eprintln!(
            "{} run now, {} already in {}{}{}",
            ran.ran,
            ran.kept,
            dir.display(),
            if ran.stopped > 0 {
                format!(", {} not started (stopped)", ran.stopped)
            } else {
                String::new()
            },
            if ran.failed.is_empty() {
                String::new()
            } else {
                format!(", {} failed", ran.failed.len())
            }
        );
    }
    match finished {
        Ok(done) => Ok(Campaign::Finished(file, done)),
        // A shard that is not the last: the others write the files when they finish.
        Err(CampaignError::Missing { missing, total, .. })
            if shard.is_some() && ran.failed.is_empty() && ran.stopped == 0 =>
        {
            if !quiet {
                eprintln!(
                    "shard {shard_name} is done; the campaign has {} of {total} runs: the last shard to finish \
                     writes the files (or run `simnet sweep merge {}`)",
                    total - missing,
                    dir.display()
                );
            }
            Ok(Campaign::Ended(ExitCode::SUCCESS))
        }
        Err(e @ CampaignError::Missing { .. }) => {
            eprintln!("error: {e}: rerun the same command to run only what is missing");
            Ok(Campaign::Ended(if ran.stopped > 0 {
                exit_code(true)
            } else {
                ExitCode::from(1)
            }))
        }
        Err(e) => Err(usage_or_run(e)),
    }
}

/// The tables of a finished campaign, their Parquet copies, and what was written.
fn wrote(dir: &Path, file: &PlanFile, done: campaign::Finished, format: Format) -> anyhow::Result<ExitCode> {
    let files = files_of(dir, &done, format)?;
    print_points(file, &done.stats)?;
    outln!("\n{}", wrote_line(dir, &files, done.runs));
    Ok(ExitCode::SUCCESS)
}

/// Every file a finished campaign wrote, with the Parquet copies `format` asks for.
pub(super) fn files_of(dir: &Path, done: &campaign::Finished, format: Format) -> anyhow::Result<Vec<String>> {
    let mut files = done.files.clone();
    if format == Format::Parquet {
        let copies = parquet_copies(dir, &files)?;
        files.extend(copies);
    }
    Ok(files)
}

pub(super) fn wrote_line(dir: &Path, files: &[String], runs: usize) -> String {
    format!("wrote {}/{{{}}} ({runs} runs)", dir.display(), files.join(", "))
}

/// `sweep merge`: every shard directory's records into `out`, checked to be one campaign; the files once all runs are
/// there.
fn merge(dirs: &[PathBuf], out: Option<&Path>, format: Format, quiet: bool) -> anyhow::Result<ExitCode> {
    let started = campaign::now();
    let mut plans = Vec::new();
    for d in dirs {
        let path = d.join("plan.json");
        let text =
            campaign::read_capped(&path).map_err(|e| UsageError::Option(format!("{e} (not a sweep's --out?)")))?;
        let plan = PlanFile::parse(&text)
            .map_err(|e| UsageError::Option(format!("{}: not a sweep's plan ({e})", path.display())))?;
        plans.push((d, plan));
    }
    let (first_dir, file) = plans[0].clone();
    for (d, p) in &plans[1..] {
        if let Some(why) = p.differs(&file) {
            return Err(UsageError::Option(format!(
                "{} and {} are not shards of one campaign: {} {why}",
                first_dir.display(),
                d.display(),
                d.display()
            ))
            .into());
        }
    }
    let out = out.unwrap_or(first_dir);
    let store = Store::open(out, &file).map_err(usage_or_run)?;
    let mut copied = 0;
    for (d, _) in &plans {
        let theirs = Store { dir: d.to_path_buf() };
        for r in file.runs() {
            if store.has(&r.key) {
                continue;
            }
            if let Some(rec) = theirs.get(&r, &file).map_err(usage_or_run)? {
                store.put(&rec).map_err(usage_or_run)?;
                copied += 1;
            }
        }
        // Each shard's provenance comes along.
        if let Ok(entries) = std::fs::read_dir(d.join("shards")) {
            for e in entries.flatten() {
                let target = out.join("shards").join(e.file_name());
                if e.path() != target {
                    std::fs::create_dir_all(out.join("shards"))?;
                    std::fs::copy(e.path(), &target)?;
                }
            }
        }
    }
    if !quiet {
        eprintln!("{copied} runs copied into {}", out.display());
    }
    let merger = campaign::Runner {
        shard: "merge".into(),
        command: std::env::args().collect(),
        transport: "-".into(),
    };
    let me = ShardInfo::of(merger, started, 0);
    match campaign::finish(&store, &file, &me) {
        Ok(done) => wrote(out, &file, done, format),
        Err(e @ CampaignError::Missing { .. }) => {
            // The directories given do not hold the whole campaign: the input is incomplete (exit 2).
            eprintln!(
                "error: {e}: a shard has not finished, or its directory is not among the {} given",
                dirs.len()
            );
            Ok(ExitCode::from(2))
        }
        Err(e) => Err(usage_or_run(e)),
    }
}

/// One run over UDP on loopback (the virtual clock); a stop ends it early (then it is not stored).
fn over_udp(s: &Scenario, stop: &Arc<AtomicBool>) -> Result<crate::Summary, String> {
    net::run_blocking(Arc::new(s.clone()), RunOptions::default(), stop.clone(), 1)
        .map(|r| r.summary())
        .map_err(|e| e.to_string())
}

/// Ctrl-C or SIGTERM sets `stop`: no further run starts, the finished ones stay stored.
fn watch_signals(stop: Arc<AtomicBool>) {
    std::thread::spawn(move || {
        let Ok(rt) = tokio::runtime::Builder::new_current_thread().enable_all().build() else {
            return;
        };
        rt.block_on(shutdown_signal());
        stop.store(true, Ordering::SeqCst);
        eprintln!("\nstopping: the runs under way finish and are kept; rerun the same command to go on");
    });
}

/// The stack file: the same sweep in every task, its shard from the task's slot.
fn stack(args: &SweepArgs, topology: &str) -> String {
    let builtin = builtin::get(topology).is_some() && !Path::new(topology).is_file();
    let mut a: Vec<String> = vec![
        "-t".into(),
        if builtin {
            topology.to_string()
        } else {
            "/topology.toml".into()
        },
    ];
    for s in &args.set {
        a.extend(["--set".into(), s.clone()]);
    }
    a.extend(["--seeds".into(), args.seeds.to_string()]);
    if let Some(e) = &args.estimators {
        let names: Vec<&str> = super::args::EstimatorChoice::kinds(e)
            .iter()
            .map(|k| k.name())
            .collect();
        a.extend(["--estimators".into(), names.join(",")]);
    }
    if let Some(r) = args.rounds {
        a.extend(["--rounds".into(), r.to_string()]);
    }
    if let Some(d) = args.duration {
        a.extend(["--duration".into(), d.to_string()]);
    }
    a.extend(["--transport".into(), args.transport.name().into()]);
    campaign::stack_file(&campaign::StackOptions {
        image: args.image.clone(),
        replicas: args.replicas as usize,
        args: a,
        topology_file: (!builtin).then(|| topology.to_string()),
    })
}

/// Each point's mean error per estimator with its 95 % interval, as a markdown table.
fn print_points(plan: &PlanFile, stats: &[campaign::PointStat]) -> std::io::Result<()> {
    let mut out = std::io::stdout().lock();
    writeln!(
        out,
        "{}: {}, mean over {} seeds ± half the 95 % confidence interval\n",
        plan.topology,
        plan.model.error_text().label,
        plan.seeds
    )?;
    let (header, rows) = campaign::mean_error_table(plan, stats);
    writeln!(out, "| {} |", header.join(" | "))?;
    writeln!(out, "|{}", "---|".repeat(header.len()))?;
    for r in rows {
        writeln!(out, "| {} |", r.join(" | "))?;
    }
    Ok(())
}
