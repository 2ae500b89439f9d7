//! `summary.json`, the stdout table, `trace.csv` and `links.csv`.

use std::io::{self, Write};

use serde::{Deserialize, Serialize};

use super::observer::FusedSummary;
use crate::link::LinkCounters;
use crate::node::NodeReport;
use crate::observe::metrics::{FilterSummary, RxCounters};
use crate::scenario::Scenario;

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct NodeSummary {
    pub id: u32,
    pub role: crate::scenario::Role,
    pub networked: Option<FilterSummary>,
    pub independent: Option<FilterSummary>,
    /// networked mean error / independent mean error.
    pub error_ratio: Option<f64>,
    pub malformed: u64,
    pub corrupted: u64,
    pub restarts: u64,
    pub steps_down: u64,
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct LinkSummary {
    pub from: u32,
    pub to: u32,
    pub sent: u64,
    pub delivered: u64,
    /// Never usable: dropped by the loss model or a scheduled fault, or lost in the socket layer.
    pub lost: u64,
    pub lost_random: u64,
    pub lost_down: u64,
    pub late: u64,
    pub duplicated: u64,
    pub corrupted: u64,
    pub loss_rate: Option<f64>,
    pub delivered_fraction: Option<f64>,
    /// γ: the fraction of the receiver's steps in which a measurement from the sender arrived in time (Sinopoli's
    /// arrival rate).
    pub arrival_rate: Option<f64>,
    pub mean_loss_run: f64,
    pub longest_loss_run: u64,
}

impl LinkSummary {
    /// Join the sender's link counters with what the receiver saw from that sender.
    pub fn join(from: u32, to: u32, tx: &LinkCounters, rx: &RxCounters) -> LinkSummary {
        let usable_or_seen = rx.delivered + rx.late + rx.corrupted + rx.while_down;
        // Copies (duplicates) can only make the receiver's counts larger than what was sent once.
        let lost = tx.sent.saturating_sub(usable_or_seen.min(tx.sent));
        let frac = |x: u64| (tx.sent > 0).then(|| x as f64 / tx.sent as f64);
        LinkSummary {
            from,
            to,
            sent: tx.sent,
            delivered: rx.delivered,
            lost: lost + rx.while_down,
            lost_random: tx.lost_random,
            lost_down: tx.lost_down + rx.while_down,
            late: rx.late,
            duplicated: tx.duplicated,
            corrupted: rx.corrupted,
            loss_rate: frac(lost + rx.while_down),
            delivered_fraction: frac(rx.delivered),
            arrival_rate: (rx.steps > 0).then(|| 1.0 - rx.missing_steps as f64 / rx.steps as f64),
            mean_loss_run: tx.mean_loss_run(),
            longest_loss_run: tx.longest_loss_run.max(tx.current_run),
        }
    }
}

/// How a run was set up, so that a result file says how it was made.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Settings {
    pub duration_s: f64,
    pub burn_in_s: f64,
    pub deadline_s: f64,
    pub trajectory: crate::motion::Trajectory,
    pub split_channels: bool,
    /// The command-line (or environment) overrides applied to the file.
    pub overrides: crate::scenario::Overrides,
    /// Every directed link's resolved settings (loss model, delay, jitter, duplication, corruption).
    pub links: Vec<LinkSetting>,
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct LinkSetting {
    pub from: u32,
    pub to: u32,
    #[serde(flatten)]
    pub config: crate::link::LinkConfig,
}

impl Settings {
    pub fn of(topo: &Scenario) -> Settings {
        Settings {
            duration_s: topo.sim.duration_s,
            burn_in_s: topo.sim.burn_in_s,
            deadline_s: topo.sim.deadline_s,
            trajectory: topo.sim.trajectory,
            split_channels: topo.sim.split_channels,
            overrides: topo.applied.clone(),
            links: topo
                .links
                .iter()
                .map(|l| LinkSetting {
                    from: topo.nodes[l.from].id,
                    to: topo.nodes[l.to].id,
                    config: l.config,
                })
                .collect(),
        }
    }
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Summary {
    /// The simnet version that made this file.
    #[serde(default)]
    pub simnet_version: String,
    pub topology: String,
    pub source: String,
    pub model: crate::model::Kind,
    pub seed: u64,
    pub clock: crate::sim::Clock,
    pub rate_hz: f64,
    pub steps: u64,
    pub burn_in_steps: u64,
    pub interrupted: bool,
    pub wall_s: f64,
    pub socket_losses: u64,
    pub nodes: Vec<NodeSummary>,
    pub links: Vec<LinkSummary>,
    pub fused: Option<FusedSummary>,
    #[serde(default)]
    pub settings: Option<Settings>,
    /// Set in the part a `simnet node` writes; absent from whole-run summaries.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub part: Option<PartInfo>,
}

impl Summary {
    /// (networked, independent) scored errors of every estimating node whose error was measured
    /// ([`FilterSummary::scored_error`]).
    pub fn scored_errors(&self) -> Vec<(f64, f64)> {
        self.nodes
            .iter()
            .filter_map(|n| {
                let (a, b) = (n.networked.as_ref()?, n.independent.as_ref()?);
                Some((a.scored_error()?, b.scored_error()?))
            })
            .collect()
    }

    #[allow(clippy::too_many_arguments)]
    pub fn build(
        topo: &Scenario,
        clock: crate::sim::Clock,
        reports: &[NodeReport],
        fused: Option<FusedSummary>,
        steps: u64,
        interrupted: bool,
        wall_s: f64,
        socket_losses: u64,
    ) -> Summary {
        let nodes = reports
            .iter()
            .map(|r| {
                let networked = r.networked.as_ref().map(|m| m.summary(true));
                let independent = r.independent.as_ref().map(|m| m.summary(false));
                // An estimator has no measurement of its own: its twin only predicts, and a ratio means nothing.
                let error_ratio = match (&networked, &independent) {
                    _ if r.role == crate::scenario::Role::Estimator => None,
                    (Some(a), Some(b)) => match (a.mean_error, b.mean_error) {
                        (Some(x), Some(y)) if y > 0.0 => Some(x / y),
                        _ => None,
                    },
                    _ => None,
                };
                NodeSummary {
                    id: r.id,
                    role: r.role,
                    networked,
                    independent,
                    error_ratio,
                    malformed: r.counters.malformed,
                    corrupted: r.counters.corrupted,
                    restarts: r.counters.restarts,
                    steps_down: r.counters.steps_down,
                }
            })
            .collect();
        let mut links = Vec::new();
        for r in reports {
            for (to, tx) in &r.links_out {
                let rx = reports
                    .iter()
                    .find(|x| x.index == *to)
                    .map(|x| x.rx[r.index])
                    .unwrap_or_default();
                links.push(LinkSummary::join(r.id, topo.nodes[*to].id, tx, &rx));
            }
        }
        Summary {
            simnet_version: env!("CARGO_PKG_VERSION").to_string(),
            topology: topo.name.clone(),
            source: topo.source.clone(),
            model: topo.model.get().kind(),
            seed: topo.sim.seed,
            clock,
            rate_hz: topo.sim.rate_hz,
            steps,
            burn_in_steps: topo.sim.burn_in_steps(),
            interrupted,
            wall_s,
            socket_losses,
            nodes,
            links,
            fused,
            settings: Some(Settings::of(topo)),
            part: None,
        }
    }

    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a summary always serialises")
    }

    /// The human-readable table printed on stdout.
    pub fn write_table(&self, w: &mut impl Write) -> io::Result<()> {
        let f = |v: Option<f64>| {
            v.map_or("—".to_string(), |x| {
                if x.abs() < 1e4 {
                    format!("{x:.4}")
                } else {
                    format!("{x:.3e}")
                }
            })
        };
        let e = |v: Option<f64>| v.map_or("—".to_string(), |x| format!("{x:.3e}"));
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
            self.wall_s
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
            let (Some(a), Some(b)) = (&n.networked, &n.independent) else {
                writeln!(
                    w,
                    "{:>5} {:>9} │ {:^48} │ {:>8} │",
                    n.id, n.role, "senses and sends only", ""
                )?;
                continue;
            };
            let mut status = Vec::new();
            if a.diverged {
                status.push("networked DIVERGED");
            }
            if n.role == crate::scenario::Role::Estimator {
                status.push("no own sensor: independent = prediction only");
            } else if b.diverged {
                status.push("independent DIVERGED");
            }
            if n.restarts > 0 {
                status.push("restarted");
            }
            writeln!(
                w,
                "{:>5} {:>9} │ {:>10} {:>10} {:>7} │ {:>10} {:>10} │ {:>8} │ {}",
                n.id,
                n.role,
                f(a.mean_error),
                f(b.mean_error),
                n.error_ratio.map_or("—".into(), |r| format!("{r:.3}")),
                e(a.mean_trace_p_post),
                e(b.mean_trace_p_post),
                pct(a.lmi_feasible_fraction),
                if status.is_empty() {
                    "ok".to_string()
                } else {
                    status.join(", ")
                }
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
        if self.socket_losses > 0 {
            writeln!(
                w,
                "note: {} delivered by the link layer lost in the socket layer",
                crate::scenario::count(self.socket_losses as usize, "datagram")
            )?;
        }
        Ok(())
    }
}

/// `links.csv`: the per-link counters.
pub fn write_links(w: &mut impl Write, links: &[LinkSummary]) -> io::Result<()> {
    use super::trace::num;
    let opt = |v: Option<f64>| v.map_or(String::new(), num);
    writeln!(w, "from,to,sent,delivered,late,corrupted,lost,lost_random,lost_down,duplicated,loss_rate,arrival_rate,mean_loss_run,longest_loss_run")?;
    for l in links {
        writeln!(
            w,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            l.from,
            l.to,
            l.sent,
            l.delivered,
            l.late,
            l.corrupted,
            l.lost,
            l.lost_random,
            l.lost_down,
            l.duplicated,
            opt(l.loss_rate),
            opt(l.arrival_rate),
            num(l.mean_loss_run),
            l.longest_loss_run
        )?;
    }
    Ok(())
}

/// What a part adds to the summary schema.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct PartInfo {
    pub node: u32,
    pub first_step: u64,
    pub steps_done: u64,
    /// Sender-side counters of each outgoing link, by destination id.
    pub links_out: Vec<(u32, crate::link::LinkCounters)>,
    /// Receiver-side counters, by source id.
    pub rx: Vec<(u32, crate::observe::metrics::RxCounters)>,
    /// How the observer fuses this run's estimates.
    pub fusion: crate::model::FusionLayout,
}
