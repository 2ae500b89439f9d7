//! SVG plots drawn with plotters and an embedded DejaVu font (no system fonts needed): trajectories, error over time
//! and trace P over time, networked against independent.

use std::collections::BTreeMap;
use std::sync::Once;

use plotters::prelude::*;
use plotters::style::FontStyle;

use super::observer::FusedRow;
use crate::model::{Kind, TrajectoryView};
use crate::node::TraceRow;

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

/// True trajectory and estimates: the x–y plane at equal scale for pose, roll, pitch and yaw in three panels
/// against time for attitude (networked estimates), x₀ against time for linear ([`TrajectoryView`]).
pub fn trajectory(
    rows: &[TraceRow],
    fused: &[FusedRow],
    view: TrajectoryView,
    title: &str,
) -> Result<String, PlotError> {
    if view == TrajectoryView::Angles {
        return attitude_trajectory(rows, title);
    }
    font();
    let name = "trajectory";
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(err(name))?;
        let all = series(rows);
        let pose = view == TrajectoryView::Plane;
        let xy = |r: &TraceRow, est: bool| -> (f64, f64) {
            let v = if est { &r.est } else { &r.truth };
            if pose {
                (v[0], v[1])
            } else {
                (r.t, v[0])
            }
        };
        let scaled: Vec<(f64, f64)> = rows
            .iter()
            .map(|r| xy(r, false))
            .chain(
                all.iter()
                    .filter(|s| !s.off_scale())
                    .flat_map(|s| s.rows.iter().map(|r| xy(r, true))),
            )
            .collect();
        let (mut x0, mut x1) = axis(scaled.iter().map(|p| p.0), false);
        let (mut y0, mut y1) = axis(scaled.iter().map(|p| p.1), false);
        if pose {
            // Equal scale on both axes: widen the narrower range to the plotting area's aspect ratio.
            let (w, h) = (SIZE.0 as f64 - 60.0 - 24.0, SIZE.1 as f64 - 40.0 - 24.0 - 30.0);
            let (sx, sy) = ((x1 - x0) / w, (y1 - y0) / h);
            if sx > sy {
                let c = 0.5 * (y0 + y1);
                (y0, y1) = (c - 0.5 * sx * h, c + 0.5 * sx * h);
            } else {
                let c = 0.5 * (x0 + x1);
                (x0, x1) = (c - 0.5 * sy * w, c + 0.5 * sy * w);
            }
        }
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(err(name))?;
        chart
            .configure_mesh()
            .x_desc(if pose { "x (m)" } else { "t (s)" })
            .y_desc(if pose { "y (m)" } else { "x₀" })
            .x_label_formatter(&|v| tick(*v))
            .y_label_formatter(&|v| tick(*v))
            .draw()
            .map_err(err(name))?;
        // Pose curves run in the plane: clamping one coordinate of a point is clipping enough to stay on the chart.
        let clip = |(x, y): (f64, f64)| (x.clamp(x0, x1), y);
        if let Some(first) = all.first() {
            let truth = runs(
                first
                    .rows
                    .iter()
                    .map(|r| (r.step, clip(xy(r, false)).0, xy(r, false).1)),
                y0,
                y1,
            );
            draw_runs(&mut chart, truth, BLACK.stroke_width(2), Some("truth".into()), name)?;
        }
        let many = all.iter().filter(|s| s.networked).count() > MAX_NODE_LINES;
        for (i, s) in all.iter().enumerate() {
            let c = if many {
                palette(if s.networked { 1 } else { 0 })
            } else {
                palette(i / 2)
            };
            let style = match (s.networked, many) {
                (true, false) => c.stroke_width(1),
                (false, false) => c.mix(0.35).stroke_width(1),
                (_, true) => c.mix(0.3).stroke_width(1),
            };
            let label = if many {
                let first_of_kind = all.iter().position(|o| o.networked == s.networked) == Some(i);
                first_of_kind.then(|| {
                    format!(
                        "{} estimates, one line per node ({} nodes)",
                        if s.networked { "networked" } else { "independent" },
                        all.iter().filter(|o| o.networked == s.networked).count()
                    )
                })
            } else {
                Some(s.label())
            };
            let r = runs(
                s.rows.iter().map(|r| (r.step, clip(xy(r, true)).0, xy(r, true).1)),
                y0,
                y1,
            );
            draw_runs(&mut chart, r, style, label, name)?;
        }
        if pose && !fused.is_empty() {
            let style = RGBColor(0, 0, 0).mix(0.6).stroke_width(2);
            let r = runs(
                fused.iter().map(|f| (f.step, f.median[0].clamp(x0, x1), f.median[1])),
                y0,
                y1,
            );
            draw_runs(&mut chart, r, style, Some("fused (CI, median 20)".into()), name)?;
        }
        legend(&mut chart, name)?;
        root.present().map_err(err(name))?;
    }
    Ok(out)
}

