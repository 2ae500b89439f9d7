//! SVG plots drawn with plotters and an embedded DejaVu font (no system fonts needed): trajectories, error over time
//! and trace P over time, networked against independent.

use std::collections::BTreeMap;
use std::sync::Once;

use plotters::prelude::*;
use plotters::style::FontStyle;

use super::observer::FusedRow;
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

fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let pad = ((hi - lo) * 0.05).max(1e-9);
    (lo - pad, hi + pad)
}

/// Series per (node, filter) in step order.
fn series(rows: &[TraceRow]) -> BTreeMap<(u32, bool), Vec<&TraceRow>> {
    let mut m: BTreeMap<(u32, bool), Vec<&TraceRow>> = BTreeMap::new();
    for r in rows {
        m.entry((r.node, r.networked)).or_default().push(r);
    }
    m
}

/// True trajectory and estimates: the x–y plane for pose, roll, pitch and yaw against time for attitude (networked
/// estimates only), x₀ against time for linear. `model` is the model's kind.
pub fn trajectory(rows: &[TraceRow], fused: &[FusedRow], model: &str, title: &str) -> Result<String, PlotError> {
    font();
    let name = "trajectory";
    let (pose, attitude) = (model == "pose", model == "attitude");
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(err(name))?;
        let mut s = series(rows);
        if attitude {
            s.retain(|(_, networked), _| *networked);
        }
        // Component c of the curve: one per Euler angle for attitude.
        let components = if attitude { 3 } else { 1 };
        let xy = |r: &TraceRow, est: bool, c: usize| -> (f64, f64) {
            let v = if est { &r.est } else { &r.truth };
            if pose {
                (v[0], v[1])
            } else if attitude {
                (r.t, v[c].to_degrees())
            } else {
                (r.t, v[0])
            }
        };
        let all = || {
            rows.iter()
                .flat_map(move |r| (0..components).flat_map(move |c| [xy(r, false, c), xy(r, true, c)]))
                .filter(|(x, y)| x.is_finite() && y.is_finite())
        };
        let (x0, x1) = range(all().map(|p| p.0));
        let (y0, y1) = range(all().map(|p| p.1));
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
            .y_desc(if pose {
                "y (m)"
            } else if attitude {
                "roll, pitch, yaw (°)"
            } else {
                "x₀"
            })
            .draw()
            .map_err(err(name))?;
        let finite = |p: &(f64, f64)| p.0.is_finite() && p.1.is_finite();
        if let Some(first) = s.values().next() {
            for c in 0..components {
                let drawn = chart
                    .draw_series(LineSeries::new(
                        first.iter().map(|r| xy(r, false, c)).filter(finite),
                        BLACK.stroke_width(2),
                    ))
                    .map_err(err(name))?;
                if c == 0 {
                    drawn
                        .label("truth")
                        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], BLACK.stroke_width(2)));
                }
            }
        }
        for (i, ((node, networked), pts)) in s.iter().enumerate() {
            let c = palette(if attitude { i } else { i / 2 });
            let style = if *networked {
                c.stroke_width(1)
            } else {
                c.mix(0.35).stroke_width(1)
            };
            for comp in 0..components {
                let drawn = chart
                    .draw_series(LineSeries::new(
                        pts.iter().map(|r| xy(r, true, comp)).filter(finite),
                        style,
                    ))
                    .map_err(err(name))?;
                if comp == 0 {
                    drawn
                        .label(format!(
                            "node {node} {}",
                            if *networked { "networked" } else { "independent" }
                        ))
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], style));
                }
            }
        }
        if pose && !fused.is_empty() {
            let style = RGBColor(0, 0, 0).mix(0.6).stroke_width(2);
            chart
                .draw_series(LineSeries::new(fused.iter().map(|f| (f.median[0], f.median[1])), style))
                .map_err(err(name))?
                .label("fused (CI, median 20)")
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], style));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(err(name))?;
        root.present().map_err(err(name))?;
    }
    Ok(out)
}

