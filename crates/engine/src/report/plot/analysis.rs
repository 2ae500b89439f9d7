//! Analysis plots: covariance bounds against arrival rate, β-protocol curves, named lines.

use super::*;

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
            .build_cartesian_2d((x0 - 0.02).max(0.0)..1.0, log_axis(lo, hi))
            .map_err(err(name))?;
        chart
            .configure_mesh()
            .x_desc("arrival rate λ")
            .y_desc("trace")
            .y_label_formatter(&|v| tick(*v))
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
        legend(&mut chart, name, SeriesLabelPosition::UpperRight)?;
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
        legend(&mut chart, name, SeriesLabelPosition::UpperRight)?;
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
                legend(&mut chart, name, SeriesLabelPosition::UpperRight)?;
            }};
        }
        if log {
            body!(builder
                .build_cartesian_2d(x0..x1, log_axis(y0 / 1.5, y1 * 1.5))
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
