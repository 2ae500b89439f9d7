//! `trace.csv`, written row by row while a run goes (memory does not grow with the run's length), and the sample of
//! rows the plots draw (every step up to [`PLOT_STEPS`] steps, every k-th step beyond).
//!
//! Columns: `step,t,node,estimator,true_*,est_*,var_*,error,trace_p_prior,trace_p_post,received,feasible,nees,diverged`.
//! `estimator` is `networked`, `independent`, a distributed estimator the run holds (`kcf`, `ci`, …: its update at
//! that node, `received` empty), `fused` (covariance intersection, ω = 0.5) or `fused_median` (its 20-sample
//! centred median, pose only); fused rows have no node and fill only the columns the fusion covers (position for
//! pose). `var_*` is the posterior variance of each column, `error` the step's error figure. Numbers
//! are written in their shortest round-trip form; a missing value is an empty cell.

use std::io::{self, Write};

use crate::node::TraceRow;
use crate::observe::fusion::FusedRow;
use crate::observe::Filter;

/// The columns of `measurements.csv`: `rows`, `values` and `r` (R over those rows, row-major) are `;`-separated.
pub const MEASUREMENTS_HEADER: &str = "step,t,node,channel,rows,values,r";
/// The columns of `estimators.csv`: each estimator's estimate at each node and step, its error rows `;`-separated.
pub const ESTIMATORS_HEADER: &str = "step,t,estimator,node,error,values";

/// Steps drawn per series before the plots thin the sample to every k-th step.
pub const PLOT_STEPS: u64 = 5000;

/// A number as `trace.csv` writes it: shortest round-trip form, `inf`/`-inf`, empty for NaN.
pub fn num(v: f64) -> String {
    if v.is_nan() {
        String::new()
    } else if v.is_infinite() {
        if v > 0.0 { "inf" } else { "-inf" }.into()
    } else {
        format!("{v:?}")
    }
}

/// The header of `trace.csv` for these column names.
pub fn header(columns: &[String]) -> String {
    let mut h = String::from("step,t,node,estimator");
    for prefix in ["true_", "est_", "var_"] {
        for c in columns {
            h.push(',');
            h.push_str(prefix);
            h.push_str(c);
        }
    }
    h.push_str(",error,trace_p_prior,trace_p_post,received,feasible,nees,diverged");
    h
}

/// Streams `trace.csv` (when given a writer) and keeps the plot sample.
pub struct TraceWriter {
    out: Option<Box<dyn Write + Send>>,
    columns: Vec<String>,
    /// The fused rows are a quaternion, reported as Euler angles.
    quaternion: bool,
    dt: f64,
    /// Plot every `stride`-th step.
    stride: u64,
    kept: Vec<TraceRow>,
    fused: Vec<FusedRow>,
    /// The first write error; later rows are not written, and [`TraceWriter::finish`] returns it.
    error: Option<io::Error>,
    /// Opens a node's `imu-ID.csv` (by node id) on its first IMU row; none: IMU rows are not kept.
    imu_files: Option<ImuOpener>,
    /// Open IMU files by node id, and whether each has magnetometer columns.
    imu: std::collections::BTreeMap<u32, (Box<dyn Write + Send>, bool)>,
    /// `measurements.csv` and the observation its R columns come from.
    measurements: Option<(Box<dyn Write + Send>, crate::estimate::Observation)>,
    /// `estimators.csv`.
    estimators: Option<Box<dyn Write + Send>>,
}

/// Opens the `imu-ID.csv` of node ID.
pub type ImuOpener = Box<dyn FnMut(u32) -> io::Result<Box<dyn Write + Send>> + Send>;

impl TraceWriter {
    /// Keep a plot sample of a run of `steps` steps; `columns` as [`crate::model::Report::columns`], `layout` how
    /// the fused rows are laid out.
    pub fn new(columns: Vec<String>, layout: &crate::model::FusionLayout, dt: f64, steps: u64) -> TraceWriter {
        TraceWriter {
            out: None,
            columns,
            quaternion: layout.quaternion,
            dt,
            stride: steps.div_ceil(PLOT_STEPS).max(1),
            kept: Vec::new(),
            fused: Vec::new(),
            error: None,
            imu_files: None,
            imu: Default::default(),
            measurements: None,
            estimators: None,
        }
    }

    /// The recorder of a run of `topo`.
    pub fn for_topology(topo: &crate::scenario::Scenario) -> TraceWriter {
        TraceWriter::new(
            topo.model().get().columns(),
            &topo.model().get().fusion(),
            topo.sim().dt(),
            topo.sim().steps(),
        )
    }

    /// Keep every row (an analysis that needs all of them; memory grows with the run).
    pub fn keep_all(mut self) -> TraceWriter {
        self.stride = 1;
        self
    }

    /// Also write every row to `w`, starting with the header.
    pub fn to_writer(mut self, w: Box<dyn Write + Send>) -> TraceWriter {
        self.out = Some(w);
        let h = header(&self.columns);
        self.write(|w| writeln!(w, "{h}"));
        self
    }

