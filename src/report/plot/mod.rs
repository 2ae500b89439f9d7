//! SVG plots drawn with plotters and an embedded DejaVu font (no system fonts needed). `run.rs`: one run's
//! trajectories, error and trace P over time, networked against independent; `analysis.rs`: covariance bounds,
//! protocol curves and named lines; `estimators.rs`: every distributed estimator's error against time; `sweep.rs`: a campaign's figures against the swept key with confidence bands. This file: the axes, legends, colours and series they share.

use std::collections::BTreeMap;
use std::sync::Once;

use plotters::prelude::*;
use plotters::style::FontStyle;

use crate::model::{Kind, TrajectoryView};
use crate::node::TraceRow;
use crate::observe::fusion::FusedRow;

#[derive(Debug, thiserror::Error)]
#[error("plot `{name}`: {message}")]
pub struct PlotError {
    pub name: &'static str,
    pub message: String,
}

fn font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The bundled font is a valid TrueType file; failing here would be a build defect.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, dejavu::sans::regular());
    });
}

const SIZE: (u32, u32) = (1000, 640);

fn palette(i: usize) -> RGBColor {
    const C: [RGBColor; 8] = [
        RGBColor(214, 39, 40),
        RGBColor(31, 119, 180),
        RGBColor(44, 160, 44),
        RGBColor(148, 103, 189),
        RGBColor(255, 127, 14),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(23, 190, 207),
    ];
    C[i % C.len()]
}

fn err<E: std::fmt::Display>(name: &'static str) -> impl Fn(E) -> PlotError {
    move |e| PlotError {
        name,
        message: e.to_string(),
    }
}

/// The largest magnitude an axis shows: beyond it (a diverged covariance reaches 1e308) curves are clipped.
const AXIS_LIMIT: f64 = 1e300;

/// An axis range over the finite values (positive ones on a log axis), padded, always finite and non-empty: no
/// value can make plotters loop on an infinite range.
fn axis(values: impl Iterator<Item = f64>, log: bool) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite() && (!log || *v > 0.0)) {
        let v = v.clamp(-AXIS_LIMIT, AXIS_LIMIT);
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if log {
        if !lo.is_finite() {
            return (1e-6, 1.0);
        }
        let (lo, hi) = ((lo / 1.5).max(1.0 / AXIS_LIMIT), (hi * 1.5).min(AXIS_LIMIT));
        // At least one decade, so that the axis has ticks.
        (lo.min(hi / 10.0), hi)
    } else {
        if !lo.is_finite() {
            return (0.0, 1.0);
        }
        let pad = ((hi - lo) * 0.05).max(1e-9 * hi.abs().max(lo.abs())).max(1e-12);
        ((lo - pad).max(-AXIS_LIMIT), (hi + pad).min(AXIS_LIMIT))
    }
}

/// A tick label: three significant digits at most, `1e-4` rather than `9.999999999e-5`.
pub fn tick(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let e = format!("{v:.2e}");
    let (m, exp) = e.split_once('e').unwrap_or((&e, "0"));
    let exp: i32 = exp.parse().unwrap_or(0);
    let m = m.trim_end_matches('0').trim_end_matches('.');
    if (-3..=4).contains(&exp) {
        let r: f64 = format!("{m}e{exp}").parse().unwrap_or(v);
        format!("{r}")
    } else {
        format!("{m}e{exp}")
    }
}

/// Beyond this many nodes a plot draws the median and the min–max band across nodes instead of a line per node.
pub const MAX_NODE_LINES: usize = 6;

/// One node filter's rows in step order.
struct Series<'a> {
    node: u32,
    networked: bool,
    rows: Vec<&'a TraceRow>,
}

impl Series<'_> {
    /// Left out of the axis scale: a twin with no measurement of its own (prediction only) or a diverged filter.
    fn off_scale(&self) -> bool {
        self.rows.iter().all(|r| r.received.is_empty()) || self.rows.iter().any(|r| r.diverged)
    }

    fn label(&self) -> String {
        format!(
            "node {} {}{}",
            self.node,
            if self.networked { "networked" } else { "independent" },
            if self.off_scale() {
                if self.rows.iter().any(|r| r.diverged) {
                    " (diverged: clipped, not in scale)"
                } else {
                    " (prediction only: clipped, not in scale)"
                }
            } else {
                ""
            }
        )
    }
}

