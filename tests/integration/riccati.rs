//! Covariance against theory: the DARE without loss (a), Sinopoli's bounds with intermittent observations (b), NEES
//! consistency (g).
#![allow(non_snake_case)]

use nalgebra::{DMatrix, DVector};
use simnet::estimate::Gaussian;
use simnet::estimate::{kalman_update, predict, MissingChannels, Observation};
use simnet::report::trace::TraceWriter;
use simnet::scenario::{Overrides, Scenario};
use simnet::sim::{Sim, SimOptions};

use crate::common;

/// A tracking-like system: position/velocity with a slowly decaying velocity, position measured.
pub const CV2: &str = r#"
name = "cv2"
[sim]
rate_hz = 100.0
duration_s = 20.0
burn_in_s = 2.0
seed = 1
[model]
kind = "linear"
a = [[1.0, 0.1], [0.0, 0.95]]
c = [[1.0, 0.0]]
q = [[0.001, 0.0], [0.0, 0.01]]
r = [[0.5]]
x0 = [0.0, 0.0]
p0 = [[1.0, 0.0], [0.0, 1.0]]
[consensus]
beta0 = 0.0
matrix = [[0.0, 0.0], [1.0, 0.0]]
[[node]]
id = 0
role = "sensor"
[[node]]
id = 1
role = "estimator"
[[edge]]
nodes = [0, 1]
directed = true
"#;

/// The filtering DARE P = A P Aᵀ − A P Cᵀ (C P Cᵀ + R)⁻¹ C P Aᵀ + Q by the structure-preserving doubling algorithm
/// (Chu, Fan, Lin 2005), written as X = Âᵀ X (I + G X)⁻¹ Â + H with Â = Aᵀ, G = Cᵀ R⁻¹ C, H = Q: a different method
/// from the filter's step-by-step recursion.
fn dare_sda(A: &DMatrix<f64>, C: &DMatrix<f64>, Q: &DMatrix<f64>, R: &DMatrix<f64>) -> DMatrix<f64> {
    let n = A.nrows();
    let I = DMatrix::<f64>::identity(n, n);
    let mut Ak = A.transpose();
    let mut G = C.transpose() * R.clone().try_inverse().unwrap() * C;
    let mut H = Q.clone();
    for _ in 0..60 {
        let W = (&I + &G * &H).try_inverse().unwrap();
        let A1 = &Ak * &W * &Ak;
        let G1 = &G + &Ak * &W * &G * Ak.transpose();
        let H1 = &H + Ak.transpose() * &H * &W * &Ak;
        let done = (&H1 - &H).amax() <= 1e-15 * H1.amax();
        Ak = A1;
        G = G1;
        H = H1;
        if done {
            break;
        }
    }
    H
}

fn linear(t: &Scenario) -> (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>, DMatrix<f64>) {
    match t.model().as_linear() {
        Some(m) => (m.A().clone(), m.C().clone(), m.Q().clone(), m.R().clone()),
        _ => panic!("linear model expected"),
    }
}

/// (a) Without loss, P_{k|k−1} converges to the DARE solution (1e-6 relative): the filter recursion checked against
/// the doubling algorithm, and the mean trace P_{k|k−1} of a networked run (sensor → estimator over UDP) against its
/// trace.
#[test]
fn prior_covariance_converges_to_the_dare() {
    let t = common::topology(CV2, Overrides::default());
    let (A, C, Q, R) = linear(&t);
    let X = dare_sda(&A, &C, &Q, &R);
    // X solves the DARE (residual check of the independent solution itself).
    let S = &C * &X * C.transpose() + &R;
    let res = &A * &X * A.transpose() - &A * &X * C.transpose() * S.try_inverse().unwrap() * &C * &X * A.transpose()
        + &Q
        - &X;
    assert!(res.amax() < 1e-12 * X.amax(), "SDA residual {}", res.amax());

    let obs = Observation {
        H: C.clone(),
        R: R.clone(),
        angle_rows: vec![false],
        channel_of_row: vec![0],
    };
    let mut g = Gaussian {
        x: DVector::zeros(2),
        P: DMatrix::identity(2, 2),
    };
    let z = DVector::from_element(1, 0.3);
    for _ in 0..2000 {
        g = kalman_update(&g, &obs, &z, &[true], MissingChannels::Drop).unwrap();
        g = predict(&g, &A, &Q);
    }
    let rel = (&g.P - &X).amax() / X.amax();
    assert!(
        rel < 1e-6,
        "P_(k|k-1) differs from the DARE solution by {rel:e} (relative)"
    );

    let s = common::simulate(t);
    let est = s
        .nodes
        .iter()
        .find(|n| n.role == simnet::scenario::Role::Estimator)
        .unwrap();
    let mean_prior = est.networked.as_ref().unwrap().mean_trace_p_prior.unwrap();
    let rel = (mean_prior - X.trace()).abs() / X.trace();
    assert!(
        rel < 1e-6,
        "networked run: mean trace P prior {mean_prior} vs trace DARE {} ({rel:e})",
        X.trace()
    );
}

