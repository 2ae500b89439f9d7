//! `report.html`: one self-contained page (inline CSS and SVG, nothing fetched) for a run — its tables, plots and
//! provenance (a campaign's page, built from the same parts, is `page` of the crate `simnet-campaign`).

use std::fmt::Write;

use crate::Summary;

const STYLE: &str = "body{font-family:sans-serif;margin:2em auto;max-width:1200px;padding:0 1em;color:#222}\
h1{font-size:1.6em}h2{font-size:1.25em;margin-top:2em;border-bottom:1px solid #ccc}\
table{border-collapse:collapse;margin:.5em 0;font-size:.9em}\
th,td{border:1px solid #ccc;padding:.25em .6em;text-align:right}th{background:#f2f2f2}\
td.l,th.l{text-align:left}.meta{color:#555}figure{margin:1em 0}figure svg{max-width:100%;height:auto}\
figure.wide{width:calc(100vw - 2em);margin-left:calc(50% - 50vw + 1em)}\
pre{background:#f7f7f7;padding:.8em;overflow:auto;font-size:.85em}dt{font-weight:bold;margin-top:.4em}";

/// `s` with `&`, `<`, `>` and `"` escaped, for text and attribute values.
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            c => out.push(c),
        }
    }
    out
}

/// An SVG made by simnet's plots, inline: the document's own root element, any XML prologue dropped.
pub fn inline_svg(svg: &str) -> &str {
    svg.find("<svg").map_or("", |i| &svg[i..])
}

/// The page's opening up to `<body>`: its title and the style every simnet page shares (a run's, a campaign's).
pub fn head(title: &str) -> String {
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n<title>{}</title>\n\
         <style>{STYLE}</style>\n</head>\n<body>\n",
        escape(title)
    )
}

/// A table: header cells (the first column left-aligned) and rows, `id` for scripts and tests.
pub fn table(id: &str, header: &[String], rows: &[Vec<String>]) -> String {
    let mut t = format!("<table id=\"{id}\">\n<tr>");
    for (i, h) in header.iter().enumerate() {
        let _ = write!(t, "<th{}>{}</th>", if i == 0 { " class=\"l\"" } else { "" }, escape(h));
    }
    t.push_str("</tr>\n");
    for r in rows {
        t.push_str("<tr>");
        for (i, c) in r.iter().enumerate() {
            let _ = write!(t, "<td{}>{}</td>", if i == 0 { " class=\"l\"" } else { "" }, escape(c));
        }
        t.push_str("</tr>\n");
    }
    t.push_str("</table>\n");
    t
}

fn figure(v: Option<f64>) -> String {
    super::summary::figure(v)
}

fn trace_figure(v: Option<f64>) -> String {
    super::summary::trace_figure(v)
}

fn pct(v: Option<f64>) -> String {
    v.map_or("—".to_string(), |x| format!("{:.1} %", 100.0 * x))
}

/// How a run was made, for its page's header: the command line, the run's conditions, the simnet build.
pub struct RunHeader {
    pub command: String,
    /// `pose model, seed 1, loss 20.0 %`.
    pub conditions: String,
    /// The version, and the git commit when the build knew it.
    pub build: String,
}

