//! What commands write: an output directory checked before the run; a whole run's files written into a fresh
//! staging directory inside it and moved into place as a set, recorded in `.simnet-outputs` (so that a later run
//! removes what an earlier one wrote and nothing else); the summary on stdout; progress bars.

use super::*;

/// Every sensing node's own measurements ([`crate::report::trace::MEASUREMENTS_HEADER`]).
pub(super) const MEASUREMENTS: &str = "measurements.csv";
/// Every datagram sent and every copy delivered (`--capture`, [`crate::report::capture`]).
pub(super) const CAPTURE: &str = "capture.csv";
/// Every distributed estimator's estimate at each node and step ([`crate::report::trace::ESTIMATORS_HEADER`]).
pub(super) const ESTIMATORS: &str = "estimators.csv";
/// The list of the files the last whole run wrote into a directory, and whether that set is complete.
pub(crate) const OUTPUTS: &str = ".simnet-outputs";
/// Held (`flock`) by the one process writing a whole run into a directory.
const LOCK: &str = ".simnet-lock";
/// Staging directories: `.simnet-stage-<random>`.
const STAGE_PREFIX: &str = ".simnet-stage-";

/// A bad output directory is a usage error found before any work (exit 2), for every command that writes one.
pub(crate) fn check_out(dir: &Path) -> Result<(), UsageError> {
    check_dir(dir).map(|_| ())
}

/// `dir` exists (or was made) and can be written: a file of a random name is created (never through a planted
/// link: `create_new`) and removed again.
fn check_dir(dir: &Path) -> Result<PathBuf, UsageError> {
    let bad = |what: String| UsageError::Option(format!("--out {}: {what}", dir.display()));
    if dir.exists() && !dir.is_dir() {
        return Err(bad("exists and is not a directory".into()));
    }
    std::fs::create_dir_all(dir).map_err(|e| bad(format!("cannot create it: {e}")))?;
    let probe = dir.join(format!(".simnet-write-check-{}", crate::fresh::token()));
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
        .map_err(|e| bad(format!("cannot write in it: {e}")))?;
    let _ = std::fs::remove_file(&probe);
    Ok(dir.to_path_buf())
}

/// The files a whole run (`simnet run`, `simnet collect`) writes, whatever its options: with `imu-ID.csv` and the
/// Parquet copies of the CSVs, the only names a run ever removes (and only when `.simnet-outputs` lists them).
const RUN_FILES: [&str; 12] = [
    "summary.json",
    "trace.csv",
    "links.csv",
    "trajectory.svg",
    "error.svg",
    "trace_p.svg",
    "estimators.svg",
    "map.svg",
    "report.html",
    MEASUREMENTS,
    ESTIMATORS,
    CAPTURE,
];

/// Whether `name` is a file a whole run may write.
pub(crate) fn run_file(name: &str) -> bool {
    let csv = name.strip_suffix(".parquet").map(|b| format!("{b}.csv"));
    let name = csv.as_deref().unwrap_or(name);
    RUN_FILES.contains(&name)
        || name
            .strip_prefix("imu-")
            .and_then(|r| r.strip_suffix(".csv"))
            .is_some_and(|id| !id.is_empty() && id.bytes().all(|b| b.is_ascii_digit()))
}

/// `.simnet-outputs`: what the last whole run wrote into the directory. `complete` is false while a run moves its
/// files into place (a kill then leaves a mixed set, and says so); `files` then lists the old and the new names.
#[derive(Debug, Default, serde::Serialize, serde::Deserialize)]
pub(crate) struct Outputs {
    pub complete: bool,
    pub files: Vec<String>,
}

impl Outputs {
    /// The list in `dir`, if there is a readable one; only plain names of a run's kinds are kept from it (a
    /// crafted list names nothing else to remove).
    pub(crate) fn read(dir: &Path) -> Option<Outputs> {
        let text = crate::input::read_text(&dir.join(OUTPUTS), crate::input::MAX_JSON).ok()?;
        let mut o: Outputs = serde_json::from_str(&text).ok()?;
        o.files.retain(|n| run_file(n) && !n.contains(['/', '\\']));
        Some(o)
    }

