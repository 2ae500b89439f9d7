//! The table printed on stdout.

use super::*;
use std::io::{self, Write};

/// A figure of the table: four decimals, or three significant digits in exponent form from 1e4 on; `—` unknown.
pub(crate) fn figure(v: Option<f64>) -> String {
    v.map_or("—".to_string(), |x| {
        if x.abs() < 1e4 {
            format!("{x:.4}")
        } else {
            format!("{x:.3e}")
        }
    })
}

/// A trace or a variance: three significant digits in plain notation from 0.01 to 10⁴ (`2.32`, not `2.321e0`;
/// 2321 keeps its units digit), `7.630e-4` outside.
pub(crate) fn trace_figure(v: Option<f64>) -> String {
    v.map_or("—".to_string(), |x| {
        let a = x.abs();
        if a == 0.0 {
            "0".to_string()
        } else if (0.01..1e4).contains(&a) {
            let decimals = (2 - a.log10().floor() as i32).max(0) as usize;
            format!("{x:.decimals$}")
        } else {
            format!("{x:.3e}")
        }
    })
}

impl NodeSummary {
    /// What the table's status column says of the node: `ok`, or what is not.
    pub fn status(&self) -> String {
        let Some(b) = &self.independent else {
            return "senses and sends only".to_string();
        };
        let mut status = Vec::new();
        match &self.networked {
            Some(a) if a.diverged => status.push("networked DIVERGED"),
            Some(_) => {}
            // An estimating node without one: its model's nodes observe differently (sequeira cannot run).
            None => status.push("no networked filter: the nodes observe differently"),
        }
        if self.role == crate::scenario::Role::Estimator {
            status.push("no own sensor: independent = prediction only");
        } else if b.diverged {
            status.push("independent DIVERGED");
        }
        if self.restarts > 0 {
            status.push("restarted");
        }
        if status.is_empty() {
            "ok".to_string()
        } else {
            status.join(", ")
        }
    }
}

