//! Command line: clap definitions, tracing setup, exit codes (0 success, 2 bad input, 1 failure while running).

/// `println!` that returns a closed stdout as an error (exit 141) instead of panicking.
macro_rules! outln {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        writeln!(std::io::stdout(), $($t)*)?
    }};
}

/// `print!` the same way.
macro_rules! out {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        write!(std::io::stdout(), $($t)*)?
    }};
}

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;

use clap::{Args, Parser, Subcommand, ValueEnum};

use crate::net::{self, Clock, RunOptions};
use crate::report::trace::TraceWriter;
use crate::report::{plot, summary};
use crate::scenario::{builtin, Overrides, Scenario, ScenarioError};

mod args;
mod attitude;
mod bounds;
mod compare;
mod node;
mod out;
mod protocol;
mod reconstruct;
mod reproduce;
mod run;
mod sweep;

pub use args::RunArgs;
use args::*;
use bounds::bounds;
pub use bounds::BoundsArgs;
use node::{collect, compose, keygen, run_node};
pub use node::{CollectArgs, ComposeArgs, KeygenArgs, NodeArgs};
pub(crate) use out::check_out;
use out::*;
use run::run;

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
    /// Quiet: on stderr only errors (no log lines, no progress bar); results still go to stdout and --out.
    #[arg(short, long, global = true, conflicts_with = "verbose")]
    pub quiet: bool,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Run a topology (the default command).
    Run(RunArgs),
    /// List the built-in topologies.
    Topologies,
    /// List the distributed estimators, with their references and parameters.
    Estimators,
    /// Every estimator side by side over loss × rounds × seeds, in memory: mean errors against the centralized reference.
    Compare(compare::CompareArgs),
    /// A campaign: any scenario keys × seeds on every core, resumable, with confidence intervals; sharded with
    /// --shard I/N, joined with `sweep merge`, run on Docker Swarm with --emit stack.
    Sweep(sweep::SweepArgs),
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
    /// Print a docker compose file that runs a topology with one container per node, authenticated with a
    /// network key handed to them as a Docker secret.
    Compose(ComposeArgs),
    /// Write a network key file: every datagram of a run holding it is authenticated (AES-128-CCM).
    Keygen(KeygenArgs),
    /// Covariance bounds of a linear model under intermittent observations (Sinopoli et al.): λ_min, λ̄, S̄, V̄.
    Bounds(BoundsArgs),
    /// Find β weights that keep (17) and (19) feasible along a run with the most useful exchange (Sequeira (2023) §5).
    Protocol(protocol::ProtocolArgs),
    /// Rerun a source document's experiments: a table of its claims with simnet's figures, and the plots.
    #[command(subcommand)]
    Reproduce(reproduce::Paper),
    /// Position from a recorded IMU file as a boundary value problem (FEM), beside the trapezoid rule.
    Reconstruct(reconstruct::ReconstructArgs),
    /// Attitude from a recording as its maker wrote it: the EKF and the multiplicative EKF with noise estimated from
    /// the file, Madgwick, Mahony, VQF and the gyro alone, and any filter run elsewhere, scored against its reference
    /// orientation.
    Attitude(attitude::AttitudeArgs),
}

/// An error for the user: exit code 2.
#[derive(Debug, thiserror::Error)]
pub enum UsageError {
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    #[error("{0}")]
    Option(String),
}

impl From<crate::scenario::FlagError> for UsageError {
    fn from(e: crate::scenario::FlagError) -> Self {
        match e {
            crate::scenario::FlagError::Scenario(e) => UsageError::Scenario(e),
            e => UsageError::Option(e.to_string()),
        }
    }
}

/// `simnet -q sweep …` as `simnet sweep -q …`: the top-level run options conflict with a subcommand, and clap counts
/// the global flags given before one among them.
fn global_flags_after_subcommand(mut args: Vec<std::ffi::OsString>) -> Vec<std::ffi::OsString> {
    use clap::CommandFactory;
    let global = |a: &std::ffi::OsString| {
        let a = a.to_string_lossy();
        a == "--quiet"
            || a == "--verbose"
            || (a.starts_with('-')
                && !a.starts_with("--")
                && a.len() > 1
                && a[1..].chars().all(|c| c == 'q' || c == 'v'))
    };
    let leading = args.iter().skip(1).take_while(|a| global(a)).count();
    let names: Vec<String> = Cli::command()
        .get_subcommands()
        .map(|c| c.get_name().to_string())
        .collect();
    if leading > 0 && args.get(1 + leading).is_some_and(|a| names.iter().any(|n| *a == **n)) {
        let flags: Vec<_> = args.drain(1..1 + leading).collect();
        args.splice(2..2, flags);
    }
    args
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
    main_with(std::env::args_os().collect())
}

