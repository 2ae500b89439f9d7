//! `kcf`: the Kalman-consensus filter of Olfati-Saber (2009), "Kalman-consensus filter: optimality, stability, and
//! performance", Algorithm 1: each node's Kalman update with its own measurement plus a consensus term on the
//! neighbours' priors,
//!
//!   x̂ᵢ = x̄ᵢ + Kᵢ (zᵢ − Hᵢ x̄ᵢ) + Cᵢ Σⱼ (x̄ⱼ − x̄ᵢ),   Cᵢ = γ Pᵢ / (1 + ‖Pᵢ‖_F),
//!   Mᵢ = (I − KᵢHᵢ) Pᵢ (I − KᵢHᵢ)ᵀ + Kᵢ Rᵢ Kᵢᵀ.
//!
//! One exchange per step (round 0: the prior); further rounds carry nothing for it. The sum runs over the
//! neighbours whose prior arrived: a lost message removes its term, as a link absent from the graph would.

use nalgebra::DVector;

use super::local::own_update;
use super::registry::{Registration, Role, Scheme};
use super::{Context, Estimator, Message, StepInput};
use crate::estimate::{wrap_rows, EstimateError, Gaussian, MissingChannels};

/// `kcf` in the registry.
pub(super) const REGISTRATION: Registration = Registration {
    scheme: Scheme {
        name: "kcf",
        reference: "Olfati-Saber (2009), Kalman-consensus filter, Algorithm 1",
        messages: "round 0: the prior estimate",
        parameters: "estimators.kcf_gamma (consensus gain; default 1/(1 + max degree))",
    },
    role: Role::Node(|ctx, g, policy, p| Box::new(Kcf::new(ctx, g, policy, p.kcf_gamma))),
};

/// The Kalman consensus filter (KCF).
pub struct Kcf {
    ctx: Context,
    g: Gaussian,
    policy: MissingChannels,
    /// The consensus gain γ.
    gamma: f64,
    /// Σⱼ (x̄ⱼ − x̄ᵢ) over the priors that arrived this step.
    pull: DVector<f64>,
}

impl Kcf {
    /// The scheme at the node of `ctx`, from `initial`, with consensus gain `gamma`.
    pub fn new(ctx: Context, initial: Gaussian, policy: MissingChannels, gamma: f64) -> Kcf {
        let n = initial.x.len();
        Kcf {
            ctx,
            g: initial,
            policy,
            gamma,
            pull: DVector::zeros(n),
        }
    }
}

impl Estimator for Kcf {
    fn name(&self) -> &'static str {
        "kcf"
    }
    fn state(&self) -> Option<&Gaussian> {
        Some(&self.g)
    }
    fn state_mut(&mut self) -> Option<&mut Gaussian> {
        Some(&mut self.g)
    }
    fn begin(&mut self, _input: &StepInput<'_>) -> Result<(), EstimateError> {
        self.pull.fill(0.0);
        Ok(())
    }
    fn message(&self, round: usize) -> Option<Message> {
        (round == 0).then(|| Message::Estimate(self.g.clone()))
    }
    fn combine(&mut self, round: usize, arrived: &[(usize, &Message)], _: &StepInput<'_>) -> Result<(), EstimateError> {
        if round != 0 {
            return Ok(());
        }
        for (_, m) in arrived {
            if let Message::Estimate(o) = m {
                if o.x.len() == self.g.x.len() {
                    self.pull += self.ctx.difference(&o.x, &self.g.x);
                }
            }
        }
        Ok(())
    }
    fn finish(&mut self, input: &StepInput<'_>) -> Result<(), EstimateError> {
        let prior_P = self.g.P.clone();
        let mut post = own_update(&self.g, input, self.policy)?;
        if self.gamma != 0.0 {
            let C = &prior_P * (self.gamma / (1.0 + prior_P.norm()));
            post.x += C * &self.pull;
            wrap_rows(&mut post.x, &self.ctx.angle_states);
        }
        self.g = post;
        Ok(())
    }
}