/// Roll, pitch and yaw in three panels against time: truth and the networked estimates.
fn attitude_trajectory(rows: &[TraceRow], title: &str) -> Result<String, PlotError> {
    font();
    let name = "trajectory";
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(err(name))?;
        let all = series(rows);
        let root = root.titled(title, ("sans-serif", 22)).map_err(err(name))?;
        let panels = root.split_evenly((3, 1));
        let net: Vec<&Series> = all.iter().filter(|s| s.networked).collect();
        let many = net.len() > MAX_NODE_LINES;
        for (c, (panel, angle)) in panels.iter().zip(["roll", "pitch", "yaw"]).enumerate() {
            let deg = |v: &[f64]| v[c].to_degrees();
            let scaled = net.iter().filter(|s| !s.off_scale()).flat_map(|s| s.rows.iter());
            let (y0, y1) = axis(
                rows.iter().map(|r| deg(&r.truth)).chain(scaled.map(|r| deg(&r.est))),
                false,
            );
            let t1 = rows.iter().map(|r| r.t).fold(1e-9, f64::max);
            let mut chart = ChartBuilder::on(panel)
                .margin(6)
                .x_label_area_size(if c == 2 { 34 } else { 0 })
                .y_label_area_size(60)
                .build_cartesian_2d(0.0..t1, y0..y1)
                .map_err(err(name))?;
            let mut mesh = chart.configure_mesh();
            mesh.y_desc(format!("{angle} (°)")).y_label_formatter(&|v| tick(*v));
            if c == 2 {
                mesh.x_desc("t (s)");
            }
            mesh.draw().map_err(err(name))?;
            if let Some(first) = all.first() {
                let truth = runs(first.rows.iter().map(|r| (r.step, r.t, deg(&r.truth))), y0, y1);
                draw_runs(&mut chart, truth, BLACK.stroke_width(2), Some("truth".into()), name)?;
            }
            for (i, s) in net.iter().enumerate() {
                let style = if many {
                    palette(1).mix(0.35).stroke_width(1)
                } else {
                    palette(i).stroke_width(1)
                };
                let label = if many {
                    (i == 0).then(|| format!("networked estimates ({} nodes)", net.len()))
                } else {
                    Some(s.label())
                };
                let r = runs(s.rows.iter().map(|r| (r.step, r.t, deg(&r.est))), y0, y1);
                draw_runs(&mut chart, r, style, label, name)?;
            }
            if c == 0 {
                legend(&mut chart, name)?;
            }
        }
        root.present().map_err(err(name))?;
    }
    Ok(out)
}

