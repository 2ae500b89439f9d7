//! The observer's view of the distributed estimators: each one's disagreement across nodes and median-over-nodes
//! error every step, and the centralized reference — one fusion center that has every sensing node's measurement
//! of the step, with no loss, predicting with the center's IMU (the optimum for a linear model).
#![allow(non_snake_case)]

use std::collections::BTreeMap;
use std::sync::Arc;

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::estimate::{Gaussian, Observation};
use crate::estimators::{Centralized, Context, Estimator, Kind, Message, StepInput};
use crate::model::{FusionLayout, Model};
use crate::node::Feed;
use crate::observe::metrics::FilterMetrics;
use crate::observe::StepEstimate;
use crate::scenario::Scenario;

/// One estimator's error at one step, for plots: the median over the nodes (the reference's own).
#[derive(Debug, Clone, PartialEq)]
pub struct SchemeRow {
    pub step: u64,
    pub kind: Kind,
    pub median_error: f64,
    pub disagreement: f64,
}

/// One node's estimate of one estimator at one step, for `estimators.csv`: the error rows and the error.
#[derive(Debug, Clone, PartialEq)]
pub struct EstimatorRow {
    pub step: u64,
    pub kind: Kind,
    /// The node's id in the file (the center's for the reference).
    pub node: u32,
    pub error: f64,
    /// The estimate's error rows ([`FusionLayout::pick`]).
    pub values: Vec<f64>,
}

/// What the observer measured of one estimator.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Agreement {
    /// Mean over the counted steps of the mean distance of the node estimates from their average (error rows).
    pub disagreement: Option<f64>,
    /// Mean over the counted steps of the median-over-nodes error.
    pub median_error: Option<f64>,
}

#[derive(Default)]
struct Sums {
    disagreement: f64,
    median: f64,
    n_median: u64,
    n: u64,
}

pub struct SchemeObserver {
    layout: FusionLayout,
    burn_in: u64,
    sums: BTreeMap<Kind, Sums>,
    reference: Option<Reference>,
    rows: Vec<SchemeRow>,
    node_rows: Vec<EstimatorRow>,
    ids: Vec<u32>,
    record: bool,
}

impl SchemeObserver {
    pub fn new(scenario: &Scenario, record: bool) -> SchemeObserver {
        let e = scenario.estimators();
        SchemeObserver {
            layout: scenario.model().get().fusion(),
            burn_in: scenario.sim().burn_in_steps(),
            sums: BTreeMap::new(),
            reference: e
                .run
                .contains(&Kind::Centralized)
                .then(|| Reference::new(scenario))
                .flatten(),
            rows: Vec::new(),
            node_rows: Vec::new(),
            ids: scenario.nodes().iter().map(|n| n.id).collect(),
            record,
        }
    }

    /// One step's estimates of every estimating node.
    pub fn push(&mut self, estimates: &[StepEstimate]) {
        let Some(first) = estimates.first() else { return };
        let (step, truth) = (first.step, &first.truth);
        let mut by_kind: BTreeMap<Kind, Vec<Vec<f64>>> = BTreeMap::new();
        let known = self.layout.error_rows.iter().all(|&i| truth[i].is_finite());
        let t = self.layout.pick(truth);
        for e in estimates {
            for (k, x) in &e.schemes {
                let values = self.layout.pick(x);
                if self.record {
                    self.node_rows.push(EstimatorRow {
                        step,
                        kind: *k,
                        node: self.ids.get(e.node).copied().unwrap_or(e.node as u32),
                        error: if known {
                            self.layout.distance(&t, &values)
                        } else {
                            f64::NAN
                        },
                        values: values.clone(),
                    });
                }
                by_kind.entry(*k).or_default().push(values);
            }
        }
        for (kind, xs) in by_kind {
            let mean = self.mean(&xs);
            let dis = xs.iter().map(|x| self.layout.distance(x, &mean)).sum::<f64>() / xs.len() as f64;
            let median = known.then(|| {
                let errs: Vec<f64> = xs.iter().map(|x| self.layout.distance(&t, x)).collect();
                crate::stats::median(&errs)
            });
            self.record(step, kind, median, dis);
        }
    }

    fn record(&mut self, step: u64, kind: Kind, median: Option<f64>, dis: f64) {
        let s = self.sums.entry(kind).or_default();
        if step >= self.burn_in && dis.is_finite() {
            s.disagreement += dis;
            s.n += 1;
            if let Some(m) = median.filter(|m| m.is_finite()) {
                s.median += m;
                s.n_median += 1;
            }
        }
        if self.record {
            self.rows.push(SchemeRow {
                step,
                kind,
                median_error: median.unwrap_or(f64::NAN),
                disagreement: dis,
            });
        }
    }

    /// The mean of picks of the error rows (quaternions brought to one sign and normalised).
    fn mean(&self, xs: &[Vec<f64>]) -> Vec<f64> {
        let n = xs.first().map_or(0, Vec::len);
        let mut m = vec![0.0; n];
        for x in xs {
            let sign = if self.layout.quaternion && x.iter().zip(&xs[0]).map(|(a, b)| a * b).sum::<f64>() < 0.0 {
                -1.0
            } else {
                1.0
            };
            m.iter_mut().zip(x).for_each(|(a, b)| *a += sign * b);
        }
        m.iter_mut().for_each(|a| *a /= xs.len() as f64);
        if self.layout.quaternion {
            let norm = m.iter().map(|v| v * v).sum::<f64>().sqrt();
            if norm > 0.0 {
                m.iter_mut().for_each(|a| *a /= norm);
            }
        }
        m
    }

