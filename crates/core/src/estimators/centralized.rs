//! `centralized`: one fusion center that updates with every sensing node's measurement of the step, stacked — the
//! optimum for a linear model (the Kalman filter of the whole network). In information form:
//!
//!   Y = P̄⁻¹ + Σₗ HₗᵀRₗ⁻¹Hₗ,   x̂ = x̄ + Y⁻¹ Σₗ HₗᵀRₗ⁻¹ (zₗ − Hₗ x̄),   P = Y⁻¹,
//!
//! equal to the Kalman update with the stacked measurement and a block-diagonal R. Every node sends its measurement
//! to the center in round 0; only the center holds an estimate. Whether the measurements reach it without loss
//! (`centralized`, the reference) or over lossy links (`centralized-net`) is the network's business, not this
//! file's.

use super::registry::{Registration, Role, Scheme};
use super::{Context, Estimator, Info, Message, StepInput};
use crate::estimate::{symmetrize, wrap_rows, EstimateError, Gaussian};
use crate::model::Measurement;

/// `centralized` in the registry: the observer hosts it, every measurement delivered whole.
pub(super) const REGISTRATION: Registration = Registration {
    scheme: Scheme {
        name: "centralized",
        reference: "one fusion center, every sensing node's measurement stacked (the Kalman filter of the network)",
        messages: "round 0: the measurement, to the center",
        parameters:
            "estimators.sink (the center; default: the first sensing node); every measurement reaches it with no loss",
    },
    role: Role::Center,
};

/// `centralized-net` in the registry: the same center, over the scenario's medium.
pub(super) const NET_REGISTRATION: Registration = Registration {
    scheme: Scheme {
        name: "centralized-net",
        reference: "the same fusion center, reached over lossy links: a star from every sensing node to the sink",
        messages: "round 0: the measurement, to the sink, by the step's deadline",
        parameters:
            "estimators.sink; the scenario's link to the sink where one exists, else a star link with [link]'s faults",
    },
    role: Role::Center,
};

/// The centralized Kalman filter: every node's measurement stacked, one filter.
pub struct Centralized {
    ctx: Context,
    /// The center's filter; `None` at a node that only reports.
    g: Option<Gaussian>,
    own: Option<Measurement>,
    /// What arrived, by source.
    received: Vec<(usize, Measurement)>,
}

impl Centralized {
    /// At the center (`initial` is its prior) or at a reporting node (`None`).
    pub fn new(ctx: Context, initial: Option<Gaussian>) -> Centralized {
        Centralized {
            ctx,
            g: initial,
            own: None,
            received: Vec::new(),
        }
    }
}

impl Estimator for Centralized {
    fn name(&self) -> &'static str {
        "centralized"
    }
    fn state(&self) -> Option<&Gaussian> {
        self.g.as_ref()
    }
    fn state_mut(&mut self) -> Option<&mut Gaussian> {
        self.g.as_mut()
    }
    fn begin(&mut self, input: &StepInput<'_>) -> Result<(), EstimateError> {
        self.own = input.own.cloned();
        self.received.clear();
        Ok(())
    }
    fn message(&self, round: usize) -> Option<Message> {
        // The center's own measurement is used where it is taken.
        (round == 0 && self.g.is_none())
            .then(|| self.own.clone().map(Message::Measurement))
            .flatten()
    }
    fn combine(&mut self, round: usize, arrived: &[(usize, &Message)], _: &StepInput<'_>) -> Result<(), EstimateError> {
        if round == 0 && self.g.is_some() {
            for (s, m) in arrived {
                if let Message::Measurement(m) = m {
                    self.received.push((*s, m.clone()));
                }
            }
        }
        Ok(())
    }
    fn finish(&mut self, input: &StepInput<'_>) -> Result<(), EstimateError> {
        let Some(prior) = &self.g else { return Ok(()) };
        let n = prior.x.len();
        let mut Y = Info::of(prior)?.Y;
        let mut innovation = nalgebra::DVector::zeros(n);
        let own = self.own.iter().map(|m| (self.ctx.index, m));
        for (s, m) in own.chain(self.received.iter().map(|(s, m)| (*s, m))) {
            let info = input.information(prior, s, m)?;
            innovation += &info.y - &info.Y * &prior.x;
            Y += info.Y;
        }
        let mut g = Info {
            Y,
            y: nalgebra::DVector::zeros(n),
        }
        .gaussian()?;
        symmetrize(&mut g.P);
        g.x = &prior.x + &g.P * innovation;
        wrap_rows(&mut g.x, &self.ctx.angle_states);
        self.g = Some(g);
        Ok(())
    }
}