    fn write(&self, dir: &Path) -> std::io::Result<()> {
        let json = serde_json::to_string_pretty(self).map_err(std::io::Error::other)?;
        write_atomic(&dir.join(OUTPUTS), format!("{json}\n").as_bytes())
    }
}

/// The directory a whole run writes into: its files go into a fresh staging directory inside it and
/// [`RunDir::commit`] moves them into place as a set. Held by one process at a time (a lock file); dropped without
/// a commit (an error), the staging directory is removed and the directory is as it was.
pub(super) struct RunDir {
    pub(super) dir: PathBuf,
    /// Where this run's files are written until the commit: made with a random name that must not exist yet.
    pub(super) stage: PathBuf,
    committed: bool,
    _lock: std::fs::File,
}

impl RunDir {
    /// `dir`, checked and locked, with a fresh staging directory. `inputs` are the files the run reads: one in
    /// `dir` under a name the run writes is refused (exit 2), the run would overwrite what it reads. Staging
    /// directories a killed run left are removed.
    pub(super) fn open(dir: &Path, inputs: &[(String, PathBuf)]) -> Result<RunDir, UsageError> {
        let dir = check_dir(dir)?;
        let bad = |what: String| UsageError::Option(format!("--out {}: {what}", dir.display()));
        if let Ok(here) = dir.canonicalize() {
            for (what, path) in inputs {
                let (Ok(p), Some(name)) = (path.canonicalize(), path.file_name()) else {
                    continue;
                };
                let name = name.to_string_lossy();
                if p.parent() == Some(here.as_path()) && run_file(&name) {
                    return Err(bad(format!(
                        "`{name}` there is an input of this run ({what}) and a name a run writes: write the run \
                         into another directory"
                    )));
                }
            }
        }
        // A link or a fifo planted under the lock's name is never followed (O_NOFOLLOW) or waited on (O_NONBLOCK),
        // in the one call that opens it: nothing can be swapped in between a check and the open.
        let not_regular = || bad(format!("{LOCK} there is not a regular file: remove it"));
        let lock = std::os::unix::fs::OpenOptionsExt::custom_flags(
            std::fs::OpenOptions::new()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false),
            libc::O_NOFOLLOW | libc::O_NONBLOCK,
        )
        .open(dir.join(LOCK))
        .map_err(|e| match e.raw_os_error() {
            Some(libc::ELOOP) | Some(libc::ENXIO) => not_regular(),
            _ => bad(format!("cannot open {LOCK}: {e}")),
        })?;
        if !lock.metadata().is_ok_and(|m| m.is_file()) {
            return Err(not_regular());
        }
        match lock.try_lock() {
            Ok(()) => {}
            Err(std::fs::TryLockError::WouldBlock) => {
                return Err(bad("another simnet is writing a run into it".into()));
            }
            Err(std::fs::TryLockError::Error(e)) => return Err(bad(format!("cannot lock {LOCK}: {e}"))),
        }
        // Holding the lock, any staging directory is a leftover of a process that died.
        if let Ok(entries) = std::fs::read_dir(&dir) {
            for e in entries.flatten() {
                let n = e.file_name().to_string_lossy().into_owned();
                if n.starts_with(STAGE_PREFIX) && e.file_type().is_ok_and(|t| t.is_dir()) {
                    let _ = std::fs::remove_dir_all(e.path());
                }
            }
        }
        let stage = dir.join(format!("{STAGE_PREFIX}{}", crate::fresh::token()));
        std::fs::create_dir(&stage).map_err(|e| bad(format!("cannot create {}: {e}", stage.display())))?;
        Ok(RunDir {
            dir,
            stage,
            committed: false,
            _lock: lock,
        })
    }

    /// The recorder that streams `trace.csv` into the staging directory.
    pub(super) fn trace(&self, topo: &Scenario) -> Result<TraceWriter, UsageError> {
        Ok(TraceWriter::for_topology(topo).to_writer(self.create("trace.csv")?))
    }

    /// Close the streamed `trace.csv`; the plot sample it kept.
    pub(super) fn finish_trace(
        &self,
        rec: Option<TraceWriter>,
    ) -> anyhow::Result<(Vec<crate::node::TraceRow>, Vec<crate::observe::fusion::FusedRow>)> {
        use anyhow::Context;
        rec.map(TraceWriter::finish)
            .transpose()
            .with_context(|| format!("cannot write {}", self.dir.join("trace.csv").display()))
            .map(Option::unwrap_or_default)
    }

    /// `NAME` in the staging directory, for a recorder.
    pub(super) fn create(&self, name: &str) -> Result<Box<dyn Write + Send>, UsageError> {
        let path = self.stage.join(name);
        let f = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&path)
            .map_err(|e| UsageError::Option(format!("--out: cannot write {}: {e}", path.display())))?;
        Ok(Box::new(std::io::BufWriter::new(f)))
    }

    /// Opens `imu-ID.csv` in the staging directory for the recorder.
    pub(super) fn imu_opener(&self) -> crate::report::trace::ImuOpener {
        let stage = self.stage.clone();
        Box::new(move |id| {
            let f = std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(stage.join(format!("imu-{id}.csv")))?;
            Ok(Box::new(std::io::BufWriter::new(f)) as Box<dyn Write + Send>)
        })
    }

    /// Move the run's files (`wrote`, all in the staging directory) into place as a set and remove the files an
    /// earlier run recorded in `.simnet-outputs` that this one did not write: the list first says the move is under
    /// way (with both sets), then, once every file is in place, that this set is complete.
    pub(super) fn commit(mut self, wrote: &[String]) -> anyhow::Result<()> {
        use anyhow::Context;
        let before = Outputs::read(&self.dir).map(|o| o.files).unwrap_or_default();
        let mut both = before.clone();
        both.extend(wrote.iter().filter(|n| !before.contains(n)).cloned());
        let listed = |o: &Outputs| {
            o.write(&self.dir)
                .with_context(|| format!("cannot write {}", self.dir.join(OUTPUTS).display()))
        };
        listed(&Outputs {
            complete: false,
            files: both,
        })?;
        for name in wrote {
            let to = self.dir.join(name);
            std::fs::rename(self.stage.join(name), &to).with_context(|| format!("cannot write {}", to.display()))?;
        }
        for name in before.iter().filter(|n| !wrote.contains(n)) {
            let path = self.dir.join(name);
            if std::fs::symlink_metadata(&path).is_ok_and(|m| m.is_file()) {
                std::fs::remove_file(&path).with_context(|| format!("cannot remove {}", path.display()))?;
            }
        }
        listed(&Outputs {
            complete: true,
            files: wrote.to_vec(),
        })?;
        self.committed = true;
        let _ = std::fs::remove_dir_all(&self.stage);
        Ok(())
    }
}

