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

impl OutDir {
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

/// summary.json, links.csv and the three plots, each written atomically; the names written.
pub(super) fn write_files(
    dir: &Path,
    s: &summary::Summary,
    dt: f64,
    rows: &[crate::node::TraceRow],
    fused: &[crate::observe::fusion::FusedRow],
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