    /// Also stream each sensing node's IMU samples (with the true pose) to the file `open` gives for its id.
    pub fn with_imu(mut self, open: ImuOpener) -> TraceWriter {
        self.imu_files = Some(open);
        self
    }

    /// Also stream every sensing node's own measurements to `w` ([`MEASUREMENTS_HEADER`]): one line per node,
    /// step and channel, with the rows it carries, their values and the block of R over them, so that any
    /// estimator can be recomputed from the file.
    pub fn with_measurements(mut self, mut w: Box<dyn Write + Send>, obs: crate::estimate::Observation) -> TraceWriter {
        match writeln!(w, "{MEASUREMENTS_HEADER}") {
            Ok(()) => self.measurements = Some((w, obs)),
            Err(e) => self.error = Some(e),
        }
        self
    }

    /// Also stream every distributed estimator's estimates to `w` ([`ESTIMATORS_HEADER`]).
    pub fn with_estimators(mut self, mut w: Box<dyn Write + Send>) -> TraceWriter {
        match writeln!(w, "{ESTIMATORS_HEADER}") {
            Ok(()) => self.estimators = Some(w),
            Err(e) => self.error = Some(e),
        }
        self
    }

    /// The estimators' rows of a step.
    pub fn estimators(&mut self, rows: &[crate::observe::schemes::EstimatorRow]) {
        use std::fmt::Write as _;
        let (Some(w), None) = (self.estimators.as_mut(), self.error.as_ref()) else {
            return;
        };
        let mut text = String::new();
        for r in rows {
            let t = num((r.step as f64 * self.dt * 1e9).round() / 1e9);
            let values: Vec<String> = r.values.iter().map(|v| num(*v)).collect();
            let _ = writeln!(
                text,
                "{},{t},{},{},{},{}",
                r.step,
                r.kind.name(),
                r.node,
                num(r.error),
                values.join(";")
            );
        }
        if let Err(e) = w.write_all(text.as_bytes()) {
            self.error = Some(e);
        }
    }

    /// Nodes' own measurements of one step.
    pub fn measurements(&mut self, rows: &[crate::node::MeasurementRow]) {
        use std::fmt::Write as _;
        let (Some((w, obs)), None) = (self.measurements.as_mut(), self.error.as_ref()) else {
            return;
        };
        let join = |v: &mut dyn Iterator<Item = String>| v.collect::<Vec<_>>().join(";");
        let mut text = String::new();
        for m in rows {
            let t = num((m.step as f64 * self.dt * 1e9).round() / 1e9);
            for c in 0..obs.channels() {
                let at: Vec<usize> = (0..m.rows.len())
                    .filter(|&i| obs.channel_of_row.get(m.rows[i]) == Some(&c))
                    .collect();
                if at.is_empty() {
                    continue;
                }
                let rows = join(&mut at.iter().map(|&i| m.rows[i].to_string()));
                let values = join(&mut at.iter().map(|&i| num(m.values[i])));
                let r = join(
                    &mut at
                        .iter()
                        .flat_map(|&i| at.iter().map(move |&j| (m.rows[i], m.rows[j])))
                        .map(|(a, b)| num(obs.R[(a, b)])),
                );
                let _ = writeln!(text, "{},{t},{},{c},{rows},{values},{r}", m.step, m.node);
            }
        }
        if let Err(e) = w.write_all(text.as_bytes()) {
            self.error = Some(e);
        }
    }

    /// Whether IMU rows are wanted.
    pub fn records_imu(&self) -> bool {
        self.imu_files.is_some()
    }

    /// One step's IMU rows of node `id`.
    pub fn imu(&mut self, id: u32, rows: &[crate::node::ImuRow]) {
        let (Some(open), None, Some(first)) = (self.imu_files.as_mut(), self.error.as_ref(), rows.first()) else {
            return;
        };
        if let std::collections::btree_map::Entry::Vacant(slot) = self.imu.entry(id) {
            let mag = first.mag.is_some();
            match open(id).and_then(|mut w| w.write_all(crate::imu_csv::header(mag).as_bytes()).map(|_| w)) {
                Ok(w) => {
                    slot.insert((w, mag));
                }
                Err(e) => {
                    self.error = Some(e);
                    return;
                }
            }
        }
        let Some((w, mag)) = self.imu.get_mut(&id) else { return };
        let mut text = String::new();
        for r in rows {
            crate::imu_csv::push_row(&mut text, r, *mag);
        }
        if let Err(e) = w.write_all(text.as_bytes()) {
            self.error = Some(e);
        }
    }

    /// Ids of the nodes whose IMU file was written.
    pub fn imu_nodes(&self) -> Vec<u32> {
        self.imu.keys().copied().collect()
    }

    fn write(&mut self, f: impl FnOnce(&mut dyn Write) -> io::Result<()>) {
        if self.error.is_some() {
            return;
        }
        if let Some(w) = self.out.as_mut() {
            if let Err(e) = f(w.as_mut()) {
                self.error = Some(e);
            }
        }
    }

