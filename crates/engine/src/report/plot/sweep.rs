//! A campaign's figures against the swept key: one panel per figure (columns) and per combination of the other
//! swept keys (rows), one line per estimator with its 95 % confidence band.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::{axis, err, font, log_axis, palette, tick, PlotError};

/// One estimator's line: (x, mean, CI low, CI high) per point.
#[derive(Debug, Clone)]
pub struct SweepLine {
    pub label: String,
    pub points: Vec<(f64, f64, f64, f64)>,
    /// Drawn black and thick: the reference.
    pub reference: bool,
    /// Its colour in every panel (an index into the palette).
    pub colour: usize,
}

fn colour(l: &SweepLine) -> RGBColor {
    if l.reference {
        BLACK
    } else {
        palette(l.colour)
    }
}

/// Width of the legend column at the right.
const LEGEND: u32 = 190;

/// One panel: a figure at one combination of the other keys.
#[derive(Debug, Clone)]
pub struct SweepPanel {
    pub title: String,
    pub y_desc: String,
    /// A log axis when every value is positive and spans more than a decade.
    pub lines: Vec<SweepLine>,
}

/// Most panel rows drawn.
pub const MAX_ROWS: usize = 6;

/// `panels` row by row, `columns` to a row; `x_labels` names the x positions when the key is not numeric.
pub fn sweep(
    panels: &[SweepPanel],
    columns: usize,
    x_desc: &str,
    x_labels: Option<&[String]>,
    title: &str,
) -> Result<String, PlotError> {
    const NAME: &str = "sweep";
    font();
    let columns = columns.clamp(1, 4);
    let rows = panels.len().div_ceil(columns).clamp(1, MAX_ROWS);
    let size = (540 * columns as u32 + LEGEND, 60 + 400 * rows as u32);
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, size).into_drawing_area();
        root.fill(&WHITE).map_err(err(NAME))?;
        let root = root.titled(title, ("sans-serif", 24)).map_err(err(NAME))?;
        let (plots, key) = root.split_horizontally(size.0 - LEGEND);
        let areas = plots.split_evenly((rows, columns));
        for (panel, area) in panels.iter().zip(areas) {
            draw_panel(&area, panel, x_desc, x_labels)?;
        }
        // One legend for every panel: each estimator keeps its colour throughout.
        let mut seen: Vec<&SweepLine> = Vec::new();
        for l in panels.iter().flat_map(|p| &p.lines) {
            if !seen.iter().any(|s| s.label == l.label) {
                seen.push(l);
            }
        }
        for (i, l) in seen.iter().enumerate() {
            let y = 40 + 26 * i as i32;
            let c = colour(l);
            key.draw(&PathElement::new(
                vec![(10, y), (40, y)],
                c.stroke_width(if l.reference { 3 } else { 2 }),
            ))
            .map_err(err(NAME))?;
            key.draw(&Text::new(l.label.clone(), (48, y - 9), ("sans-serif", 18)))
                .map_err(err(NAME))?;
        }
        root.present().map_err(err(NAME))?;
    }
    Ok(out)
}

fn draw_panel(
    area: &DrawingArea<SVGBackend<'_>, Shift>,
    p: &SweepPanel,
    x_desc: &str,
    x_labels: Option<&[String]>,
) -> Result<(), PlotError> {
    const NAME: &str = "sweep";
    let all = || p.lines.iter().flat_map(|l| l.points.iter());
    let (x0, x1) = axis(all().map(|q| q.0), false);
    let ys = || all().flat_map(|q| [q.1, q.2, q.3]);
    let positive = ys().filter(|v| v.is_finite()).all(|v| v > 0.0);
    let (lo, hi) = ys()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |a, v| (a.0.min(v), a.1.max(v)));
    let log = positive && lo.is_finite() && hi > 10.0 * lo;
    let (y0, y1) = axis(ys(), log);
    let mut builder = ChartBuilder::on(area);
    builder
        .caption(&p.title, ("sans-serif", 20))
        .margin(10)
        .x_label_area_size(48)
        .y_label_area_size(80);
    let x_fmt = |v: &f64| match x_labels {
        Some(names) => {
            let i = v.round();
            if (v - i).abs() < 1e-9 && i >= 0.0 {
                names.get(i as usize).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        }
        None => tick(*v),
    };
    macro_rules! body {
        ($chart:expr) => {{
            let mut chart = $chart;
            let mut mesh = chart.configure_mesh();
            // Larger than plotters' default: the figure is wide and a page shows it scaled down.
            mesh.x_desc(x_desc)
                .y_desc(p.y_desc.as_str())
                .label_style(("sans-serif", 16))
                .axis_desc_style(("sans-serif", 16))
                .x_label_formatter(&x_fmt)
                .y_label_formatter(&|v| tick(*v));
            if let Some(names) = x_labels {
                mesh.x_labels(names.len() + 1);
            }
            mesh.draw().map_err(err(NAME))?;
            for line in &p.lines {
                let c = colour(line);
                let pts: Vec<(f64, f64, f64, f64)> = line
                    .points
                    .iter()
                    .copied()
                    .filter(|q| q.0.is_finite() && q.1.is_finite() && (!log || q.1 > 0.0))
                    .map(|(x, m, l, h)| (x, m.clamp(y0, y1), l, h))
                    .collect();
                // The band: upper edge out, lower edge back, where the interval is known.
                let band: Vec<(f64, f64)> = pts
                    .iter()
                    .filter(|q| q.2.is_finite() && q.3.is_finite())
                    .map(|q| (q.0, q.3.clamp(y0, y1)))
                    .chain(
                        pts.iter()
                            .rev()
                            .filter(|q| q.2.is_finite() && q.3.is_finite())
                            .map(|q| (q.0, q.2.clamp(y0, y1))),
                    )
                    .collect();
                if band.len() >= 4 {
                    chart
                        .draw_series(std::iter::once(Polygon::new(band, c.mix(0.15).filled())))
                        .map_err(err(NAME))?;
                }
                let style = c.stroke_width(if line.reference { 3 } else { 2 });
                chart
                    .draw_series(LineSeries::new(pts.iter().map(|q| (q.0, q.1)), style))
                    .map_err(err(NAME))?;
                chart
                    .draw_series(pts.iter().map(|q| Circle::new((q.0, q.1), 3, c.filled())))
                    .map_err(err(NAME))?;
            }
        }};
    }
    if log {
        body!(builder
            .build_cartesian_2d(x0..x1, log_axis(y0, y1))
            .map_err(err(NAME))?);
    } else {
        body!(builder.build_cartesian_2d(x0..x1, y0..y1).map_err(err(NAME))?);
    }
    Ok(())
}
