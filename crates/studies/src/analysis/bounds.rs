//! Sinopoli's covariance bounds (S̄ ≤ lim E[P_{k|k−1}] ≤ V̄, [`simnet_engine::estimate::bounds`]) of a linear model, set
//! against the mean trace P_{k|k−1} that whole in-memory runs measure at each arrival rate λ.
#![allow(non_snake_case)]

use nalgebra::DMatrix;

use simnet_engine::checks::Checks;
use simnet_engine::estimate::bounds::{
    critical_upper, lambda_min, lower_bound, markov_condition, spectral_radius, upper_bound, Critical, FixedPoint,
};
use simnet_engine::estimate::EstimateError;
use simnet_engine::link::LossModel;
use simnet_engine::model::matrix_rows;
use simnet_engine::scenario::{Overrides, Role, Scenario, ScenarioError};
use simnet_engine::sim::{Sim, SimError};

#[derive(Debug, thiserror::Error)]
pub enum BoundsError {
    #[error("`{name}` has {what}: bounds need y = C x + v (kind = \"linear\", observe = \"state\")")]
    NotLinear { name: String, what: String },
    #[error("the eigenvalues of A did not converge")]
    Eigenvalues,
    #[error("`{0}` has no estimator node fed over the network: nothing to measure")]
    NoEstimator(String),
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    #[error(transparent)]
    Sim(#[from] SimError),
    #[error(transparent)]
    Estimate(#[from] EstimateError),
}

/// x⁺ = A x + w (cov Q), y = C x + v (cov R), checked as a topology's `[model]` table is.
#[derive(Debug, Clone)]
pub struct System {
    pub A: DMatrix<f64>,
    pub C: DMatrix<f64>,
    pub Q: DMatrix<f64>,
    pub R: DMatrix<f64>,
}

impl System {
    /// The same checks as a `[model]` table of kind "linear" (sizes, symmetry, definiteness); `what` names the
    /// matrices' origin in the errors.
    pub fn new(
        A: DMatrix<f64>,
        C: DMatrix<f64>,
        Q: DMatrix<f64>,
        R: DMatrix<f64>,
        what: &str,
    ) -> Result<System, BoundsError> {
        let raw = simnet_engine::model::RawModel {
            kind: Some("linear".into()),
            a: Some(matrix_rows(&A)),
            c: Some(matrix_rows(&C)),
            q: Some(matrix_rows(&Q)),
            r: Some(matrix_rows(&R)),
            ..Default::default()
        };
        let mut ck = Checks::default();
        simnet_engine::model::parse(raw, &mut ck);
        if !ck.problems.is_empty() {
            return Err(ScenarioError::Invalid {
                file: what.to_string(),
                problems: ck.problems,
            }
            .into());
        }
        Ok(System { A, C, Q, R })
    }

    /// The linear model of `scenario`.
    pub fn of(scenario: &Scenario) -> Result<System, BoundsError> {
        let m = scenario.model().as_linear().ok_or_else(|| BoundsError::NotLinear {
            name: scenario.name().to_string(),
            what: match scenario.model() {
                simnet_engine::model::ModelConfig::Ranged { .. } => "a linear model observed by ranges".into(),
                m => format!("a {} model", m.kind()),
            },
        })?;
        Ok(System {
            A: m.A().clone(),
            C: m.C().clone(),
            Q: m.Q().clone(),
            R: m.R().clone(),
        })
    }
}

/// What the system's spectrum says before any λ is chosen.
#[derive(Debug, Clone, Copy)]
pub struct Stability {
    /// ρ(A).
    pub rho: f64,
    /// λ_min = 1 − 1/ρ(A)²: below it the expected covariance diverges.
    pub lambda_min: f64,
    /// λ̄, where the MARE stops having a fixed point (∞: even without loss the filter is unstable).
    pub critical: Critical,
}

pub fn stability(s: &System) -> Result<Stability, BoundsError> {
    Ok(Stability {
        rho: spectral_radius(&s.A).ok_or(BoundsError::Eigenvalues)?,
        lambda_min: lambda_min(&s.A).unwrap_or(f64::NAN),
        critical: critical_upper(&s.A, &s.C, &s.Q, &s.R, 1e-6)?,
    })
}

/// S̄ and V̄ at arrival rate λ.
pub fn at(s: &System, lambda: f64) -> Result<(FixedPoint, FixedPoint), BoundsError> {
    Ok((
        lower_bound(&s.A, &s.Q, lambda)?,
        upper_bound(&s.A, &s.C, &s.Q, &s.R, lambda)?,
    ))
}

/// The Gilbert–Elliott condition for `loss` ([`markov_condition`]): (ρ(A)² ρ(T D), ρ(T D), holds), and whether it is
/// also sufficient here (scalar, or C invertible). None for Bernoulli loss.
pub fn markov(s: &System, loss: &LossModel) -> Option<((f64, f64, bool), bool)> {
    let LossModel::GilbertElliott {
        p,
        r,
        one_minus_h,
        one_minus_k,
    } = *loss
    else {
        return None;
    };
    let exact = s.A.nrows() == 1 || (s.C.is_square() && s.C.clone().try_inverse().is_some());
    markov_condition(&s.A, p, r, one_minus_h, one_minus_k).map(|m| (m, exact))
}

/// The mean trace P_{k|k−1} over the estimator nodes of `scenario` run in memory with i.i.d. arrivals at rate λ
/// (Bernoulli loss 1 − λ on every link); none when no estimator reports one.
pub fn measure(scenario: &Scenario, lambda: f64) -> Result<Option<f64>, BoundsError> {
    let t = scenario.with(&Overrides {
        loss: Some(LossModel::Bernoulli { p: 1.0 - lambda }),
        ..Default::default()
    })?;
    let estimators: Vec<u32> = t
        .nodes()
        .iter()
        .filter(|n| n.role == Role::Estimator)
        .map(|n| n.id)
        .collect();
    if estimators.is_empty() {
        return Err(BoundsError::NoEstimator(t.name().to_string()));
    }
    let s = Sim::new(&t)?.run()?.summary();
    let v: Vec<f64> = s
        .nodes
        .iter()
        .filter(|n| estimators.contains(&n.id))
        .filter_map(|n| n.networked.as_ref().and_then(|f| f.mean_trace_p_prior))
        .collect();
    Ok((!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64))
}

/// One λ of a sweep: the bounds and, when a scenario was given, the measured mean.
#[derive(Debug, Clone)]
pub struct SweepRow {
    pub lambda: f64,
    pub lower: FixedPoint,
    pub upper: FixedPoint,
    pub measured: Option<f64>,
}

/// Twelve arrival rates from just above `start` (λ̄, or λ_min when λ̄ is infinite) to 1.
pub fn grid(st: &Stability) -> Vec<f64> {
    let bar = st.critical.value();
    let start = if bar.is_finite() { bar } else { st.lambda_min };
    (1..=12)
        .map(|i| start + (1.0 - start) * i as f64 / 12.0)
        .filter(|l| *l < 1.0 + 1e-12)
        .collect()
}

/// The bounds at each λ of `lambdas`, each measured on `scenario` when given; `tick` after each.
pub fn sweep(
    s: &System,
    lambdas: &[f64],
    scenario: Option<&Scenario>,
    tick: &mut dyn FnMut(&SweepRow),
) -> Result<Vec<SweepRow>, BoundsError> {
    let mut rows = Vec::with_capacity(lambdas.len());
    for &lambda in lambdas {
        let (lower, upper) = at(s, lambda)?;
        let measured = match scenario {
            Some(t) => measure(t, lambda)?,
            None => None,
        };
        let row = SweepRow {
            lambda,
            lower,
            upper,
            measured,
        };
        tick(&row);
        rows.push(row);
    }
    Ok(rows)
}

/// `bounds.csv`: λ, trace S̄, trace V̄, the measured mean (empty where there is none).
pub fn csv(rows: &[SweepRow]) -> String {
    let o = |v: Option<f64>| v.map_or(String::new(), |x| format!("{x}"));
    let mut out = String::from("lambda,trace_s_bar,trace_v_bar,measured_trace_p_prior\n");
    for r in rows {
        out += &format!(
            "{},{},{},{}\n",
            r.lambda,
            o(r.lower.matrix().map(|m| m.trace())),
            o(r.upper.matrix().map(|m| m.trace())),
            o(r.measured)
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Sinopoli's scalar example: a measured run lies between the bounds at every λ of the sweep, and the csv has a
    /// row per λ.
    #[test]
    fn scalar_runs_lie_between_the_bounds() {
        let t = Scenario::resolve("sinopoli-scalar").unwrap();
        let sys = System::of(&t).unwrap();
        let st = stability(&sys).unwrap();
        assert!((st.lambda_min - 0.36).abs() < 1e-12 && (st.critical.value() - 0.36).abs() < 1e-12);
        let lambdas = [0.5, 0.7, 0.9];
        let mut seen = 0;
        let rows = sweep(&sys, &lambdas, Some(&t), &mut |_| seen += 1).unwrap();
        assert_eq!((seen, csv(&rows).lines().count()), (3, 4));
        for r in &rows {
            let (s, v, m) = (
                r.lower.matrix().unwrap().trace(),
                r.upper.matrix().unwrap().trace(),
                r.measured.unwrap(),
            );
            assert!(s <= m && m <= v, "λ = {}: {s} ≤ {m} ≤ {v} fails", r.lambda);
        }
    }

    #[test]
    fn bad_systems_and_scenarios_are_errors() {
        let m = |v: &[f64], r: usize| DMatrix::from_row_slice(r, v.len() / r, v);
        let e = System::new(m(&[1.0], 1), m(&[1.0, 2.0], 1), m(&[1.0], 1), m(&[1.0], 1), "test").unwrap_err();
        assert!(e.to_string().contains("model.c"), "{e}");
        let e = System::new(m(&[f64::NAN], 1), m(&[1.0], 1), m(&[1.0], 1), m(&[1.0], 1), "test").unwrap_err();
        assert!(
            e.to_string().contains("model.a") && e.to_string().contains("finite"),
            "{e}"
        );
        let ring = Scenario::resolve("ring3").unwrap();
        assert!(matches!(System::of(&ring), Err(BoundsError::NotLinear { .. })));
        assert!(matches!(measure(&ring, 0.5), Err(BoundsError::NoEstimator(_))));
        // Ranges are not y = C x: no Riccati bound for them.
        let ranges = Scenario::resolve("ranges4").unwrap();
        let e = System::of(&ranges).unwrap_err().to_string();
        assert!(e.contains("observed by ranges") && e.contains("y = C x"), "{e}");
    }
}
