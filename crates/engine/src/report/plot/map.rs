//! Where the nodes stand and what each link delivered: the world at the start of the run, x–y at equal scale, each
//! pair of linked nodes a line coloured by the fraction of its datagrams delivered (both directions pooled).

use std::collections::BTreeMap;

use plotters::prelude::*;

use super::{axis, equal_scale, err, font, tick, PlotError, SIZE};
use crate::report::summary::LinkSummary;

/// Width of the key column at the right.
const KEY: u32 = 230;

/// The colour of a fraction delivered: red at 0, orange at ½, yellow at ¾, green at 1 (most links deliver more than
/// half, so the scale spends its hues there).
fn delivered_colour(f: f64) -> RGBColor {
    const STOPS: [(f64, [f64; 3]); 6] = [
        (0.0, [180.0, 20.0, 30.0]),
        (0.25, [220.0, 60.0, 30.0]),
        (0.5, [240.0, 130.0, 20.0]),
        (0.75, [225.0, 190.0, 30.0]),
        (0.9, [150.0, 190.0, 40.0]),
        (1.0, [30.0, 140.0, 40.0]),
    ];
    let f = if f.is_finite() { f.clamp(0.0, 1.0) } else { 0.0 };
    let i = STOPS
        .iter()
        .rposition(|(at, _)| *at <= f)
        .unwrap_or(0)
        .min(STOPS.len() - 2);
    let ((a, ca), (b, cb)) = (STOPS[i], STOPS[i + 1]);
    let w = (f - a) / (b - a);
    let c = |k: usize| (ca[k] + w * (cb[k] - ca[k])).round() as u8;
    RGBColor(c(0), c(1), c(2))
}

/// The map of `nodes` (id, x, y in m) and `links`; `None` when the nodes do not stand apart (an IMU network's nodes
/// on one package at its origin): a map of one point says nothing.
pub fn map(nodes: &[(u32, f64, f64)], links: &[LinkSummary], title: &str) -> Result<Option<String>, PlotError> {
    const NAME: &str = "map";
    let spread = |f: fn(&(u32, f64, f64)) -> f64| {
        let (lo, hi) = nodes
            .iter()
            .map(f)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
        hi - lo
    };
    if nodes.len() < 2 || spread(|n| n.1).max(spread(|n| n.2)) <= 1e-9 {
        return Ok(None);
    }
    font();
    let at: BTreeMap<u32, (f64, f64)> = nodes.iter().map(|&(id, x, y)| (id, (x, y))).collect();
    // Both directions of a pair pooled: (sent, delivered).
    let mut pairs: BTreeMap<(u32, u32), (u64, u64)> = BTreeMap::new();
    for l in links {
        let e = pairs.entry((l.from.min(l.to), l.from.max(l.to))).or_default();
        e.0 += l.sent;
        e.1 += l.delivered;
    }
    let (x0, x1) = axis(nodes.iter().map(|n| n.1), false);
    let (y0, y1) = axis(nodes.iter().map(|n| n.2), false);
    let ((x0, x1), (y0, y1)) = equal_scale((x0, x1), (y0, y1), 70.0);
    let mut out = String::new();
    {
        let whole = SVGBackend::with_string(&mut out, (SIZE.0 + KEY, SIZE.1)).into_drawing_area();
        whole.fill(&WHITE).map_err(err(NAME))?;
        let (root, key) = whole.split_horizontally(SIZE.0);
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(err(NAME))?;
        chart
            .configure_mesh()
            .x_desc("x (m)")
            .y_desc("y (m)")
            .x_label_formatter(&|v| tick(*v))
            .y_label_formatter(&|v| tick(*v))
            .draw()
            .map_err(err(NAME))?;
        let mut never_sent = false;
        for ((a, b), (sent, delivered)) in &pairs {
            let (Some(&pa), Some(&pb)) = (at.get(a), at.get(b)) else {
                continue;
            };
            let style = if *sent == 0 {
                never_sent = true;
                RGBColor(160, 160, 160).stroke_width(1)
            } else {
                delivered_colour(*delivered as f64 / *sent as f64).stroke_width(2)
            };
            chart
                .draw_series(std::iter::once(PathElement::new(vec![pa, pb], style)))
                .map_err(err(NAME))?;
        }
        // Each node a dot; its id beside it, up and to the right, where no link starts (up to 100 nodes).
        let labelled = nodes.len() <= 100;
        chart
            .draw_series(nodes.iter().map(|&(id, x, y)| {
                let label = if labelled { id.to_string() } else { String::new() };
                EmptyElement::at((x, y))
                    + Circle::new((0, 0), 5, BLACK.filled())
                    + Text::new(label, (6, -17), ("sans-serif", 13).into_font())
            }))
            .map_err(err(NAME))?;
        let text = |s: &str, x: i32, y: i32| Text::new(s.to_string(), (x, y), ("sans-serif", 14));
        key.draw(&text("links: datagrams delivered", 12, 60))
            .map_err(err(NAME))?;
        key.draw(&text("(both directions pooled)", 12, 80)).map_err(err(NAME))?;
        for (i, f) in [1.0, 0.9, 0.75, 0.5, 0.25, 0.0].into_iter().enumerate() {
            let y = 110 + 24 * i as i32;
            key.draw(&PathElement::new(
                vec![(12, y), (40, y)],
                delivered_colour(f).stroke_width(3),
            ))
            .map_err(err(NAME))?;
            key.draw(&text(&format!("{:.0} %", 100.0 * f), 48, y - 7))
                .map_err(err(NAME))?;
        }
        if never_sent {
            let y = 110 + 24 * 6;
            key.draw(&PathElement::new(
                vec![(12, y), (40, y)],
                RGBColor(160, 160, 160).stroke_width(1),
            ))
            .map_err(err(NAME))?;
            key.draw(&text("nothing sent", 48, y - 7)).map_err(err(NAME))?;
        }
        key.draw(&text("positions at the start", 12, 290)).map_err(err(NAME))?;
        whole.present().map_err(err(NAME))?;
    }
    Ok(Some(out))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn link(from: u32, to: u32, sent: u64, delivered: u64) -> LinkSummary {
        serde_json::from_value(serde_json::json!({
            "from": from, "to": to, "sent": sent, "delivered": delivered, "lost": sent - delivered,
            "lost_random": 0, "lost_down": 0, "late": 0, "duplicated": 0, "corrupted": 0, "loss_rate": null,
            "delivered_fraction": null, "arrival_rate": null, "mean_loss_run": 0.0, "longest_loss_run": 0,
        }))
        .unwrap()
    }

    #[test]
    fn nodes_at_one_point_make_no_map_and_apart_they_do() {
        let links = [link(0, 1, 10, 9), link(1, 0, 10, 1)];
        assert!(map(&[(0, 0.0, 0.0), (1, 0.0, 0.0)], &links, "t").unwrap().is_none());
        let svg = map(&[(0, 0.0, 0.0), (1, 30.0, 40.0)], &links, "t").unwrap().unwrap();
        // Both directions pooled: 10 of 20 delivered, drawn in the colour of 50 %.
        let RGBColor(r, g, b) = delivered_colour(0.5);
        assert!(svg.contains(&format!("#{r:02X}{g:02X}{b:02X}")), "{svg}");
        assert_eq!(delivered_colour(1.0), RGBColor(30, 140, 40));
        assert_eq!(delivered_colour(0.0), RGBColor(180, 20, 30));
        assert_eq!(delivered_colour(0.75), RGBColor(225, 190, 30));
        assert_eq!(delivered_colour(f64::NAN), delivered_colour(0.0));
    }
}
