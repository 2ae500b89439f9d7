//! The observer's view of the distributed estimators: each one's disagreement across nodes and median-over-nodes
//! error every step, and the two fusion centers at the sink, predicting with its IMU: `centralized`, which has every
//! sensing node's measurement of the step with no loss (the optimum for a linear model), and `centralized-net`,
//! which has those that reach the sink over lossy links by the deadline.
#![allow(non_snake_case)]

use std::collections::BTreeMap;
use std::sync::Arc;

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::estimate::fusion::Omega;
use crate::estimate::{Gaussian, Observation};
use crate::estimators::{Centralized, Context, Estimator, Kind, Message, StepInput};
use crate::link::{Egress, Link, Stream};
use crate::medium::{Medium, PairwiseMedium, Transmission};
use crate::model::Measurement;
use crate::model::{FusionLayout, Model};
use crate::observe::metrics::FilterMetrics;
use crate::observe::StepEstimate;
use crate::scenario::Scenario;
use crate::sensor::ImuInterval;
use crate::wire::{Datagram, Header, Payload};

/// What a node hands the observer's fusion centers each step: its own measurement, and the prediction input of the
/// step (the centers predict with the sink's IMU).
#[derive(Debug, Clone)]
pub struct Feed {
    pub node: usize,
    pub step: u64,
    pub own: Option<Measurement>,
    pub imu: Option<ImuInterval>,
    /// The truth's re-basing shift this step (linear model).
    pub shift: Option<DVector<f64>>,
    /// The fresh prior the node started from this step (its first step, a restart, a late join).
    pub prior: Option<Gaussian>,
    /// The true state of the step, which the node's testbed adds (its endpoint never sees it: empty until then).
    pub truth: DVector<f64>,
    /// At the sink, when the run holds centralized-net: the neighbours' measurements that arrived over the
    /// scenario's links by the deadline (the same datagrams `sequeira` fused).
    pub heard: Option<std::collections::BTreeMap<usize, Measurement>>,
}

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
    /// Mean over the counted steps of the error of the nodes' estimates fused by covariance intersection (ω = 0.5,
    /// as the two filters' `fused`); none where the covariances are not known.
    pub fused_error: Option<f64>,
}

#[derive(Default)]
struct Sums {
    disagreement: f64,
    median: f64,
    n_median: u64,
    n: u64,
    fused: f64,
    n_fused: u64,
}

