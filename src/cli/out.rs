//! What commands write: an output directory checked before the run, files written whole (write, then rename),
//! the summary on stdout, progress bars.

use super::*;

/// An output directory checked before the run: it exists (or was made) and can be written.
pub(super) struct OutDir {
    pub(super) dir: PathBuf,
}

pub(super) const TRACE_TMP: &str = "trace.csv.tmp";
/// Every sensing node's own measurements ([`crate::report::trace::MEASUREMENTS_HEADER`]).
pub(super) const MEASUREMENTS: &str = "measurements.csv";
/// Every distributed estimator's estimate at each node and step ([`crate::report::trace::ESTIMATORS_HEADER`]).
pub(super) const ESTIMATORS: &str = "estimators.csv";

/// A bad output directory is a usage error found before any work (exit 2), for every command that writes one.
pub(crate) fn check_out(dir: &Path) -> Result<(), UsageError> {
    OutDir::prepare(dir).map(|_| ())
}

/// The files a whole run (`simnet run`, `simnet collect`) writes, whatever its options: with `imu-ID.csv` and the
/// Parquet copies of the CSVs, the kinds [`OutDir::remove_stale`] may remove.
const RUN_FILES: [&str; 10] = [
    "summary.json",
    "trace.csv",
    "links.csv",
    "trajectory.svg",
    "error.svg",
    "trace_p.svg",
    "estimators.svg",
    "report.html",
    MEASUREMENTS,
    ESTIMATORS,
];

/// Whether `name` is a file a whole run writes.
fn run_file(name: &str) -> bool {
    let csv = name.strip_suffix(".parquet").map(|b| format!("{b}.csv"));
    let name = csv.as_deref().unwrap_or(name);
    RUN_FILES.contains(&name)
        || name
            .strip_prefix("imu-")
            .and_then(|r| r.strip_suffix(".csv"))
            .is_some_and(|id| !id.is_empty() && id.bytes().all(|b| b.is_ascii_digit()))
}

impl OutDir {
    /// After a run wrote `wrote`: remove the files of a run's kinds it did not write (an earlier run's
    /// `estimators.csv` beside a run without estimators), so that the directory holds one run's files as a set.
    /// Done last, so that a run that fails leaves the earlier run's files whole.
    pub(super) fn remove_stale(&self, wrote: &[String]) -> anyhow::Result<()> {
        for e in std::fs::read_dir(&self.dir)?.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            if run_file(&name) && !wrote.contains(&name) && e.file_type().is_ok_and(|t| t.is_file()) {
                std::fs::remove_file(e.path())?;
            }
        }
        Ok(())
    }

    pub(super) fn prepare(dir: &Path) -> Result<OutDir, UsageError> {
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
    pub(super) fn trace(&self, topo: &Scenario) -> Result<TraceWriter, UsageError> {
        let path = self.dir.join(TRACE_TMP);
        let f = std::fs::File::create(&path)
            .map_err(|e| UsageError::Option(format!("--out: cannot write {}: {e}", path.display())))?;
        Ok(TraceWriter::for_topology(topo).to_writer(Box::new(std::io::BufWriter::new(f))))
    }

    /// Close the streamed `trace.csv`; the plot sample it kept.
    pub(super) fn finish_trace(
        &self,
        rec: Option<TraceWriter>,
    ) -> anyhow::Result<(Vec<crate::node::TraceRow>, Vec<crate::observe::fusion::FusedRow>)> {
        use anyhow::Context;
        let path = self.dir.join("trace.csv");
        let sample = rec
            .map(TraceWriter::finish)
            .transpose()
            .with_context(|| format!("cannot write {}", path.display()))?
            .unwrap_or_default();
        std::fs::rename(self.dir.join(TRACE_TMP), &path).with_context(|| format!("cannot write {}", path.display()))?;
        Ok(sample)
    }

    /// Opens `measurements.csv.tmp` for the recorder ([`OutDir::rename_tmp`] gives it its name at the end).
    pub(super) fn measurements(&self) -> Result<Box<dyn Write + Send>, UsageError> {
        self.tmp(MEASUREMENTS)
    }

    /// Opens `NAME.tmp` for a recorder ([`OutDir::rename_tmp`] gives it its name at the end).
    pub(super) fn tmp(&self, name: &str) -> Result<Box<dyn Write + Send>, UsageError> {
        let path = self.dir.join(format!("{name}.tmp"));
        let f = std::fs::File::create(&path)
            .map_err(|e| UsageError::Option(format!("--out: cannot write {}: {e}", path.display())))?;
        Ok(Box::new(std::io::BufWriter::new(f)))
    }

    /// Opens `imu-ID.csv.tmp` for the recorder ([`OutDir::rename_tmp`] gives it its name at the end).
    pub(super) fn imu_opener(&self) -> crate::report::trace::ImuOpener {
        let dir = self.dir.clone();
        Box::new(move |id| {
            let f = std::fs::File::create(dir.join(format!("imu-{id}.csv.tmp")))?;
            Ok(Box::new(std::io::BufWriter::new(f)) as Box<dyn Write + Send>)
        })
    }

    pub(super) fn rename_tmp(&self, name: &str) -> anyhow::Result<()> {
        use anyhow::Context;
        let path = self.dir.join(name);
        std::fs::rename(self.dir.join(format!("{name}.tmp")), &path)
            .with_context(|| format!("cannot write {}", path.display()))
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
    let d = OutDir { dir: dir.to_path_buf() };
    d.put("summary.json", s.to_json().as_bytes())?;
    let mut buf = Vec::new();
    summary::write_links(&mut buf, &s.links)?;
    d.put("links.csv", &buf)?;
    let title = |what: &str| format!("{} — {what} (seed {})", s.topology, s.seed);
    let mut plots: Vec<Plot> = vec![
        (
            "trajectory.svg",
            "trajectories".into(),
            plot::trajectory(rows, fused, s.model.trajectory_view(), &title("trajectories"))?,
        ),
        (
            "error.svg",
            "error over time, networked against independent".into(),
            plot::error(rows, fused, dt, s.model, &title("error, networked vs independent"))?,
        ),
        (
            "trace_p.svg",
            "trace of the covariance, networked against independent".into(),
            plot::trace_p(rows, dt, &title("trace P, networked vs independent"))?,
        ),
    ];
    plots.extend(extra);
    let mut wrote: Vec<String> = ["trace.csv", "summary.json", "links.csv"].map(String::from).to_vec();
    for (name, _, svg) in &plots {
        d.put(name, svg.as_bytes())?;
        wrote.push(name.to_string());
    }
    let captioned: Vec<(String, String)> = plots.into_iter().map(|(_, c, svg)| (c, svg)).collect();
    d.put("report.html", crate::report::html::run_page(s, &captioned).as_bytes())?;
    wrote.push("report.html".into());
    Ok(wrote)
}