/// Sinopoli et al.: S̄ = (1−λ) A S̄ Aᵀ + Q (a Lyapunov equation, solved by iteration) and V̄ = g_λ(V̄) iterated from 0.
fn sinopoli_bounds(lambda: f64) -> (f64, f64) {
    let (a, c, q, r) = (-1.25f64, 1.0f64, 1.0f64, 2.5f64);
    let mut s = 0.0;
    for _ in 0..100_000 {
        s = (1.0 - lambda) * a * s * a + q;
    }
    let mut v = 0.0;
    for _ in 0..100_000 {
        v = a * v * a + q - lambda * a * v * c * (c * v * c + r).recip() * c * v * a;
    }
    (s, v)
}

/// (b) Long-run mean of trace P_{k|k−1} between trace S̄ and trace V̄ at arrival rates 0.5 and 0.8; at 0.2, below
/// λ_c = 0.36, the covariance diverges and the summary says so.
#[test]
fn sinopoli_scalar_bounds_hold_and_divergence_is_reported() {
    for (lambda, duration) in [(0.5, 1000.0), (0.8, 200.0)] {
        let (s_bar, v_bar) = sinopoli_bounds(lambda);
        let reference = if lambda == 0.5 {
            (4.5714, 11.9559)
        } else {
            (1.4545, 4.3382)
        };
        assert!((s_bar - reference.0).abs() / reference.0 < 1e-3 && (v_bar - reference.1).abs() / reference.1 < 1e-3);
        let o = Overrides {
            duration_s: Some(duration),
            ..common::bernoulli(1.0 - lambda, 1)
        };
        let s = common::simulate(common::topology("sinopoli-scalar", o));
        let est = s
            .nodes
            .iter()
            .find(|n| n.role == simnet::scenario::Role::Estimator)
            .unwrap();
        let net = est.networked.as_ref().unwrap();
        let mean = net.mean_trace_p_prior.unwrap();
        println!("λ = {lambda}: S̄ = {s_bar:.4} ≤ measured {mean:.4} ≤ V̄ = {v_bar:.4}");
        assert!(
            s_bar < mean && mean < v_bar,
            "λ = {lambda}: {mean} outside [{s_bar}, {v_bar}]"
        );
        assert!(!net.diverged);
        // The link really delivered about λ of the datagrams.
        let delivered = s.links[0].delivered as f64 / s.links[0].sent as f64;
        let sigma = (lambda * (1.0 - lambda) / s.links[0].sent as f64).sqrt();
        assert!((delivered - lambda).abs() < 3.0 * sigma, "delivered {delivered}");
    }
    let s = common::simulate(common::topology("sinopoli-scalar", common::bernoulli(0.8, 1)));
    let est = s
        .nodes
        .iter()
        .find(|n| n.role == simnet::scenario::Role::Estimator)
        .unwrap();
    assert!(
        est.networked.as_ref().unwrap().diverged,
        "λ = 0.2 < λc must be reported as diverged"
    );
}

/// (g) NEES of the linear filter without loss: over M independent runs, Σ NEES at a fixed step is χ²(nM); it lies in
/// the two-sided 95 % band.
#[test]
fn linear_nees_is_in_its_chi_square_band() {
    let runs = 100u64;
    let step = 400u64;
    let mut sum = 0.0;
    for seed in 1..=runs {
        let t = common::topology(CV2, common::seed(seed));
        let opts = SimOptions {
            trace: Some(TraceWriter::for_topology(&t).keep_all()),
            ..Default::default()
        };
        let mut sim = Sim::with_options(&t, opts).unwrap();
        for _ in 0..=step {
            sim.step().unwrap();
        }
        let (rows, _) = sim.finish().trace.unwrap().finish().unwrap();
        let id = t.nodes()[1].id;
        let row = rows
            .iter()
            .find(|row| row.step == step && row.filter == simnet::observe::Filter::Networked && row.node == id)
            .unwrap();
        sum += row.nees;
    }
    let dof = 2.0 * runs as f64;
    let (lo, hi) = (
        simnet::stats::chi2_quantile(0.025, dof),
        simnet::stats::chi2_quantile(0.975, dof),
    );
    println!("Σ NEES = {sum:.1}, 95 % band of χ²({dof}) = [{lo:.1}, {hi:.1}]");
    assert!(lo < sum && sum < hi, "Σ NEES {sum} outside [{lo}, {hi}]");
}
