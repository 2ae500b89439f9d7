//! The distributed estimators simnet sets side by side, each one [`Estimator`]: a per-node state machine that
//! predicts with the node's model, takes the node's own measurement, sends one [`Message`] per round, combines what
//! arrived, and ends the step with its posterior. Pure: the node (or a test's graph) moves the messages and decides
//! what is lost. A message that did not arrive is simply absent from `combine`; each scheme's file says how it
//! treats the gap.
//!
//! | file | scheme |
//! |---|---|
//! | `registry.rs` | the one registry: [`Kind`], the built-in schemes in order, [`register`] for a program's own |
//! | `message.rs` | a [`Message`]'s wire form |
//! | `local.rs` | `independent`: the node's own Kalman filter |
//! | `centralized.rs` | `centralized`: one fusion center with every sensing node's measurement (the optimum for linear models) |
//! | `kcf.rs` | `kcf`: Kalman-consensus filter, Olfati-Saber (2009) |
//! | `icf.rs` | `icf`: information-weighted consensus filter, Kamal, Farrell & Roy-Chowdhury (2013) |
//! | `hcmci.rs` | `hcmci`: hybrid consensus on measurements and information, Battistelli et al. (2015) |
//! | `diffusion.rs` | `diffusion`: diffusion Kalman filter, adapt-then-combine, Cattivelli & Sayed (2010) |
//! | `ci.rs` | `ci`: covariance intersection of the neighbours' estimates |
//!
//! Angle states (the pose model's attitude) are wrapped where an innovation or a difference of estimates is formed,
//! and a neighbour's information pair is moved by whole turns to the node's side of ±π before it is averaged
//! (`Info::toward`): the average of y = Y x over estimates at +π − ε and −π + ε would otherwise point at 0. On a
//! double cover (the attitude model's unit quaternion, q and −q one attitude) a neighbour's estimate takes the sign
//! nearer the node's own in the same place.
//!
//! A non-linear observation (the attitude EKF) is linearised about the estimate each update starts from
//! ([`StepInput::about`]): every scheme then runs in its extended (EKF) form, each node linearising about its own
//! estimate (the extension Battistelli et al. (2015) give for HCMCI, applied to every scheme alike). A node's
//! information pairs are formed about its own prior; a neighbour's raw measurement (centralized, diffusion) is
//! linearised by the receiver.
#![allow(non_snake_case)]

mod centralized;
mod ci;
mod diffusion;
mod hcmci;
mod icf;
mod kcf;
mod local;
mod message;
mod registry;
mod sequeira;
#[cfg(test)]
mod tests;

use std::borrow::Cow;

use nalgebra::{DMatrix, DVector};

use crate::estimate::{
    cholesky, kalman_update, symmetrize, wrap_rows, EstimateError, Gaussian, MissingChannels, Observation,
};
use crate::model::{Measurement, Model, Site};

pub use centralized::Centralized;
pub use ci::Ci;
pub use diffusion::Diffusion;
pub use hcmci::Hcmci;
pub use icf::Icf;
pub use kcf::Kcf;
pub use local::Local;
pub use message::{from_body, to_body, MessageError};
pub use registry::{
    build, register, schemes, Builder, Configure, Configured, Kind, NodeBuilder, Params, RegisterError, Scheme,
};
pub use sequeira::{Guarded, Sequeira, SequeiraParams, NOT_ALIKE};

/// What one node's estimator knows of the network.
#[derive(Debug, Clone)]
pub struct Context {
    /// This node, by index.
    pub index: usize,
    /// Nodes in the network (ICF and HCMCI scale information by it).
    pub nodes: usize,
    /// Consensus weights to each neighbour (sorted by node index) and to itself.
    pub weights: Vec<(usize, f64)>,
    /// The consensus weight on its own estimate.
    pub self_weight: f64,
    /// State rows that are angles.
    pub angle_states: Vec<bool>,
    /// x and −x are one state (a unit quaternion).
    pub double_cover: bool,
}

impl Context {
    /// Node `index` of `nodes`, with its consensus weights, on `model`'s state.
    pub fn new(index: usize, nodes: usize, (weights, self_weight): Weights, model: &dyn Model) -> Context {
        Context {
            index,
            nodes,
            weights,
            self_weight,
            angle_states: model.angle_states(),
            double_cover: model.fusion().quaternion,
        }
    }

    fn weight(&self, j: usize) -> f64 {
        weight_in(&self.weights, j)
    }