/// The page of one run: `plots` are (caption, SVG text) in the order shown.
pub fn run_page(s: &Summary, plots: &[(String, String)], header: &RunHeader) -> String {
    let title = format!("simnet · {} · seed {}", s.topology, s.seed);
    let mut h = head(&title);
    let _ = writeln!(
        h,
        "<h1>{}</h1>",
        escape(&format!("simnet · {} ({} model)", s.topology, s.model))
    );
    let _ = writeln!(
        h,
        "<p class=\"meta\">{}</p>",
        escape(&format!(
            "{} · {} clock · {} steps at {} Hz{} · {:.2} s wall · simnet {}",
            header.conditions,
            s.clock.as_str(),
            s.steps,
            s.rate_hz,
            if s.interrupted { " · INTERRUPTED" } else { "" },
            s.transport.wall_s,
            header.build
        ))
    );
    let _ = writeln!(h, "<p class=\"meta\"><code>{}</code></p>", escape(&header.command));
    let _ = writeln!(
        h,
        "<h2>Nodes</h2>\n<p>{} after the burn-in; trace P: mean trace of the posterior covariance.</p>",
        escape(s.model.error_text().legend)
    );
    let rows: Vec<Vec<String>> = s
        .nodes
        .iter()
        .map(|n| {
            let (a, b) = (n.networked.as_ref(), n.independent.as_ref());
            vec![
                n.id.to_string(),
                n.role.to_string(),
                figure(a.and_then(|a| a.mean_error)),
                figure(b.and_then(|b| b.mean_error)),
                n.error_ratio.map_or("—".into(), |r| format!("{r:.3}")),
                trace_figure(a.and_then(|a| a.mean_trace_p_post)),
                trace_figure(b.and_then(|b| b.mean_trace_p_post)),
                pct(a.and_then(|a| a.lmi_feasible_fraction)),
                n.status(),
            ]
        })
        .collect();
    h.push_str(&table(
        "nodes",
        &[
            "node",
            "role",
            "networked error",
            "independent error",
            "ratio",
            "networked trace P",
            "independent trace P",
            "LMI feasible",
            "status",
        ]
        .map(String::from),
        &rows,
    ));
    if !s.estimators.is_empty() {
        let rounds = s.settings.as_ref().map_or(1, |x| x.rounds);
        let _ = writeln!(
            h,
            "<h2>Estimators</h2>\n<p>Side by side on the same samples and link verdicts, {}.</p>",
            crate::scenario::count(rounds, "consensus round")
        );
        let mut names: Vec<&String> = s.estimators.keys().collect();
        names.sort_by_key(|n| (n.as_str() != "centralized", crate::estimators::Kind::rank(n)));
        let rows: Vec<Vec<String>> = names
            .iter()
            .map(|n| {
                let e = &s.estimators[*n];
                vec![
                    n.to_string(),
                    figure(e.mean_error),
                    e.ratio_to_centralized.map_or("—".into(), |r| format!("{r:.3}")),
                    figure(e.median_error),
                    figure(e.disagreement),
                    e.messages.to_string(),
                    format!("{:.1}", e.bytes as f64 / 1e3),
                    e.diverged.to_string(),
                ]
            })
            .collect();
        h.push_str(&table(
            "estimators",
            &[
                "estimator",
                "mean error",
                "× centralized",
                "median error",
                "disagreement",
                "messages",
                "kB sent",
                "diverged",
            ]
            .map(String::from),
            &rows,
        ));
    }
    if !s.links.is_empty() {
        h.push_str("<h2>Links</h2>\n<p>sent = delivered + late + corrupted + lost; γ: steps in which a measurement arrived in time.</p>\n");
        let rows: Vec<Vec<String>> = s
            .links
            .iter()
            .map(|l| {
                vec![
                    format!("{} → {}", l.from, l.to),
                    l.sent.to_string(),
                    l.delivered.to_string(),
                    l.late.to_string(),
                    l.corrupted.to_string(),
                    l.lost.to_string(),
                    l.duplicated.to_string(),
                    pct(l.loss_rate),
                    pct(l.arrival_rate),
                    format!("{:.2}", l.mean_loss_run),
                ]
            })
            .collect();
        let t = table(
            "links",
            &[
                "link",
                "sent",
                "delivered",
                "late",
                "corrupted",
                "lost",
                "duplicated",
                "loss",
                "γ",
                "mean loss run",
            ]
            .map(String::from),
            &rows,
        );
        // A long list folds away.
        if rows.len() > 30 {
            let _ = writeln!(
                h,
                "<details><summary>{} directed links</summary>\n{t}</details>",
                rows.len()
            );
        } else {
            h.push_str(&t);
        }
    }
    if let Some(f) = &s.fused {
        let _ = writeln!(
            h,
            "<p>Fused ({}, covariance intersection, ω = 0.5): error {}, trace P {}; trace-optimal ω: error {}.</p>",
            escape(&crate::scenario::count(f.nodes, "node")),
            figure(f.mean_error),
            trace_figure(f.mean_trace_p),
            figure(f.optimal_mean_error)
        );
    }
    if !plots.is_empty() {
        h.push_str("<h2>Plots</h2>\n");
        for (caption, svg) in plots {
            let _ = writeln!(
                h,
                "<figure>\n{}\n<figcaption>{}</figcaption>\n</figure>",
                inline_svg(svg),
                escape(caption)
            );
        }
    }
    h.push_str("<h2>Provenance</h2>\n<dl>\n");
    let mut dl = |k: &str, v: &str| {
        let _ = writeln!(h, "<dt>{}</dt><dd>{}</dd>", escape(k), escape(v));
    };
    dl("simnet", &s.simnet_version);
    dl("topology", &format!("{} ({})", s.topology, s.source));
    dl("seed", &s.seed.to_string());
    if let Some(st) = &s.settings {
        dl(
            "run",
            &format!(
                "{} s, burn-in {} s, deadline {} s, trajectory {}",
                st.duration_s, st.burn_in_s, st.deadline_s, st.trajectory
            ),
        );
        dl("scenario SHA-256", &st.scenario_sha256);
    }
    h.push_str("</dl>\n");
    if let Some(st) = &s.settings {
        let _ = writeln!(
            h,
            "<details><summary>The resolved scenario (TOML: <code>simnet -t FILE</code> runs it again)</summary>\
             <pre>{}</pre></details>",
            escape(&st.scenario)
        );
    }
    h.push_str("</body>\n</html>\n");
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_is_escaped_and_svg_inlined() {
        assert_eq!(
            escape("<a href=\"x\">&</a>"),
            "&lt;a href=&quot;x&quot;&gt;&amp;&lt;/a&gt;"
        );
        assert_eq!(
            inline_svg("<?xml version=\"1.0\"?>\n<svg width=\"1\"></svg>"),
            "<svg width=\"1\"></svg>"
        );
        let t = table("t", &["a<b".into()], &[vec!["<script>".into()]]);
        assert!(t.contains("a&lt;b") && t.contains("&lt;script&gt;") && !t.contains("<script>"));
    }
}