fn series(rows: &[TraceRow]) -> Vec<Series<'_>> {
    let mut m: BTreeMap<(u32, bool), Vec<&TraceRow>> = BTreeMap::new();
    for r in rows {
        m.entry((r.node, !r.networked)).or_default().push(r);
    }
    m.into_iter()
        .map(|((node, ind), rows)| Series {
            node,
            networked: !ind,
            rows,
        })
        .collect()
}

/// Points split into runs where steps are missing (a crashed node) or a value is not finite, so a gap stays a
/// gap; y clamped into [lo, hi] (drawn clipped).
fn runs(pts: impl Iterator<Item = (u64, f64, f64)>, lo: f64, hi: f64) -> Vec<Vec<(f64, f64)>> {
    let pts: Vec<(u64, f64, f64)> = pts.collect();
    // The sampling stride of the plot (every k-th step for long runs).
    let stride = pts
        .windows(2)
        .map(|w| w[1].0.saturating_sub(w[0].0))
        .filter(|d| *d > 0)
        .min()
        .unwrap_or(1);
    let mut out: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut last: Option<u64> = None;
    for (step, x, y) in pts {
        if !(x.is_finite() && y.is_finite()) {
            last = None;
            continue;
        }
        if last.is_none_or(|l| step > l + stride) {
            out.push(Vec::new());
        }
        if let Some(run) = out.last_mut() {
            run.push((x, y.clamp(lo, hi)));
        }
        last = Some(step);
    }
    out
}

/// The legend box, upper right, as every plot draws it.
fn legend<'a, DB: DrawingBackend + 'a, CT: plotters::coord::CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    name: &'static str,
) -> Result<(), PlotError> {
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(err(name))
}

fn legend_line(style: ShapeStyle) -> impl Fn((i32, i32)) -> PathElement<(i32, i32)> {
    move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], style)
}

/// Draws `runs` as one legend entry (or none).
fn draw_runs<DB: DrawingBackend, CT: plotters::coord::CoordTranslate<From = (f64, f64)>>(
    chart: &mut ChartContext<'_, DB, CT>,
    runs: Vec<Vec<(f64, f64)>>,
    style: ShapeStyle,
    label: Option<String>,
    name: &'static str,
) -> Result<(), PlotError> {
    let mut first = true;
    for run in runs {
        let drawn = chart.draw_series(LineSeries::new(run, style)).map_err(err(name))?;
        if first {
            if let Some(l) = &label {
                drawn.label(l.clone()).legend(legend_line(style));
            }
            first = false;
        }
    }
    Ok(())
}

/// Median and min–max across nodes per step: (step, t, median, min, max).
fn across_nodes(series: &[&Series], value: &dyn Fn(&TraceRow) -> f64) -> Vec<(u64, f64, f64, f64, f64)> {
    let mut by_step: BTreeMap<u64, (f64, Vec<f64>)> = BTreeMap::new();
    for s in series {
        for r in &s.rows {
            let v = value(r);
            if v.is_finite() {
                by_step.entry(r.step).or_insert((r.t, Vec::new())).1.push(v);
            }
        }
    }
    by_step
        .into_iter()
        .map(|(step, (t, mut v))| {
            v.sort_by(f64::total_cmp);
            let m = v.len();
            let med = if m % 2 == 1 {
                v[m / 2]
            } else {
                0.5 * (v[m / 2 - 1] + v[m / 2])
            };
            (step, t, med, v[0], v[m - 1])
        })
        .collect()
}

mod analysis;
mod estimators;
mod run;
mod sweep;

pub use analysis::{covariance_bounds, lines, protocol_curve, BoundsRow, ProtocolPoint};
pub use estimators::estimators;
pub use run::{error, trace_p, trajectory};
pub use sweep::{sweep, SweepLine, SweepPanel, MAX_ROWS as MAX_SWEEP_ROWS};