/// A per-step quantity against time: a line per node and filter (networked solid, independent faded), or beyond
/// [`MAX_NODE_LINES`] nodes the median and min–max band across nodes, networked against independent.
#[allow(clippy::too_many_arguments)]
fn over_time(
    name: &'static str,
    rows: &[TraceRow],
    fused: &[FusedRow],
    dt: f64,
    title: &str,
    y_desc: &str,
    value: impl Fn(&TraceRow) -> f64,
    log: bool,
) -> Result<String, PlotError> {
    font();
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(err(name))?;
        let all = series(rows);
        let t_max = rows.iter().map(|r| r.t).fold(0.0, f64::max).max(dt);
        let in_scale = all
            .iter()
            .filter(|s| !s.off_scale())
            .flat_map(|s| s.rows.iter().map(|r| value(r)))
            .chain(fused.iter().map(|f| f.median_error));
        let (lo, hi) = axis(in_scale, log);
        let many = all.iter().filter(|s| s.networked).count() > MAX_NODE_LINES;
        let mut cb = ChartBuilder::on(&root);
        cb.caption(title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70);
        macro_rules! draw {
            ($chart:expr) => {{
                let mut chart = $chart;
                chart
                    .configure_mesh()
                    .x_desc("t (s)")
                    .y_desc(y_desc)
                    .y_label_formatter(&|v| tick(*v))
                    .draw()
                    .map_err(err(name))?;
                let pts = |s: &Series| runs(s.rows.iter().map(|r| (r.step, r.t, value(r))), lo, hi);
                if many {
                    for networked in [false, true] {
                        let kind: Vec<&Series> = all.iter().filter(|s| s.networked == networked).collect();
                        let (scaled, off): (Vec<&Series>, Vec<&Series>) = kind.iter().partition(|s| !s.off_scale());
                        let c = palette(if networked { 1 } else { 0 });
                        let what = if networked { "networked" } else { "independent" };
                        let agg = across_nodes(&scaled, &value);
                        let clampy = |v: f64| v.clamp(lo, hi);
                        let band = runs(agg.iter().map(|a| (a.0, a.1, clampy(a.4))), lo, hi);
                        let lower = runs(agg.iter().map(|a| (a.0, a.1, clampy(a.3))), lo, hi);
                        for (k, (up, down)) in band.into_iter().zip(lower).enumerate() {
                            let poly: Vec<(f64, f64)> = up.iter().copied().chain(down.into_iter().rev()).collect();
                            let drawn = chart
                                .draw_series(std::iter::once(Polygon::new(poly, c.mix(0.18).filled())))
                                .map_err(err(name))?;
                            if k == 0 {
                                drawn
                                    .label(format!("{what}: min–max over {} nodes", scaled.len()))
                                    .legend(move |(x, y)| {
                                        Rectangle::new([(x, y - 5), (x + 18, y + 5)], c.mix(0.18).filled())
                                    });
                            }
                        }
                        let med = runs(agg.iter().map(|a| (a.0, a.1, a.2)), lo, hi);
                        draw_runs(
                            &mut chart,
                            med,
                            c.stroke_width(2),
                            Some(format!("{what}: median over nodes")),
                            name,
                        )?;
                        for (i, s) in off.iter().enumerate() {
                            let label = (i == 0).then(|| {
                                format!(
                                    "{what}: {} diverged or prediction only (clipped, not in scale)",
                                    crate::scenario::count(off.len(), "node")
                                )
                            });
                            draw_runs(&mut chart, pts(s), c.mix(0.5).stroke_width(1), label, name)?;
                        }
                    }
                } else {
                    for (i, s) in all.iter().enumerate() {
                        let c = palette(i / 2);
                        let style = if s.networked {
                            c.stroke_width(1)
                        } else {
                            c.mix(0.5).stroke_width(1)
                        };
                        draw_runs(&mut chart, pts(s), style, Some(s.label()), name)?;
                    }
                }
                if name == "error" && !fused.is_empty() {
                    let label = if fused.iter().any(|f| f.smoothed) {
                        "fused (CI, median 20)"
                    } else {
                        "fused (CI)"
                    };
                    let r = runs(
                        fused.iter().map(|f| (f.step, f.step as f64 * dt, f.median_error)),
                        lo,
                        hi,
                    );
                    draw_runs(&mut chart, r, BLACK.stroke_width(2), Some(label.into()), name)?;
                }
                legend(&mut chart, name)?;
            }};
        }
        if log {
            draw!(cb
                .build_cartesian_2d(0.0..t_max, (lo..hi).log_scale())
                .map_err(err(name))?);
        } else {
            draw!(cb.build_cartesian_2d(0.0..t_max, lo.min(0.0)..hi).map_err(err(name))?);
        }
        root.present().map_err(err(name))?;
    }
    Ok(out)
}

/// The error figure against time, as the node computed it: position (pose), rotation angle (attitude), state
/// (linear).
pub fn error(rows: &[TraceRow], fused: &[FusedRow], dt: f64, model: Kind, title: &str) -> Result<String, PlotError> {
    let y = model.error_text().axis;
    over_time("error", rows, fused, dt, title, y, |r| r.error, false)
}

pub fn trace_p(rows: &[TraceRow], dt: f64, title: &str) -> Result<String, PlotError> {
    over_time(
        "trace_p",
        rows,
        &[],
        dt,
        title,
        "trace P (posterior)",
        |r| r.trace_p_post,
        true,
    )
}

/// (λ, trace S̄, trace V̄, measured mean trace P_{k|k−1}); `None` where there is no fixed point or no measurement.
pub type BoundsRow = (f64, Option<f64>, Option<f64>, Option<f64>);

