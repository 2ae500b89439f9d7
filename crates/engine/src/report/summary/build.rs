//! A summary from a run's node reports and fusion.

use super::*;
use crate::link::LinkCounters;
use crate::node::NodeReport;
use crate::observe::metrics::RxCounters;
use crate::scenario::Scenario;

impl LinkSummary {
    /// Join the sender's link counters with what the receiver saw from that sender.
    pub fn join(from: u32, to: u32, tx: &LinkCounters, rx: &RxCounters) -> LinkSummary {
        // Saturating: the counters of a multi-host run come from part files, which may be damaged.
        let usable_or_seen = [rx.late, rx.corrupted, rx.while_down]
            .into_iter()
            .fold(rx.delivered, u64::saturating_add);
        // Copies (duplicates) can only make the receiver's counts larger than what was sent once.
        let lost = tx.sent.saturating_sub(usable_or_seen.min(tx.sent));
        let lost_all = lost.saturating_add(rx.while_down);
        let frac = |x: u64| (tx.sent > 0).then(|| x as f64 / tx.sent as f64);
        LinkSummary {
            from,
            to,
            sent: tx.sent,
            delivered: rx.delivered,
            lost: lost_all,
            lost_random: tx.lost_random,
            lost_down: tx.lost_down.saturating_add(rx.while_down),
            late: rx.late,
            duplicated: tx.duplicated,
            corrupted: rx.corrupted,
            loss_rate: frac(lost_all),
            delivered_fraction: frac(rx.delivered),
            arrival_rate: (rx.steps > 0).then(|| 1.0 - rx.missing_steps as f64 / rx.steps as f64),
            mean_loss_run: tx.mean_loss_run(),
            longest_loss_run: tx.longest_loss_run.max(tx.current_run),
            gated: rx.gated,
            seq_gaps: rx.seq_gaps,
            radio: None,
        }
    }
}

impl Settings {
    pub fn of(topo: &Scenario) -> Settings {
        Settings {
            duration_s: topo.sim().duration_s,
            burn_in_s: topo.sim().burn_in_s,
            deadline_s: topo.sim().deadline_s,
            trajectory: topo.sim().trajectory,
            split_channels: topo.sim().split_channels,
            rounds: topo.estimators().rounds,
            overrides: topo.applied().clone(),
            links: topo
                .links()
                .iter()
                .map(|l| LinkSetting {
                    from: topo.nodes()[l.from].id,
                    to: topo.nodes()[l.to].id,
                    config: l.config,
                })
                .collect(),
            scenario: topo.to_toml(),
            scenario_sha256: topo.digest(),
            faults: topo.faults().windows(|i| topo.nodes()[i].id),
        }
    }
}

impl Summary {
    #[allow(clippy::too_many_arguments)]
    pub fn build(
        topo: &Scenario,
        clock: crate::report::summary::Clock,
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
                    rejected: r.counters.rejected,
                    implausible_step: r.counters.implausible_step,
                    unknown_address: r.counters.unknown_address,
                    gated: r.counters.gated,
                }
            })
            .collect();
        let mut links = Vec::new();
        for r in reports {
            for (to, tx) in &r.links_out {
                let rx = reports
                    .iter()
                    .find(|x| x.index == *to)
                    .map(|x| x.rx.get(r.index))
                    .unwrap_or_default();
                let mut l = LinkSummary::join(r.id, topo.nodes()[*to].id, tx, &rx);
                l.radio = r
                    .radio_links
                    .iter()
                    .find(|(j, _)| j == to)
                    .map(|(_, q)| LinkRadio::of(q));
                links.push(l);
            }
        }
        let attacks = AttackSummary::of(topo, reports, &links);
        Summary {
            simnet_version: env!("CARGO_PKG_VERSION").to_string(),
            topology: topo.name().to_string(),
            source: topo.source().to_string(),
            model: topo.model().kind(),
            seed: topo.sim().seed,
            clock,
            rate_hz: topo.sim().rate_hz,
            steps,
            burn_in_steps: topo.sim().burn_in_steps(),
            interrupted,
            transport: Transport {
                wall_s,
                kernel_drops: reports
                    .iter()
                    .filter(|r| r.counters.kernel_drops > 0)
                    .map(|r| (r.id, r.counters.kernel_drops))
                    .collect(),
                ..Transport::default()
            },
            socket_losses,
            nodes,
            links,
            fused,
            estimators: Default::default(),
            settings: Some(Settings::of(topo)),
            part: None,
            security: topo.security().key.as_ref().map(|_| SecuritySummary {
                aead: "AES-128-CCM, 8-byte tag".into(),
                key: topo.security().key_source.clone().unwrap_or_default(),
                rejected: reports.iter().fold(Default::default(), |mut a, r| {
                    a.add(&r.counters.rejected);
                    a
                }),
            }),
            attacks,
            attack_effect: Vec::new(),
            radio: RadioSummary::of(topo, reports, steps),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Counters read from a damaged part file saturate instead of overflowing.
    #[test]
    fn joining_huge_counters_saturates() {
        let tx = LinkCounters {
            sent: 10,
            lost_down: u64::MAX,
            ..Default::default()
        };
        let rx = RxCounters {
            delivered: u64::MAX,
            late: u64::MAX,
            while_down: u64::MAX,
            ..Default::default()
        };
        let l = LinkSummary::join(0, 1, &tx, &rx);
        assert_eq!((l.lost, l.lost_down, l.delivered), (u64::MAX, u64::MAX, u64::MAX));
        let rx = RxCounters {
            delivered: 7,
            ..Default::default()
        };
        let l = LinkSummary::join(0, 1, &tx, &rx);
        assert_eq!((l.lost, l.loss_rate), (3, Some(0.3)));
    }
}
