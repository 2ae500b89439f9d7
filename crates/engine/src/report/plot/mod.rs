//! SVG plots drawn with plotters and an embedded DejaVu font (no system fonts needed). `run.rs`: one run's
//! trajectories, error and trace P over time, networked against independent; `analysis.rs`: covariance bounds,
//! protocol curves and named lines; `estimators.rs`: every distributed estimator's error against time; `map.rs`: where the nodes stand and what each link delivered; `sweep.rs`: a campaign's figures against the swept key with confidence bands; `budget.rs`: error against what each estimator spends on the network. This file: the axes, legends, colours and series they share.

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

/// Ten colours (Tableau's), as many as the estimator registry has entries: a plot of every estimator gives each its
/// own.
const PALETTE: [RGBColor; 10] = [
    RGBColor(214, 39, 40),
    RGBColor(31, 119, 180),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
];

fn palette(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

/// An estimator's colour: by its place in the registry, so that it keeps its colour in every plot.
fn estimator_colour(kind: crate::estimators::Kind) -> RGBColor {
    palette(usize::from(kind.id()))
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

/// x and y ranges at equal scale on a chart of [`SIZE`] with a y label area `y_labels` px wide: the narrower range
/// widened about its centre to the plotting area's aspect ratio (a plane drawn undistorted).
fn equal_scale((x0, x1): (f64, f64), (y0, y1): (f64, f64), y_labels: f64) -> ((f64, f64), (f64, f64)) {
    let (w, h) = (SIZE.0 as f64 - y_labels - 24.0, SIZE.1 as f64 - 40.0 - 24.0 - 30.0);
    let (sx, sy) = ((x1 - x0) / w, (y1 - y0) / h);
    if sx > sy {
        let c = 0.5 * (y0 + y1);
        ((x0, x1), (c - 0.5 * sx * h, c + 0.5 * sx * h))
    } else {
        let c = 0.5 * (x0 + x1);
        ((c - 0.5 * sy * w, c + 0.5 * sy * w), (y0, y1))
    }
}

/// A log axis over [lo, hi] with its ticks at 1, 2 and 5 times each power of ten (at the powers alone past four
/// decades, at every k-th power past twelve) and its fine grid at 1–9 times them (at the powers past twelve): plotters' own log ticks repeat the power of ten that ends one
/// decade and starts the next (a label drawn twice, a band of fine lines about it).
fn log_axis(
    lo: f64,
    hi: f64,
) -> plotters::coord::combinators::WithKeyPoints<plotters::coord::combinators::LogCoord<f64>> {
    use plotters::coord::combinators::BindKeyPoints;
    let (d0, d1) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
    let within = |v: &f64| (lo..=hi).contains(v);
    let at = |ms: &[f64]| -> Vec<f64> {
        (d0..=d1)
            .flat_map(|d| ms.iter().map(move |m| m * 10f64.powi(d)))
            .filter(within)
            .collect()
    };
    let decades = d1 - d0;
    // Past four decades the powers alone, every k-th of them past twelve: at most a dozen labels on the axis.
    let (bold, light) = if decades > 12 {
        let every = (decades + 11) / 12;
        let powers: Vec<f64> = (d0..=d1).map(|d| 10f64.powi(d)).filter(within).collect();
        let labelled = (d0..=d1)
            .filter(|d| (d - d0) % every == 0)
            .map(|d| 10f64.powi(d))
            .filter(within)
            .collect();
        (labelled, powers)
    } else if decades > 4 {
        (at(&[1.0]), at(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]))
    } else {
        (at(&[1.0, 2.0, 5.0]), at(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]))
    };
    (lo..hi).log_scale().with_key_points(bold).with_light_points(light)
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
        let networked = match r.filter {
            crate::observe::Filter::Networked => true,
            crate::observe::Filter::Independent => false,
            crate::observe::Filter::Scheme(_) => continue,
        };
        m.entry((r.node, !networked)).or_default().push(r);
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

/// The legend box at `corner`, as every plot draws it.
fn legend<'a, DB: DrawingBackend + 'a, CT: plotters::coord::CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    name: &'static str,
    corner: SeriesLabelPosition,
) -> Result<(), PlotError> {
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(corner)
        .draw()
        .map_err(err(name))
}

