//! One run's plots: trajectories, error and trace P over time.

use super::*;

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
            ((x0, x1), (y0, y1)) = equal_scale((x0, x1), (y0, y1), 60.0);
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
        legend(&mut chart, name, SeriesLabelPosition::UpperRight)?;
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
                legend(&mut chart, name, SeriesLabelPosition::UpperRight)?;
            }
        }
        root.present().map_err(err(name))?;
    }
    Ok(out)
}

/// A per-step quantity against time: a line per node and filter (networked solid, independent faded), or beyond
/// [`MAX_NODE_LINES`] nodes the median and min–max band across nodes, networked against independent. The y-scale
/// is taken from `burn_in_s` on (the start's transient would flatten the rest); the burn-in is shaded and what it
/// holds beyond the scale is drawn clipped.
#[allow(clippy::too_many_arguments)]
fn over_time(
    name: &'static str,
    rows: &[TraceRow],
    fused: &[FusedRow],
    dt: f64,
    burn_in_s: f64,
    title: &str,
    y_desc: &str,
    value: impl Fn(&TraceRow) -> f64,
    log: bool,
    faults: &[crate::link::FaultWindow],
) -> Result<String, PlotError> {
    font();
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(err(name))?;
        let all = series(rows);
        let t_max = rows.iter().map(|r| r.t).fold(0.0, f64::max).max(dt);
        // A burn-in as long as the run leaves nothing to scale on: then the whole run is.
        let from = if burn_in_s < t_max { burn_in_s } else { 0.0 };
        let in_scale = all
            .iter()
            .filter(|s| !s.off_scale())
            .flat_map(|s| s.rows.iter().filter(|r| r.t >= from).map(|r| value(r)))
            .chain(
                fused
                    .iter()
                    .filter(|f| f.step as f64 * dt >= from)
                    .map(|f| f.median_error),
            );
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
                if from > 0.0 {
                    let shade = RGBColor(0, 0, 0).mix(0.07).filled();
                    chart
                        .draw_series(std::iter::once(Rectangle::new([(0.0, lo), (from, hi)], shade)))
                        .map_err(err(name))?
                        .label("burn-in: not in the y-scale (clipped)")
                        .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 18, y + 5)], shade));
                }
                // Each fault window shaded (the first few named in the legend), under the lines.
                let fault_shade = RGBColor(255, 150, 0).mix(0.16).filled();
                for (i, w) in faults.iter().enumerate() {
                    let end = w.end_s.unwrap_or(t_max).min(t_max);
                    if w.start_s >= t_max || end <= w.start_s {
                        continue;
                    }
                    let drawn = chart
                        .draw_series(std::iter::once(Rectangle::new(
                            [(w.start_s, lo), (end, hi)],
                            fault_shade,
                        )))
                        .map_err(err(name))?;
                    let label = match i {
                        0..=2 => format!("{}, {}–{} s", w.label(), tick(w.start_s), tick(end)),
                        3 => format!("… {} more faults", faults.len() - 3),
                        _ => continue,
                    };
                    drawn
                        .label(label)
                        .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 18, y + 5)], fault_shade));
                }
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
                let drawn = rows.iter().map(|r| (r.t, value(r).clamp(lo, hi))).chain(
                    fused
                        .iter()
                        .map(|f| (f.step as f64 * dt, f.median_error.clamp(lo, hi))),
                );
                legend(
                    &mut chart,
                    name,
                    emptiest_corner(drawn, (0.0, t_max), (lo, hi), log),
                )?;
            }};
        }
        if log {
            draw!(cb.build_cartesian_2d(0.0..t_max, log_axis(lo, hi)).map_err(err(name))?);
        } else {
            draw!(cb.build_cartesian_2d(0.0..t_max, lo.min(0.0)..hi).map_err(err(name))?);
        }
        root.present().map_err(err(name))?;
    }
    Ok(out)
}

/// The error figure against time, as the node computed it: position (pose), rotation angle (attitude), state
/// (linear).
/// The error against time; the y-scale from `burn_in_s` on.
pub fn error(
    rows: &[TraceRow],
    fused: &[FusedRow],
    dt: f64,
    burn_in_s: f64,
    model: Kind,
    title: &str,
    faults: &[crate::link::FaultWindow],
) -> Result<String, PlotError> {
    let y = model.error_text().axis;
    over_time(
        "error",
        rows,
        fused,
        dt,
        burn_in_s,
        title,
        y,
        |r| r.error,
        false,
        faults,
    )
}

/// The trace of the posterior covariance against time; the y-scale from `burn_in_s` on.
pub fn trace_p(
    rows: &[TraceRow],
    dt: f64,
    burn_in_s: f64,
    title: &str,
    faults: &[crate::link::FaultWindow],
) -> Result<String, PlotError> {
    over_time(
        "trace_p",
        rows,
        &[],
        dt,
        burn_in_s,
        title,
        "trace P (posterior)",
        |r| r.trace_p_post,
        true,
        faults,
    )
}