pub struct SchemeObserver {
    layout: FusionLayout,
    burn_in: u64,
    sums: BTreeMap<Kind, Sums>,
    /// `centralized` and `centralized-net`, when the run holds them.
    references: Vec<Reference>,
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
            references: e
                .run
                .iter()
                .filter(|k| k.is_center())
                .filter_map(|&k| Reference::new(scenario, k))
                .collect(),
            rows: Vec::new(),
            node_rows: Vec::new(),
            ids: scenario.nodes().iter().map(|n| n.id).collect(),
            record,
        }
    }

    /// For `simnet collect`: the agreement of the nodes' estimates read back from their parts, with no fusion center.
    pub fn of_parts(layout: FusionLayout, burn_in: u64) -> SchemeObserver {
        SchemeObserver {
            layout,
            burn_in,
            sums: BTreeMap::new(),
            references: Vec::new(),
            rows: Vec::new(),
            node_rows: Vec::new(),
            ids: Vec::new(),
            record: false,
        }
    }

    /// One step's estimates of every estimating node.
    pub fn push(&mut self, estimates: &[StepEstimate]) {
        let Some(first) = estimates.first() else { return };
        let (step, truth) = (first.step, &first.truth);
        let mut by_kind: BTreeMap<Kind, Vec<Vec<f64>>> = BTreeMap::new();
        let known = self.layout.error_rows.iter().all(|&i| truth[i].is_finite());
        // The fused error counts after the burn-in only: before it, nothing is copied for fusion.
        let fuse = known && step >= self.burn_in;
        // Each scheme's node estimates with their covariances, while every node's is known.
        let mut gaussians: BTreeMap<Kind, Option<Vec<Gaussian>>> = BTreeMap::new();
        let t = self.layout.pick(truth);
        for e in estimates {
            for s in &e.schemes {
                let (k, x) = (&s.kind, &s.x);
                if fuse {
                    let g = gaussians.entry(*k).or_insert_with(|| Some(Vec::new()));
                    match (g.as_mut(), &s.P) {
                        (Some(gs), Some(P)) => gs.push(Gaussian {
                            x: x.clone(),
                            P: P.clone(),
                        }),
                        _ => *g = None,
                    }
                }
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
        for (kind, gs) in gaussians {
            let Some(mut gs) = gs.filter(|gs| !gs.is_empty()) else {
                continue;
            };
            self.layout.align(&mut gs);
            let fused = crate::estimate::fusion::cascade(&gs, Omega::Fixed(0.5), &self.layout.angle_states);
            if let Some(e) = fused
                .ok()
                .and_then(|f| self.layout.error(truth, &f.x))
                .filter(|e| e.is_finite())
            {
                let s = self.sums.entry(kind).or_default();
                s.fused += e;
                s.n_fused += 1;
            }
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

    /// One step's feeds of every node that was up: the fusion centers update.
    pub fn push_feeds(&mut self, mut feeds: Vec<Feed>) {
        feeds.sort_by_key(|f| f.node);
        for i in 0..self.references.len() {
            let r = &mut self.references[i];
            let Some((step, error, values)) = r.step(&feeds, &self.layout) else {
                continue;
            };
            let (kind, center) = (r.kind, r.center);
            if self.record {
                self.node_rows.push(EstimatorRow {
                    step,
                    kind,
                    node: self.ids.get(center).copied().unwrap_or(center as u32),
                    error: error.unwrap_or(f64::NAN),
                    values,
                });
            }
            self.record(step, kind, error, 0.0);
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
            fused_error: mean(s.fused, s.n_fused),
        }
    }

    /// A fusion center's figures (`centralized` or `centralized-net`) and its node.
    pub fn center(&self, kind: Kind) -> Option<(usize, &FilterMetrics)> {
        self.references
            .iter()
            .find(|r| r.kind == kind)
            .map(|r| (r.center, r.scorer.metrics(crate::observe::Filter::Networked)))
    }

    /// What centralized-net's measurements to the sink came to.
    pub fn star_traffic(&self) -> Option<StarTraffic> {
        self.references.iter().find_map(|r| r.star.as_ref()).map(|s| s.traffic)
    }
}

/// A fusion center at the sink: [`Centralized`] fed every sensing node's measurement of the step (`centralized`),
/// or only those that reach the sink by the deadline ([`Star`], `centralized-net`).
struct Reference {
    kind: Kind,
    center: usize,
    model: Arc<dyn Model>,
    obs: Observation,
    Q: DMatrix<f64>,
    dt: f64,
    est: Option<Centralized>,
    ctx: Context,
    scorer: crate::observe::Scorer,
    star: Option<Star>,
}

/// centralized-net's links to the sink. From a node the scenario links to the sink, the measurement is the datagram
/// the sink itself received by the deadline ([`Feed::heard`]): that slot's verdict is the link layer's one decision.
/// From any other node a star link with the `[link]` faults and its own seeded stream carries the datagram, sent at
/// the step's time, in a medium of its own; it counts if a copy arrives intact by the deadline. It travels no socket.
struct Star {
    /// The star links, one sender each: every node but the sink and those with a scenario link to it.
    medium: PairwiseMedium,
    sink: usize,
    faults: crate::link::FaultSchedule,
    /// D, from a step's time to its deadline.
    deadline: std::time::Duration,
    ids: Vec<u32>,
    traffic: StarTraffic,
}

/// What centralized-net's measurements to the sink came to.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StarTraffic {
    /// Datagrams sent to the sink (one per sensing node that was up and step), and their bytes.
    pub messages: u64,
    pub bytes: u64,
    /// Those the sink had by the deadline.
    pub delivered: u64,
}

impl Star {
    fn new(s: &Scenario, sink: usize) -> Star {
        let e = s.estimators();
        let linked: std::collections::HashSet<usize> = s.in_links(sink).map(|l| l.from).collect();
        let star = |j: usize| {
            let rng = crate::rng::stream(s.sim().seed, "star", j as u64, sink as u64);
            Egress::new(vec![Link::new(j, sink, e.star_link, rng)])
        };
        Star {
            medium: (0..s.nodes().len())
                .filter(|&j| j != sink && !linked.contains(&j) && s.nodes()[j].role.senses())
                .fold(PairwiseMedium::new(), |m, j| m.with_sender(j, star(j))),
            sink,
            faults: s.faults().clone(),
            deadline: s.deadline_delay(),
            ids: s.nodes().iter().map(|n| n.id).collect(),
            traffic: StarTraffic::default(),
        }
    }

    /// Whether node `f`'s measurement of its step reaches the sink, which `heard` what its scenario links carried.
    fn reaches(
        &mut self,
        f: &Feed,
        m: &Measurement,
        heard: Option<&BTreeMap<usize, Measurement>>,
        dt: f64,
    ) -> Option<Measurement> {
        let rows = (0..m.z.len())
            .filter(|&r| m.present[r])
            .fold(0u64, |acc, r| acc | 1 << r);
        let values = (0..m.z.len()).filter(|&r| m.present[r]).map(|r| m.z[r]).collect();
        let at = crate::time::Time::at_step(f.step, dt);
        let dg = Datagram {
            header: Header::new(self.ids[f.node], self.ids[self.sink], f.step as u32, at),
            payload: Payload::measurement(rows, values),
        };
        let bytes = dg.encode().unwrap_or_default();
        self.traffic.messages += 1;
        self.traffic.bytes += bytes.len() as u64;
        let got = if self.medium.carries(f.node) {
            let tx = Transmission {
                to: crate::medium::Dest::Node(self.sink),
                at,
                group: vec![bytes],
                stream: Stream::Measurement,
            };
            self.medium.transmit(f.node, tx, &self.faults);
            // A corrupted copy fails its checksum; a duplicate may still arrive whole; a copy after the deadline is
            // late.
            let mut intact = false;
            while let Some(d) = self.medium.poll_delivery(f.node, at + self.deadline) {
                intact |= Datagram::decode(&d.bytes).is_ok();
            }
            while self.medium.poll_delivery(f.node, crate::time::Time::MAX).is_some() {}
            intact.then(|| m.clone())
        } else {
            heard.and_then(|h| h.get(&f.node)).cloned()
        };
        self.traffic.delivered += got.is_some() as u64;
        got
    }
}

impl Reference {
    /// At the sink (`estimators.sink`); none in a network without a sensing node.
    fn new(s: &Scenario, kind: Kind) -> Option<Reference> {
        let center = s.estimators().sink?;
        let model = s.model().shared();
        let dt = s.sim().dt();
        let obs = model.observation();
        Some(Reference {
            kind,
            center,
            Q: model.process_noise(Some(&s.nodes()[center].sensor), dt),
            ctx: Context::new(center, s.nodes().len(), (Vec::new(), 1.0), &*model),
            scorer: crate::observe::Scorer::new(model.clone(), s.sim().burn_in_steps(), s.sim().divergence_trace),
            obs,
            dt,
            model,
            est: None,
            star: (kind == Kind::CentralizedNet).then(|| Star::new(s, center)),
        })
    }

    /// Step with `feeds` (sorted by node); the step, the error and the estimate's error rows.
    fn step(&mut self, feeds: &[Feed], layout: &FusionLayout) -> Option<(u64, Option<f64>, Vec<f64>)> {
        let center = feeds.iter().find(|f| f.node == self.center)?;
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
        let dt = self.dt;
        let messages: Vec<(usize, Measurement)> = feeds
            .iter()
            .filter(|f| f.node != self.center)
            .filter_map(|f| {
                let m = f.own.as_ref()?;
                let m = match self.star.as_mut() {
                    Some(star) => star.reaches(f, m, center.heard.as_ref(), dt)?,
                    None => m.clone(),
                };
                Some((f.node, m))
            })
            .collect();
        // A non-linear observation (the attitude EKF) is linearised about the center's prior (the center
        // linearises each measurement): the stacked EKF update.
        let input = StepInput {
            model: &*self.model,
            obs: &self.obs,
            node: self.center,
            own: center.own.as_ref(),
            heard: &[],
            step: center.step,
        };
        let messages: Vec<(usize, Message)> = messages
            .into_iter()
            .map(|(j, m)| (j, Message::Measurement(m)))
            .collect();
        let arrived: Vec<(usize, &Message)> = messages.iter().map(|(j, m)| (*j, m)).collect();
        let ok = est
            .begin(&input)
            .and_then(|_| est.combine(0, &arrived, &input))
            .and_then(|_| est.finish(&input));
        if ok.is_err() {
            est.reset(prior.clone());
        } else if let Some(g) = est.state_mut() {
            self.model.normalize(g);
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
