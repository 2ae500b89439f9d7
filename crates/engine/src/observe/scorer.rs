//! The truth against each update: the figures `summary.json` reports for each filter.

use std::sync::Arc;

use super::metrics::FilterMetrics;
use super::{Filter, Score, Update};
use crate::estimate::nees;
use crate::model::Model;

/// Scores every update of one node's two filters and keeps their running figures.
static EMPTY: FilterMetrics = FilterMetrics::EMPTY;

pub struct Scorer {
    model: Arc<dyn Model>,
    angle_states: Vec<bool>,
    /// The error rows ([`crate::model::Report::error`] without building the layout each step).
    layout: crate::model::FusionLayout,
    /// Steps before this one are the burn-in: tracked for divergence only.
    burn_in_steps: u64,
    /// A filter whose trace P exceeds this is marked diverged.
    divergence_trace: f64,
    networked: FilterMetrics,
    independent: FilterMetrics,
    /// The distributed estimators', by kind.
    schemes: Vec<(crate::estimators::Kind, FilterMetrics)>,
}

impl Scorer {
    pub fn new(model: Arc<dyn Model>, burn_in_steps: u64, divergence_trace: f64) -> Scorer {
        Scorer {
            angle_states: model.angle_states(),
            layout: model.fusion(),
            model,
            burn_in_steps,
            divergence_trace,
            networked: FilterMetrics::default(),
            independent: FilterMetrics::default(),
            schemes: Vec::new(),
        }
    }

    /// Score `u` and add it to its filter's figures.
    pub fn score(&mut self, u: &Update<'_>) -> Score {
        let m = match u.filter {
            Filter::Networked => &mut self.networked,
            Filter::Independent => &mut self.independent,
            Filter::Scheme(kind) => match self.schemes.iter().position(|(k, _)| *k == kind) {
                Some(i) => &mut self.schemes[i].1,
                None => {
                    self.schemes.push((kind, FilterMetrics::default()));
                    &mut self.schemes.last_mut().expect("just pushed").1
                }
            },
        };
        if u.failed {
            m.mark_diverged();
        }
        let (tp, tq) = (u.prior.P.trace(), u.post.P.trace());
        if tq > self.divergence_trace || tp > self.divergence_trace || !tq.is_finite() {
            m.mark_diverged();
        }
        let error = self.layout.error(u.truth, &u.post.x);
        let v = nees(u.post, &self.model.aligned(u.truth, &u.post.x), &self.angle_states);
        m.record(u.step >= self.burn_in_steps, error, tp, tq, v, u.feasible);
        Score {
            error,
            nees: v,
            trace_p_prior: tp,
            trace_p_post: tq,
            diverged: m.diverged,
        }
    }

    pub fn metrics(&self, f: Filter) -> &FilterMetrics {
        match f {
            Filter::Networked => &self.networked,
            Filter::Independent => &self.independent,
            Filter::Scheme(kind) => self.schemes.iter().find(|(k, _)| *k == kind).map_or(&EMPTY, |(_, m)| m),
        }
    }

    /// Every distributed estimator's figures, by kind.
    pub fn scheme_metrics(&self) -> &[(crate::estimators::Kind, FilterMetrics)] {
        &self.schemes
    }
}
