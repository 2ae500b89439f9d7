//! `simnet run`'s options (shared by `node`, `protocol` and `reproduce`): value parsers, the overrides they
//! make and the scenario they select.

use super::*;
// The ranges of `RUN_OPTIONS`: the command line refuses what `--set`, a sweep and Python refuse, in the same words.
use crate::scenario::options::check;
use crate::scenario::{parse_set, Flags};

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
    /// Distributed estimators to run beside the two filters, comma-separated, or `all` (see `simnet estimators`).
    #[arg(long, env = "SIMNET_ESTIMATORS", value_delimiter = ',', value_parser = estimator)]
    pub estimators: Option<Vec<EstimatorChoice>>,
    /// Consensus rounds per step (1 to 100), each with its sub-deadline inside the step.
    #[arg(long, env = "SIMNET_ROUNDS", value_parser = rounds)]
    pub rounds: Option<u64>,
    /// Pace steps by the wall clock instead of the virtual lockstep clock.
    #[arg(long)]
    pub realtime: bool,
    /// The network key (`simnet keygen`): every datagram authenticated with it (AES-128-CCM).
    #[arg(long, env = "SIMNET_KEY_FILE")]
    pub key_file: Option<PathBuf>,
    /// Authenticate every datagram with a key of the run's own (from its seed): an in-process run measures the cost.
    #[arg(long)]
    pub auth: bool,
    /// Any key of the scenario, as in its file (`consensus.gate=0.999`, `attack[0].bias=[20]`), after the options
    /// above; repeatable.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Write summary.json, trace.csv, links.csv and SVG plots here.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// With --out: also write capture.csv, every datagram sent and every copy delivered (a tap on the medium).
    #[arg(long)]
    pub capture: bool,
    /// Print summary.json on stdout instead of the table.
    #[arg(long)]
    pub json: bool,
    /// With --out: also write every CSV table as Parquet (zstd; needs a build with the `parquet` feature).
    #[arg(long, value_enum, default_value = "csv")]
    pub format: Format,
}

/// The format of the tables written besides the CSVs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, ValueEnum)]
pub enum Format {
    #[default]
    Csv,
    Parquet,
}

impl Format {
    /// Parquet needs the `parquet` feature: a build without it refuses the option before any work.
    pub fn check(self) -> Result<Format, UsageError> {
        if self == Format::Parquet && !cfg!(feature = "parquet") {
            return Err(UsageError::Option(
                "--format parquet: this simnet was built without Parquet (cargo build --release --features parquet)"
                    .into(),
            ));
        }
        Ok(self)
    }
}

/// Each of `names` in `dir` that is a `.csv` beside itself as `.parquet`; the names written.
pub(super) fn parquet_copies(dir: &Path, names: &[String]) -> anyhow::Result<Vec<String>> {
    #[cfg(feature = "parquet")]
    {
        let mut wrote = Vec::new();
        for n in names.iter().filter(|n| n.ends_with(".csv")) {
            let pq = format!("{}.parquet", n.trim_end_matches(".csv"));
            crate::report::parquet::csv_to_parquet(&dir.join(n), &dir.join(&pq))?;
            wrote.push(pq);
        }
        Ok(wrote)
    }
    #[cfg(not(feature = "parquet"))]
    {
        let _ = (dir, names);
        Ok(Vec::new())
    }
}

/// One `--estimators` entry: a scheme, or every scheme.
#[derive(Debug, Clone, PartialEq)]
pub struct EstimatorChoice(Vec<crate::estimators::Kind>);

impl EstimatorChoice {
    /// Every scheme of the entries, sorted, once each.
    pub fn kinds(choices: &[EstimatorChoice]) -> Vec<crate::estimators::Kind> {
        let mut all: Vec<_> = choices.iter().flat_map(|c| c.0.iter().copied()).collect();
        all.sort();
        all.dedup();
        all
    }
}

pub(super) fn estimator(s: &str) -> Result<EstimatorChoice, String> {
    crate::estimators::Kind::parse_list(&[s.to_string()]).map(EstimatorChoice)
}

pub(super) fn parse_f64(s: &str) -> Result<f64, String> {
    s.parse::<f64>().map_err(|_| format!("`{s}` is not a number"))
}

pub(super) fn probability(s: &str) -> Result<f64, String> {
    check::probability(parse_f64(s)?)
}

pub(super) fn positive(s: &str) -> Result<f64, String> {
    check::positive(parse_f64(s)?)
}

/// A wait in seconds: positive, at most a day.
pub(super) fn seconds_in_a_day(s: &str) -> Result<f64, String> {
    let v = positive(s)?;
    if v <= 86_400.0 {
        Ok(v)
    } else {
        Err(format!("must be at most 86400 s (a day), got {v}"))
    }
}

pub(super) fn non_negative(s: &str) -> Result<f64, String> {
    check::non_negative(parse_f64(s)?)
}

pub(super) fn rounds(s: &str) -> Result<u64, String> {
    check::rounds(
        s.parse()
            .map_err(|_| format!("`{s}` is not a whole number of rounds"))?,
    )
}

pub(super) fn at_least_one(s: &str) -> Result<f64, String> {
    check::at_least_one(parse_f64(s)?)
}

