//! The types every update shares — a state estimate, an observation model, the rule for rows no source delivered,
//! a consensus source and outcome — below both the dynamic updates ([`super::kalman`], [`super::consensus`]) and
//! their fixed-size fast path ([`super::fixed`]), which both call.

use nalgebra::{DMatrix, DVector};

use super::wrap_rows;

/// A state estimate: mean and covariance.
#[derive(Debug, Clone, PartialEq)]
pub struct Gaussian {
    /// The state estimate x.
    pub x: DVector<f64>,
    /// Its covariance P.
    pub P: DMatrix<f64>,
}

/// How an observation maps the state: z = H x + v, v ~ N(0, R).
#[derive(Debug, Clone)]
pub struct Observation {
    /// The observation matrix H (z = H x + v).
    pub H: DMatrix<f64>,
    /// The measurement noise covariance R.
    pub R: DMatrix<f64>,
    /// Rows that are angles: innovations on them wrap to (−π, π].
    pub angle_rows: Vec<bool>,
    /// Which rows travel in which channel (pose: position = 0, orientation = 1).
    pub channel_of_row: Vec<usize>,
}

impl Observation {
    /// Rows of the measurement.
    pub fn dim(&self) -> usize {
        self.H.nrows()
    }
    /// Channels the rows are grouped in.
    pub fn channels(&self) -> usize {
        self.channel_of_row.iter().copied().max().map_or(0, |c| c + 1)
    }
    /// Innovation z − H x with angle rows wrapped.
    pub fn innovation(&self, z: &DVector<f64>, x: &DVector<f64>) -> DVector<f64> {
        let mut v = z - &self.H * x;
        wrap_rows(&mut v, &self.angle_rows);
        v
    }
}

/// What to do with a row that no source delivered.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MissingChannels {
    /// R̄ᵢᵢ = λ² Rᵢᵢ; valid only for a diagonal R (its coupling to the other rows is left as it is).
    Inflate(f64),
    /// Remove the row from H, R and z.
    Drop,
}

impl MissingChannels {
    /// The λ of a rule that keeps every row, given the rows `present`: λ itself when inflating, 1 when dropping
    /// but nothing is missing; `None` when rows would be dropped.
    pub fn kept_rows_lambda(self, present: &[bool]) -> Option<f64> {
        match self {
            MissingChannels::Inflate(l) => Some(l),
            MissingChannels::Drop => present.iter().all(|p| *p).then_some(1.0),
        }
    }

    /// Inflate when R is diagonal, drop rows when it is correlated (inflation is then not equivalent).
    pub fn for_noise(R: &DMatrix<f64>, lambda: f64) -> MissingChannels {
        let diagonal = (0..R.nrows()).all(|i| (0..R.ncols()).all(|j| i == j || R[(i, j)] == 0.0));
        if diagonal {
            MissingChannels::Inflate(lambda)
        } else {
            MissingChannels::Drop
        }
    }
}

/// One measurement that reached the node in time: its weight βⱼ, its value, and which rows it carries.
#[derive(Debug, Clone)]
pub struct Source<'a> {
    /// The source's consensus weight β.
    pub beta: f64,
    /// Its measurement z.
    pub z: &'a DVector<f64>,
    /// Which rows of `z` arrived.
    pub present: &'a [bool],
}

/// A consensus update's posterior and whether the LMI conditions held.
#[derive(Debug, Clone)]
pub struct ConsensusOutcome {
    /// The fused estimate.
    pub posterior: Gaussian,
    /// (17) and (19) hold at the β used ([`super::consensus::feasible`]).
    pub feasible: bool,
}
