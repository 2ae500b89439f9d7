//! A model that linearises says so in `linearize_at` alone, and every estimator sees it; a model whose nodes observe
//! differently (a range from where each stands) is linearised at each measurement's site.

use std::borrow::Cow;
use std::sync::Arc;

use nalgebra::{DMatrix, DVector, Matrix2, Vector2};

use super::*;
use crate::estimate::{kalman_update, MissingChannels};
use crate::model::{Linear, Measurement, Observed, Ranges, Sensed, Sensing, Site, Truth};
use crate::sensor::Sensor;

/// z = H x + c: a linear model's observation with an offset, which only its `linearize_at` takes off.
#[derive(Debug)]
struct Offset {
    inner: Linear,
    c: f64,
}

impl Sensing for Offset {
    fn observation(&self) -> Observation {
        self.inner.observation()
    }
    fn linearize_at<'a>(
        &self,
        template: &'a Observation,
        _prior: &Gaussian,
        _site: Site,
        z: &[&'a DVector<f64>],
    ) -> (Cow<'a, Observation>, Vec<Cow<'a, DVector<f64>>>) {
        let shifted = z.iter().map(|z| Cow::Owned(z.add_scalar(-self.c))).collect();
        (Cow::Borrowed(template), shifted)
    }
    fn sense(&self, sensor: &mut Sensor, truth: &Truth, site: Site, t: f64) -> Sensed {
        self.inner.sense(sensor, truth, site, t)
    }
}

/// The independent filter of a model that only overrides `linearize_at` is the Kalman update of the measurement
/// it hands back (z − c), not of the raw one: the estimators ask the model nothing else.
#[test]
fn a_models_linearisation_reaches_every_update() {
    let A = DMatrix::from_row_slice(2, 2, &[1.0, 0.1, 0.0, 1.0]);
    let obs = Observation {
        H: DMatrix::from_row_slice(1, 2, &[1.0, 0.0]),
        R: DMatrix::from_element(1, 1, 0.25),
        angle_rows: vec![false],
        channel_of_row: vec![0],
    };
    let Q = DMatrix::identity(2, 2) * 0.01;
    let model = Observed {
        base: Arc::new(linear_model(&A, &obs, &Q)),
        sensing: Offset {
            inner: linear_model(&A, &obs, &Q),
            c: 3.0,
        },
    };
    let prior = Gaussian {
        x: DVector::from_vec(vec![0.5, -0.2]),
        P: DMatrix::from_row_slice(2, 2, &[1.0, 0.2, 0.2, 0.5]),
    };
    let own = Measurement::full(DVector::from_vec(vec![4.1]));
    let heard = [(0, &own)];
    let input = StepInput {
        model: &model,
        obs: &obs,
        node: 0,
        own: Some(&own),
        heard: &heard,
        step: 1,
    };
    let mut local = Local::new(prior.clone(), MissingChannels::Drop);
    local.finish(&input).unwrap();
    let want = kalman_update(
        &prior,
        &obs,
        &DVector::from_vec(vec![1.1]),
        &[true],
        MissingChannels::Drop,
    )
    .unwrap();
    let got = local.state().unwrap();
    assert!(
        (&got.x - &want.x).amax() < 1e-12 && (&got.P - &want.P).amax() < 1e-12,
        "{got:?} against {want:?}"
    );
    // The raw measurement would have moved the estimate elsewhere: the test can tell the two apart.
    let raw = kalman_update(&prior, &obs, &own.z, &[true], MissingChannels::Drop).unwrap();
    assert!((&raw.x - &want.x).amax() > 0.1);
}

/// Four nodes at the corners of a 20 m square ranging a body that stands still (A = I).
fn ranges() -> Observed<Ranges> {
    let obs = Observation {
        H: DMatrix::identity(2, 2),
        R: DMatrix::identity(2, 2),
        angle_rows: vec![false; 2],
        channel_of_row: vec![0; 2],
    };
    let I = DMatrix::identity(2, 2);
    Observed {
        base: Arc::new(linear_model(&I, &obs, &(&I * 0.01))),
        sensing: Ranges::planar(vec![[0.0, 0.0], [20.0, 0.0], [0.0, 20.0], [20.0, 20.0]], 2, 0.04).unwrap(),
    }
}

/// The ranges each corner reads of a body at (10, 10), with fixed errors.
fn readings(model: &Observed<Ranges>) -> Vec<Measurement> {
    let body = Vector2::new(10.0, 10.0);
    let errors = [0.1, -0.2, 0.05, 0.15];
    let at = model.sensing.sites();
    (0..4)
        .map(|i| {
            Measurement::full(DVector::from_element(
                1,
                (body - Vector2::from(at[i])).norm() + errors[i],
            ))
        })
        .collect()
}

fn range_prior() -> Gaussian {
    Gaussian {
        x: DVector::from_vec(vec![8.0, 11.0]),
        P: DMatrix::from_row_slice(2, 2, &[4.0, 0.5, 0.5, 3.0]),
    }
}