impl Summary {
    /// The human-readable table printed on stdout.
    pub fn write_table(&self, w: &mut impl Write) -> io::Result<()> {
        let f = figure;
        let e = trace_figure;
        let pct = |v: Option<f64>| v.map_or("—".to_string(), |x| format!("{:.1} %", 100.0 * x));
        writeln!(
            w,
            "simnet · {} ({} model) · seed {} · {} clock · {} steps at {} Hz{} · {:.2} s wall",
            self.topology,
            self.model,
            self.seed,
            self.clock,
            self.steps,
            self.rate_hz,
            if self.interrupted { " · INTERRUPTED" } else { "" },
            self.transport.wall_s
        )?;
        let unit = self.model.error_text().legend;
        writeln!(
            w,
            "{unit} (after the burn-in); trP: mean trace of the posterior covariance"
        )?;
        writeln!(w)?;
        writeln!(
            w,
            "{:>5} {:>9} │ {:>10} {:>10} {:>7} │ {:>10} {:>10} │ {:>8} │ status",
            "node", "role", "net err", "ind err", "ratio", "net trP", "ind trP", "LMI ok"
        )?;
        writeln!(w, "{}", "─".repeat(100))?;
        for n in &self.nodes {
            let (a, Some(b)) = (n.networked.as_ref(), &n.independent) else {
                writeln!(
                    w,
                    "{:>5} {:>9} │ {:^48} │ {:>8} │",
                    n.id, n.role, "senses and sends only", ""
                )?;
                continue;
            };
            writeln!(
                w,
                "{:>5} {:>9} │ {:>10} {:>10} {:>7} │ {:>10} {:>10} │ {:>8} │ {}",
                n.id,
                n.role,
                f(a.and_then(|a| a.mean_error)),
                f(b.mean_error),
                n.error_ratio.map_or("—".into(), |r| format!("{r:.3}")),
                e(a.and_then(|a| a.mean_trace_p_post)),
                e(b.mean_trace_p_post),
                pct(a.and_then(|a| a.lmi_feasible_fraction)),
                n.status()
            )?;
        }
        writeln!(w)?;
        if !self.links.is_empty() {
            writeln!(
                w,
                "links: sent = delivered + late + corrupted + lost; dup = extra copies (not in sent); γ = steps in which a measurement arrived in time"
            )?;
            writeln!(
                w,
                "{:>9} │ {:>7} {:>9} {:>6} {:>6} {:>7} │ {:>6} │ {:>8} {:>8} {:>9}",
                "link", "sent", "delivered", "late", "corr", "lost", "dup", "loss", "γ", "mean run"
            )?;
            writeln!(w, "{}", "─".repeat(98))?;
        }
        for l in &self.links {
            writeln!(
                w,
                "{:>9} │ {:>7} {:>9} {:>6} {:>6} {:>7} │ {:>6} │ {:>8} {:>8} {:>9.2}",
                format!("{} → {}", l.from, l.to),
                l.sent,
                l.delivered,
                l.late,
                l.corrupted,
                l.lost,
                l.duplicated,
                pct(l.loss_rate),
                pct(l.arrival_rate),
                l.mean_loss_run
            )?;
        }
        self.write_radio(w)?;
        self.write_estimators(w)?;
        if let Some(fu) = &self.fused {
            writeln!(w)?;
            writeln!(
                w,
                "fused ({}, covariance intersection): ω = 0.5 error {} (median-filtered {}), trace P {}; trace-optimal ω error {}, trace P {}",
                crate::scenario::count(fu.nodes, "node"),
                f(fu.mean_error),
                f(fu.median_mean_error),
                e(fu.mean_trace_p),
                f(fu.optimal_mean_error),
                e(fu.optimal_mean_trace_p)
            )?;
        }
        if let Some(sec) = &self.security {
            let r = &sec.rejected;
            writeln!(
                w,
                "authenticated ({}, key: {}): {} datagrams refused — bad tag {}, replay {}, too old {}, unknown source {}",
                sec.aead,
                sec.key,
                r.total(),
                r.bad_tag,
                r.replay,
                r.too_old,
                r.unknown_source
            )?;
        }
        self.write_attacks(w)?;
        let gated: u64 = self.nodes.iter().map(|n| n.gated).sum();
        if gated > 0 {
            writeln!(
                w,
                "innovation gate: {gated} neighbours' measurements left out of the networked update"
            )?;
        }
        let implausible: u64 = self.nodes.iter().map(|n| n.implausible_step).sum();
        let unknown: u64 = self.nodes.iter().map(|n| n.unknown_address).sum();
        if implausible + unknown > 0 {
            writeln!(
                w,
                "untrusted datagrams, counted and never used: {implausible} claimed a step outside the run or too far \
                 ahead, {unknown} came from an address that is no neighbour's"
            )?;
        }
        if let Some(s) = &self.transport.schedule {
            writeln!(
                w,
                "schedule: steps started at most {:.1} ms late; {} of {} node-steps more than one period late",
                s.max_lag_ms, s.late_steps, s.steps
            )?;
        }
        let kernel = self.transport.kernel_drops_total();
        if kernel > 0 {
            writeln!(
                w,
                "note: the kernel dropped {kernel} datagrams on full receive buffers (socket losses, apart from the link \
                 layer's)"
            )?;
        }
        if self.socket_losses > 0 {
            writeln!(
                w,
                "note: {} of the virtual clock lost in the socket layer (each carries one step's datagrams on one link)",
                crate::scenario::count(self.socket_losses as usize, "frame")
            )?;
        }
        Ok(())
    }