impl Drop for RunDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.stage);
        }
    }
}

/// A directory a node writes its part into (`trace-ID.csv`, `estimates-ID.csv`, `node-ID.json`): several nodes may
/// share it, so each file is written whole under its own name and nothing else is touched.
pub(super) struct PartDir {
    pub(super) dir: PathBuf,
}

impl PartDir {
    pub(super) fn prepare(dir: &Path) -> Result<PartDir, UsageError> {
        Ok(PartDir { dir: check_dir(dir)? })
    }

    pub(super) fn put(&self, name: &str, bytes: &[u8]) -> anyhow::Result<()> {
        use anyhow::Context;
        let path = self.dir.join(name);
        write_atomic(&path, bytes).with_context(|| format!("cannot write {}", path.display()))
    }
}
/// summary.json or the table (with an optional note under it) on stdout.
pub(super) fn print_summary(s: &summary::Summary, json: bool, note: Option<&str>) -> std::io::Result<()> {
    let mut stdout = std::io::stdout().lock();
    if json {
        writeln!(stdout, "{}", s.to_json())
    } else {
        s.write_table(&mut stdout)?;
        note.map_or(Ok(()), |n| writeln!(stdout, "{n}"))
    }
}

pub(super) fn progress_bar(steps: u64) -> indicatif::ProgressBar {
    progress_bar_of(
        steps,
        "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} steps ({per_sec}, eta {eta})",
    )
}

