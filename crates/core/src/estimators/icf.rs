//! `icf`: the information-weighted consensus filter of Kamal, Farrell & Roy-Chowdhury (2013), "Information weighted
//! consensus filters and their application in distributed camera networks", IEEE TAC 58(12), Algorithm 1:
//!
//!   Vᵢ⁰ = Jᵢ⁻ / N + Uᵢ,   vᵢ⁰ = Jᵢ⁻ x̄ᵢ / N + uᵢ   (Jᵢ⁻ = Pᵢ⁻¹, Uᵢ = HᵢᵀRᵢ⁻¹Hᵢ, uᵢ = HᵢᵀRᵢ⁻¹zᵢ),
//!   L rounds of average consensus on (Vᵢ, vᵢ),   x̂ᵢ = Vᵢ⁻¹ vᵢ,   Jᵢ⁺ = N Vᵢ.
//!
//! The consensus step is vᵢ ← vᵢ + Σⱼ πᵢⱼ (vⱼ − vᵢ) with Metropolis weights πᵢⱼ in place of the paper's uniform ε
//! (both converge to the average on a connected graph; Metropolis needs no bound on the degree). A message that did
//! not arrive drops its term — its weight stays with the node, the update's own form — so the average is no longer
//! preserved exactly under loss: that bias is what a lossy network does to ICF.

use super::registry::{Registration, Role, Scheme};
use super::{Context, Estimator, Info, Message, StepInput};
use crate::estimate::{wrap_rows, EstimateError, Gaussian};

/// `icf` in the registry.
pub(super) const REGISTRATION: Registration = Registration {
    scheme: Scheme {
        name: "icf",
        reference: "Kamal, Farrell & Roy-Chowdhury (2013), IEEE TAC 58(12), Algorithm 1",
        messages: "every round: the information pair (V, v)",
        parameters: "estimators.rounds; Metropolis weights",
    },
    role: Role::Node(|ctx, g, _, _| Box::new(Icf::new(ctx, g))),
};

/// The information consensus filter (ICF).
pub struct Icf {
    ctx: Context,
    g: Gaussian,
    /// (Vᵢ, vᵢ) during the step's rounds.
    v: Info,
}

impl Icf {
    /// The scheme at the node of `ctx`, from `initial`.
    pub fn new(ctx: Context, initial: Gaussian) -> Icf {
        let n = initial.x.len();
        Icf {
            ctx,
            g: initial,
            v: Info::zero(n),
        }
    }
}

impl Estimator for Icf {
    fn name(&self) -> &'static str {
        "icf"
    }
    fn state(&self) -> Option<&Gaussian> {
        Some(&self.g)
    }
    fn state_mut(&mut self) -> Option<&mut Gaussian> {
        Some(&mut self.g)
    }
    fn begin(&mut self, input: &StepInput<'_>) -> Result<(), EstimateError> {
        let mut v = Info::of(&self.g)?.scaled(1.0 / self.ctx.nodes as f64);
        if let Some(m) = input.own {
            v.add(1.0, &input.information(&self.g, input.node, m)?);
        }
        self.v = v;
        Ok(())
    }
    fn message(&self, _round: usize) -> Option<Message> {
        Some(Message::Information(self.v.clone()))
    }
    fn combine(&mut self, _: usize, arrived: &[(usize, &Message)], _: &StepInput<'_>) -> Result<(), EstimateError> {
        let own = self.v.clone();
        for (j, m) in arrived {
            if let Message::Information(o) = m {
                if o.y.len() == own.y.len() {
                    let w = self.ctx.weight(*j);
                    match o.toward(&self.g.x, &self.ctx) {
                        Some(mv) => self.v.add(w, &o.moved(&mv)),
                        None => self.v.add(w, o),
                    }
                    self.v.add(-w, &own);
                }
            }
        }
        Ok(())
    }
    fn finish(&mut self, _input: &StepInput<'_>) -> Result<(), EstimateError> {
        let g = self.v.gaussian()?;
        self.g = Gaussian {
            P: g.P / self.ctx.nodes as f64,
            x: g.x,
        };
        wrap_rows(&mut self.g.x, &self.ctx.angle_states);
        Ok(())
    }
}
