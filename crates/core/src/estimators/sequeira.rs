//! `sequeira`: the β-weighted consensus of Sequeira (2023) over the measurements that reached the node by the
//! step's deadline (its own among them), eqs. (5)–(10), under the LMI guard (17), (19): where the guard fails the
//! node takes the independent update that step (§5).

use nalgebra::DVector;

use super::registry::{Registration, Role, Scheme};
use super::{Estimator, Message, StepInput};
use crate::estimate::{guarded_update, EstimateError, Gaussian, LmiTerms, MissingChannels, Source};
use crate::model::Site;

/// Why a model whose nodes observe differently is refused: eqs. (5)–(10) form one gain K from one H for every source.
pub const NOT_ALIKE: &str =
    "Sequeira (2023) eqs. (5)–(10) form one gain from one h for every source, and this model's nodes observe differently (Sensing::observes_alike)";

/// `sequeira` in the registry: the node runs it as its networked filter, over the measurements its links carry.
pub(super) const REGISTRATION: Registration = Registration {
    scheme: Scheme {
        name: "sequeira",
        reference: "Sequeira (2023), Sensors 23(18) 7838: beta-weighted consensus, eqs. 5-10, LMI guard (17), (19)",
        messages: "round 0: the measurement",
        parameters: "consensus.beta0, consensus.self / neighbor or matrix, consensus.lmi",
    },
    role: Role::Filters,
};

/// The parameters of one node's consensus update.
#[derive(Debug, Clone, PartialEq)]
pub struct SequeiraParams {
    /// This node, by index: its own measurement is the guard's fallback.
    pub index: usize,
    /// β₀: the weight of the prior (eq. (5)).
    pub beta0: f64,
    /// This node's row of β: (source, βᵢⱼ), sorted by source; a source with no entry weighs 0.
    pub beta: Vec<(usize, f64)>,
    /// α and γ of (15), (17), (19).
    pub alpha: f64,
    /// γ of (15): the bound's growth per step.
    pub gamma: f64,
    /// The guard refuses an update that fails (17) or (19).
    pub guard: bool,
    /// How a row no source delivered is handled.
    pub policy: MissingChannels,
}

impl SequeiraParams {
    fn weight(&self, j: usize) -> f64 {
        super::weight_in(&self.beta, j)
    }
}

/// What the last update found beside its posterior.
#[derive(Debug, Clone)]
pub struct Guarded {
    /// (17) and (19) held, or the guard is off.
    pub feasible: bool,
    /// The β-independent LMI terms over every measurement that arrived, when asked for ([`Sequeira::record_terms`]);
    /// `Ok(None)` on a step without data.
    pub terms: Option<Result<Option<LmiTerms>, EstimateError>>,
}

/// One node's networked filter: consensus over whatever arrived.
#[derive(Debug, Clone)]
pub struct Sequeira {
    g: Gaussian,
    params: SequeiraParams,
    record_terms: bool,
    last: Option<Guarded>,
}

impl Sequeira {
    /// The filter from `initial`.
    pub fn new(initial: Gaussian, params: SequeiraParams) -> Sequeira {
        Sequeira {
            g: initial,
            params,
            record_terms: false,
            last: None,
        }
    }

    /// Whether each update also computes the LMI terms of every source that arrived, whatever its β (so that a
    /// search over β may weigh it): [`Guarded::terms`].
    pub fn record_terms(&mut self, on: bool) {
        self.record_terms = on;
    }

    /// What the last update found; taken, so that a step without an update reports none.
    pub fn take_guarded(&mut self) -> Option<Guarded> {
        self.last.take()
    }
}

impl Estimator for Sequeira {
    fn name(&self) -> &'static str {
        "sequeira"
    }
    fn state(&self) -> Option<&Gaussian> {
        Some(&self.g)
    }
    fn state_mut(&mut self) -> Option<&mut Gaussian> {
        Some(&mut self.g)
    }
    /// The measurement travels on the node's own stream (the round-0 datagram every scheme's messages ride with).
    fn message(&self, _round: usize) -> Option<Message> {
        None
    }
    fn combine(&mut self, _: usize, _: &[(usize, &Message)], _: &StepInput<'_>) -> Result<(), EstimateError> {
        Ok(())
    }
    /// The consensus update over `input.heard`, each linearised about the prior (the attitude EKF), summed in source
    /// order so that sums are deterministic.
    fn finish(&mut self, input: &StepInput<'_>) -> Result<(), EstimateError> {
        let p = &self.params;
        let prior = &self.g;
        if !input.model.observes_alike() {
            return Err(EstimateError::Unsupported {
                scheme: "sequeira",
                why: NOT_ALIKE,
            });
        }
        let zs: Vec<&DVector<f64>> = input.heard.iter().map(|(_, m)| &m.z).collect();
        // Every node observes alike: the node's own site linearises every source's measurement.
        let (obs, z) = input
            .model
            .linearize_at(input.obs, prior, Site { node: input.node }, &zs);
        let sources: Vec<Source<'_>> = input
            .heard
            .iter()
            .zip(&z)
            .filter(|((s, _), _)| p.weight(*s) > 0.0)
            .map(|((s, m), z)| Source {
                beta: p.weight(*s),
                z,
                present: &m.present,
            })
            .collect();
        // The independent update if (17)/(19) fail: the own measurement, else the highest-weight source.
        let own = input.heard.iter().position(|(s, _)| *s == p.index).map(|i| Source {
            beta: 1.0,
            z: &z[i],
            present: &input.heard[i].1.present,
        });
        let fallback = own.or_else(|| sources.iter().max_by(|a, b| a.beta.total_cmp(&b.beta)).cloned());
        let terms = self.record_terms.then(|| {
            let data: Vec<(&DVector<f64>, &[bool])> = input
                .heard
                .iter()
                .zip(&z)
                .map(|((_, m), z)| (z.as_ref(), &m.present[..]))
                .collect();
            LmiTerms::new(prior, &obs, p.beta0, &data, p.policy, input.step, p.alpha, p.gamma)
        });
        let guard = p.guard.then_some((p.alpha, p.gamma));
        let (post, feasible) = guarded_update(
            prior,
            &obs,
            p.beta0,
            &sources,
            fallback.as_ref(),
            p.policy,
            input.step,
            guard,
        );
        self.last = Some(Guarded { feasible, terms });
        self.g = post?;
        Ok(())
    }
}
