//! `ci`: each node updates with its own measurement, then for L rounds fuses its neighbours' estimates with its own
//! by covariance intersection with consensus weights (Julier & Uhlmann 1997; the consensus on information of
//! Battistelli & Chisci 2014): P⁻¹ = Σⱼ πᵢⱼ Pⱼ⁻¹, x = P Σⱼ πᵢⱼ Pⱼ⁻¹ xⱼ, over the node and the estimates that arrived,
//! the weights of the missing renormalised away. Angle states of a neighbour's estimate are unwrapped towards the
//! node's own first.

use super::local::own_update;
use super::registry::{Registration, Role, Scheme};
use super::{renormalised, Context, Estimator, Info, Message, StepInput};
use crate::estimate::{wrap_rows, EstimateError, Gaussian, MissingChannels};

/// `ci` in the registry.
pub(super) const REGISTRATION: Registration = Registration {
    scheme: Scheme {
        name: "ci",
        reference: "covariance intersection with consensus weights (Julier & Uhlmann 1997; Battistelli & Chisci 2014)",
        messages: "every round: the estimate (x, P)",
        parameters: "estimators.rounds; Metropolis weights",
    },
    role: Role::Node(|ctx, g, policy, _| Box::new(Ci::new(ctx, g, policy))),
};

/// Covariance intersection of the neighbours' estimates after the node's own update.
pub struct Ci {
    ctx: Context,
    g: Gaussian,
    policy: MissingChannels,
}

impl Ci {
    /// The scheme at the node of `ctx`, from `initial`, missing rows handled by `policy`.
    pub fn new(ctx: Context, initial: Gaussian, policy: MissingChannels) -> Ci {
        Ci {
            ctx,
            g: initial,
            policy,
        }
    }
}

impl Estimator for Ci {
    fn name(&self) -> &'static str {
        "ci"
    }
    fn state(&self) -> Option<&Gaussian> {
        Some(&self.g)
    }
    fn state_mut(&mut self) -> Option<&mut Gaussian> {
        Some(&mut self.g)
    }
    fn begin(&mut self, input: &StepInput<'_>) -> Result<(), EstimateError> {
        self.g = own_update(&self.g, input, self.policy)?;
        Ok(())
    }
    fn message(&self, _round: usize) -> Option<Message> {
        Some(Message::Estimate(self.g.clone()))
    }
    fn combine(&mut self, _: usize, arrived: &[(usize, &Message)], _: &StepInput<'_>) -> Result<(), EstimateError> {
        let n = self.g.x.len();
        let mut theirs = Vec::with_capacity(arrived.len());
        for (j, m) in arrived {
            if let Message::Estimate(o) = m {
                if o.x.len() == n && o.P.shape() == (n, n) {
                    let o = Gaussian {
                        x: self.ctx.aligned(&o.x, &self.g.x).into_owned(),
                        P: o.P.clone(),
                    };
                    theirs.push((*j, Info::of(&o)?));
                }
            }
        }
        let own = Info::of(&self.g)?;
        let mut fused = Info::zero(n);
        for (w, info) in renormalised(&self.ctx, &own, theirs.iter().map(|(j, t)| (*j, t))) {
            fused.add(w, info);
        }
        let mut g = fused.gaussian()?;
        wrap_rows(&mut g.x, &self.ctx.angle_states);
        self.g = g;
        Ok(())
    }
}