/// trace S̄ and trace V̄ against λ (log scale), measured means as points, λ_min and λ̄ marked.
pub fn covariance_bounds(
    rows: &[BoundsRow],
    lambda_min: f64,
    lambda_bar: f64,
    title: &str,
) -> Result<String, PlotError> {
    font();
    let name = "bounds";
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(err(name))?;
        let vals: Vec<f64> = rows
            .iter()
            .flat_map(|r| [r.1, r.2, r.3])
            .flatten()
            .filter(|v| *v > 0.0 && v.is_finite())
            .collect();
        let lo = vals.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = vals.iter().copied().fold(0.0, f64::max);
        let (lo, hi) = if lo.is_finite() {
            (lo / 1.5, hi * 1.5)
        } else {
            (0.1, 10.0)
        };
        let x0 = if lambda_min.is_finite() {
            lambda_min.min(lambda_bar)
        } else {
            0.0
        };
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d((x0 - 0.02).max(0.0)..1.0, (lo..hi).log_scale())
            .map_err(err(name))?;
        chart
            .configure_mesh()
            .x_desc("arrival rate λ")
            .y_desc("trace")
            .draw()
            .map_err(err(name))?;
        let line = |sel: fn(&BoundsRow) -> Option<f64>| -> Vec<(f64, f64)> {
            rows.iter().filter_map(|r| sel(r).map(|v| (r.0, v))).collect()
        };
        let blue = RGBColor(31, 119, 180);
        let red = RGBColor(214, 39, 40);
        chart
            .draw_series(LineSeries::new(line(|r| r.1), blue.stroke_width(2)))
            .map_err(err(name))?
            .label("trace S̄ (lower bound)")
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], blue.stroke_width(2)));
        chart
            .draw_series(LineSeries::new(line(|r| r.2), red.stroke_width(2)))
            .map_err(err(name))?
            .label("trace V̄ (upper bound)")
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], red.stroke_width(2)));
        let measured = line(|r| r.3);
        if !measured.is_empty() {
            chart
                .draw_series(measured.iter().map(|p| Circle::new(*p, 5, BLACK.filled())))
                .map_err(err(name))?
                .label("measured mean trace P(k|k−1)")
                .legend(|(x, y)| Circle::new((x + 9, y), 5, BLACK.filled()));
        }
        if lambda_bar.is_finite() {
            chart
                .draw_series(LineSeries::new(
                    [(lambda_bar, lo), (lambda_bar, hi)],
                    BLACK.mix(0.5).stroke_width(1),
                ))
                .map_err(err(name))?
                .label(format!("λ̄ = {lambda_bar:.4}"))
                .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], BLACK.mix(0.5)));
        }
        legend(&mut chart, name)?;
        root.present().map_err(err(name))?;
    }
    Ok(out)
}

/// One protocol on the exchange plot: (exchanged weight, mean error, worst-seed error, feasible).
pub type ProtocolPoint = (f64, f64, f64, bool);

