//! `estimators.{name}` of `summary.json`: every estimator a run held, with the figures `networked` and
//! `independent` have per node, their mean over the nodes, the disagreement across nodes, and the traffic.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::estimators::Kind;
use crate::node::NodeReport;
use crate::observe::metrics::FilterSummary;
use crate::observe::schemes::SchemeObserver;
use crate::scenario::Scenario;

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct EstimatorNode {
    pub id: u32,
    #[serde(flatten)]
    pub figures: FilterSummary,
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct EstimatorSummary {
    /// Mean over the nodes of each node's mean error (the center's own for `centralized`).
    pub mean_error: Option<f64>,
    /// Mean over the counted steps of the median-over-nodes error.
    pub median_error: Option<f64>,
    /// This mean error over `centralized`'s, when the run holds it.
    pub ratio_to_centralized: Option<f64>,
    /// Mean over the counted steps of the mean distance of the node estimates from their average.
    pub disagreement: Option<f64>,
    /// Mean over the counted steps of the error of the node estimates fused by covariance intersection (ω = 0.5,
    /// as `fused` of the two filters); none for the fusion centers and where covariances are not known.
    #[serde(default)]
    pub fused_error: Option<f64>,
    /// Nodes that diverged.
    pub diverged: usize,
    /// Messages (one per out-link and round) and bytes the nodes sent for this estimator; the measurements of
    /// `sequeira` (its only traffic) count under it, `centralized`'s reference travels no link, and
    /// `centralized-net`'s are one measurement to the sink per sensing node and step.
    pub messages: u64,
    pub bytes: u64,
    /// `centralized-net`: the measurements that reached the sink by the deadline.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub delivered: Option<u64>,
    pub nodes: Vec<EstimatorNode>,
}

impl EstimatorSummary {
    /// Every estimator of the run, by name.
    pub fn of_run(
        topo: &Scenario,
        reports: &[NodeReport],
        observer: Option<&SchemeObserver>,
    ) -> BTreeMap<String, EstimatorSummary> {
        let mut out = BTreeMap::new();
        let star = observer.and_then(SchemeObserver::star_traffic);
        for &kind in &topo.estimators().run {
            let nodes: Vec<EstimatorNode> = match kind {
                Kind::Centralized | Kind::CentralizedNet => observer
                    .and_then(|o| o.center(kind))
                    .map(|(center, m)| EstimatorNode {
                        id: topo.nodes()[center].id,
                        figures: m.summary(false),
                    })
                    .into_iter()
                    .collect(),
                _ => reports
                    .iter()
                    .filter(|r| r.role.estimates())
                    .filter_map(|r| {
                        let m = match kind {
                            Kind::Sequeira => r.networked.as_ref(),
                            Kind::Independent => r.independent.as_ref(),
                            _ => r.schemes.iter().find(|(k, _)| *k == kind).map(|(_, m)| m),
                        }?;
                        Some(EstimatorNode {
                            id: r.id,
                            figures: m.summary(kind == Kind::Sequeira),
                        })
                    })
                    .collect(),
            };
            let (messages, bytes) = match kind {
                Kind::Sequeira => reports
                    .iter()
                    .flat_map(|r| &r.links_out)
                    .fold((0, 0), |(m, b), (_, c)| (m + c.sent, b + c.bytes)),
                Kind::CentralizedNet => star.map_or((0, 0), |t| (t.messages, t.bytes)),
                _ => reports
                    .iter()
                    .flat_map(|r| &r.traffic)
                    .filter(|(k, _)| *k == kind)
                    .fold((0, 0), |(m, b), (_, t)| (m + t.messages, b + t.bytes)),
            };
            let errors: Vec<f64> = nodes.iter().filter_map(|n| n.figures.mean_error).collect();
            let agreement = observer.map(|o| o.agreement(kind)).unwrap_or_default();
            out.insert(
                kind.name().to_string(),
                EstimatorSummary {
                    mean_error: (!errors.is_empty() && errors.len() == nodes.len())
                        .then(|| errors.iter().sum::<f64>() / errors.len() as f64),
                    median_error: agreement.median_error,
                    ratio_to_centralized: None,
                    disagreement: (!kind.is_center()).then_some(agreement.disagreement).flatten(),
                    fused_error: (!kind.is_center()).then_some(agreement.fused_error).flatten(),
                    diverged: nodes.iter().filter(|n| n.figures.diverged).count(),
                    messages,
                    bytes,
                    delivered: (kind == Kind::CentralizedNet).then(|| star.map_or(0, |t| t.delivered)),
                    nodes,
                },
            );
        }
        if let Some(c) = out.get("centralized").and_then(|c| c.mean_error) {
            for e in out.values_mut() {
                e.ratio_to_centralized = e.mean_error.map(|m| m / c);
            }
        }
        out
    }
}
