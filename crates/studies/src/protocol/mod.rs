//! The β protocol search of Sequeira (2023) §5: start from independent nodes, increase the weight each node gives
//! its neighbours' measurements, and keep (17) and (19) feasible at every step of a run.
//!
//! The family (default build): node i with d in-neighbours gets βᵢⱼ = u per neighbour and βᵢᵢ = 1 − d·u until the
//! weights are uniform (u = 1/(d+1)); past that every weight grows with u, up to a row sum σ (`max_row_sum`).
//! σ = 1 keeps every row a weighted average of innovations; then P̄ of (9) is positive semidefinite, so (19) holds
//! for any u, and (17) fails only if α is below ‖K S Kᵀ‖. A larger σ lets the gain grow until (19) or (17) bind.
//!
//! Each candidate is scored by whole runs of in-memory nodes ([`simnet_engine::sim::Sim`], the same state
//! machines the sockets drive), on several seeds: a protocol is feasible when no node's guard rejected a single
//! update on any seed. The feasibility boundary along the family is found by bisection between the grid points that
//! bracket it. Among feasible protocols the search returns the one with the most exchanged weight
//! whose mean error (over nodes and seeds) is within [`ERROR_TIE`] of the lowest ([`Objective::Error`]: the paper's "optimization
//! problem on the space of the feasible β", with its Figs. 9b/11b as the objective), or simply the one with the most
//! exchanged weight ([`Objective::Exchange`]). With the `sdp` feature,
//! the `sdp` module searches all β, not only the family, for the most exchanged weight.

use serde::Serialize;

use simnet_engine::scenario::{Overrides, Scenario, ScenarioError};
use simnet_engine::sim::{RunResults, Sim, SimError, SimOptions};

#[cfg(feature = "sdp")]
pub mod sdp;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Objective {
    /// Lowest mean position error (over nodes and seeds) among feasible protocols (ties within 1 %: the most
    /// exchange). Seeds diverging exclude a protocol.
    Error,
    /// Most weight to the neighbours among feasible protocols.
    Exchange,
}

#[derive(Debug, Clone)]
pub struct SearchConfig {
    /// Seeds of the scoring runs.
    pub seeds: Vec<u64>,
    /// Grid points on [0, u_max], ends included.
    pub grid: usize,
    /// Bisection steps on the feasibility boundary.
    pub bisect: usize,
    /// σ ≥ 1: the largest row sum Σⱼ βᵢⱼ.
    pub max_row_sum: f64,
    pub objective: Objective,
    /// Past row sum 1 feasibility rests on the scoring runs alone: a protocol there must lie this fraction of u
    /// inside the boundary they found.
    pub margin: f64,
}

#[derive(Debug, thiserror::Error)]
pub enum ProtocolError {
    #[error("--max-row-sum must be at least 1 (independent nodes have row sum 1), got {0}")]
    RowSum(f64),
    #[error("--grid needs at least 2 points, got {0}")]
    Grid(usize),
    #[error("no seeds to score protocols with")]
    NoSeeds,
    #[error("topology `{0}` has no node that both measures and receives a neighbour's measurement: nothing to weigh")]
    NoExchange(String),
    #[error(
        "no feasible protocol: even independent nodes violate (17) or (19) at some step (α = {alpha}, γ = {gamma}); \
         raise consensus.lmi.alpha"
    )]
    NoneFeasible { alpha: f64, gamma: f64 },
    #[error(
        "topology `{0}`: no estimating node has a known truth to score protocols against (its recorded IMU files \
         have no reference columns)"
    )]
    NoReference(String),
    #[error(
        "topology `{0}`: its nodes observe differently (model.observe or a registered Sensing), so they run no \
         networked filter, and a β protocol weighs that filter's sources"
    )]
    NoNetworked(String),
    /// A protocol the scenario's validator rejects.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    #[error(transparent)]
    Sim(#[from] SimError),
}

/// Mean errors within this fraction of the lowest count as equal; among them the most exchange wins.
pub const ERROR_TIE: f64 = 0.01;