/// A per-step quantity against time, one line per node and filter (networked solid, independent faded).
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
        let s = series(rows);
        let t_max = rows.iter().map(|r| r.t).fold(0.0, f64::max).max(dt);
        let vals = rows.iter().map(&value).chain(fused.iter().map(|f| f.median_error));
        let (lo, hi) = if log {
            // Multiplicative padding: an additive one can push the lower end below zero.
            let pos: Vec<f64> = vals.filter(|v| *v > 0.0 && v.is_finite()).collect();
            let lo = pos.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = pos.iter().copied().fold(0.0, f64::max);
            if lo.is_finite() {
                (lo / 1.5, hi * 1.5)
            } else {
                (1e-6, 1.0)
            }
        } else {
            range(vals)
        };
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
                    .draw()
                    .map_err(err(name))?;
                for (i, ((node, networked), pts)) in s.iter().enumerate() {
                    let c = palette(i / 2);
                    let style = if *networked {
                        c.stroke_width(1)
                    } else {
                        c.mix(0.3).stroke_width(1)
                    };
                    chart
                        .draw_series(LineSeries::new(
                            pts.iter()
                                .map(|r| (r.t, value(r)))
                                .filter(|(_, v)| v.is_finite() && (!log || *v > 0.0)),
                            style,
                        ))
                        .map_err(err(name))?
                        .label(format!(
                            "node {node} {}",
                            if *networked { "networked" } else { "independent" }
                        ))
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], style));
                }
                if name == "error" && !fused.is_empty() {
                    let style = BLACK.stroke_width(2);
                    chart
                        .draw_series(LineSeries::new(
                            fused.iter().map(|f| (f.step as f64 * dt, f.median_error)),
                            style,
                        ))
                        .map_err(err(name))?
                        .label(if fused.iter().all(|f| f.median == f.fused) {
                            "fused (CI)"
                        } else {
                            "fused (CI, median 20)"
                        })
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], style));
                }
                chart
                    .configure_series_labels()
                    .background_style(WHITE.mix(0.85))
                    .border_style(BLACK)
                    .position(SeriesLabelPosition::UpperRight)
                    .draw()
                    .map_err(err(name))?;
            }};
        }
        if log {
            let lo = if lo > 0.0 { lo } else { hi * 1e-6 };
            draw!(cb
                .build_cartesian_2d(0.0..t_max, (lo..hi.max(lo * 10.0)).log_scale())
                .map_err(err(name))?);
        } else {
            draw!(cb.build_cartesian_2d(0.0..t_max, lo.min(0.0)..hi).map_err(err(name))?);
        }
        root.present().map_err(err(name))?;
    }
    Ok(out)
}

/// The error figure against time: position (pose), rotation angle (attitude, from the Euler columns), state
/// (linear).
pub fn error(rows: &[TraceRow], fused: &[FusedRow], dt: f64, model: &str, title: &str) -> Result<String, PlotError> {
    let y = match model {
        "pose" => "position error (m)",
        "attitude" => "attitude error (°)",
        _ => "state error",
    };
    over_time(
        "error",
        rows,
        fused,
        dt,
        title,
        y,
        |r| match model {
            "attitude" => {
                use crate::estimate::attitude::{angle_between, from_euler};
                let q = |v: &[f64]| from_euler(&nalgebra::Vector3::new(v[0], v[1], v[2]));
                angle_between(&q(&r.truth), &q(&r.est)).to_degrees()
            }
            _ => {
                let n = if model == "pose" { 3 } else { r.truth.len() };
                (0..n).map(|i| (r.truth[i] - r.est[i]).powi(2)).sum::<f64>().sqrt()
            }
        },
        false,
    )
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
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(err(name))?;
        root.present().map_err(err(name))?;
    }
    Ok(out)
}

/// One protocol on the exchange plot: (exchanged weight, mean error, worst-seed error, feasible).
pub type ProtocolPoint = (f64, f64, f64, bool);

/// Mean error against exchanged weight (the consensus seed's Figs. 9b/11b), with the independent filters' error,
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
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(err(name))?;
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
                chart
                    .configure_series_labels()
                    .background_style(WHITE.mix(0.85))
                    .border_style(BLACK)
                    .position(SeriesLabelPosition::UpperRight)
                    .draw()
                    .map_err(err(name))?;
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