impl RunArgs {
    /// The options as the library takes them.
    pub fn flags(&self) -> Result<Flags, UsageError> {
        Ok(Flags {
            loss: self.loss,
            loss_model: self.loss_model.map(|k| match k {
                LossKind::Bernoulli => crate::scenario::LossKind::Bernoulli,
                LossKind::GilbertElliott => crate::scenario::LossKind::GilbertElliott,
            }),
            burst: self.burst,
            delay: self.delay,
            jitter: self.jitter,
            duplicate: self.duplicate,
            corrupt: self.corrupt,
            duration: self.duration,
            rate: self.rate,
            seed: self.seed,
            estimators: self.estimators.as_deref().map(EstimatorChoice::kinds),
            rounds: self.rounds,
            key_file: self.key_file.as_ref().map(|p| p.display().to_string()),
            auth: self.auth,
            set: self.set.iter().map(|kv| parse_set(kv)).collect::<Result<_, _>>()?,
        })
    }

    pub fn overrides(&self) -> Result<Overrides, UsageError> {
        Ok(self.flags()?.overrides()?)
    }

    /// The topology with the command-line overrides applied.
    pub fn topology(&self) -> Result<Scenario, UsageError> {
        let name = self
            .topology
            .as_deref()
            .ok_or_else(|| UsageError::Option("--topology NAME|PATH is required (see `simnet topologies`)".into()))?;
        let t = self.flags()?.apply(&Scenario::resolve(name)?)?;
        for w in t.warnings() {
            tracing::warn!("{}: {w}", t.name());
        }
        Ok(t)
    }
}

/// How to read a recording beyond what it says of itself (`simnet attitude`, `simnet reconstruct`).
#[derive(clap::Args, Debug, Clone, Default)]
pub struct ReadFlags {
    /// Columns the usual names miss: TARGET=COLUMN pairs, e.g. `t=Counter/rate,ax=Acc_X,qw=Quat_w` (COLUMN/K,
    /// COLUMN*K scale; /rate divides by --rate).
    #[arg(long, value_parser = crate::imu_csv::layout::parse_columns)]
    pub columns: Option<crate::imu_csv::layout::ColumnMap>,
    /// Units the header does not give: accel=g|m/s2, gyro=deg/s|rad/s, time=s|ms|us, angle=deg|rad (comma-separated).
    #[arg(long, value_parser = crate::imu_csv::layout::parse_units)]
    pub units: Option<crate::imu_csv::layout::Units>,
    /// Samples per second, for a file whose time column counts samples (or that has none).
    #[arg(long, value_parser = positive)]
    pub rate: Option<f64>,
}

impl ReadFlags {
    pub fn options(&self) -> crate::imu_csv::layout::ReadOptions {
        crate::imu_csv::layout::ReadOptions {
            columns: self.columns.clone().unwrap_or_default(),
            units: self.units.clone().unwrap_or_default(),
            rate_hz: self.rate,
        }
    }
}

#[cfg(test)]
mod tests {
    use clap::{CommandFactory, Parser};

    use super::super::Cli;
    use crate::scenario::{parse_value, Flags, RunOption, RUN_OPTIONS};

    /// `simnet run`'s arguments that make the scenario are exactly the table's options; the rest say where the
    /// scenario comes from and what is written.
    #[test]
    fn the_run_options_are_the_tables() {
        let cmd = Cli::command();
        let run = cmd.find_subcommand("run").unwrap();
        let mut rest: Vec<&str> = run
            .get_arguments()
            .filter_map(|a| a.get_long())
            .filter(|l| RunOption::named(l).is_none() && !["help", "version"].contains(l))
            .collect();
        rest.sort();
        assert_eq!(
            rest,
            ["capture", "format", "json", "out", "realtime", "set", "topology"]
        );
        for o in RUN_OPTIONS {
            assert!(
                run.get_arguments().any(|a| a.get_long() == Some(o.name)),
                "--{}",
                o.name
            );
        }
    }

    /// Each option's value on the command line and through the table (`--set`, a sweep, Python): the same
    /// values accepted with the same result, the same ones refused with the same words.
    #[test]
    fn the_command_line_and_the_table_agree_on_every_value() {
        let samples = [
            "0",
            "1",
            "0.5",
            "1.5",
            "-1",
            "3",
            "nan",
            "inf",
            "1e-3",
            "2.5",
            "101",
            "100",
            "kcf",
            "kcf,icf",
            "all",
            "nope",
            "bernoulli",
            "gilbert-elliott",
            "x",
        ];
        for o in RUN_OPTIONS.iter().filter(|o| o.name != "auth" && o.name != "key-file") {
            for v in samples {
                let mut argv: Vec<String> = ["simnet", "run", "-t", "ring3", "--loss", "0.1"]
                    .map(String::from)
                    .into();
                if o.name == "loss" {
                    argv.truncate(4);
                }
                argv.extend([format!("--{}", o.name), v.to_string()]);
                let cli = Cli::try_parse_from(&argv);
                let mut by_table = Flags::default();
                let table = o.read(&mut by_table, &parse_value(v));
                match (cli, table) {
                    (Ok(c), Ok(())) => {
                        let Some(super::super::Command::Run(args)) = c.command else {
                            panic!("{argv:?}: not a run")
                        };
                        let f = args.flags().unwrap();
                        let mut want = Flags::default();
                        o.read(&mut want, &parse_value(v)).unwrap();
                        if o.name != "loss" {
                            want.loss = Some(0.1);
                        }
                        assert_eq!(f, want, "{argv:?}");
                    }
                    (Err(c), Err(t)) => {
                        // A value out of range: clap's "invalid value" message ends with the table's words.
                        if t.starts_with("must be") || t.starts_with("a mean loss run") {
                            assert!(c.to_string().contains(&t), "--{} {v}: {c} / {t}", o.name);
                        }
                    }
                    (c, t) => panic!(
                        "--{} {v}: the command line says {:?}, the table {t:?}",
                        o.name,
                        c.map(|_| ())
                    ),
                }
            }
        }
    }
}
