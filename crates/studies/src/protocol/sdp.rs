//! General β search with Clarabel's PSD cones (feature `sdp`): for each node, the most weight to its neighbours over
//! all β (not only the family) such that (17) and (19) hold at every recorded step of a run.
//!
//! At a step the data P, A = (1 − β₀) K S Kᵀ and K z̃ⱼ are fixed and the conditions are matrix inequalities in β:
//! - (19) D + Σ βⱼ Fⱼ − C ≻ 0 with C = (Σ βⱼ K z̃ⱼ)(·)ᵀ is, by a Schur complement, the LMI
//!   [[D + Σ βⱼ Fⱼ, Σ βⱼ K z̃ⱼ], [·ᵀ, 1]] ≻ 0 — exact and convex in β;
//! - (17) −I ≺ Z ≺ I with Z = e^{γk}/α (−A − C + Σ βⱼ Fⱼ): the lower side is the same Schur form with P replaced by
//!   I·α e^{−γk}; the upper side I·α e^{−γk} + A − Σ βⱼ Fⱼ + C ≻ 0 is not convex in β, and dropping C ⪰ 0 gives the
//!   convex inner approximation I·α e^{−γk} + A − Σ βⱼ Fⱼ ⪰ 0 (the paper's "relaxation by scaling terms", §3).
//!
//! Every solution therefore satisfies the exact conditions. Steps enter by constraint generation: solve, check every
//! recorded step directly ([`simnet_engine::estimate::LmiTerms::check`]), add the worst violated steps, solve again.
//! Linear constraints: 0 ≤ βᵢⱼ ≤ βᵢᵢ ≤ 1 (each node privileges its own measurement, as the paper's protocols do)
//! and Σⱼ βᵢⱼ ≤ σ.

#![allow(non_snake_case)]

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, NonnegativeConeT, PSDTriangleConeT, SolverStatus, SupportedConeT,
};
use nalgebra::{DMatrix, DVector};

use super::{evaluate, run_in_memory, sources_of, Evaluation, SearchConfig};
use simnet_engine::node::LmiStep;
use simnet_engine::scenario::Scenario;

// Links the system OpenBLAS that Clarabel's PSD cones call.
extern crate openblas_src;