    /// One column per estimator, node by node, then each estimator's figures against the centralized reference.
    fn write_estimators(&self, w: &mut impl Write) -> io::Result<()> {
        if self.estimators.is_empty() {
            return Ok(());
        }
        let f = figure;
        let rounds = self.settings.as_ref().map_or(1, |s| s.rounds);
        // The reference first, then the schemes in `simnet estimators` order.
        let mut names: Vec<&String> = self.estimators.keys().collect();
        names.sort_by_key(|n| (n.as_str() != "centralized", crate::estimators::Kind::rank(n)));
        writeln!(
            w,
            "estimators ({}): mean error per node, side by side on the same samples and link verdicts",
            crate::scenario::count(rounds, "consensus round")
        )?;
        let width = names.iter().map(|n| n.len()).max().unwrap_or(0).max(11);
        write!(w, "{:>5} │", "node")?;
        for n in &names {
            write!(w, " {n:>width$}")?;
        }
        writeln!(w)?;
        writeln!(w, "{}", "─".repeat(8 + (width + 1) * names.len()))?;
        // Each estimator's cell by node id: the table stays linear in the nodes.
        let cells: Vec<std::collections::HashMap<u32, String>> = names
            .iter()
            .map(|n| {
                self.estimators[*n]
                    .nodes
                    .iter()
                    .map(|x| {
                        let c = if x.figures.diverged {
                            "DIVERGED".to_string()
                        } else {
                            f(x.figures.mean_error)
                        };
                        (x.id, c)
                    })
                    .collect()
            })
            .collect();
        for node in &self.nodes {
            if cells.iter().all(|c| !c.contains_key(&node.id)) {
                continue;
            }
            write!(w, "{:>5} │", node.id)?;
            for c in &cells {
                write!(w, " {:>width$}", c.get(&node.id).map_or("·", String::as_str))?;
            }
            writeln!(w)?;
        }
        writeln!(w)?;
        writeln!(
            w,
            "{:>width$} │ {:>10} {:>9} {:>10} │ {:>12} │ {:>10} {:>10} │ diverged",
            "estimator", "mean err", "× central", "median err", "disagreement", "messages", "kB sent"
        )?;
        writeln!(w, "{}", "─".repeat(88 + width))?;
        for n in &names {
            let e = &self.estimators[*n];
            writeln!(
                w,
                "{:>width$} │ {:>10} {:>9} {:>10} │ {:>12} │ {:>10} {:>10.1} │ {}",
                n,
                f(e.mean_error),
                e.ratio_to_centralized.map_or("—".into(), |r| format!("{r:.3}")),
                f(e.median_error),
                f(e.disagreement),
                e.messages,
                e.bytes as f64 / 1e3,
                e.diverged
            )?;
        }
        if self.estimators.contains_key("centralized") {
            writeln!(
                w,
                "centralized: every sensing node's measurement reaches one center with no loss (the reference; exact where the measurements are linear in the state)"
            )?;
        }
        if let Some(e) = self.estimators.get("centralized-net") {
            let (got, sent) = (e.delivered.unwrap_or(0), e.messages);
            writeln!(
                w,
                "centralized-net: {got} of {sent} measurements ({:.1} %) reached the center (node {}) over lossy links by the deadline",
                100.0 * got as f64 / sent.max(1) as f64,
                e.nodes.first().map_or("—".to_string(), |n| n.id.to_string())
            )?;
        }
        Ok(())
    }
}

impl Summary {
    /// One line per attack, then each node's error beside the same seed's clean run.
    fn write_attacks(&self, w: &mut impl Write) -> io::Result<()> {
        for (i, a) in self.attacks.iter().enumerate() {
            let who = match (a.target, a.claim, a.node) {
                (Some(t), Some(c), _) => format!("on node {t} claiming node {c}"),
                (Some(t), None, _) => format!("on node {t}"),
                (_, _, Some(n)) => format!("by compromised node {n}"),
                _ => String::new(),
            };
            let until = a
                .end_s
                .map_or("the end".to_string(), |e| format!("{} s", crate::checks::num(e)));
            let d = &a.datagrams;
            let causes: Vec<String> = d.rejected.causes().iter().map(|(c, n)| format!("{c} {n}")).collect();
            let rejected = if causes.is_empty() {
                "0 rejected".to_string()
            } else {
                format!("{} rejected ({})", d.rejected.total(), causes.join(", "))
            };
            let what = if a.kind == crate::attack::AttackKind::FalseData {
                format!("{} measurements sent", d.sent)
            } else {
                format!("{} sent, {} used, {} ignored, {rejected}", d.sent, d.used, d.ignored)
            };
            let gate = match a.gated_clean {
                Some(c) if a.gated + c > 0 => format!("; gate left out {} on its links (clean run {c})", a.gated),
                None if a.gated > 0 => format!("; gate left out {} on its links", a.gated),
                _ => String::new(),
            };
            writeln!(
                w,
                "attack {i}: {} {who}, from {} s to {until}: {what}{gate}",
                a.kind.as_str(),
                crate::checks::num(a.start_s)
            )?;
        }
        if self.attack_effect.is_empty() {
            return Ok(());
        }
        let unit = self.model.error_text().legend;
        writeln!(w, "under attack against the same seed's clean run ({unit}):")?;
        for n in &self.attack_effect {
            writeln!(
                w,
                "{:>5}  net err {:>10}  clean {:>10}  change {:>10}",
                n.id,
                figure(n.mean_error),
                figure(n.clean_mean_error),
                n.shift().map_or("—".to_string(), |s| format!("{s:+.4}"))
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::trace_figure;

    #[test]
    fn a_trace_reads_plain_between_a_hundredth_and_ten_thousand() {
        let f = |x: f64| trace_figure(Some(x));
        assert_eq!(
            [f(2.321), f(23.21), f(232.1), f(2321.4), f(0.0123), f(-2.321)],
            ["2.32", "23.2", "232", "2321", "0.0123", "-2.32"]
        );
        assert_eq!([f(7.63e-4), f(12345.0), f(0.0)], ["7.630e-4", "1.234e4", "0"]);
        assert_eq!(trace_figure(None), "—");
    }
}