    /// How a neighbour's estimate `x` is brought to the node's side of its estimate `about`: on a double cover the
    /// sign nearer `about`, else whole turns on the angle rows that bring them within π; none when `x` stays.
    fn toward(&self, x: &DVector<f64>, about: &DVector<f64>) -> Option<Move> {
        if self.double_cover {
            return (x.dot(about) < 0.0).then_some(Move::Flip);
        }
        if !self.angle_states.iter().any(|a| *a) {
            return None;
        }
        let d = DVector::from_fn(x.len(), |i, _| {
            if self.angle_states.get(i) == Some(&true) {
                about[i] + crate::geom::wrap_angle(x[i] - about[i]) - x[i]
            } else {
                0.0
            }
        });
        d.iter().any(|v| *v != 0.0).then_some(Move::Turn(d))
    }

    /// A neighbour's estimate on the node's side of `about` ([`Context::toward`]).
    fn aligned<'a>(&self, x: &'a DVector<f64>, about: &DVector<f64>) -> Cow<'a, DVector<f64>> {
        match self.toward(x, about) {
            Some(Move::Flip) => Cow::Owned(-x),
            Some(Move::Turn(d)) => Cow::Owned(x + d),
            None => Cow::Borrowed(x),
        }
    }

    /// x − about with `x` on the node's side, angle rows wrapped: what a consensus term sums.
    fn difference(&self, x: &DVector<f64>, about: &DVector<f64>) -> DVector<f64> {
        let mut d = self.aligned(x, about).into_owned() - about;
        wrap_rows(&mut d, &self.angle_states);
        d
    }
}

/// How a neighbour's estimate moves to the node's side ([`Context::toward`]).
#[derive(Debug, Clone, PartialEq)]
enum Move {
    /// −x: the other sign of a double cover.
    Flip,
    /// x + d: whole turns on the angle rows.
    Turn(DVector<f64>),
}

/// One node's consensus weights to its neighbours (sorted by node index), and to itself.
pub type Weights = (Vec<(usize, f64)>, f64);

/// The weight of column `j` in a sparse row sorted by column (0 when absent).
pub fn weight_in(row: &[(usize, f64)], j: usize) -> f64 {
    row.binary_search_by_key(&j, |(c, _)| *c).map_or(0.0, |i| row[i].1)
}

/// Metropolis–Hastings weights (Xiao, Boyd & Lall 2005): πᵢⱼ = 1 / (1 + max(dᵢ, dⱼ)) to each neighbour j,
/// πᵢᵢ = 1 − Σⱼ πᵢⱼ; doubly stochastic on an undirected graph, so that consensus converges to the average.
pub fn metropolis(neighbours: &[Vec<usize>]) -> Vec<Weights> {
    neighbours
        .iter()
        .map(|ns| {
            let mut w: Vec<(usize, f64)> = ns
                .iter()
                .map(|&j| (j, 1.0 / (1.0 + ns.len().max(neighbours[j].len()) as f64)))
                .collect();
            w.sort_by_key(|(j, _)| *j);
            let own = 1.0 - w.iter().map(|(_, v)| v).sum::<f64>();
            (w, own)
        })
        .collect()
}

/// An information pair: Y = P⁻¹ and y = P⁻¹ x.
#[derive(Debug, Clone, PartialEq)]
pub struct Info {
    /// The information matrix Y = P⁻¹.
    pub Y: DMatrix<f64>,
    /// The information vector y = P⁻¹ x.
    pub y: DVector<f64>,
}

impl Info {
    /// The zero pair of an n-state (no information).
    pub fn zero(n: usize) -> Info {
        Info {
            Y: DMatrix::zeros(n, n),
            y: DVector::zeros(n),
        }
    }

    /// The pair of an estimate: (P⁻¹, P⁻¹ x).
    pub fn of(g: &Gaussian) -> Result<Info, EstimateError> {
        let Y = cholesky(&g.P, "P")?.inverse();
        Ok(Info { y: &Y * &g.x, Y })
    }

    /// The estimate of the pair: (Y⁻¹, Y⁻¹ y).
    pub fn gaussian(&self) -> Result<Gaussian, EstimateError> {
        let mut P = cholesky(&self.Y, "information matrix")?.inverse();
        symmetrize(&mut P);
        let x = &P * &self.y;
        if x.iter().chain(P.iter()).any(|v| !v.is_finite()) {
            return Err(EstimateError::NonFinite { what: "estimate" });
        }
        Ok(Gaussian { x, P })
    }