/// The command line with `args`, the first the program's name.
pub fn main_with(args: Vec<std::ffi::OsString>) -> ExitCode {
    let given = args.len() > 1;
    // An empty override (compose passes `${SIMNET_LOSS:-}`) means unset: the topology's own setting.
    for v in crate::compose::ENV {
        if std::env::var_os(v).is_some_and(|x| x.is_empty()) {
            std::env::remove_var(v);
        }
    }
    let cli = Cli::parse_from(global_flags_after_subcommand(args));
    init_tracing(cli.verbose, cli.quiet);
    let result = match cli.command {
        Some(Command::Topologies) => list_topologies().map(|_| ExitCode::SUCCESS),
        Some(Command::Estimators) => list_estimators().map(|_| ExitCode::SUCCESS),
        Some(Command::Validate { files }) => validate(&files),
        Some(Command::Run(args)) => run(&args, cli.quiet),
        Some(Command::Compare(args)) => compare::compare(&args, cli.quiet),
        Some(Command::Attitude(args)) => attitude::attitude(&args),
        Some(Command::Sweep(args)) => sweep::sweep(&args, cli.quiet),
        Some(Command::Node(args)) => run_node(&args, cli.quiet),
        Some(Command::Collect(args)) => collect(&args),
        Some(Command::Compose(args)) => compose(&args),
        Some(Command::Keygen(args)) => keygen(&args),
        Some(Command::Bounds(args)) => bounds(&args),
        Some(Command::Protocol(args)) => protocol::protocol(&args, cli.quiet),
        Some(Command::Reproduce(paper)) => reproduce::reproduce(&paper, cli.quiet),
        Some(Command::Reconstruct(args)) => reconstruct::reconstruct(&args),
        None if cli.run.topology.is_some() => run(&cli.run, cli.quiet),
        None if given => Err(UsageError::Option(
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
            eprintln!("error: {}", message(&e));
            ExitCode::from(if bad_input(&e) { 2 } else { 1 })
        }
    }
}

/// Whether an error is the user's input (exit 2): the one place that maps each layer's errors to an exit code.
fn bad_input(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.is::<UsageError>()
            || c.is::<ScenarioError>()
            || c.is::<crate::scenario::FlagError>()
            || c.is::<crate::wire::secure::KeyError>()
            || c.is::<crate::net::host::PeerError>()
            || c.downcast_ref::<crate::net::NetError>()
                .is_some_and(|n| matches!(n, crate::net::NetError::BindAt { .. } | crate::net::NetError::WholeMedium(_)))
            || c.downcast_ref::<crate::campaign::CampaignError>()
                .is_some_and(crate::campaign::CampaignError::is_usage)
            || c.downcast_ref::<crate::sim::SimError>()
                .is_some_and(|s| matches!(s, crate::sim::SimError::Scenario(_)))
            // A recording or a constraint the boundary-value problem cannot take.
            || c.is::<crate::reconstruct::ReconstructError>()
            || c.is::<crate::estimate::bvp::BvpError>()
    })
}

/// The error and its causes, each said once (a cause whose text its parent already quotes is not repeated).
fn message(e: &anyhow::Error) -> String {
    let mut out = String::new();
    for c in e.chain() {
        let s = c.to_string();
        if !out.contains(&s) {
            if !out.is_empty() {
                out.push_str(": ");
            }
            out.push_str(&s);
        }
    }
    out
}

fn list_topologies() -> anyhow::Result<()> {
    for (name, text) in builtin::ALL {
        let d = Scenario::from_toml(text, name)
            .map(|t| t.description().to_string())
            .unwrap_or_else(|e| format!("(invalid: {e})"));
        outln!("{name:<16} {d}");
    }
    Ok(())
}