    /// One step's rows of the nodes' filters.
    pub fn rows(&mut self, rows: Vec<TraceRow>) {
        if self.out.is_some() {
            let mut text = String::new();
            for r in &rows {
                row_text(&mut text, r);
            }
            self.write(|w| w.write_all(text.as_bytes()));
        }
        // The plots draw the node's two filters; the schemes' figures have plots of their own.
        let stride = self.stride;
        let drawn = |r: &TraceRow| r.step.is_multiple_of(stride) && !matches!(r.filter, Filter::Scheme(_));
        self.kept.extend(rows.into_iter().filter(drawn));
    }

    /// Fused rows as the observer finishes them.
    pub fn fused(&mut self, rows: Vec<FusedRow>) {
        if rows.is_empty() {
            return;
        }
        if self.out.is_some() {
            let mut text = String::new();
            for f in &rows {
                self.fused_text(&mut text, f);
            }
            self.write(|w| w.write_all(text.as_bytes()));
        }
        let stride = self.stride;
        self.fused.extend(rows.into_iter().filter(|r| r.step % stride == 0));
    }

    fn fused_text(&self, text: &mut String, f: &FusedRow) {
        use std::fmt::Write as _;
        let n = self.columns.len();
        // The fused values in the reported columns: Euler angles of the quaternion for attitude, else the fused
        // rows in order (position for pose), the remaining columns empty.
        let cells = |v: &[f64]| -> Vec<f64> {
            let mut c = if self.quaternion && v.len() == 4 {
                let q = nalgebra::Vector4::new(v[0], v[1], v[2], v[3]);
                crate::estimate::attitude::to_euler(&q).iter().copied().collect()
            } else {
                v.to_vec()
            };
            c.resize(n, f64::NAN);
            c
        };
        let truth = cells(&f.truth);
        let t = num((f.step as f64 * self.dt * 1e9).round() / 1e9);
        let mut line = |name: &str, est: &[f64], error: f64, trace_p: f64| {
            let _ = write!(text, "{},{t},,{name}", f.step);
            for v in truth.iter().chain(cells(est).iter()) {
                let _ = write!(text, ",{}", num(*v));
            }
            text.push_str(&",".repeat(n));
            let _ = writeln!(text, ",{},{},{},,,,", num(error), num(trace_p), num(trace_p));
        };
        line("fused", &f.fused, f.error, f.trace_p);
        if f.smoothed {
            line("fused_median", &f.median, f.median_error, f64::NAN);
        }
    }

    /// Flush the file and hand back the plot sample (node rows in step order, fused rows).
    pub fn finish(mut self) -> io::Result<(Vec<TraceRow>, Vec<FusedRow>)> {
        self.write(|w| w.flush());
        for (w, _) in self.imu.values_mut() {
            if let Err(e) = w.flush() {
                self.error.get_or_insert(e);
            }
        }
        if let Some((w, _)) = self.measurements.as_mut() {
            if let Err(e) = w.flush() {
                self.error.get_or_insert(e);
            }
        }
        if let Some(w) = self.estimators.as_mut() {
            if let Err(e) = w.flush() {
                self.error.get_or_insert(e);
            }
        }
        match self.error {
            Some(e) => Err(e),
            None => Ok((self.kept, self.fused)),
        }
    }
}

/// One node filter's row.
fn row_text(text: &mut String, r: &TraceRow) {
    use std::fmt::Write as _;
    let t = num((r.t * 1e9).round() / 1e9);
    let _ = write!(text, "{},{t},{},{}", r.step, r.node, r.filter.name());
    for v in r.truth.iter().chain(&r.est).chain(&r.var) {
        let _ = write!(text, ",{}", num(*v));
    }
    let received: Vec<String> = r.received.iter().map(|x| x.to_string()).collect();
    let _ = writeln!(
        text,
        ",{},{},{},{},{},{},{}",
        num(r.error),
        num(r.trace_p_prior),
        num(r.trace_p_post),
        received.join(";"),
        r.feasible,
        num(r.nees),
        r.diverged
    );
}

/// `trace.csv` of these rows at once (a node's part; tests).
pub fn write_trace(w: &mut impl Write, columns: &[String], rows: &[TraceRow]) -> io::Result<()> {
    writeln!(w, "{}", header(columns))?;
    let mut text = String::new();
    for r in rows {
        row_text(&mut text, r);
    }
    w.write_all(text.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_shortest_round_trip() {
        for v in [0.1, 1e-5, 1.7e308, -2.5, 123456.789, 5e-324] {
            assert_eq!(num(v).parse::<f64>().unwrap(), v);
        }
        assert_eq!(num(0.1), "0.1");
        assert_eq!(num(1.7e308), "1.7e308");
        assert_eq!(num(f64::NAN), "");
        assert_eq!(num(f64::NEG_INFINITY), "-inf");
    }
}
