//! The `[consensus]` table: β (given, uniform or Metropolis), rounds, the LMI guard.

use super::*;

impl Validator {
    pub(super) fn consensus(
        &mut self,
        c: RawConsensus,
        nodes: &[NodeConfig],
        linked: &std::collections::HashSet<(usize, usize)>,
    ) -> ConsensusConfig {
        let n = nodes.len();
        let beta0 = self.prob("consensus.beta0", c.beta0, 0.0);
        if c.matrix.is_some() && (c.self_weight.is_some() || c.neighbor.is_some()) {
            self.bad(
                "consensus.matrix",
                "give either `matrix` or `self`/`neighbor`, not both",
            );
        }
        let metropolis = match c.weights.as_deref() {
            None => false,
            Some("metropolis") => true,
            Some(other) => {
                self.bad(
                    "consensus.weights",
                    format!("unknown rule `{other}`: the rule simnet knows is \"metropolis\""),
                );
                false
            }
        };
        if metropolis && (c.matrix.is_some() || c.self_weight.is_some() || c.neighbor.is_some()) {
            self.bad(
                "consensus.weights",
                "give either `weights` or `matrix` or `self`/`neighbor`, not two of them",
            );
        }
        let beta = match &c.matrix {
            _ if metropolis => metropolis_weights(nodes, linked),
            Some(m) => {
                if m.len() != n || m.iter().any(|r| r.len() != n) {
                    self.bad(
                        "consensus.matrix",
                        format!("must be {n}×{n} (one row and column per [[node]])"),
                    );
                    Beta::default()
                } else {
                    for (i, row) in m.iter().enumerate() {
                        for (j, &b) in row.iter().enumerate() {
                            if !(b >= 0.0 && b.is_finite()) {
                                self.bad(
                                    format!("consensus.matrix[{i}][{j}]"),
                                    format!("weights must be ≥ 0, got {b}"),
                                );
                            } else if b > 0.0 && i != j && !linked.contains(&(j, i)) {
                                self.bad(
                                    format!("consensus.matrix[{i}][{j}]"),
                                    format!(
                                        "weight {b} but no link carries node {}'s measurement to node {}",
                                        nodes[j].id, nodes[i].id
                                    ),
                                );
                            }
                        }
                    }
                    Beta::from_dense(m)
                }
            }
            None => {
                let s = self.non_negative("consensus.self", c.self_weight, 1.0);
                let nb = self.non_negative("consensus.neighbor", c.neighbor, 0.0);
                let mut rows: Vec<Vec<(usize, f64)>> = (0..n)
                    .map(|i| {
                        if nodes[i].role.senses() {
                            vec![(i, s)]
                        } else {
                            Vec::new()
                        }
                    })
                    .collect();
                for &(j, i) in linked {
                    if nodes[j].role.senses() {
                        // An estimator without a sensor of its own gives its sources the whole weight.
                        let w = if nodes[i].role == Role::Estimator && c.neighbor.is_none() {
                            1.0
                        } else {
                            nb
                        };
                        rows[i].push((j, w));
                    }
                }
                Beta::from_rows(rows)
            }
        };
        for (i, node) in nodes.iter().enumerate() {
            if node.role.estimates() && beta.row(i).is_empty() && c.matrix.is_some() {
                self.bad(
                    format!("consensus.matrix[{i}]"),
                    format!("node {} estimates but gives every measurement weight 0", node.id),
                );
            }
        }
        let l = c.lmi.unwrap_or_default();
        let lmi = LmiConfig {
            alpha: self.positive("consensus.lmi.alpha", l.alpha, 1000.0),
            gamma: self.non_negative("consensus.lmi.gamma", l.gamma, 1e-5),
            enabled: l.enabled.unwrap_or(true),
        };
        let inflation = self.positive("consensus.inflation", c.inflation, 1e3);
        if inflation < 1.0 {
            self.bad(
                "consensus.inflation",
                format!("λ inflates a missing channel and must be ≥ 1, got {inflation}"),
            );
        }
        let gate = match c.gate {
            Some(p) if !(p > 0.0 && p < 1.0) => {
                self.bad(
                    "consensus.gate",
                    format!("is the probability of the χ² quantile an innovation must stay under, in (0, 1), got {p}"),
                );
                None
            }
            g => g,
        };
        ConsensusConfig {
            beta0,
            beta,
            lmi,
            inflation,
            gate,
        }
    }
}

/// β from the graph's Metropolis–Hastings weights ([`crate::estimators::metropolis`], over the nodes linked with
/// each node either way). β weighs measurements, so each row keeps the measurements node i can have — its own if it
/// senses, its sensing in-neighbours' — renormalised to sum to one.
fn metropolis_weights(nodes: &[NodeConfig], linked: &std::collections::HashSet<(usize, usize)>) -> Beta {
    let mut around: Vec<std::collections::BTreeSet<usize>> = vec![Default::default(); nodes.len()];
    for &(a, b) in linked {
        around[a].insert(b);
        around[b].insert(a);
    }
    let around: Vec<Vec<usize>> = around.into_iter().map(|s| s.into_iter().collect()).collect();
    let rows = crate::estimators::metropolis(&around)
        .into_iter()
        .enumerate()
        .map(|(i, (weights, own))| {
            let mut row: Vec<(usize, f64)> = Vec::new();
            if nodes[i].role.senses() {
                row.push((i, own));
            }
            row.extend(
                weights
                    .into_iter()
                    .filter(|&(j, _)| linked.contains(&(j, i)) && nodes[j].role.senses()),
            );
            let total: f64 = row.iter().map(|(_, w)| w).sum();
            if total > 0.0 {
                row.iter_mut().for_each(|(_, w)| *w /= total);
            }
            row
        })
        .collect();
    Beta::from_rows(rows)
}