fn list_estimators() -> anyhow::Result<()> {
    for s in crate::estimators::schemes() {
        outln!(
            "{}\n  {}\n  sends: {}\n  parameters: {}",
            s.name,
            s.reference,
            s.messages,
            s.parameters
        );
    }
    outln!("\nchoose with --estimators a,b,c (or all) and --rounds L, or [estimators] run = [...] in a topology file");
    Ok(())
}

fn validate(files: &[PathBuf]) -> anyhow::Result<ExitCode> {
    let mut bad = false;
    for f in files {
        match Scenario::from_path(f).and_then(|t| t.check_recordings().map(|_| t)) {
            Ok(t) => outln!(
                "{}: ok — `{}`, {}, {}, {} model, {} steps",
                f.display(),
                t.name(),
                crate::scenario::count(t.nodes().len(), "node"),
                crate::scenario::count(t.links().len(), "directed link"),
                t.model().kind(),
                t.sim().steps()
            ),
            Err(e) => {
                bad = true;
                eprintln!("{e}");
            }
        }
    }
    Ok(if bad { ExitCode::from(2) } else { ExitCode::SUCCESS })
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

    /// Every `simnet …` command written inline in README's and the book's prose parses as the command line does
    /// today: a renamed option or subcommand fails here. Placeholders (`FILE`, `N`, `…`) take a value of their kind;
    /// a command named without its required arguments (`simnet bounds`) counts as parsed.
    #[test]
    fn every_inline_command_of_readme_and_the_book_parses() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let mut pages = vec![root.join("README.md")];
        let mut book: Vec<_> = std::fs::read_dir(root.join("docs/src"))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|x| x == "md"))
            .collect();
        book.sort();
        pages.extend(book);
        fn placeholder(w: &str) -> Option<&str> {
            Some(match w {
                "N" => "0",
                "T" | "TOPOLOGY" | "NAME" => "ring3",
                "FILE" => "file.toml",
                "DIR" | "DIR1" | "DIR2" => "dir",
                "S" => "10",
                "HZ" => "50",
                "PAPER" => "sequeira",
                "…" | "..." | "DIR..." => return None,
                w => w,
            })
        }
        let mut checked = 0;
        let mut wrong = Vec::new();
        for page in &pages {
            let text = std::fs::read_to_string(page).unwrap();
            // Prose only: the shell blocks run in the long suite.
            let prose: String = text.split("```").step_by(2).collect::<Vec<_>>().join(" ");
            for span in prose.split('`').skip(1).step_by(2) {
                let Some(rest) = span.strip_prefix("simnet ") else {
                    continue;
                };
                let words: Vec<String> = rest
                    .split_whitespace()
                    .take_while(|w| !w.starts_with('>') && !w.starts_with('|'))
                    .map(|w| w.trim_matches(|c| c == '[' || c == ']'))
                    .filter(|w| !w.is_empty())
                    .filter_map(placeholder)
                    .map(String::from)
                    .collect();
                let args = std::iter::once("simnet".into()).chain(words.into_iter().map(std::ffi::OsString::from));
                let mut argv = super::global_flags_after_subcommand(args.collect());
                checked += 1;
                // An option named without its value (`simnet run --out`) is given one.
                let no_value = |a: &[std::ffi::OsString]| {
                    Cli::try_parse_from(a).is_err_and(|e| e.kind() == clap::error::ErrorKind::InvalidValue)
                };
                if argv.last().is_some_and(|a| a.to_string_lossy().starts_with("--")) && no_value(&argv) {
                    argv.push("dir".into());
                }
                if let Err(e) = Cli::try_parse_from(&argv) {
                    use clap::error::ErrorKind::*;
                    if !matches!(
                        e.kind(),
                        MissingRequiredArgument
                            | DisplayHelp
                            | DisplayVersion
                            | DisplayHelpOnMissingArgumentOrSubcommand
                    ) {
                        wrong.push(format!("{}: `simnet {rest}`: {}", page.display(), e.kind()));
                    }
                }
            }
        }
        assert!(checked > 50, "only {checked} inline commands found");
        assert!(wrong.is_empty(), "{}", wrong.join("\n"));
    }
}
