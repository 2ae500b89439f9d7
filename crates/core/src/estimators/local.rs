//! `independent`: the node's own Kalman filter (Joseph form), the baseline every scheme is measured against.

use super::registry::{Registration, Role, Scheme};
use super::{Estimator, Message, StepInput};
use crate::estimate::{EstimateError, Gaussian, MissingChannels};

/// `independent` in the registry: the node runs it as its second filter beside `sequeira` ([`super::Sequeira`]).
pub(super) const REGISTRATION: Registration = Registration {
    scheme: Scheme {
        name: "independent",
        reference: "the node's own Kalman filter (Joseph form), the baseline of Sequeira (2023)",
        messages: "none",
        parameters: "-",
    },
    role: Role::Filters,
};

/// The node's own filter alone: the baseline.
#[derive(Debug, Clone)]
pub struct Local {
    g: Gaussian,
    policy: MissingChannels,
}

impl Local {
    /// The filter from `initial`, missing rows handled by `policy`.
    pub fn new(initial: Gaussian, policy: MissingChannels) -> Local {
        Local { g: initial, policy }
    }
}

/// The Kalman update with the node's own measurement (linearised about `g`), or the prior when it has none
/// (intermittent observation).
pub(super) fn own_update(
    g: &Gaussian,
    input: &StepInput<'_>,
    policy: MissingChannels,
) -> Result<Gaussian, EstimateError> {
    match input.own {
        Some(m) => input.update(g, input.node, m, policy),
        None => Ok(g.clone()),
    }
}

impl Estimator for Local {
    fn name(&self) -> &'static str {
        "independent"
    }
    fn state(&self) -> Option<&Gaussian> {
        Some(&self.g)
    }
    fn state_mut(&mut self) -> Option<&mut Gaussian> {
        Some(&mut self.g)
    }
    fn message(&self, _round: usize) -> Option<Message> {
        None
    }
    fn combine(&mut self, _: usize, _: &[(usize, &Message)], _: &StepInput<'_>) -> Result<(), EstimateError> {
        Ok(())
    }
    fn finish(&mut self, input: &StepInput<'_>) -> Result<(), EstimateError> {
        self.g = own_update(&self.g, input, self.policy)?;
        Ok(())
    }
}
