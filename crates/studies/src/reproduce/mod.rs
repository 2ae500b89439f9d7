//! Reproductions of the source documents' experiments: each runs simnet's own models and writes a table of the
//! paper's claims with simnet's figures beside them, and the plots. A claim that does not hold is reported as such.

use serde::Serialize;

use simnet_engine::node::TraceRow;
use simnet_engine::observe::fusion::FusedRow;
use simnet_engine::report::summary::Summary;
use simnet_engine::scenario::Scenario;

pub mod lesecq;
pub mod nieminen;
pub mod rigid_pair;
pub mod sequeira;

/// One claim of a paper and what simnet measured.
#[derive(Debug, Clone, Serialize)]
pub struct Claim {
    pub id: &'static str,
    /// Section or figure of the paper.
    pub source: &'static str,
    pub claim: &'static str,
    /// simnet's figures, in words.
    pub figures: String,
    /// Whether it held on every seed.
    pub holds: bool,
}

/// A run's results as a reproduction needs them.
pub struct RunResult {
    pub summary: Summary,
    pub rows: Vec<TraceRow>,
    pub fused: Vec<FusedRow>,
}

/// Runs a topology (over UDP, in the CLI); `record` keeps the per-step rows for plots.
pub type Runner<'a> = &'a dyn Fn(&Scenario, bool) -> Result<RunResult, ReproduceError>;

#[derive(Debug, thiserror::Error)]
pub enum ReproduceError {
    #[error(transparent)]
    Scenario(#[from] simnet_engine::scenario::ScenarioError),
    #[error(transparent)]
    Sim(#[from] simnet_engine::sim::SimError),
    /// A run the [`Runner`] could not do (over UDP in the CLI: a socket, a worker).
    #[error(transparent)]
    Run(Box<dyn std::error::Error + Send + Sync>),
    #[error(transparent)]
    Protocol(#[from] crate::protocol::ProtocolError),
    #[error(transparent)]
    Plot(#[from] simnet_engine::report::plot::PlotError),
    #[error(transparent)]
    Estimate(#[from] simnet_engine::estimate::EstimateError),
    #[error(transparent)]
    Bvp(#[from] simnet_engine::estimate::bvp::BvpError),
    #[error(transparent)]
    Io(#[from] std::io::Error),
    /// An experiment that cannot be set up as asked (its message says why).
    #[error("{0}")]
    Setup(String),
}

/// The claims as a Markdown table.
pub fn markdown(title: &str, claims: &[Claim]) -> String {
    let mut s = format!("# {title}\n\n| # | where | claim | simnet | reproduced |\n|---|---|---|---|---|\n");
    for c in claims {
        s.push_str(&format!(
            "| {} | {} | {} | {} | {} |\n",
            c.id,
            c.source,
            c.claim,
            c.figures,
            if c.holds { "yes" } else { "**no**" }
        ));
    }
    s
}