/// The scores of one protocol over the search seeds.
#[derive(Debug, Clone, Serialize)]
pub struct Evaluation {
    /// Family parameter (NaN for a protocol outside the family).
    pub u: f64,
    /// Mean over exchanging nodes of Σ_{j≠i} βᵢⱼ.
    pub exchange: f64,
    /// Mean over seeds of the nodes' mean networked position error (burn-in excluded).
    pub mean_error: f64,
    /// The worst seed's mean networked error.
    pub worst_error: f64,
    /// The same for the independent filters (they do not depend on β).
    pub independent_error: f64,
    /// Steps, all nodes and seeds, at which (17) or (19) failed.
    pub infeasible_steps: u64,
    pub diverged: bool,
    /// Estimating nodes whose error could be measured (the fewest of any seed); the errors are means over them.
    pub scored_nodes: usize,
}

impl Evaluation {
    pub fn feasible(&self) -> bool {
        self.infeasible_steps == 0
    }
}

/// How far along the family (17) and (19) held.
#[derive(Debug, Clone, Copy, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Boundary {
    /// Feasible on the whole family up to u_max.
    NotReached { u_max: f64 },
    /// Feasible at `feasible`, not at `infeasible`.
    Between { feasible: f64, infeasible: f64 },
}

#[derive(Debug, Clone, Serialize)]
pub struct SearchResult {
    /// Every family protocol scored, by u.
    pub curve: Vec<Evaluation>,
    pub boundary: Boundary,
    pub chosen: Evaluation,
    /// The chosen β, rounded to 1e-4 (what the topology file carries).
    pub beta: Vec<Vec<f64>>,
    /// The topology's own protocol on the same seeds.
    pub reference: Evaluation,
}

/// Sensing nodes whose measurements reach node i (node indices, i excluded).
pub fn sources_of(topo: &Scenario, i: usize) -> Vec<usize> {
    let mut v: Vec<usize> = topo
        .in_links(i)
        .map(|l| l.from)
        .filter(|&j| j != i && topo.nodes()[j].role.senses())
        .collect();
    v.sort_unstable();
    v.dedup();
    v
}

/// Nodes whose β row the search sets: they measure, estimate and hear at least one neighbour.
fn exchanging(topo: &Scenario) -> Vec<usize> {
    (0..topo.nodes().len())
        .filter(|&i| {
            let r = topo.nodes()[i].role;
            r.senses() && r.estimates() && !sources_of(topo, i).is_empty()
        })
        .collect()
}

/// The largest u that changes any row.
pub fn u_max(topo: &Scenario, max_row_sum: f64) -> f64 {
    exchanging(topo)
        .into_iter()
        .map(|i| max_row_sum / (sources_of(topo, i).len() + 1) as f64)
        .fold(0.0, f64::max)
}

/// The largest u at which every row sums to at most 1.
pub fn u_row_sum_one(topo: &Scenario) -> f64 {
    exchanging(topo)
        .into_iter()
        .map(|i| 1.0 / (sources_of(topo, i).len() + 1) as f64)
        .fold(f64::INFINITY, f64::min)
}

/// The family's β at parameter u; rows of other nodes are kept from the topology.
pub fn family(topo: &Scenario, u: f64, max_row_sum: f64) -> Vec<Vec<f64>> {
    let mut beta = topo.consensus().beta.to_dense();
    for i in exchanging(topo) {
        let src = sources_of(topo, i);
        let d = src.len() as f64;
        let ui = u.min(max_row_sum / (d + 1.0));
        let row = &mut beta[i];
        row.iter_mut().for_each(|b| *b = 0.0);
        row[i] = if ui <= 1.0 / (d + 1.0) { 1.0 - d * ui } else { ui };
        for j in src {
            row[j] = ui;
        }
    }
    beta
}

