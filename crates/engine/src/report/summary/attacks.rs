//! What each `[[attack]]` did: its datagrams' fates, the innovation gate's count on the links it used, and every
//! node's error beside the same seed's clean run.

use super::*;
use crate::attack::{AttackKind, Tally};
use crate::node::NodeReport;
use crate::scenario::Scenario;

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct AttackSummary {
    pub kind: AttackKind,
    /// The node attacked (outsiders), by id.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub target: Option<u32>,
    /// The node whose datagrams were forged, tampered with or replayed.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub claim: Option<u32>,
    /// The compromised node (false-data).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub node: Option<u32>,
    pub start_s: f64,
    /// None: to the end of the run.
    pub end_s: Option<f64>,
    /// Sent, used, ignored (accepted but nothing new) and rejected by cause; for false-data, the measurements the
    /// compromised node sent while the attack was under way.
    pub datagrams: Tally,
    /// Measurements the innovation gate left out on the links the attack used (claim → target; for false-data,
    /// the compromised node's out-links), the whole run.
    pub gated: u64,
    /// The same count in the same seed's clean run.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub gated_clean: Option<u64>,
}

/// One node's error under attack and in the same seed's clean run.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct AttackEffect {
    pub id: u32,
    pub mean_error: Option<f64>,
    pub clean_mean_error: Option<f64>,
    pub rms_error: Option<f64>,
    pub clean_rms_error: Option<f64>,
}

impl AttackEffect {
    /// Mean error under attack − in the clean run.
    pub fn shift(&self) -> Option<f64> {
        Some(self.mean_error? - self.clean_mean_error?)
    }
}

impl AttackSummary {
    pub(super) fn of(topo: &Scenario, reports: &[NodeReport], links: &[LinkSummary]) -> Vec<AttackSummary> {
        let id = |i: Option<usize>| i.map(|i| topo.nodes()[i].id);
        topo.attacks()
            .iter()
            .enumerate()
            .map(|(i, a)| {
                let datagrams = reports.iter().flat_map(|r| &r.attacks).filter(|(j, _)| *j == i).fold(
                    Tally::default(),
                    |mut t, (_, x)| {
                        t.add(x);
                        t
                    },
                );
                let (target, claim, node) = (id(a.target), id(a.claim), id(a.node));
                AttackSummary {
                    kind: a.kind,
                    target,
                    claim,
                    node,
                    start_s: a.start_s,
                    end_s: a.end_s.is_finite().then_some(a.end_s),
                    datagrams,
                    gated: gated_on(links, a.kind, target, claim, node),
                    gated_clean: None,
                }
            })
            .collect()
    }
}

impl AttackSummary {
    /// The attacks of a multi-host run from its parts (each counts what its own node saw), the gate's counts from
    /// the joined `links`; parts that disagree on the attacks keep the first part's list.
    pub fn merge(parts: &[Summary], links: &[LinkSummary]) -> Vec<AttackSummary> {
        let Some(first) = parts.first() else { return Vec::new() };
        let mut out = first.attacks.clone();
        for (i, a) in out.iter_mut().enumerate() {
            a.datagrams = parts
                .iter()
                .filter_map(|p| p.attacks.get(i))
                .fold(Tally::default(), |mut t, x| {
                    t.add(&x.datagrams);
                    t
                });
            a.gated = gated_on(links, a.kind, a.target, a.claim, a.node);
        }
        out
    }
}

/// The gate's count on the links an attack used.
fn gated_on(
    links: &[LinkSummary],
    kind: AttackKind,
    target: Option<u32>,
    claim: Option<u32>,
    node: Option<u32>,
) -> u64 {
    links
        .iter()
        .filter(|l| match kind {
            AttackKind::FalseData => Some(l.from) == node,
            AttackKind::Flood => false,
            _ => Some(l.from) == claim && Some(l.to) == target,
        })
        .map(|l| l.gated)
        .sum()
}

impl Summary {
    /// Set each attack's and each node's figures beside those of `clean`, the same seed's run without attacks.
    pub fn compare_clean(&mut self, clean: &Summary) {
        for a in &mut self.attacks {
            a.gated_clean = Some(gated_on(&clean.links, a.kind, a.target, a.claim, a.node));
        }
        let figures = |s: &Summary, id: u32| {
            s.nodes
                .iter()
                .find(|n| n.id == id)
                .and_then(|n| n.networked.as_ref())
                .map(|f| (f.mean_error, f.rms_error))
                .unwrap_or_default()
        };
        self.attack_effect = self
            .nodes
            .iter()
            .filter(|n| n.networked.is_some())
            .map(|n| {
                let ((mean, rms), (clean_mean, clean_rms)) = (figures(self, n.id), figures(clean, n.id));
                AttackEffect {
                    id: n.id,
                    mean_error: mean,
                    clean_mean_error: clean_mean,
                    rms_error: rms,
                    clean_rms_error: clean_rms,
                }
            })
            .collect();
    }
}