/// The corner where a legend covers the fewest of the points drawn: of the four corner boxes (a third of the width,
/// 40 % of the height), the one holding the fewest, upper right on a tie.
fn emptiest_corner(
    points: impl Iterator<Item = (f64, f64)>,
    x: (f64, f64),
    y: (f64, f64),
    log_y: bool,
) -> SeriesLabelPosition {
    let fy = |v: f64| if log_y { v.max(f64::MIN_POSITIVE).ln() } else { v };
    let (y0, y1) = (fy(y.0), fy(y.1));
    // Upper right, upper left, lower right, lower left.
    let mut count = [0usize; 4];
    for (px, py) in points.filter(|(a, b)| a.is_finite() && b.is_finite()) {
        let u = (px - x.0) / (x.1 - x.0);
        let v = (fy(py) - y0) / (y1 - y0);
        let (left, right, top, bottom) = (u < 1.0 / 3.0, u > 2.0 / 3.0, v > 0.6, v < 0.4);
        for (i, inside) in [top && right, top && left, bottom && right, bottom && left]
            .into_iter()
            .enumerate()
        {
            count[i] += usize::from(inside);
        }
    }
    let corners = [
        SeriesLabelPosition::UpperRight,
        SeriesLabelPosition::UpperLeft,
        SeriesLabelPosition::LowerRight,
        SeriesLabelPosition::LowerLeft,
    ];
    let best = (0..4).min_by_key(|&i| (count[i], i)).unwrap_or(0);
    corners[best].clone()
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

#[cfg(test)]
mod tests {
    #[test]
    fn every_estimator_has_a_colour_of_its_own() {
        let all = crate::estimators::Kind::BUILTIN;
        assert!(
            all.len() <= super::PALETTE.len(),
            "{} estimators, {} colours",
            all.len(),
            super::PALETTE.len()
        );
        let colours: std::collections::BTreeSet<(u8, u8, u8)> = all
            .iter()
            .map(|k| super::estimator_colour(*k))
            .map(|c| (c.0, c.1, c.2))
            .collect();
        assert_eq!(colours.len(), all.len());
    }

    #[test]
    fn a_legend_goes_where_the_data_is_not() {
        use plotters::chart::SeriesLabelPosition as P;
        let corner = |pts: Vec<(f64, f64)>| super::emptiest_corner(pts.into_iter(), (0.0, 10.0), (0.0, 1.0), false);
        assert!(matches!(corner(vec![]), P::UpperRight));
        // A line along the top: the legend goes below it.
        let top: Vec<(f64, f64)> = (0..100).map(|i| (f64::from(i) / 10.0, 0.95)).collect();
        assert!(matches!(corner(top.clone()), P::LowerRight));
        // Data everywhere but the lower left.
        let mut most = top;
        most.extend((0..100).map(|i| (5.0 + f64::from(i) / 20.0, 0.1)));
        assert!(matches!(corner(most), P::LowerLeft));
    }

    #[test]
    fn a_log_axis_names_each_tick_once() {
        use plotters::coord::ranged1d::{BoldPoints, Ranged};
        let axis = super::log_axis(0.8, 45.0);
        let bold = axis.key_points(BoldPoints(100));
        let mut unique = bold.clone();
        unique.dedup();
        assert_eq!(bold, unique, "a tick repeated");
        assert_eq!(bold, [1.0, 2.0, 5.0, 10.0, 20.0]);
        assert_eq!(
            super::log_axis(1e-6, 1e3).key_points(BoldPoints(100)).len(),
            10,
            "past four decades: the powers alone"
        );
    }
}

mod analysis;
mod budget;
mod estimators;
mod map;
mod run;
mod sweep;

pub use analysis::{covariance_bounds, lines, protocol_curve, BoundsRow, ProtocolPoint};
pub use budget::{budget, BudgetPoint};
pub use estimators::estimators;
pub use map::map;
pub use run::{error, trace_p, trajectory};
pub use sweep::{sweep, SweepLine, SweepPanel, MAX_ROWS as MAX_SWEEP_ROWS};