/// Mean over exchanging nodes of the weight given to neighbours.
pub fn exchange(topo: &Scenario, beta: &[Vec<f64>]) -> f64 {
    let nodes = exchanging(topo);
    if nodes.is_empty() {
        return 0.0;
    }
    let total: f64 = nodes
        .iter()
        .map(|&i| {
            beta[i]
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != i)
                .map(|(_, b)| b)
                .sum::<f64>()
        })
        .sum();
    total / nodes.len() as f64
}

/// The topology with protocol β and the LMI guard on (its α, γ).
pub fn with_protocol(topo: &Scenario, beta: &[Vec<f64>]) -> Result<Scenario, ScenarioError> {
    topo.with_beta(beta, true)
}

/// One run in memory with `seed` ([`Sim`]); `record_lmi` keeps each node's per-step LMI terms.
pub fn run_in_memory(topo: &Scenario, seed: u64, record_lmi: bool) -> Result<RunResults, ProtocolError> {
    let t = topo.with(&Overrides {
        seed: Some(seed),
        ..Default::default()
    })?;
    let opts = SimOptions {
        record_lmi,
        no_fusion: true,
        ..Default::default()
    };
    Ok(Sim::with_options(&t, opts)?.run()?)
}

/// Score protocol β on `seeds`.
pub fn evaluate(topo: &Scenario, beta: &[Vec<f64>], u: f64, seeds: &[u64]) -> Result<Evaluation, ProtocolError> {
    let t = with_protocol(topo, beta)?;
    let mut per_seed = Vec::with_capacity(seeds.len());
    let mut independent = 0.0;
    let mut infeasible_steps = 0;
    let mut diverged = false;
    let mut scored_nodes = usize::MAX;
    for &seed in seeds {
        let results = run_in_memory(&t, seed, false)?;
        let (mut net, mut ind, mut n) = (0.0, 0.0, 0usize);
        for r in results.reports {
            let (Some(mn), Some(mi)) = (r.networked, r.independent) else {
                continue;
            };
            let (sn, si) = (mn.summary(true), mi.summary(false));
            diverged |= sn.diverged;
            infeasible_steps += sn.lmi_infeasible_steps.unwrap_or(0);
            if let (Some(en), Some(ei)) = (sn.scored_error(), si.scored_error()) {
                net += en;
                ind += ei;
                n += 1;
            }
        }
        scored_nodes = scored_nodes.min(n);
        let n = n.max(1) as f64;
        per_seed.push(net / n);
        independent += ind / n;
    }
    let s = seeds.len().max(1) as f64;
    Ok(Evaluation {
        u,
        exchange: exchange(topo, beta),
        mean_error: per_seed.iter().sum::<f64>() / s,
        worst_error: per_seed.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        independent_error: independent / s,
        infeasible_steps,
        diverged,
        scored_nodes: if seeds.is_empty() { 0 } else { scored_nodes },
    })
}

/// Score family points in parallel, one worker per core; `tick` after each protocol.
fn evaluate_many(
    topo: &Scenario,
    us: &[f64],
    cfg: &SearchConfig,
    tick: &(dyn Fn() + Sync),
) -> Result<Vec<Evaluation>, ProtocolError> {
    simnet_engine::par::map(
        us,
        |&u| evaluate(topo, &family(topo, u, cfg.max_row_sum), u, &cfg.seeds),
        tick,
    )
    .into_iter()
    .collect()
}

/// How many protocol evaluations [`search`] runs at most (for a progress bar).
pub fn planned_evaluations(cfg: &SearchConfig) -> u64 {
    (cfg.grid + cfg.bisect + 1) as u64
}

