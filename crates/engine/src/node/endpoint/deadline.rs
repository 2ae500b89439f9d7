//! The close of a step at its deadline: both filters and the distributed estimators finish with what arrived, and
//! each update is handed out for the testbed's observer to score and record.

#[allow(unused_imports)]
use super::*;
use crate::estimators::{Estimator, Kind, StepInput};
use crate::observe::SchemeEstimate;

/// One estimator's update at the deadline of a step.
#[derive(Debug, Clone)]
pub struct Updated {
    pub filter: Filter,
    pub prior: Gaussian,
    /// The posterior; the prior carried on when the update `failed`.
    pub post: Gaussian,
    pub failed: bool,
    /// (17) and (19) held (always true but for the networked filter).
    pub feasible: bool,
    /// Ids of the sources whose measurements it used (when [`Listening::sources`]; none for a distributed
    /// estimator, whose messages are not measurements).
    pub received: Vec<u32>,
}

/// A step an estimating node closed: its updates, in the order `trace.csv` lists them (networked, independent, the
/// distributed estimators), and what the fusion observer takes of it.
#[derive(Debug, Clone)]
pub struct Closing {
    /// The β-independent LMI terms of the networked update (when [`Listening::lmi`]).
    pub lmi: Option<LmiStep>,
    pub updates: Vec<Updated>,
    /// The networked filter's estimate.
    pub networked: Option<Gaussian>,
    /// The node's two filters' estimates where the run lists them as schemes (`independent`, `sequeira`).
    pub filters: Vec<SchemeEstimate>,
}

impl Endpoint {
    /// The deadline of step k: every estimator finishes with what arrived; the updates are handed out (none from a
    /// node that does not estimate, or was down).
    pub(crate) fn handle_deadline(&mut self, k: u64) -> Option<Closing> {
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
                n.record_terms(self.listening.lmi);
                let r = n.finish(&input);
                (Some(r), n.take_guarded())
            }
            None => (None, None),
        };
        let independent = filters.independent.finish(&input);
        let feasible = guarded.as_ref().is_none_or(|g| g.feasible);
        let mut lmi = None;
        match guarded.and_then(|g| g.terms) {
            Some(Ok(Some(terms))) => {
                lmi = Some(LmiStep {
                    k,
                    sources: used.iter().map(|(s, _)| *s).collect(),
                    terms,
                });
            }
            Some(Err(e)) => {
                self.counters.lmi_failures += 1;
                tracing::debug!(node = self.id, step = k, "LMI terms not computed: {e}");
            }
            Some(Ok(None)) | None => {}
        }
        // The sources' ids are for the observer's probes (the trace's `received` column); built only when listened to.
        let (received, own_only): (Vec<u32>, Vec<u32>) = if !self.listening.sources {
            Default::default()
        } else {
            let r: Vec<u32> = used.iter().map(|(s, _)| self.topo.nodes()[*s].id).collect();
            let own = r.iter().copied().filter(|r| *r == self.id).collect();
            (r, own)
        };
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
        let mut updates = Vec::with_capacity(2 + self.schemes.kinds().count());
        for (filter, est, prior, failed) in [networked, independent].into_iter().flatten() {
            // A failed update keeps stepping from the prior (the estimator left it as it was), so that the run
            // finishes and the rest of the figures stand; a posterior is brought back onto the model's manifold.
            if !failed {
                est.state_mut().into_iter().for_each(|g| input.model.normalize(g));
            }
            let Some(post) = est.state() else { continue };
            let networked = filter == Filter::Networked;
            updates.push(Updated {
                filter,
                prior,
                post: post.clone(),
                failed,
                feasible: !networked || feasible,
                received: if networked { received.clone() } else { own_only.clone() },
            });
            if !post.x.iter().chain(post.P.iter()).all(|v| v.is_finite()) {
                est.reset(self.initial.clone());
            }
        }
        self.inbox.recycle(inbox);
        if let Some(posts) = posts.filter(|_| self.role.estimates()) {
            let kinds = self.schemes.kinds();
            updates.extend(kinds.zip(posts).map(|(kind, (prior, post, failed))| Updated {
                filter: Filter::Scheme(kind),
                prior,
                post,
                failed,
                feasible: true,
                received: Vec::new(),
            }));
        }
        let filters = self.filters.as_ref()?;
        let run = &self.topo.estimators().run;
        let mut own = Vec::new();
        for (kind, est) in [
            (Kind::Independent, Some(&filters.independent as &dyn Estimator)),
            (Kind::Sequeira, filters.networked.as_ref().map(|n| n as &dyn Estimator)),
        ] {
            if let Some(g) = est.and_then(|e| e.state()).filter(|_| run.contains(&kind)) {
                own.push(SchemeEstimate {
                    kind,
                    x: g.x.clone(),
                    P: Some(g.P.clone()),
                });
            }
        }
        Some(Closing {
            lmi,
            updates,
            networked: filters.networked.as_ref().and_then(|n| n.state()).cloned(),
            filters: own,
        })
    }
}
