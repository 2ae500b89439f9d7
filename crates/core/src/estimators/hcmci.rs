//! `hcmci`: hybrid consensus on measurements and information, Battistelli, Chisci, Mugnai, Farina & Graziano (2015),
//! "Consensus-based linear and nonlinear filtering", IEEE TAC 60(5): the prior's information (Ωᵢ, qᵢ) and the
//! measurement's (δΩᵢ, δqᵢ) = (HᵢᵀRᵢ⁻¹Hᵢ, HᵢᵀRᵢ⁻¹zᵢ) are each averaged over L rounds with consensus weights πᵢⱼ,
//! then combined as
//!
//!   Ωᵢ = Ωᵢ^L + ω δΩᵢ^L,   qᵢ = qᵢ^L + ω δqᵢ^L,   x̂ᵢ = Ωᵢ⁻¹ qᵢ,   Pᵢ = Ωᵢ⁻¹.
//!
//! ω = N (the default) makes the measurement part the network's sum once consensus has converged; the averaging of
//! the priors is covariance intersection, which keeps the filter stable for any L ≥ 1 (the paper's result). A
//! message that did not arrive is left out and the remaining weights renormalised, so that each round stays a
//! convex combination.

use super::registry::{Registration, Role, Scheme};
use super::{renormalised, Context, Estimator, Info, Message, StepInput};
use crate::estimate::{wrap_rows, EstimateError, Gaussian};

/// `hcmci` in the registry.
pub(super) const REGISTRATION: Registration = Registration {
    scheme: Scheme {
        name: "hcmci",
        reference: "Battistelli, Chisci, Mugnai, Farina & Graziano (2015), IEEE TAC 60(5)",
        messages: "every round: the prior's and the measurement's information pairs",
        parameters: "estimators.rounds; estimators.hcmci_omega (default: the number of nodes); Metropolis weights",
    },
    role: Role::Node(|ctx, g, _, p| {
        let omega = p.hcmci_omega.unwrap_or(ctx.nodes as f64);
        Box::new(Hcmci::new(ctx, g, omega))
    }),
};

/// Hybrid consensus on measurements and on information (HCMCI).
pub struct Hcmci {
    ctx: Context,
    g: Gaussian,
    /// The weight ω of the measurement information.
    omega: f64,
    prior: Info,
    measurement: Info,
}

impl Hcmci {
    /// The scheme at the node of `ctx`, from `initial`, with weight `omega` on the measurements.
    pub fn new(ctx: Context, initial: Gaussian, omega: f64) -> Hcmci {
        let n = initial.x.len();
        Hcmci {
            ctx,
            g: initial,
            omega,
            prior: Info::zero(n),
            measurement: Info::zero(n),
        }
    }
}

impl Estimator for Hcmci {
    fn name(&self) -> &'static str {
        "hcmci"
    }
    fn state(&self) -> Option<&Gaussian> {
        Some(&self.g)
    }
    fn state_mut(&mut self) -> Option<&mut Gaussian> {
        Some(&mut self.g)
    }
    fn begin(&mut self, input: &StepInput<'_>) -> Result<(), EstimateError> {
        self.prior = Info::of(&self.g)?;
        self.measurement = match input.own {
            Some(m) => input.information(&self.g, input.node, m)?,
            None => Info::zero(self.g.x.len()),
        };
        Ok(())
    }
    fn message(&self, _round: usize) -> Option<Message> {
        Some(Message::Hybrid {
            prior: self.prior.clone(),
            measurement: self.measurement.clone(),
        })
    }
    fn combine(&mut self, _: usize, arrived: &[(usize, &Message)], _: &StepInput<'_>) -> Result<(), EstimateError> {
        let n = self.g.x.len();
        let own = (self.prior.clone(), self.measurement.clone());
        let theirs: Vec<(usize, (Info, Info))> = arrived
            .iter()
            .filter_map(|(j, m)| match m {
                Message::Hybrid { prior, measurement } if prior.y.len() == n && measurement.y.len() == n => {
                    // Both pairs were formed about the sender's prior: one move brings them to this node's side.
                    Some((
                        *j,
                        match prior.toward(&self.g.x, &self.ctx) {
                            Some(mv) => (prior.moved(&mv), measurement.moved(&mv)),
                            None => (prior.clone(), measurement.clone()),
                        },
                    ))
                }
                _ => None,
            })
            .collect();
        let (mut p, mut q) = (Info::zero(n), Info::zero(n));
        for (w, (a, b)) in renormalised(&self.ctx, &own, theirs.iter().map(|(j, t)| (*j, t))) {
            p.add(w, a);
            q.add(w, b);
        }
        self.prior = p;
        self.measurement = q;
        Ok(())
    }
    fn finish(&mut self, _input: &StepInput<'_>) -> Result<(), EstimateError> {
        let mut fused = self.prior.clone();
        fused.add(self.omega, &self.measurement);
        self.g = fused.gaussian()?;
        wrap_rows(&mut self.g.x, &self.ctx.angle_states);
        Ok(())
    }
}