    /// The information of measurement `m` (the rows it carries): U = Hᵀ R⁻¹ H, u = Hᵀ R⁻¹ z, with angle rows of z
    /// taken within π of H `about` (the node's prior), so that u − U·about is the wrapped innovation's information.
    pub fn of_measurement(obs: &Observation, m: &Measurement, about: &DVector<f64>) -> Result<Info, EstimateError> {
        let rows: Vec<usize> = (0..obs.dim()).filter(|&r| m.present.get(r) == Some(&true)).collect();
        let n = obs.H.ncols();
        if rows.is_empty() {
            return Ok(Info::zero(n));
        }
        if m.z.len() != obs.dim() {
            return Err(EstimateError::Dimension {
                what: format!("measurement of {} rows, expected {}", m.z.len(), obs.dim()),
            });
        }
        let H = obs.H.select_rows(rows.iter());
        let R = obs.R.select_rows(rows.iter()).select_columns(rows.iter());
        let Rinv = cholesky(&R, "R")?.inverse();
        let predicted = &H * about;
        let mut nu = DVector::from_iterator(rows.len(), rows.iter().map(|&r| m.z[r])) - &predicted;
        let angles: Vec<bool> = rows.iter().map(|&r| obs.angle_rows[r]).collect();
        wrap_rows(&mut nu, &angles);
        let HtRinv = H.transpose() * Rinv;
        Ok(Info {
            Y: &HtRinv * &H,
            y: &HtRinv * (predicted + nu),
        })
    }

    /// How the estimate this pair carries, x = Y⁻¹ y, moves to the node's side of `about` ([`Context::toward`]);
    /// none when it stays, or Y is singular.
    fn toward(&self, about: &DVector<f64>, ctx: &Context) -> Option<Move> {
        if !ctx.double_cover && !ctx.angle_states.iter().any(|a| *a) {
            return None;
        }
        let x = cholesky(&self.Y, "information matrix").ok()?.solve(&self.y);
        ctx.toward(&x, about)
    }

    /// The pair of the moved estimate: (Y, −y) for the other sign, (Y, y + Y d) for whole turns. A measurement's
    /// pair linearised about the sender's prior moves with it: h is even in q (C(−q) = −C(q), the same offset), so
    /// the pair about −q̂ is (U, −u).
    fn moved(&self, m: &Move) -> Info {
        match m {
            Move::Flip => Info {
                Y: self.Y.clone(),
                y: -&self.y,
            },
            Move::Turn(d) => Info {
                y: &self.y + &self.Y * d,
                Y: self.Y.clone(),
            },
        }
    }

    fn scaled(&self, a: f64) -> Info {
        Info {
            Y: &self.Y * a,
            y: &self.y * a,
        }
    }

    fn add(&mut self, a: f64, o: &Info) {
        self.Y += &o.Y * a;
        self.y.axpy(a, &o.y, 1.0);
    }
}

/// What travels between two nodes' estimators in one round.
#[derive(Debug, Clone, PartialEq)]
pub enum Message {
    /// A measurement and the rows it carries (centralized, diffusion's adapt step).
    Measurement(Measurement),
    /// An information pair (ICF).
    Information(Info),
    /// The prior's and the measurement's information pairs (HCMCI).
    Hybrid {
        /// The prior's pair.
        prior: Info,
        /// The measurement's pair.
        measurement: Info,
    },
    /// An estimate (KCF's prior, diffusion's combine step, CI).
    Estimate(Gaussian),
    /// Bytes in a format the scheme itself writes and reads (a registered scheme's own encoding: quantised values,
    /// a compressed state, anything): they travel as they are, at least one byte; the receiving scheme decodes them.
    Own(bytes::Bytes),
}

/// What a node hands its estimators each step: its model, the observation (a template whose H the model linearises,
/// for a non-linear one) and the node's own measurement (none for a naive node, or when sensing failed).
#[derive(Clone, Copy)]
pub struct StepInput<'a> {
    /// The node's model.
    pub model: &'a dyn Model,
    /// The step's observation (H, R).
    pub obs: &'a Observation,
    /// The node whose step it is, by index: the site of its own measurement.
    pub node: usize,
    /// The node's own measurement of the step, if any arrived.
    pub own: Option<&'a Measurement>,
    /// The step's measurements the node believes, its own among them, by source (sorted): what its links carried
    /// by the step's deadline, less what the innovation gate left out. Empty where the driver hands none (the
    /// observer's fusion centers take theirs as messages).
    pub heard: &'a [(usize, &'a Measurement)],
    /// The step's number (the LMI guard's bound grows with it, eq. (15)).
    pub step: u64,
}

