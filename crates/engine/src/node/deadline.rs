//! The close of a step at its deadline: both filters and the distributed estimators finish with what arrived,
//! each one scored, and the step recorded.

#[allow(unused_imports)]
use super::*;
use crate::estimators::{Estimator, Kind, StepInput};
use crate::observe::SchemeEstimate;

impl Node {
    /// The deadline of step k: every estimator finishes with what arrived; the updates are scored and recorded.
    pub(super) fn handle_deadline(&mut self, k: u64) -> Option<StepEstimate> {
        let inbox = self.inbox.close(k, &self.in_sources)?;
        if let Some(f) = self.feed.as_mut().filter(|_| self.star_sink) {
            f.heard = Some(inbox.iter().cloned().collect());
        }
        // A neighbour's measurement too far from what this node predicts is left out (the innovation gate): the
        // networked filter's prior, or the node's own where the model leaves it no networked filter.
        let prior = self
            .filters
            .as_ref()
            .and_then(|f| f.networked.as_ref().map_or(f.independent.state(), |n| n.state()));
        let gated: Vec<usize> = match prior {
            Some(prior) => inbox
                .iter()
                .filter(|(s, p)| self.trust.gates(&*self.model, &self.obs, prior, Site { node: *s }, p))
                .map(|(s, _)| *s)
                .collect(),
            None => Vec::new(),
        };
        for s in &gated {
            self.counters.gated += 1;
            self.inbox.rx.get_mut(*s).gated += 1;
        }
        // Own + received, in source order (deterministic sums).
        let mut used: Vec<(usize, &Measurement)> = Vec::new();
        if let Some(own) = self.inbox.own() {
            used.push((self.index, own));
        }
        used.extend(inbox.iter().filter(|(s, _)| !gated.contains(s)).map(|(s, p)| (*s, p)));
        used.sort_by_key(|(s, _)| *s);
        let input = StepInput {
            model: &*self.model,
            obs: &self.obs,
            node: self.index,
            own: self.inbox.own(),
            heard: &used,
            step: k,
        };
        let posts = match self.schemes.is_empty() {
            true => None,
            false => self.schemes.finish(k, &input, &self.wire),
        };
        let filters = self.filters.as_mut()?;
        let priors = (
            filters.networked.as_ref().and_then(|n| n.state()).cloned(),
            filters.independent.state()?.clone(),
        );
        let (networked, guarded) = match filters.networked.as_mut() {
            Some(n) => {
                n.record_terms(self.probes.lmi.is_some());
                let r = n.finish(&input);
                (Some(r), n.take_guarded())
            }
            None => (None, None),
        };
        let independent = filters.independent.finish(&input);
        let feasible = guarded.as_ref().is_none_or(|g| g.feasible);
        match guarded.and_then(|g| g.terms) {
            Some(Ok(Some(terms))) => {
                let step = LmiStep {
                    k,
                    sources: used.iter().map(|(s, _)| *s).collect(),
                    terms,
                };
                self.probes.each().for_each(|p| p.on_lmi(&step));
            }
            Some(Err(e)) => {
                self.counters.lmi_failures += 1;
                tracing::debug!(node = self.id, step = k, "LMI terms not computed: {e}");
            }
            Some(Ok(None)) | None => {}
        }
        let truth = self.truth.state(&*self.model);
        // The sources' ids are for the probes (the trace's `received` column); none are built when there is no probe.
        let (received, own_only): (Vec<u32>, Vec<u32>) = if self.probes.is_empty() {
            Default::default()
        } else {
            let r: Vec<u32> = used.iter().map(|(s, _)| self.topo.nodes()[*s].id).collect();
            let own = r.iter().copied().filter(|r| *r == self.id).collect();
            (r, own)
        };
        let t = k as f64 * self.topo.sim().dt();
        let networked = match (filters.networked.as_mut(), priors.0, networked) {
            (Some(n), Some(prior), Some(r)) => Some((Filter::Networked, n as &mut dyn Estimator, prior, r.is_err())),
            _ => None,
        };
        let independent = Some((
            Filter::Independent,
            &mut filters.independent as &mut dyn Estimator,
            priors.1,
            independent.is_err(),
        ));
        let both = [networked, independent];
        for (filter, est, prior, failed) in both.into_iter().flatten() {
            // A failed update keeps stepping from the prior (the estimator left it as it was), so that the run
            // finishes and the rest of the figures stand; a posterior is brought back onto the model's manifold.
            if !failed {
                est.state_mut().into_iter().for_each(|g| input.model.normalize(g));
            }
            let Some(post) = est.state() else { continue };
            let networked = filter == Filter::Networked;
            let u = Update {
                node: self.id,
                step: k,
                t,
                filter,
                truth: &truth,
                prior: &prior,
                post,
                failed,
                feasible: !networked || feasible,
                received: if networked { &received } else { &own_only },
            };
            let score = self.scorer.score(&u);
            self.probes.each().for_each(|p| p.on_update(&u, &score));
            if !post.x.iter().chain(post.P.iter()).all(|v| v.is_finite()) {
                est.reset(self.initial.clone());
            }
        }
        self.inbox.recycle(inbox);
        let mut schemes = self.score_schemes(k, posts, &truth);
        let filters = self.filters.as_ref()?;
        let run = &self.topo.estimators().run;
        for (kind, est) in [
            (Kind::Independent, Some(&filters.independent as &dyn Estimator)),
            (Kind::Sequeira, filters.networked.as_ref().map(|n| n as &dyn Estimator)),
        ] {
            if let Some(g) = est.and_then(|e| e.state()).filter(|_| run.contains(&kind)) {
                schemes.push(SchemeEstimate {
                    kind,
                    x: g.x.clone(),
                    P: Some(g.P.clone()),
                });
            }
        }
        Some(StepEstimate {
            node: self.index,
            step: k,
            truth,
            frame: self.truth.frame(),
            networked: filters.networked.as_ref().and_then(|n| n.state()).cloned(),
            diverged: self.scorer.metrics(Filter::Networked).diverged,
            schemes,
        })
    }
}