#[derive(Debug, thiserror::Error)]
pub enum SdpError {
    #[error("the SDP for node {node} did not solve: {status}")]
    Solver { node: usize, status: String },
    #[error("node {node}: no β keeps (17) and (19) at step {step} even with independent weights; raise α")]
    Infeasible { node: usize, step: u64 },
    #[error(transparent)]
    Protocol(#[from] super::ProtocolError),
}

/// Strictness margin of the scaled LMIs (their blocks are normalised to order 1).
const MARGIN: f64 = 1e-7;
/// Steps added per constraint-generation round.
const ADD_PER_ROUND: usize = 16;
const MAX_ROUNDS: usize = 60;

/// Weights `vars` (node indices, `own` among them) of one node's row: the most weight to the others such that every
/// step in `steps` passes the direct checks. Returns the weights in the order of `vars` and the steps used as cones.
pub fn max_exchange(
    own: usize,
    vars: &[usize],
    steps: &[&LmiStep],
    max_row_sum: f64,
) -> Result<(Vec<f64>, usize), SdpError> {
    let mut active: Vec<usize> = Vec::new();
    for _ in 0..MAX_ROUNDS {
        let beta = solve(own, vars, steps, &active, max_row_sum)?;
        let mut violated: Vec<(f64, usize)> = steps
            .iter()
            .enumerate()
            .filter(|(s, _)| !active.contains(s))
            .filter_map(|(s, st)| {
                let c = st.terms.check(&step_weights(st, vars, &beta));
                (!c.feasible()).then(|| (slack(&c, st), s))
            })
            .collect();
        if violated.is_empty() {
            return Ok((beta, active.len()));
        }
        violated.sort_by(|a, b| a.0.total_cmp(&b.0));
        active.extend(violated.iter().take(ADD_PER_ROUND).map(|v| v.1));
    }
    Err(SdpError::Solver {
        node: own,
        status: format!("constraint generation did not settle in {MAX_ROUNDS} rounds"),
    })
}

/// The weights of a step's sources, from a row given over `vars`; a source outside `vars` gets 0.
pub fn step_weights(step: &LmiStep, vars: &[usize], beta: &[f64]) -> Vec<f64> {
    step.sources
        .iter()
        .map(|j| vars.iter().position(|v| v == j).map_or(0.0, |p| beta[p]))
        .collect()
}

/// How badly a check fails (more negative is worse), in units comparable across steps.
fn slack(c: &simnet_engine::estimate::LmiCheck, st: &LmiStep) -> f64 {
    let scale = st.terms.P.diagonal().amax().max(f64::MIN_POSITIVE);
    (1.0 - c.norm_z).min(c.min_eig / scale)
}

/// Upper triangle, column by column, off-diagonals × √2: Clarabel's PSD triangle vectorisation.
fn svec(m: &DMatrix<f64>) -> Vec<f64> {
    let n = m.nrows();
    let mut v = Vec::with_capacity(n * (n + 1) / 2);
    for c in 0..n {
        for r in 0..=c {
            v.push(if r == c {
                m[(r, c)]
            } else {
                m[(r, c)] * std::f64::consts::SQRT_2
            });
        }
    }
    v
}

/// [[c·X, √c·y], [√c·yᵀ, t]].
fn bordered(X: &DMatrix<f64>, y: &DVector<f64>, t: f64, c: f64) -> DMatrix<f64> {
    let n = X.nrows();
    let mut M = DMatrix::zeros(n + 1, n + 1);
    M.view_mut((0, 0), (n, n)).copy_from(&(X * c));
    let ys = y * c.sqrt();
    M.view_mut((0, n), (n, 1)).copy_from(&ys);
    M.view_mut((n, 0), (1, n)).copy_from(&ys.transpose());
    M[(n, n)] = t;
    M
}

fn solve(own: usize, vars: &[usize], steps: &[&LmiStep], active: &[usize], sigma: f64) -> Result<Vec<f64>, SdpError> {
    let nv = vars.len();
    let own_at = vars.iter().position(|v| *v == own).expect("own weight is a variable");
    // Rows of s = b − A x, kept as columns of A (one per variable) plus b.
    let mut cols: Vec<Vec<(usize, f64)>> = vec![Vec::new(); nv];
    let mut b: Vec<f64> = Vec::new();
    let mut cones: Vec<SupportedConeT<f64>> = Vec::new();
    let row = |b: &mut Vec<f64>, cols: &mut Vec<Vec<(usize, f64)>>, coeffs: &[(usize, f64)], rhs: f64| {
        let r = b.len();
        b.push(rhs);
        for &(j, a) in coeffs {
            cols[j].push((r, a));
        }
    };
    // Linear: −βⱼ ≤ 0; βⱼ − βᵢ ≤ 0; βᵢ ≤ 1; Σ β ≤ σ.
    for j in 0..nv {
        row(&mut b, &mut cols, &[(j, -1.0)], 0.0);
        if j != own_at {
            row(&mut b, &mut cols, &[(j, 1.0), (own_at, -1.0)], 0.0);
        }
    }
    row(&mut b, &mut cols, &[(own_at, 1.0)], 1.0);
    let all: Vec<(usize, f64)> = (0..nv).map(|j| (j, 1.0)).collect();
    row(&mut b, &mut cols, &all, sigma);
    cones.push(NonnegativeConeT(b.len()));

    for &s in active {
        let st = &steps[s].terms;
        let n = st.P.nrows();
        let c = 1.0 / st.P.diagonal().amax().max(f64::MIN_POSITIVE);
        let bound = DMatrix::identity(n, n) / st.scale; // I·α e^{−γk}
        let at: Vec<Option<usize>> = steps[s]
            .sources
            .iter()
            .map(|j| vars.iter().position(|v| v == j))
            .collect();
        let F = |kz: &DVector<f64>| kz * kz.transpose();
        // (19) and the lower side of (17): s = M0 + Σ βⱼ Mⱼ, so A's column j is −svec(Mⱼ).
        for base in [&st.P - &st.A, &bound - &st.A] {
            let m0 = bordered(&base, &DVector::zeros(n), 1.0, c) - DMatrix::identity(n + 1, n + 1) * MARGIN;
            let r0 = b.len();
            b.extend(svec(&m0));
            for (kz, p) in st.kz.iter().zip(&at) {
                if let Some(j) = p {
                    for (r, v) in svec(&bordered(&F(kz), kz, 0.0, c)).into_iter().enumerate() {
                        if v != 0.0 {
                            cols[*j].push((r0 + r, -v));
                        }
                    }
                }
            }
            cones.push(PSDTriangleConeT(n + 1));
        }
        // Upper side of (17), inner approximation: s = c(I·α e^{−γk} + A) − Σ βⱼ c Fⱼ.
        let m0 = (&bound + &st.A) * c - DMatrix::identity(n, n) * MARGIN;
        let r0 = b.len();
        b.extend(svec(&m0));
        for (kz, p) in st.kz.iter().zip(&at) {
            if let Some(j) = p {
                for (r, v) in svec(&(F(kz) * c)).into_iter().enumerate() {
                    if v != 0.0 {
                        cols[*j].push((r0 + r, v));
                    }
                }
            }
        }
        cones.push(PSDTriangleConeT(n));
    }

    let m = b.len();
    let mut colptr = vec![0];
    let (mut rowval, mut nzval) = (Vec::new(), Vec::new());
    for c in &mut cols {
        c.sort_by_key(|e| e.0);
        for &(r, v) in c.iter() {
            rowval.push(r);
            nzval.push(v);
        }
        colptr.push(rowval.len());
    }
    let A = CscMatrix::new(m, nv, colptr, rowval, nzval);
    let P = CscMatrix::<f64>::zeros((nv, nv));
    let q: Vec<f64> = (0..nv).map(|j| if j == own_at { 0.0 } else { -1.0 }).collect();
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .build()
        .expect("static settings are valid");
    let mut solver = DefaultSolver::new(&P, &q, &A, &b, &cones, settings).map_err(|e| SdpError::Solver {
        node: own,
        status: format!("{e:?}"),
    })?;
    solver.solve();
    match solver.solution.status {
        SolverStatus::Solved | SolverStatus::AlmostSolved => Ok(solver.solution.x.clone()),
        SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible => Err(SdpError::Infeasible {
            node: own,
            step: active.last().map_or(0, |&s| steps[s].k),
        }),
        other => Err(SdpError::Solver {
            node: own,
            status: format!("{other:?}"),
        }),
    }
}

#[derive(Debug, Clone, serde::Serialize)]
pub struct SdpResult {
    /// β rounded down to 1e-4 (so that rounding cannot leave the feasible set).
    pub beta: Vec<Vec<f64>>,
    pub evaluation: Evaluation,
    /// Run-and-solve rounds until a run with the solution stayed feasible on every seed.
    pub rounds: usize,
    /// PSD cone triples (steps) the nodes' final SDPs carried, summed over nodes.
    pub steps_as_cones: usize,
}

/// Alternate runs and SDPs: record every node's LMI terms in runs with the current β (starting at `start`), solve
/// each node's SDP over all recorded steps so far, until a run with the solution is feasible on every seed.
pub fn search(
    topo: &Scenario,
    cfg: &SearchConfig,
    start: &[Vec<f64>],
    max_rounds: usize,
) -> Result<SdpResult, SdpError> {
    let n = topo.nodes().len();
    let mut pool: Vec<Vec<LmiStep>> = vec![Vec::new(); n];
    let mut beta = start.to_vec();
    let mut last = None;
    for round in 1..=max_rounds {
        let t = super::with_protocol(topo, &beta).map_err(super::ProtocolError::from)?;
        for &seed in &cfg.seeds {
            let logs = run_in_memory(&t, seed, true)?.lmi;
            for (p, l) in pool.iter_mut().zip(logs) {
                p.extend(l);
            }
        }
        let mut next = beta.clone();
        let mut cones = 0;
        for i in 0..n {
            let role = topo.nodes()[i].role;
            let src = sources_of(topo, i);
            if !(role.senses() && role.estimates()) || src.is_empty() {
                continue;
            }
            let mut vars = src;
            vars.push(i);
            vars.sort_unstable();
            let steps: Vec<&LmiStep> = pool[i].iter().collect();
            let (w, used) = max_exchange(i, &vars, &steps, cfg.max_row_sum)?;
            cones += used;
            next[i].iter_mut().for_each(|b| *b = 0.0);
            for (j, v) in vars.iter().zip(w) {
                next[i][*j] = ((v.max(0.0)) * 1e4).floor() / 1e4;
            }
        }
        let e = evaluate(topo, &next, f64::NAN, &cfg.seeds)?;
        let done = e.feasible();
        beta = next;
        last = Some(SdpResult {
            beta: beta.clone(),
            evaluation: e,
            rounds: round,
            steps_as_cones: cones,
        });
        if done {
            break;
        }
    }
    Ok(last.expect("at least one round"))
}