/// The stacked EKF of the four ranges, each linearised about the prior at its own corner, written out in 2 × 2
/// matrices: Y = P̄⁻¹ + Σ HᵢᵀR⁻¹Hᵢ, x = x̄ + Y⁻¹ Σ HᵢᵀR⁻¹ (zᵢ − ‖x̄ − aᵢ‖).
fn stacked_ekf(model: &Observed<Ranges>, prior: &Gaussian, z: &[Measurement]) -> (Vector2<f64>, Matrix2<f64>) {
    let x = Vector2::new(prior.x[0], prior.x[1]);
    let P = Matrix2::new(prior.P[(0, 0)], prior.P[(0, 1)], prior.P[(1, 0)], prior.P[(1, 1)]);
    let mut Y = P.try_inverse().unwrap();
    let mut u = Vector2::zeros();
    let r = model.sensing.r();
    for (a, z) in model.sensing.sites().iter().zip(z) {
        let d = x - Vector2::from(*a);
        let h = d / d.norm();
        Y += h * h.transpose() / r;
        u += h * (z.z[0] - d.norm()) / r;
    }
    let P = Y.try_inverse().unwrap();
    (x + P * u, P)
}

/// The fusion center linearises each node's range at that node's site: its update is the stacked EKF of the four
/// ranges to 1e-12, which no single site's h would give.
#[test]
fn a_center_linearises_each_range_where_it_was_taken() {
    let model = ranges();
    let z = readings(&model);
    let prior = range_prior();
    let obs = model.observation();
    let ctx = Context::new(0, 4, (vec![(0, 1.0)], 1.0), &model);
    let mut center = Centralized::new(ctx, Some(prior.clone()));
    let input = StepInput {
        model: &model,
        obs: &obs,
        node: 0,
        own: Some(&z[0]),
        heard: &[],
        step: 1,
    };
    let messages: Vec<(usize, Message)> = (1..4).map(|j| (j, Message::Measurement(z[j].clone()))).collect();
    let arrived: Vec<(usize, &Message)> = messages.iter().map(|(j, m)| (*j, m)).collect();
    center.begin(&input).unwrap();
    center.combine(0, &arrived, &input).unwrap();
    center.finish(&input).unwrap();
    let got = center.state().unwrap();
    let (x, P) = stacked_ekf(&model, &prior, &z);
    for r in 0..2 {
        assert!((got.x[r] - x[r]).abs() < 1e-12, "x: {} against {x}", got.x);
        for c in 0..2 {
            assert!((got.P[(r, c)] - P[(r, c)]).abs() < 1e-12, "P: {} against {P}", got.P);
        }
    }
    // The sites matter: the same four ranges read as if node 0 had taken them all land elsewhere.
    let alike = Observed {
        base: model.base.clone(),
        sensing: Ranges::planar(vec![model.sensing.sites()[0]; 4], 2, model.sensing.r()).unwrap(),
    };
    let (wrong, _) = stacked_ekf(&alike, &prior, &z);
    assert!((wrong - x).norm() > 1.0, "{wrong} and {x}");
    // And the four ranges bring the estimate toward the body at (10, 10).
    let body = Vector2::new(10.0, 10.0);
    assert!((x - body).norm() < 0.5 && (x - body).norm() < (Vector2::new(8.0, 11.0) - body).norm() / 4.0);
}

/// A node's own filter linearises its own measurement at its own site (the `node` of its step input).
#[test]
fn a_node_linearises_its_own_range_at_its_site() {
    let model = ranges();
    let z = readings(&model);
    let prior = range_prior();
    let obs = model.observation();
    for node in 0..4 {
        let input = StepInput {
            model: &model,
            obs: &obs,
            node,
            own: Some(&z[node]),
            heard: &[],
            step: 1,
        };
        let mut local = Local::new(prior.clone(), MissingChannels::Drop);
        local.finish(&input).unwrap();
        // One range alone: the stacked EKF of that corner.
        let one = Observed {
            base: model.base.clone(),
            sensing: Ranges::planar(vec![model.sensing.sites()[node]], 2, model.sensing.r()).unwrap(),
        };
        let (x, P) = stacked_ekf(&one, &prior, &z[node..=node]);
        let got = local.state().unwrap();
        assert!(
            (got.x[0] - x[0]).abs() < 1e-12 && (got.x[1] - x[1]).abs() < 1e-12,
            "node {node}: {}",
            got.x
        );
        assert!((got.P[(0, 1)] - P[(0, 1)]).abs() < 1e-12, "node {node}: {}", got.P);
    }
}

/// Sequeira's consensus forms one gain from one h for every source (eqs. (5)–(10)): with nodes that observe
/// differently it refuses, naming why, and leaves its estimate as it was.
#[test]
fn sequeira_refuses_nodes_that_observe_differently() {
    let model = ranges();
    let z = readings(&model);
    let prior = range_prior();
    let obs = model.observation();
    let heard: Vec<(usize, &Measurement)> = z.iter().enumerate().collect();
    let input = StepInput {
        model: &model,
        obs: &obs,
        node: 0,
        own: Some(&z[0]),
        heard: &heard,
        step: 1,
    };
    let params = SequeiraParams {
        index: 0,
        beta0: 0.0,
        beta: (0..4).map(|j| (j, 0.25)).collect(),
        alpha: 1.0,
        gamma: 0.0,
        guard: false,
        policy: MissingChannels::Drop,
    };
    let mut s = Sequeira::new(prior.clone(), params);
    let e = s.finish(&input).unwrap_err();
    assert!(
        matches!(e, EstimateError::Unsupported { scheme: "sequeira", .. }),
        "{e}"
    );
    assert!(e.to_string().contains("eqs. (5)–(10)"), "{e}");
    assert_eq!(s.state(), Some(&prior));
}
