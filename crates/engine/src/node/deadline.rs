//! The close of a step at its deadline: both filters (and the distributed estimators) updated with what arrived,
//! scored, recorded.

#[allow(unused_imports)]
use super::*;

impl Node {
    /// The deadline of step k: update both filters with what arrived, record metrics.
    pub(super) fn handle_deadline(&mut self, k: u64) -> Option<StepEstimate> {
        let inbox = self.inbox.close(k, &self.in_sources)?;
        if let Some(f) = self.feed.as_mut().filter(|_| self.star_sink) {
            f.heard = Some(inbox.clone());
        }
        let mut schemes = self.finish_schemes(k);
        let filters = self.filters.as_mut()?;
        let topo = &self.topo;
        let c = topo.consensus();
        let beta = c.beta.row(self.index);
        let priors = filters.clone();

        // A neighbour's measurement too far from what this node predicts is left out (the innovation gate).
        let gated: Vec<usize> = inbox
            .iter()
            .filter(|(_, p)| self.trust.gates(&*self.model, &self.obs, &priors.networked, p))
            .map(|(s, _)| *s)
            .collect();
        for s in &gated {
            self.counters.gated += 1;
            self.inbox.rx.get_mut(*s).gated += 1;
        }
        // Networked: consensus over own + received, in source order (deterministic sums).
        let mut used: Vec<(usize, &Measurement)> = Vec::new();
        if let Some(own) = self.inbox.own() {
            used.push((self.index, own));
        }
        used.extend(inbox.iter().filter(|(s, _)| !gated.contains(s)).map(|(s, p)| (*s, p)));
        used.sort_by_key(|(s, _)| *s);
        let updated = filters::update(
            &filters::Inputs {
                model: &*self.model,
                obs: &self.obs,
                policy: self.policy,
                consensus: c,
                beta,
                index: self.index,
                k,
            },
            &priors,
            &used,
            self.probes.lmi.is_some(),
        );
        if let Some(terms) = updated.lmi {
            match terms {
                Ok(Some(terms)) => {
                    let step = LmiStep {
                        k,
                        sources: used.iter().map(|(s, _)| *s).collect(),
                        terms,
                    };
                    self.probes.each().for_each(|p| p.on_lmi(&step));
                }
                Ok(None) => {}
                Err(e) => {
                    self.counters.lmi_failures += 1;
                    tracing::debug!(node = self.id, step = k, "LMI terms not computed: {e}");
                }
            }
        }
        let feasible = updated.feasible;
        let truth = self.truth.state(&*self.model);
        // The sources' ids are for the probes (the trace's `received` column); none are built when there is no probe.
        let (received, own_only): (Vec<u32>, Vec<u32>) = if self.probes.is_empty() {
            Default::default()
        } else {
            let r: Vec<u32> = used.iter().map(|(s, _)| topo.nodes()[*s].id).collect();
            let own = r.iter().copied().filter(|r| *r == self.id).collect();
            (r, own)
        };
        let t = k as f64 * topo.sim().dt();
        for (filter, post, prior, slot) in [
            (
                Filter::Networked,
                updated.networked,
                &priors.networked,
                &mut filters.networked,
            ),
            (
                Filter::Independent,
                updated.independent,
                &priors.independent,
                &mut filters.independent,
            ),
        ] {
            // A failed update keeps stepping from the prior, so that the run finishes and the rest of the figures stand.
            let (post, failed) = match post {
                Ok(g) => (g, false),
                Err(_) => (prior.clone(), true),
            };
            let networked = filter == Filter::Networked;
            let u = Update {
                node: self.id,
                step: k,
                t,
                filter,
                truth: &truth,
                prior,
                post: &post,
                failed,
                feasible: !networked || feasible,
                received: if networked { &received } else { &own_only },
            };
            let score = self.scorer.score(&u);
            self.probes.each().for_each(|p| p.on_update(&u, &score));
            *slot = if post.x.iter().chain(post.P.iter()).all(|v| v.is_finite()) {
                post
            } else {
                self.initial.clone()
            };
        }
        let run = &self.topo.estimators().run;
        for (kind, g) in [
            (crate::estimators::Kind::Independent, &filters.independent),
            (crate::estimators::Kind::Sequeira, &filters.networked),
        ] {
            if run.contains(&kind) {
                schemes.push((kind, g.x.clone()));
            }
        }
        Some(StepEstimate {
            node: self.index,
            step: k,
            truth,
            frame: self.truth.frame(),
            networked: filters.networked.clone(),
            diverged: self.scorer.metrics(Filter::Networked).diverged,
            schemes,
        })
    }
}
