//! Error against what a scheme spends on the network (`simnet compare --plot`): each estimator at each number of
//! rounds a point — its mean error relative to the reference with the 95 % interval over the seeds, at its mean
//! spending — and one estimator's points joined in order of rounds, so that the best scheme for a given budget is the
//! lowest point left of it.

use plotters::prelude::*;

use super::{axis, err, estimator_colour, font, log_axis, tick, PlotError, SIZE};
use crate::estimators::Kind;

/// One estimator at one number of rounds.
#[derive(Debug, Clone, PartialEq)]
pub struct BudgetPoint {
    pub kind: Kind,
    pub rounds: u64,
    /// What it spent (the channel's load, or bytes a node sends a second).
    pub x: f64,
    /// Its mean error relative to the reference, and the 95 % interval of that mean.
    pub y: f64,
    pub y_low: f64,
    pub y_high: f64,
}

/// The plot of `points`, `x_desc` naming what was spent.
pub fn budget(points: &[BudgetPoint], x_desc: &str, title: &str) -> Result<String, PlotError> {
    const NAME: &str = "budget";
    font();
    let shown: Vec<&BudgetPoint> = points.iter().filter(|p| p.x.is_finite() && p.y.is_finite()).collect();
    let log_x = shown.iter().all(|p| p.x > 0.0) && {
        let (lo, hi) = shown
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |a, p| (a.0.min(p.x), a.1.max(p.x)));
        hi > 10.0 * lo
    };
    // A ratio's axis is logarithmic where the means span more than a factor 3; there an interval reaching below
    // zero (few seeds) is drawn to the axis' foot.
    let log_y = shown.iter().all(|p| p.y > 0.0) && {
        let (lo, hi) = shown
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |a, p| (a.0.min(p.y), a.1.max(p.y)));
        hi > 3.0 * lo
    };
    let ys = || {
        shown
            .iter()
            .flat_map(|p| [p.y, p.y_low, p.y_high])
            .filter(move |v| !log_y || *v > 0.0)
    };
    let (x0, x1) = axis(shown.iter().map(|p| p.x), log_x);
    let (y0, y1) = axis(ys(), log_y);
    let mut kinds: Vec<Kind> = shown.iter().map(|p| p.kind).collect();
    kinds.sort();
    kinds.dedup();
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(err(NAME))?;
        // The legend in a column of its own: the costliest points sit at the top right.
        let (plot, key) = root.split_horizontally(SIZE.0 - 170);
        for (i, &kind) in kinds.iter().enumerate() {
            let (y, c) = (50 + 24 * i as i32, estimator_colour(kind));
            key.draw(&PathElement::new(vec![(6, y), (32, y)], c.stroke_width(3)))
                .map_err(err(NAME))?;
            key.draw(&Text::new(kind.name(), (40, y - 8), ("sans-serif", 15)))
                .map_err(err(NAME))?;
        }
        let mut builder = ChartBuilder::on(&plot);
        builder
            .caption(title, ("sans-serif", 22))
            .margin(14)
            .x_label_area_size(48)
            .y_label_area_size(72);
        macro_rules! body {
            ($chart:expr) => {{
                let mut chart = $chart;
                chart
                    .configure_mesh()
                    .x_desc(x_desc)
                    .y_desc("mean error / centralized's")
                    .label_style(("sans-serif", 15))
                    .axis_desc_style(("sans-serif", 15))
                    .x_label_formatter(&|v| tick(*v))
                    .y_label_formatter(&|v| tick(*v))
                    .draw()
                    .map_err(err(NAME))?;
                for &kind in &kinds {
                    let c = estimator_colour(kind);
                    let mut own: Vec<&&BudgetPoint> = shown.iter().filter(|p| p.kind == kind).collect();
                    own.sort_by_key(|p| p.rounds);
                    let clip = |v: f64| v.clamp(y0, y1);
                    chart
                        .draw_series(LineSeries::new(
                            own.iter().map(|p| (p.x, clip(p.y))),
                            c.stroke_width(2),
                        ))
                        .map_err(err(NAME))?
                        .label(kind.name())
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], c.stroke_width(3)));
                    for (i, p) in own.iter().enumerate() {
                        let low = if p.y_low.is_finite() && (!log_y || p.y_low > 0.0) {
                            p.y_low
                        } else {
                            y0
                        };
                        if p.y_high.is_finite() {
                            chart
                                .draw_series(std::iter::once(PathElement::new(
                                    vec![(p.x, clip(low)), (p.x, clip(p.y_high))],
                                    c.stroke_width(1),
                                )))
                                .map_err(err(NAME))?;
                        }
                        chart
                            .draw_series(std::iter::once(Circle::new((p.x, clip(p.y)), 4, c.filled())))
                            .map_err(err(NAME))?;
                        // One label for the rounds that gave the same point (a scheme without rounds).
                        if own[..i].iter().any(|q| q.x == p.x && q.y == p.y) {
                            continue;
                        }
                        let same: Vec<String> = own
                            .iter()
                            .filter(|q| q.x == p.x && q.y == p.y)
                            .map(|q| q.rounds.to_string())
                            .collect();
                        let label = EmptyElement::at((p.x, clip(p.y)))
                            + Text::new(
                                format!("L={}", same.join(",")),
                                (7, -16),
                                ("sans-serif", 13).into_font().color(&c),
                            );
                        chart.draw_series(std::iter::once(label)).map_err(err(NAME))?;
                    }
                }
            }};
        }
        match (log_x, log_y) {
            (true, true) => body!(builder
                .build_cartesian_2d(log_axis(x0, x1), log_axis(y0, y1))
                .map_err(err(NAME))?),
            (true, false) => body!(builder
                .build_cartesian_2d(log_axis(x0, x1), y0..y1)
                .map_err(err(NAME))?),
            (false, true) => body!(builder
                .build_cartesian_2d(x0..x1, log_axis(y0, y1))
                .map_err(err(NAME))?),
            (false, false) => body!(builder.build_cartesian_2d(x0..x1, y0..y1).map_err(err(NAME))?),
        }
        root.present().map_err(err(NAME))?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(kind: Kind, rounds: u64, x: f64, y: f64) -> BudgetPoint {
        BudgetPoint {
            kind,
            rounds,
            x,
            y,
            y_low: y * 0.9,
            y_high: y * 1.1,
        }
    }

    #[test]
    fn every_estimator_is_in_the_legend_and_a_diverged_point_is_left_out() {
        let pts = [
            point(Kind::Kcf, 1, 0.5, 2.0),
            point(Kind::Kcf, 3, 1.5, 1.5),
            point(Kind::Icf, 1, 0.5, f64::NAN),
            point(Kind::Icf, 3, 1.4, 1.2),
        ];
        let svg = budget(&pts, "channel load", "t").unwrap();
        assert!(svg.contains("\nkcf\n</text>") && svg.contains("\nicf\n</text>"));
        assert_eq!(svg.matches("\nL=").count(), 3);
    }
}