/// The family search (module docs). `tick` is called after each protocol scored.
pub fn search(topo: &Scenario, cfg: &SearchConfig, tick: &(dyn Fn() + Sync)) -> Result<SearchResult, ProtocolError> {
    if !(cfg.max_row_sum >= 1.0 && cfg.max_row_sum.is_finite()) {
        return Err(ProtocolError::RowSum(cfg.max_row_sum));
    }
    if cfg.grid < 2 {
        return Err(ProtocolError::Grid(cfg.grid));
    }
    if cfg.seeds.is_empty() {
        return Err(ProtocolError::NoSeeds);
    }
    if !topo.model().get().observes_alike() {
        return Err(ProtocolError::NoNetworked(topo.name().to_string()));
    }
    let umax = u_max(topo, cfg.max_row_sum);
    if umax <= 0.0 {
        return Err(ProtocolError::NoExchange(topo.name().to_string()));
    }
    let reference = evaluate(topo, &topo.consensus().beta.to_dense(), f64::NAN, &cfg.seeds)?;
    tick();
    if reference.scored_nodes == 0 {
        return Err(ProtocolError::NoReference(topo.name().to_string()));
    }
    let us: Vec<f64> = (0..cfg.grid).map(|k| umax * k as f64 / (cfg.grid - 1) as f64).collect();
    let mut curve = evaluate_many(topo, &us, cfg, tick)?;

    // Feasible region: the grid points before the first infeasible one; bisect the bracket.
    let first_bad = curve.iter().position(|e| !e.feasible());
    let boundary = match first_bad {
        Some(0) => {
            return Err(ProtocolError::NoneFeasible {
                alpha: topo.consensus().lmi.alpha,
                gamma: topo.consensus().lmi.gamma,
            })
        }
        None => Boundary::NotReached { u_max: umax },
        Some(b) => {
            let (mut lo, mut hi) = (us[b - 1], us[b]);
            for _ in 0..cfg.bisect {
                let mid = 0.5 * (lo + hi);
                let e = evaluate(topo, &family(topo, mid, cfg.max_row_sum), mid, &cfg.seeds)?;
                tick();
                if e.feasible() {
                    lo = mid;
                } else {
                    hi = mid;
                }
                curve.push(e);
            }
            Boundary::Between {
                feasible: lo,
                infeasible: hi,
            }
        }
    };
    curve.sort_by(|a, b| a.u.total_cmp(&b.u));
    // Row sums ≤ 1 make P̄ ⪰ 0, so (19) holds on any data; past that keep the margin from the empirical boundary.
    let proven = u_row_sum_one(topo);
    let limit = match boundary {
        Boundary::NotReached { u_max } => u_max,
        Boundary::Between { feasible, .. } => feasible.min(proven.max(feasible * (1.0 - cfg.margin))),
    };
    let candidates: Vec<&Evaluation> = curve
        .iter()
        .filter(|e| e.u <= limit && e.feasible() && !e.diverged)
        .collect();
    let best = candidates.iter().map(|e| e.mean_error).fold(f64::INFINITY, f64::min);
    let chosen = candidates
        .into_iter()
        .filter(|e| cfg.objective == Objective::Exchange || e.mean_error <= best * (1.0 + ERROR_TIE))
        .max_by(|a, b| a.u.total_cmp(&b.u))
        .cloned()
        .ok_or(ProtocolError::NoneFeasible {
            alpha: topo.consensus().lmi.alpha,
            gamma: topo.consensus().lmi.gamma,
        })?;
    let beta = round_beta(&family(topo, chosen.u, cfg.max_row_sum));
    Ok(SearchResult {
        curve,
        boundary,
        chosen,
        beta,
        reference,
    })
}

/// β rounded to 1e-4, as a topology file carries it.
pub fn round_beta(beta: &[Vec<f64>]) -> Vec<Vec<f64>> {
    beta.iter()
        .map(|r| r.iter().map(|b| (b * 1e4).round() / 1e4).collect())
        .collect()
}