impl<'a> StepInput<'a> {
    /// The observation of `m`, taken by node `source`, about the estimate `about`, and `m` in its coordinates: as
    /// they are for a linear observation every node shares; otherwise h(x, source) ≈ h(x̂) + H (x − x̂) about
    /// x̂ = `about` ([`crate::model::Sensing::linearize_at`]), so that a linear update sees the innovation z − h(x̂).
    pub fn about<'b>(
        &'b self,
        source: usize,
        about: &Gaussian,
        m: &'b Measurement,
    ) -> (Cow<'b, Observation>, Cow<'b, Measurement>)
    where
        'a: 'b,
    {
        // One rule for every model: what `linearize_at` hands back borrowed is used as it is.
        let (obs, mut z) = self.model.linearize_at(self.obs, about, Site { node: source }, &[&m.z]);
        match z.pop() {
            Some(Cow::Owned(z)) => (
                obs,
                Cow::Owned(Measurement {
                    z,
                    present: m.present.clone(),
                }),
            ),
            Some(Cow::Borrowed(_)) | None => (obs, Cow::Borrowed(m)),
        }
    }

    /// The Kalman update of `g` with `m`, taken by node `source` (Joseph form), linearised about `g`.
    pub fn update(
        &self,
        g: &Gaussian,
        source: usize,
        m: &Measurement,
        policy: MissingChannels,
    ) -> Result<Gaussian, EstimateError> {
        let (obs, m) = self.about(source, g, m);
        kalman_update(g, &obs, &m.z, &m.present, policy)
    }

    /// The information of `m`, taken by node `source` ([`Info::of_measurement`]), linearised about `about`.
    pub fn information(&self, about: &Gaussian, source: usize, m: &Measurement) -> Result<Info, EstimateError> {
        let (obs, m) = self.about(source, about, m);
        Info::of_measurement(&obs, &m, &about.x)
    }
}

/// One distributed estimator at one node. Per step: [`Estimator::predict`], [`Estimator::begin`], then for each
/// round r = 0 … L−1 [`Estimator::message`] (sent to every out-neighbour) and [`Estimator::combine`] (what arrived,
/// sorted by source), then [`Estimator::finish`].
pub trait Estimator: Send {
    /// Its name in the registry.
    fn name(&self) -> &'static str;

    /// The node's estimate (none at a node that only reports to a fusion center).
    fn state(&self) -> Option<&Gaussian>;
    /// The node's estimate, to change (a restart, a rebase of coordinates).
    fn state_mut(&mut self) -> Option<&mut Gaussian>;

    /// The prediction to this step, by the node's model (the same for every estimator of the node).
    fn predict(&mut self, predict: &dyn Fn(&Gaussian) -> Gaussian) {
        if let Some(g) = self.state_mut() {
            *g = predict(g);
        }
    }

    /// The step's own measurement has been taken.
    fn begin(&mut self, _input: &StepInput<'_>) -> Result<(), EstimateError> {
        Ok(())
    }

    /// What this node sends in round `round`, if anything.
    fn message(&self, round: usize) -> Option<Message>;

    /// Round `round`'s messages that arrived, by source, sorted by source.
    fn combine(
        &mut self,
        round: usize,
        arrived: &[(usize, &Message)],
        input: &StepInput<'_>,
    ) -> Result<(), EstimateError>;

    /// The step ends after the last round.
    fn finish(&mut self, _input: &StepInput<'_>) -> Result<(), EstimateError> {
        Ok(())
    }

    /// Start again from `g` (a restart, or a failed update).
    fn reset(&mut self, g: Gaussian) {
        if let Some(s) = self.state_mut() {
            *s = g;
        }
    }
}

/// (πᵢᵢ Xᵢ + Σ πᵢⱼ Xⱼ) / (πᵢᵢ + Σ πᵢⱼ) over the messages that arrived: the weights of the missing renormalised
/// away, so that the combination stays convex.
fn renormalised<'a, T: 'a>(
    ctx: &Context,
    own: &'a T,
    arrived: impl Iterator<Item = (usize, &'a T)>,
) -> Vec<(f64, &'a T)> {
    let mut terms = vec![(ctx.self_weight, own)];
    terms.extend(arrived.map(|(j, t)| (ctx.weight(j), t)).filter(|(w, _)| *w > 0.0));
    let total: f64 = terms.iter().map(|(w, _)| w).sum();
    if total > 0.0 {
        terms.iter_mut().for_each(|(w, _)| *w /= total);
    }
    terms
}