/// Mean error against exchanged weight (Sequeira's Figs. 9b/11b), with the independent filters' error,
/// the topology's own protocol, the chosen one and the LMI boundary.
pub fn protocol_curve(
    curve: &[ProtocolPoint],
    independent: f64,
    reference: (f64, f64),
    chosen: (f64, f64),
    boundary: Option<f64>,
    y_desc: &str,
    title: &str,
) -> Result<String, PlotError> {
    font();
    let name = "protocol";
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(err(name))?;
        let ys: Vec<f64> = curve
            .iter()
            .flat_map(|p| [p.1, p.2])
            .chain([independent, reference.1, chosen.1])
            .filter(|v| v.is_finite())
            .collect();
        let lo = ys.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = ys.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let (lo, hi) = if lo.is_finite() {
            (lo * 0.9, hi * 1.1)
        } else {
            (0.0, 1.0)
        };
        let xmax = curve
            .iter()
            .map(|p| p.0)
            .chain([reference.0, chosen.0])
            .fold(0.0, f64::max)
            * 1.05
            + 1e-9;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(80)
            .build_cartesian_2d(0.0..xmax, lo..hi)
            .map_err(err(name))?;
        chart
            .configure_mesh()
            .x_desc("weight given to neighbours, Σ_{j≠i} β_ij (mean over nodes)")
            .y_desc(y_desc)
            .draw()
            .map_err(err(name))?;
        let blue = RGBColor(31, 119, 180);
        let red = RGBColor(214, 39, 40);
        let green = RGBColor(44, 160, 44);
        let mean: Vec<(f64, f64)> = curve.iter().filter(|p| p.1.is_finite()).map(|p| (p.0, p.1)).collect();
        let worst: Vec<(f64, f64)> = curve.iter().filter(|p| p.2.is_finite()).map(|p| (p.0, p.2)).collect();
        chart
            .draw_series(LineSeries::new(mean.clone(), blue.stroke_width(2)))
            .map_err(err(name))?
            .label("networked, mean over seeds (black: (17)/(19) violated)")
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], blue.stroke_width(2)));
        chart
            .draw_series(curve.iter().filter(|p| p.1.is_finite()).map(|p| {
                let style = if p.3 { blue.filled() } else { BLACK.filled() };
                Circle::new((p.0, p.1), 4, style)
            }))
            .map_err(err(name))?;
        chart
            .draw_series(LineSeries::new(worst, blue.mix(0.5).stroke_width(1)))
            .map_err(err(name))?
            .label("networked, worst seed")
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], blue.mix(0.5)));
        chart
            .draw_series(LineSeries::new(
                [(0.0, independent), (xmax, independent)],
                green.stroke_width(2),
            ))
            .map_err(err(name))?
            .label("independent nodes")
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], green.stroke_width(2)));
        chart
            .draw_series([TriangleMarker::new(reference, 9, BLACK.filled())])
            .map_err(err(name))?
            .label("topology's own protocol")
            .legend(|(x, y)| TriangleMarker::new((x + 9, y), 7, BLACK.filled()));
        chart
            .draw_series([Cross::new(chosen, 10, red.stroke_width(3))])
            .map_err(err(name))?
            .label("chosen protocol")
            .legend(move |(x, y)| Cross::new((x + 9, y), 7, red.stroke_width(3)));
        if let Some(b) = boundary {
            chart
                .draw_series(LineSeries::new([(b, lo), (b, hi)], BLACK.mix(0.5).stroke_width(1)))
                .map_err(err(name))?
                .label(format!("(17)/(19) boundary, exchange {b:.3}"))
                .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], BLACK.mix(0.5)));
        }
        legend(&mut chart, name)?;
        root.present().map_err(err(name))?;
    }
    Ok(out)
}

/// Named curves over a common x axis (log y when every value is positive and `log_y`); NaN points are skipped.
pub fn lines(
    series: &[(String, Vec<(f64, f64)>)],
    x_desc: &str,
    y_desc: &str,
    log_y: bool,
    title: &str,
) -> Result<String, PlotError> {
    font();
    let name = "lines";
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(err(name))?;
        let pts = || {
            series
                .iter()
                .flat_map(|s| s.1.iter())
                .filter(|p| p.0.is_finite() && p.1.is_finite())
        };
        let (x0, x1) = pts().fold((f64::INFINITY, f64::NEG_INFINITY), |a, p| (a.0.min(p.0), a.1.max(p.0)));
        let (y0, y1) = pts().fold((f64::INFINITY, f64::NEG_INFINITY), |a, p| (a.0.min(p.1), a.1.max(p.1)));
        let (x0, x1) = if x0 < x1 { (x0, x1) } else { (0.0, 1.0) };
        let log = log_y && y0 > 0.0 && y1.is_finite();
        let mut builder = ChartBuilder::on(&root);
        builder
            .caption(title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(80);
        macro_rules! body {
            ($chart:expr) => {{
                let mut chart = $chart;
                chart
                    .configure_mesh()
                    .x_desc(x_desc)
                    .y_desc(y_desc)
                    .draw()
                    .map_err(err(name))?;
                for (i, (label, s)) in series.iter().enumerate() {
                    let c = palette(i);
                    let data: Vec<(f64, f64)> = s
                        .iter()
                        .copied()
                        .filter(|p| p.0.is_finite() && p.1.is_finite() && (!log || p.1 > 0.0))
                        .collect();
                    chart
                        .draw_series(LineSeries::new(data, c.stroke_width(2)))
                        .map_err(err(name))?
                        .label(label.as_str())
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(2)));
                }
                legend(&mut chart, name)?;
            }};
        }
        if log {
            body!(builder
                .build_cartesian_2d(x0..x1, ((y0 / 1.5)..(y1 * 1.5)).log_scale())
                .map_err(err(name))?);
        } else {
            let (y0, y1) = if y0 < y1 { (y0, y1) } else { (y0 - 1.0, y0 + 1.0) };
            let pad = 0.05 * (y1 - y0);
            body!(builder
                .build_cartesian_2d(x0..x1, (y0 - pad)..(y1 + pad))
                .map_err(err(name))?);
        }
        root.present().map_err(err(name))?;
    }
    Ok(out)
}