/// `base` (a topology file's text) with the protocol β, a new name and description. Comments of the base are lost.
/// `imu_files[i]`, where given, replaces node i's `imu_csv`: the written file lives in another folder, so a path
/// relative to the base's folder would no longer resolve.
pub fn topology_text(
    base: &str,
    name: &str,
    description: &str,
    beta: &[Vec<f64>],
    imu_files: &[Option<String>],
) -> Result<String, TextError> {
    let mut doc: toml::Table = toml::from_str(base)?;
    if let Some(nodes) = doc.get_mut("node").and_then(|n| n.as_array_mut()) {
        for (node, file) in nodes.iter_mut().zip(imu_files) {
            if let (Some(node), Some(file)) = (node.as_table_mut(), file) {
                node.insert("imu_csv".into(), toml::Value::String(file.clone()));
            }
        }
    }
    doc.insert("name".into(), toml::Value::String(name.into()));
    doc.insert("description".into(), toml::Value::String(description.into()));
    let consensus = doc
        .entry("consensus")
        .or_insert_with(|| toml::Value::Table(toml::Table::new()))
        .as_table_mut()
        .ok_or(TextError::NotATable("consensus"))?;
    let rows = beta
        .iter()
        .map(|r| toml::Value::Array(r.iter().map(|b| toml::Value::Float(*b)).collect()))
        .collect();
    // The matrix replaces the base's uniform weights, which a topology may not give alongside it.
    consensus.remove("self");
    consensus.remove("neighbor");
    consensus.insert("matrix".into(), toml::Value::Array(rows));
    if let Some(lmi) = consensus.get_mut("lmi").and_then(|l| l.as_table_mut()) {
        lmi.insert("enabled".into(), toml::Value::Boolean(true));
    }
    Ok(toml::to_string(&doc)?)
}

/// Why [`topology_text`] could not write a topology.
#[derive(Debug, thiserror::Error)]
pub enum TextError {
    #[error("the base topology: {0}")]
    Parse(#[from] toml::de::Error),
    #[error("`{0}` is not a table")]
    NotATable(&'static str),
    #[error("writing TOML: {0}")]
    Write(#[from] toml::ser::Error),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn family_runs_from_independent_to_uniform_and_beyond() {
        let topo = Scenario::resolve("tri3-paper").unwrap();
        let b0 = family(&topo, 0.0, 1.0);
        assert_eq!(b0[0], vec![1.0, 0.0, 0.0]);
        let third = 1.0 / 3.0;
        let bu = family(&topo, third, 1.0);
        for r in &bu {
            assert!(r.iter().all(|b| (b - third).abs() < 1e-12), "{r:?}");
        }
        // σ = 1 caps u at uniform; σ = 3 lets every weight grow to 1.
        assert_eq!(family(&topo, 0.9, 1.0), bu);
        assert!(family(&topo, 1.0, 3.0)
            .iter()
            .flatten()
            .all(|b| (*b - 1.0).abs() < 1e-12));
        assert!((exchange(&topo, &bu) - 2.0 / 3.0).abs() < 1e-12);
        assert!((u_max(&topo, 1.0) - third).abs() < 1e-12);
    }

    #[test]
    fn written_topology_parses_with_its_protocol() {
        // pair2-paper gives a matrix, ring3 uniform `self`/`neighbor` weights.
        for name in ["pair2-paper", "ring3"] {
            let text = simnet_engine::scenario::builtin::get(name).unwrap();
            let n = Scenario::from_toml(text, name).unwrap().nodes().len();
            let beta = vec![vec![1.0 / n as f64; n]; n];
            let out = topology_text(text, "found", "found", &beta, &[]).unwrap();
            let t = Scenario::from_toml(&out, "test").unwrap();
            assert_eq!(t.name(), "found");
            assert_eq!(t.consensus().beta.to_dense(), beta);
            assert!(t.consensus().lmi.enabled);
        }
    }

    #[test]
    fn written_topology_points_at_the_imu_files_given() {
        let base = "[[node]]\nid = 0\nimu_csv = \"rel/imu-0.csv\"\n[[node]]\nid = 1\n";
        let beta = vec![vec![0.5; 2]; 2];
        let files = [Some("/data/run/imu-0.csv".to_string()), None];
        let out = topology_text(base, "found", "found", &beta, &files).unwrap();
        let doc: toml::Table = toml::from_str(&out).unwrap();
        let nodes = doc["node"].as_array().unwrap();
        assert_eq!(nodes[0]["imu_csv"].as_str(), Some("/data/run/imu-0.csv"));
        assert!(nodes[1].get("imu_csv").is_none());
    }
}