pub(super) fn progress_bar_of(len: u64, template: &str) -> indicatif::ProgressBar {
    let pb = indicatif::ProgressBar::new(len);
    pb.set_style(
        indicatif::ProgressStyle::with_template(template).unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    pb
}

pub use crate::report::write_atomic;

/// A plot beside the three every run has: (file name, caption, SVG).
pub(super) type Plot = (&'static str, String, String);

/// A run's conditions for a plot's title: the model, the seed, the measured loss over every link, and the rounds
/// of a run with distributed estimators.
pub(super) fn conditions(s: &summary::Summary) -> String {
    let (sent, lost) = s.links.iter().fold((0u64, 0u64), |(a, b), l| (a + l.sent, b + l.lost));
    let mut c = vec![format!("{} model", s.model), format!("seed {}", s.seed)];
    if sent > 0 {
        c.push(format!("loss {:.1} %", 100.0 * lost as f64 / sent as f64));
    }
    if !s.estimators.is_empty() {
        c.push(format!("L = {}", s.settings.as_ref().map_or(1, |x| x.rounds)));
    }
    c.join(", ")
}

/// summary.json, links.csv, the three plots, `extra` plots and report.html (all of them inline), each written
/// atomically; the names written.
pub(super) fn write_files(
    dir: &Path,
    s: &summary::Summary,
    dt: f64,
    rows: &[crate::node::TraceRow],
    fused: &[crate::observe::fusion::FusedRow],
    extra: Vec<Plot>,
) -> anyhow::Result<Vec<String>> {
    let d = PartDir { dir: dir.to_path_buf() };
    d.put("summary.json", s.to_json().as_bytes())?;
    let mut buf = Vec::new();
    summary::write_links(&mut buf, &s.links)?;
    d.put("links.csv", &buf)?;
    let title = |what: &str| format!("{} — {what} ({})", s.topology, conditions(s));
    // A model whose nodes observe differently runs no networked filter: the plots show the independent ones.
    let (compared, against) = if s.nodes.iter().any(|n| n.networked.is_some()) {
        ("networked vs independent", "networked against independent")
    } else {
        ("independent filters", "independent filters")
    };
    let burn_in_s = s.burn_in_steps as f64 * dt;
    let faults = s.settings.as_ref().map_or(&[][..], |x| &x.faults[..]);
    let mut plots: Vec<Plot> = vec![
        (
            "trajectory.svg",
            "trajectories".into(),
            plot::trajectory(rows, fused, s.model.trajectory_view(), &title("trajectories"))?,
        ),
        (
            "error.svg",
            format!("error over time, {against}"),
            plot::error(
                rows,
                fused,
                dt,
                burn_in_s,
                s.model,
                &title(&format!("error, {compared}")),
                faults,
            )?,
        ),
        (
            "trace_p.svg",
            format!("trace of the covariance, {against}"),
            plot::trace_p(rows, dt, burn_in_s, &title(&format!("trace P, {compared}")), faults)?,
        ),
    ];
    plots.extend(extra);
    let mut wrote: Vec<String> = ["trace.csv", "summary.json", "links.csv"].map(String::from).to_vec();
    for (name, _, svg) in &plots {
        d.put(name, svg.as_bytes())?;
        wrote.push(name.to_string());
    }
    let captioned: Vec<(String, String)> = plots.into_iter().map(|(_, c, svg)| (c, svg)).collect();
    let header = crate::report::html::RunHeader {
        command: std::env::args().collect::<Vec<_>>().join(" "),
        conditions: conditions(s),
        build: crate::campaign::simnet_build(),
    };
    d.put(
        "report.html",
        crate::report::html::run_page(s, &captioned, &header).as_bytes(),
    )?;
    wrote.push("report.html".into());
    Ok(wrote)
}
