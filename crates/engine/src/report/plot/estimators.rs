//! Every estimator's median-over-nodes error against time, the centralized reference drawn as the line to beat.

use std::collections::BTreeMap;

use plotters::prelude::*;

use super::{axis, draw_runs, err, estimator_colour, font, log_axis, runs, tick, PlotError, SIZE};
use crate::estimators::Kind;
use crate::model::Kind as ModelKind;
use crate::observe::schemes::SchemeRow;

/// (step, t, value) points of one line.
type Line = Vec<(u64, f64, f64)>;

/// Width of the key column at the right.
const KEY: u32 = 250;

/// Points per line: each is the mean of the per-step medians over a bin of steps.
const BINS: u64 = 250;

pub fn estimators(rows: &[SchemeRow], dt: f64, model: ModelKind, title: &str) -> Result<String, PlotError> {
    const NAME: &str = "estimators";
    font();
    let steps = rows.iter().map(|r| r.step + 1).max().unwrap_or(1);
    let bin = steps.div_ceil(BINS).max(1);
    let mut lines: BTreeMap<Kind, BTreeMap<u64, (f64, u32)>> = BTreeMap::new();
    for r in rows.iter().filter(|r| r.median_error.is_finite()) {
        let e = lines.entry(r.kind).or_default().entry(r.step / bin).or_default();
        e.0 += r.median_error;
        e.1 += 1;
    }
    let pts: Vec<(Kind, Line)> = lines
        .into_iter()
        .map(|(k, bins)| {
            let v = bins
                .into_iter()
                .map(|(b, (s, n))| (b * bin, (b * bin) as f64 * dt, s / f64::from(n)))
                .collect();
            (k, v)
        })
        .collect();
    // A line a thousand times above the reference (a prediction-only node's twin diverging) would flatten every other
    // line at the bottom: it is drawn clipped and its key says so.
    let peak = |v: &Line| v.iter().map(|p| p.2).fold(0.0, f64::max);
    let mut peaks: Vec<f64> = pts.iter().map(|(_, v)| peak(v)).collect();
    peaks.sort_by(f64::total_cmp);
    let reference = pts
        .iter()
        .find(|(k, _)| *k == Kind::Centralized)
        .map(|(_, v)| peak(v))
        .unwrap_or_else(|| peaks.get(peaks.len() / 2).copied().unwrap_or(0.0));
    let off_scale = |v: &Line| reference > 0.0 && peak(v) > 1e3 * reference;
    let (lo, hi) = axis(
        pts.iter()
            .filter(|(_, v)| !off_scale(v))
            .flat_map(|(_, v)| v.iter().map(|p| p.2)),
        true,
    );
    let t_max = (steps as f64 * dt).max(dt);
    let mut out = String::new();
    {
        // The key in a column of its own: with every estimator's line across the plot, no corner is free.
        let size = (SIZE.0 + KEY, SIZE.1);
        let whole = SVGBackend::with_string(&mut out, size).into_drawing_area();
        whole.fill(&WHITE).map_err(err(NAME))?;
        let (root, key) = whole.split_horizontally(SIZE.0);
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..t_max, log_axis(lo, hi))
            .map_err(err(NAME))?;
        chart
            .configure_mesh()
            .x_desc("t (s)")
            .y_desc(format!(
                "{}: median over nodes, mean per {bin} steps",
                model.error_text().axis
            ))
            .y_label_formatter(&|v| tick(*v))
            .draw()
            .map_err(err(NAME))?;
        let mut keys = Vec::new();
        for (kind, v) in pts {
            let (style, mut label) = if kind == Kind::Centralized {
                (BLACK.stroke_width(3), "centralized (reference, no loss)".to_string())
            } else {
                (estimator_colour(kind).stroke_width(2), kind.name().to_string())
            };
            if off_scale(&v) {
                label.push_str(" (off scale: clipped)");
            }
            let clipped = v.into_iter().map(|(k, t, y)| (k, t, y.min(hi)));
            draw_runs(&mut chart, runs(clipped, lo, hi), style, None, NAME)?;
            keys.push((style, label));
        }
        for (i, (style, label)) in keys.into_iter().enumerate() {
            let y = 60 + 24 * i as i32;
            key.draw(&PathElement::new(vec![(8, y), (36, y)], style))
                .map_err(err(NAME))?;
            key.draw(&Text::new(label, (44, y - 7), ("sans-serif", 14)))
                .map_err(err(NAME))?;
        }
        whole.present().map_err(err(NAME))?;
    }
    Ok(out)
}
