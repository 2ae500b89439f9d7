//! A campaign's `report.html`: its points with confidence intervals, `sweep.svg`, the manifest; laid out with the
//! run page's parts ([`simnet_engine::report::html`]).

use std::fmt::Write;

use super::{cell, mean_error_table, Manifest, PlanFile, PointStat};
use simnet_engine::report::html::{escape, head, inline_svg, table};

/// The page of a campaign: `svg` is `sweep.svg`.
pub fn sweep_page(plan: &PlanFile, manifest: &Manifest, stats: &[PointStat], svg: &str) -> String {
    let keys: Vec<&str> = plan.axes.iter().map(|a| a.key.as_str()).collect();
    let title = format!("simnet sweep · {} against {}", plan.topology, keys.join(" × "));
    let mut h = head(&title);
    let _ = writeln!(h, "<h1>{}</h1>", escape(&title));
    let _ = writeln!(
        h,
        "<p class=\"meta\">{}</p>",
        escape(&format!(
            "{} × {} = {} runs · {} model · {} to {} · simnet {}",
            simnet_engine::scenario::count(manifest.points, "point"),
            simnet_engine::scenario::count(manifest.seeds as usize, "seed"),
            manifest.runs,
            plan.model,
            manifest.started,
            manifest.finished,
            manifest.simnet
        ))
    );
    let _ = writeln!(
        h,
        "<h2>Mean error per point</h2>\n<p>{}: mean over the seeds ± half the 95 % confidence interval \
         (Student's t); loss: the measured fraction of datagrams lost.</p>",
        escape(plan.model.error_text().label)
    );
    let (header, rows) = mean_error_table(plan, stats);
    h.push_str(&table("points", &header, &rows));
    let _ = writeln!(
        h,
        "<h2>Plot</h2>\n<figure class=\"wide\">\n{}\n<figcaption>Each figure against {}, one line per estimator, 95 % \
         confidence bands.</figcaption>\n</figure>",
        inline_svg(svg),
        escape(plan.x_axis().map_or("", |a| a.key.as_str()))
    );
    h.push_str("<h2>Every figure</h2>\n<details><summary>points.csv as a table</summary>\n");
    let mut header: Vec<String> = keys.iter().map(|k| k.to_string()).collect();
    header.extend(["estimator", "metric", "n", "mean", "sd", "95 % low", "95 % high"].map(String::from));
    let rows: Vec<Vec<String>> = stats
        .iter()
        .map(|s| {
            let mut r: Vec<String> = plan.points[s.point].values.iter().map(cell).collect();
            r.extend([s.estimator.clone(), s.metric.clone(), s.stat.n.to_string()]);
            r.extend([s.stat.mean, s.stat.sd, s.stat.low, s.stat.high].map(|v| {
                if v.is_finite() {
                    format!("{v:.6}")
                } else {
                    "—".into()
                }
            }));
            r
        })
        .collect();
    h.push_str(&table("all-points", &header, &rows));
    h.push_str("</details>\n<h2>Provenance</h2>\n<dl>\n");
    let mut dl = |k: &str, v: &str| {
        let _ = writeln!(h, "<dt>{}</dt><dd>{}</dd>", escape(k), escape(v));
    };
    dl("simnet", &manifest.simnet);
    dl("command", &manifest.command.join(" "));
    dl(
        "base scenario",
        &format!("{} (SHA-256 {})", manifest.topology, manifest.base_sha256),
    );
    for a in &manifest.axes {
        dl(
            &format!("swept {}", a.key),
            &a.values.iter().map(cell).collect::<Vec<_>>().join(", "),
        );
    }
    dl("seeds", &format!("1 … {}", manifest.seeds));
    dl("estimators", &manifest.estimators.join(", "));
    h.push_str("</dl>\n");
    let rows: Vec<Vec<String>> = manifest
        .made_by
        .iter()
        .map(|m| {
            vec![
                m.shard.clone(),
                m.started.clone(),
                m.finished.clone(),
                m.cores.to_string(),
                m.ran.to_string(),
                m.transport.clone(),
                m.simnet.clone(),
            ]
        })
        .collect();
    h.push_str(&table(
        "made-by",
        &[
            "made by",
            "started",
            "finished",
            "cores",
            "runs made",
            "transport",
            "simnet",
        ]
        .map(String::from),
        &rows,
    ));
    let _ = writeln!(
        h,
        "<details><summary>The base scenario (TOML)</summary><pre>{}</pre></details>",
        escape(&manifest.base_scenario)
    );
    h.push_str("</body>\n</html>\n");
    h
}
