//! `diffusion`: the diffusion Kalman filter of Cattivelli & Sayed (2010), "Diffusion strategies for distributed
//! Kalman filtering and smoothing", IEEE TAC 55(9), in its adapt-then-combine form:
//!
//! - adapt (the incremental update): starting from the prior, one Kalman update with each measurement of the
//!   node's neighbourhood in turn — ψᵢ ← ψᵢ + P Hₗᵀ (Rₗ + Hₗ P Hₗᵀ)⁻¹ (zₗ − Hₗ ψᵢ), P ← P − P Hₗᵀ (…)⁻¹ Hₗ P
//!   (here in Joseph form, the same update, better conditioned);
//! - combine: x̂ᵢ = Σₗ cₗᵢ ψₗ over the neighbourhood; P is the adapted one.
//!
//! Round 0 carries the measurements (the adapt step), rounds 1 … L−1 the intermediate estimates ψ (the combine step,
//! repeated); with L = 1 the filter adapts only. Combination weights are Metropolis (or the identity, `combine =
//! false`); a missing ψ is left out and the remaining weights renormalised. `share = false` adapts with the node's
//! own measurement alone: with the identity combination that is the node's own filter.

use super::local::own_update;
use super::registry::{Registration, Role, Scheme};
use super::{renormalised, Context, Estimator, Message, StepInput};
use crate::estimate::{wrap_rows, EstimateError, Gaussian, MissingChannels};
use crate::model::Measurement;

/// `diffusion` in the registry.
pub(super) const REGISTRATION: Registration = Registration {
    scheme: Scheme {
        name: "diffusion",
        reference: "Cattivelli & Sayed (2010), IEEE TAC 55(9), diffusion KF, adapt-then-combine",
        messages: "round 0: the measurement; later rounds: the adapted estimate",
        parameters: "estimators.rounds; Metropolis combination, adapting with the neighbours' measurements",
    },
    role: Role::Node(|ctx, g, policy, _| Box::new(Diffusion::new(ctx, g, policy, true, true))),
};

/// Diffusion Kalman filtering: incremental updates with the neighbours' measurements, then a convex combination of their estimates.
pub struct Diffusion {
    ctx: Context,
    g: Gaussian,
    policy: MissingChannels,
    /// Adapt with the neighbours' measurements (the paper), or with the node's own alone.
    share: bool,
    /// Combine with Metropolis weights (the paper's cₗᵢ), or keep ψᵢ (the identity).
    combine: bool,
    /// ψᵢ has been adapted this step.
    adapted: bool,
    /// This step's own measurement, sent in round 0.
    own: Option<Measurement>,
}

impl Diffusion {
    /// The scheme at the node of `ctx`, from `initial`; `share` the measurements, `combine` the estimates.
    pub fn new(ctx: Context, initial: Gaussian, policy: MissingChannels, share: bool, combine: bool) -> Diffusion {
        Diffusion {
            ctx,
            g: initial,
            policy,
            share,
            combine,
            adapted: false,
            own: None,
        }
    }

    /// The incremental update over the own measurement and `others`, in source order.
    fn adapt(&mut self, input: &StepInput<'_>, others: &[(usize, &Measurement)]) -> Result<(), EstimateError> {
        let mut all: Vec<(usize, &Measurement)> = others.to_vec();
        if let Some(m) = input.own {
            all.push((self.ctx.index, m));
        }
        all.sort_by_key(|(s, _)| *s);
        let mut psi = self.g.clone();
        for (s, m) in all {
            psi = input.update(&psi, s, m, self.policy)?;
        }
        self.g = psi;
        self.adapted = true;
        Ok(())
    }
}

impl Estimator for Diffusion {
    fn name(&self) -> &'static str {
        "diffusion"
    }
    fn state(&self) -> Option<&Gaussian> {
        Some(&self.g)
    }
    fn state_mut(&mut self) -> Option<&mut Gaussian> {
        Some(&mut self.g)
    }
    fn begin(&mut self, input: &StepInput<'_>) -> Result<(), EstimateError> {
        self.adapted = false;
        self.own = input.own.filter(|_| self.share).cloned();
        Ok(())
    }
    fn message(&self, round: usize) -> Option<Message> {
        match round {
            0 => self.own.clone().map(Message::Measurement),
            _ => Some(Message::Estimate(self.g.clone())),
        }
    }
    fn combine(
        &mut self,
        round: usize,
        arrived: &[(usize, &Message)],
        input: &StepInput<'_>,
    ) -> Result<(), EstimateError> {
        if round == 0 {
            let others: Vec<(usize, &Measurement)> = arrived
                .iter()
                .filter(|_| self.share)
                .filter_map(|(j, m)| match m {
                    Message::Measurement(m) => Some((*j, m)),
                    _ => None,
                })
                .collect();
            return self.adapt(input, &others);
        }
        if !self.combine {
            return Ok(());
        }
        let n = self.g.x.len();
        let mut theirs = Vec::with_capacity(arrived.len());
        for (j, m) in arrived {
            if let Message::Estimate(o) = m {
                if o.x.len() == n {
                    theirs.push((*j, self.ctx.difference(&o.x, &self.g.x)));
                }
            }
        }
        // Σ cₗ ψₗ = ψᵢ + Σ cₗ (ψₗ − ψᵢ) (the weights sum to one), so that angles combine by their wrapped differences.
        let zero = nalgebra::DVector::zeros(n);
        let mut step = nalgebra::DVector::zeros(n);
        for (w, d) in renormalised(&self.ctx, &zero, theirs.iter().map(|(j, d)| (*j, d))) {
            step.axpy(w, d, 1.0);
        }
        self.g.x += step;
        wrap_rows(&mut self.g.x, &self.ctx.angle_states);
        Ok(())
    }
    fn finish(&mut self, input: &StepInput<'_>) -> Result<(), EstimateError> {
        if !self.adapted {
            // No round at all this step: the own measurement only.
            self.g = own_update(&self.g, input, self.policy)?;
            self.adapted = true;
        }
        Ok(())
    }
}