    /// One step's feeds of every node that was up: the reference updates.
    pub fn push_feeds(&mut self, feeds: Vec<Feed>) {
        let Some(r) = self.reference.as_mut() else { return };
        if let Some((step, error, values)) = r.step(feeds, &self.layout) {
            if self.record {
                self.node_rows.push(EstimatorRow {
                    step,
                    kind: Kind::Centralized,
                    node: self.ids.get(r.center).copied().unwrap_or(r.center as u32),
                    error: error.unwrap_or(f64::NAN),
                    values,
                });
            }
            self.record(step, Kind::Centralized, error, 0.0);
        }
    }

    /// Every step's median error and disagreement of every estimator (with `record`).
    pub fn rows(&self) -> &[SchemeRow] {
        &self.rows
    }

    /// The node rows since the last call (with `record`), for `estimators.csv`.
    pub fn drain_node_rows(&mut self) -> Vec<EstimatorRow> {
        std::mem::take(&mut self.node_rows)
    }

    pub fn agreement(&self, kind: Kind) -> Agreement {
        let Some(s) = self.sums.get(&kind) else {
            return Agreement::default();
        };
        let mean = |sum: f64, n: u64| (n > 0).then(|| sum / n as f64).filter(|v| v.is_finite());
        Agreement {
            disagreement: mean(s.disagreement, s.n),
            median_error: mean(s.median, s.n_median),
        }
    }

    /// The reference's figures and its center node.
    pub fn reference(&self) -> Option<(usize, &FilterMetrics)> {
        self.reference
            .as_ref()
            .map(|r| (r.center, r.scorer.metrics(crate::observe::Filter::Networked)))
    }
}

/// The centralized reference: [`Centralized`] at the center node, fed every sensing node's measurement.
struct Reference {
    center: usize,
    model: Arc<dyn Model>,
    obs: Observation,
    Q: DMatrix<f64>,
    dt: f64,
    est: Option<Centralized>,
    ctx: Context,
    scorer: crate::observe::Scorer,
}

impl Reference {
    /// The center is the first sensing node (its IMU drives the prediction); none in a network without one.
    fn new(s: &Scenario) -> Option<Reference> {
        let center = s.nodes().iter().position(|n| n.role.senses())?;
        let model = s.model().shared();
        let dt = s.sim().dt();
        let obs = model.observation();
        Some(Reference {
            center,
            Q: model.process_noise(Some(&s.nodes()[center].sensor), dt),
            ctx: Context {
                index: center,
                nodes: s.nodes().len(),
                weights: Vec::new(),
                self_weight: 1.0,
                angle_states: model.angle_states(),
            },
            scorer: crate::observe::Scorer::new(model.clone(), s.sim().burn_in_steps(), s.sim().divergence_trace),
            obs,
            dt,
            model,
            est: None,
        })
    }

    /// Step with `feeds`; the step and the error.
    fn step(&mut self, mut feeds: Vec<Feed>, layout: &FusionLayout) -> Option<(u64, Option<f64>, Vec<f64>)> {
        feeds.sort_by_key(|f| f.node);
        let c = feeds.iter().position(|f| f.node == self.center)?;
        let center = feeds.remove(c);
        let est = match (&mut self.est, &center.prior) {
            (Some(e), None) => {
                let (model, Q, dt, u, shift) = (&self.model, &self.Q, self.dt, center.imu, &center.shift);
                e.predict(&|g: &Gaussian| {
                    let mut p = model.predict(g, u.as_ref(), Q, dt);
                    if let Some(s) = shift {
                        p.x += s;
                    }
                    p
                });
                e
            }
            (_, prior) => {
                let g = prior.clone().unwrap_or_else(|| Gaussian {
                    x: DVector::zeros(self.obs.H.ncols()),
                    P: DMatrix::identity(self.obs.H.ncols(), self.obs.H.ncols()),
                });
                self.est.insert(Centralized::new(self.ctx.clone(), Some(g)))
            }
        };
        let prior = est.state().cloned()?;
        let input = StepInput {
            obs: &self.obs,
            own: center.own.as_ref(),
        };
        let messages: Vec<(usize, Message)> = feeds
            .into_iter()
            .filter_map(|f| f.own.map(|m| (f.node, Message::Measurement(m))))
            .collect();
        let arrived: Vec<(usize, &Message)> = messages.iter().map(|(j, m)| (*j, m)).collect();
        let ok = est
            .begin(&input)
            .and_then(|_| est.combine(0, &arrived, &input))
            .and_then(|_| est.finish(&input));
        if ok.is_err() {
            est.reset(prior.clone());
        }
        let post = est.state().cloned()?;
        let score = self.scorer.score(&crate::observe::Update {
            node: self.center as u32,
            step: center.step,
            t: center.step as f64 * self.dt,
            filter: crate::observe::Filter::Networked,
            truth: &center.truth,
            prior: &prior,
            post: &post,
            failed: ok.is_err(),
            feasible: true,
            received: &[],
        });
        Some((center.step, score.error, layout.pick(&post.x)))
    }
}
