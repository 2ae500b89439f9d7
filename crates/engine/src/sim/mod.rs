//! Whole runs in memory: every node of a scenario stepped in lockstep on the virtual clock, datagrams moved between
//! them with no socket (as quinn-proto's tests drive endpoints). Deterministic: the same scenario and seed give the
//! same [`RunResults`] as the same run over UDP (`simnet::net::run`, crate `simnet-net`) — the datagrams are the
//! same bytes, moved by a function call instead of a socket.
//!
//! ```
//! # extern crate simnet_engine as simnet;
//! let scenario = simnet::Scenario::resolve("ring3")?.with(&simnet::Overrides {
//!     duration_s: Some(2.0),
//!     ..Default::default()
//! })?;
//! let results = simnet::Sim::new(&scenario)?.run()?;
//! let summary = results.summary();
//! assert_eq!(summary.nodes.len(), 3);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! A scheme of your own is one [`crate::estimators::Estimator`] and one [`crate::estimators::register`]; a run then
//! holds it like a built-in one (its figures in `summary.estimators`, its rounds on the wire), and a topology file
//! gives its parameters in its own table, `[estimators.<name>]`, checked by key. This one is the node's own Kalman
//! filter with a fading memory α ≥ 1 (P⁻ ← α P⁻ before each update: Anderson & Moore (1979) §6.2), so with its
//! default α = 1 it must match `independent` to the last digit, and with α > 1 it must not:
//!
//! ```
//! # extern crate simnet_engine as simnet;
//! use std::sync::Arc;
//! use simnet::estimate::{EstimateError, Gaussian, MissingChannels};
//! use simnet::estimators::{register, Estimator, Kind, Message, Scheme, StepInput};
//!
//! struct Own {
//!     g: Gaussian,
//!     policy: MissingChannels,
//!     fading: f64,
//! }
//!
//! impl Estimator for Own {
//!     fn name(&self) -> &'static str {
//!         "own"
//!     }
//!     fn state(&self) -> Option<&Gaussian> {
//!         Some(&self.g)
//!     }
//!     fn state_mut(&mut self) -> Option<&mut Gaussian> {
//!         Some(&mut self.g)
//!     }
//!     fn message(&self, _round: usize) -> Option<Message> {
//!         None
//!     }
//!     fn combine(&mut self, _: usize, _: &[(usize, &Message)], _: &StepInput<'_>) -> Result<(), EstimateError> {
//!         Ok(())
//!     }
//!     fn finish(&mut self, input: &StepInput<'_>) -> Result<(), EstimateError> {
//!         if let Some(m) = input.own {
//!             let faded = Gaussian { x: self.g.x.clone(), P: &self.g.P * self.fading };
//!             self.g = input.update(&faded, input.node, m, self.policy)?;
//!         }
//!         Ok(())
//!     }
//! }
//!
//! let scheme = Scheme {
//!     name: "own",
//!     reference: "the node's own filter with a fading memory",
//!     messages: "none",
//!     parameters: "estimators.own.fading (α ≥ 1, default 1)",
//! };
//! // Read once per scenario, problems named by key; then each node's instance.
//! let own = register(scheme, |table, checks| {
//!     for key in table.keys().filter(|k| *k != "fading") {
//!         checks.bad(format!("estimators.own.{key}"), "unknown key (known: fading)");
//!     }
//!     let fading = table.get("fading").and_then(|v| v.as_float()).unwrap_or(1.0);
//!     if !(1.0..=1e3).contains(&fading) {
//!         checks.bad("estimators.own.fading", format!("must be 1 to 1000, got {fading}"));
//!     }
//!     Arc::new(move |_, g, policy| Box::new(Own { g, policy, fading }))
//! })?;
//! let scenario = simnet::Scenario::resolve("ring3")?.with(&simnet::Overrides {
//!     duration_s: Some(3.0),
//!     estimators: Some(vec![Kind::Independent, own]),
//!     ..Default::default()
//! })?;
//! let errors = |s: &simnet::Scenario, name: &str| -> Result<Vec<f64>, Box<dyn std::error::Error>> {
//!     let summary = simnet::Sim::new(s)?.run()?.summary();
//!     Ok(summary.estimators[name].nodes.iter().map(|n| n.figures.mean_error.unwrap()).collect())
//! };
//! let independent = errors(&scenario, "independent")?;
//! assert_eq!(independent.len(), 3);
//! assert_eq!(errors(&scenario, "own")?, independent); // α = 1: the Kalman filter itself
//! let faded = scenario.set("estimators.own.fading", toml::Value::Float(1.5))?; // a key like any other
//! assert!(faded.to_toml().contains("[estimators.own]"));
//! assert!(errors(&faded, "own")?.iter().zip(&independent).all(|(a, b)| a != b));
//! let refused = scenario.set("estimators.own.fading", toml::Value::Float(0.5)).unwrap_err().to_string();
//! assert!(refused.contains("estimators.own.fading"), "{refused}");
//! let misspelt = scenario.set("estimators.own.fadign", toml::Value::Float(1.5)).unwrap_err().to_string();
//! assert!(misspelt.contains("estimators.own.fadign"), "{misspelt}");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! A model of your own is a type with the five roles of [`crate::model::Model`] and one [`crate::model::register`];
//! a topology file then names it in `[model] kind` and gives its keys in `[model.params]`, checked by key like any
//! other. This one tracks a node in the plane from position fixes alone (constant velocity, white acceleration of
//! spectral density q: Bar-Shalom, Li and Kirubarajan (2001) §6.2.2), so its filter must beat the fixes it is fed,
//! whose mean error is σ √(π/2) (a 2-D normal's mean distance):
//!
//! ```
//! # extern crate simnet_engine as simnet;
//! use std::sync::Arc;
//! use nalgebra::{DMatrix, DVector, Vector3};
//! use simnet::estimate::{Gaussian, Observation};
//! use simnet::model::*;
//! use simnet::{rng::Rng, sensor::{ImuInterval, ImuSample, Sensor, SensorProfile}};
//!
//! #[derive(Debug)]
//! struct Track { q: f64, r: f64 }
//!
//! impl Dynamics for Track {
//!     fn imu_driven(&self) -> bool { false }
//!     fn process_noise(&self, _: Option<&SensorProfile>, dt: f64) -> DMatrix<f64> {
//!         let (a, b, c) = (dt.powi(3) / 3.0, dt.powi(2) / 2.0, dt);
//!         let i = DMatrix::<f64>::identity(2, 2);
//!         let mut Q = DMatrix::zeros(4, 4);
//!         Q.view_mut((0, 0), (2, 2)).copy_from(&(&i * a));
//!         Q.view_mut((0, 2), (2, 2)).copy_from(&(&i * b));
//!         Q.view_mut((2, 0), (2, 2)).copy_from(&(&i * b));
//!         Q.view_mut((2, 2), (2, 2)).copy_from(&(&i * c));
//!         Q * self.q
//!     }
//!     fn predict(&self, g: &Gaussian, _: Option<&ImuInterval>, Q: &DMatrix<f64>, dt: f64) -> Gaussian {
//!         let mut F = DMatrix::identity(4, 4);
//!         F[(0, 2)] = dt;
//!         F[(1, 3)] = dt;
//!         simnet::estimate::predict(g, &F, Q)
//!     }
//! }
//!
//! impl Sensing for Track {
//!     fn observation(&self) -> Observation {
//!         Observation {
//!             H: DMatrix::identity(2, 4),
//!             R: DMatrix::identity(2, 2) * self.r,
//!             angle_rows: vec![false; 2],
//!             channel_of_row: vec![0; 2],
//!         }
//!     }
//!     fn sense(&self, sensor: &mut Sensor, truth: &Truth, _site: Site, _t: f64) -> Sensed {
//!         let Some(now) = truth.motion_now() else { return Sensed::default() };
//!         let x = DVector::from_row_slice(&[now.p.x, now.p.y, now.v.x, now.v.y]);
//!         let z = sensor.linear(&DMatrix::identity(2, 4), &(DMatrix::identity(2, 2) * self.r.sqrt()), &x);
//!         Sensed { imu: None, z: Some(Measurement::full(z)), row: None }
//!     }
//! }
//!
//! impl Manifold for Track {
//!     fn angle_states(&self) -> Vec<bool> { vec![false; 4] }
//! }
//!
//! impl GroundTruth for Track {
//!     fn kinematic_state(&self, p: Option<Vector3<f64>>, v: Option<Vector3<f64>>, _: Option<Vector3<f64>>) -> DVector<f64> {
//!         let (p, v) = (p.unwrap_or(Vector3::repeat(f64::NAN)), v.unwrap_or(Vector3::repeat(f64::NAN)));
//!         DVector::from_row_slice(&[p.x, p.y, v.x, v.y])
//!     }
//!     fn initial(&self, truth: &DVector<f64>, _: Option<(&ImuSample, Option<&Vector3<f64>>)>, rng: &mut Rng) -> Gaussian {
//!         let P = DMatrix::from_diagonal(&DVector::from_row_slice(&[0.25, 0.25, 0.01, 0.01]));
//!         let x = truth.map(|v| if v.is_finite() { v } else { 0.0 }) + P.map(f64::sqrt) * randn(rng, 4);
//!         Gaussian { x, P }
//!     }
//! }
//!
//! impl Report for Track {
//!     fn columns(&self) -> Vec<String> { ["x", "y", "vx", "vy"].map(String::from).to_vec() }
//!     fn reported(&self, state: &DVector<f64>) -> Vec<f64> { state.iter().copied().collect() }
//!     fn reported_var(&self, g: &Gaussian) -> Vec<f64> { g.P.diagonal().iter().copied().collect() }
//!     fn fusion(&self) -> FusionLayout {
//!         FusionLayout { angle_states: vec![false; 4], error_rows: vec![0, 1], median: false, quaternion: false }
//!     }
//! }
//!
//! // Its size, 4 states × 2 rows, gets the stack kernels as simnet's own models' sizes have them.
//! simnet::estimate::fixed::register(simnet::estimate::fixed::Size::of::<4, 2>());
//! assert!(simnet::estimate::fixed::covers(4, 2));
//!
//! register(Registration {
//!     name: "track",
//!     about: "a node in the plane, constant velocity, from position fixes",
//!     error_text: Kind::Pose.error_text(),
//!     view: TrajectoryView::Plane,
//!     build: Some(|params, ck| {
//!         let get = |k: &str| params.get(k).and_then(|v| v.as_float());
//!         Arc::new(Track { q: ck.positive("model.params.q", get("q"), 0.1), r: ck.positive("model.params.r", get("r"), 0.01) })
//!     }),
//! })?;
//!
//! let file = |r: &str| format!(
//!     "name = \"tracked\"\n[sim]\nduration_s = 20.0\n[model]\nkind = \"track\"\n[model.params]\nq = 0.1\nr = {r}\n\
//!      [[node]]\n[[node]]\n[[node]]\n[[edge]]\nnodes = [0, 1]\n[[edge]]\nnodes = [1, 2]\n[[edge]]\nnodes = [2, 0]\n"
//! );
//! let refused = simnet::Scenario::from_toml(&file("-1.0"), "tracked.toml").unwrap_err().to_string();
//! assert!(refused.contains("model.params.r"), "{refused}");
//! let scenario = simnet::Scenario::from_toml(&file("0.01"), "tracked.toml")?;
//! assert_eq!(simnet::Scenario::from_toml(&scenario.to_toml(), "again")?.digest(), scenario.digest());
//! let swept = scenario.set("model.params.r", toml::Value::Float(-1.0)).unwrap_err().to_string(); // a campaign's axis
//! assert!(swept.contains("model.params.r"), "{swept}");
//! let summary = simnet::Sim::new(&scenario)?.run()?.summary();
//! assert_eq!(summary.model.as_str(), "track");
//! let fixes = 0.01f64.sqrt() * std::f64::consts::FRAC_PI_2.sqrt();
//! for node in &summary.nodes {
//!     let own = node.independent.as_ref().and_then(|f| f.mean_error).unwrap();
//!     assert!(own < fixes, "node {}: {own} m, no better than its fixes ({fixes} m)", node.id);
//! }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod results;

use std::sync::Arc;

use crate::medium::Medium;
use crate::node::{Node, StepEstimate};
use crate::observe::fusion::Observer;
use crate::report::trace::TraceWriter;
use crate::scenario::{Scenario, ScenarioError};
use crate::time::Time;

pub use results::{Clock, RunResults};

/// Called with (steps done, steps total).
pub type Progress = Arc<dyn Fn(u64, u64) + Send + Sync>;

#[derive(Debug, thiserror::Error)]
pub enum SimError {
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    #[error("there is no node {index}: the scenario has {}", crate::scenario::count(*n, "node"))]
    NoNode { index: usize, n: usize },
}

/// What a run keeps beyond its figures.
#[derive(Default)]
pub struct SimOptions {
    /// Takes the per-step rows for `trace.csv` and the plots as the run goes (none: no rows are made).
    pub trace: Option<TraceWriter>,
    pub progress: Option<Progress>,
    /// Keep every node's per-step LMI terms (for a protocol search).
    pub record_lmi: bool,
    /// Do not fuse the nodes' estimates (a search that scores the nodes alone saves the observer's work).
    pub no_fusion: bool,
    /// What carries the nodes' datagrams instead of the scenario's links ([`Scenario::pairwise_medium`]).
    ///
    /// A medium of your own decides every datagram's fate; the `[link]` rules of the file then play no part. This
    /// one delivers every datagram at once (a broadcast to every other node), so a run at 50 % loss loses nothing:
    ///
    /// ```
    /// # extern crate simnet_engine as simnet;
    /// use simnet::link::{FaultSchedule, LinkCounters};
    /// use simnet::medium::{Delivery, Dest, Medium, Transmission};
    /// use simnet::sim::SimOptions;
    /// use simnet::time::Time;
    /// use simnet::{Overrides, Scenario, Sim};
    ///
    /// #[derive(Debug)]
    /// struct Wire {
    ///     nodes: usize,
    ///     due: Vec<Delivery>,
    ///     sent: std::collections::BTreeMap<(usize, usize), u64>,
    /// }
    ///
    /// impl Medium for Wire {
    ///     fn transmit(&mut self, from: usize, tx: Transmission, _faults: &FaultSchedule) {
    ///         let to: Vec<usize> = match tx.to {
    ///             Dest::Node(j) => vec![j],
    ///             Dest::Broadcast => (0..self.nodes).filter(|&j| j != from).collect(),
    ///         };
    ///         for to in to {
    ///             *self.sent.entry((from, to)).or_default() += 1;
    ///             self.due.extend(tx.group.iter().map(|bytes| Delivery { from, to, at: tx.at, bytes: bytes.clone() }));
    ///         }
    ///     }
    ///     fn poll_delivery(&mut self, from: usize, _now: Time) -> Option<Delivery> {
    ///         let i = self.due.iter().position(|d| d.from == from)?;
    ///         Some(self.due.remove(i))
    ///     }
    ///     fn poll_timeout(&self, from: usize) -> Option<Time> {
    ///         self.due.iter().any(|d| d.from == from).then_some(Time::ZERO)
    ///     }
    ///     fn counters(&self, from: usize) -> Vec<(usize, LinkCounters)> {
    ///         let out = self.sent.iter().filter(|((f, _), _)| *f == from);
    ///         out.map(|(&(_, to), &sent)| (to, LinkCounters { sent, ..Default::default() })).collect()
    ///     }
    /// }
    ///
    /// let lossy = Overrides { loss: Some(simnet::link::LossModel::Bernoulli { p: 0.5 }), duration_s: Some(2.0), ..Default::default() };
    /// let scenario = Scenario::resolve("ring3")?.with(&lossy)?;
    /// let wire = Wire { nodes: scenario.nodes().len(), due: Vec::new(), sent: Default::default() };
    /// let opts = SimOptions { medium: Some(Box::new(wire)), ..Default::default() };
    /// let summary = Sim::with_options(&scenario, opts)?.run()?.summary();
    /// assert_eq!(summary.links.len(), 6); // ring3: every node to the other two
    /// for l in &summary.links {
    ///     assert_eq!((l.sent, l.delivered, l.lost), (scenario.sim().steps(), l.sent, 0), "{} → {}", l.from, l.to);
    /// }
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub medium: Option<Box<dyn Medium>>,
    /// Record every datagram sent and every copy delivered into this log ([`crate::medium::Capture`]: a tap on the
    /// medium, which changes nothing it carries).
    pub capture: Option<crate::medium::CaptureLog>,
}

/// The lockstep driver: [`Sim::step`] runs one step of every node, [`Sim::run`] the rest of the run.
pub struct Sim {
    scenario: Arc<Scenario>,
    nodes: Vec<Node>,
    /// What carries the nodes' datagrams: every directed link of the scenario, unless a medium was given.
    medium: Box<dyn Medium>,
    observer: Option<Observer>,
    trace: Option<TraceWriter>,
    progress: Option<Progress>,
    record_lmi: bool,
    next: u64,
}

impl Sim {
    pub fn new(scenario: &Scenario) -> Result<Sim, SimError> {
        Sim::with_options(scenario, SimOptions::default())
    }

    pub fn with_options(scenario: &Scenario, opts: SimOptions) -> Result<Sim, SimError> {
        scenario.check_recordings()?;
        let scenario = Arc::new(scenario.clone());
        let record = opts.trace.is_some();
        // Every run seals under its own epoch: no nonce of an earlier run under the same key comes again.
        let epoch = crate::fresh::boot_epoch();
        let mut nodes: Vec<Node> = (0..scenario.nodes().len())
            .map(|i| {
                let mut n = Node::new(scenario.clone(), i, record);
                n.endpoint_mut().boot(epoch);
                n
            })
            .collect();
        if opts.record_lmi {
            nodes.iter_mut().for_each(Node::record_lmi);
        }
        let medium = opts.medium.unwrap_or_else(|| scenario.whole_medium());
        Ok(Sim {
            medium: match opts.capture {
                Some(log) => Box::new(crate::medium::Capture::new(medium, log)),
                None => medium,
            },
            observer: (!opts.no_fusion).then(|| observer_for(&scenario, record)),
            scenario,
            nodes,
            trace: opts.trace,
            progress: opts.progress,
            record_lmi: opts.record_lmi,
            next: 0,
        })
    }

    pub fn scenario(&self) -> &Scenario {
        &self.scenario
    }

    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }

    /// Feed `probe` every update, IMU sample and set of LMI terms of node `index` from now on.
    pub fn add_probe(&mut self, index: usize, probe: Box<dyn crate::observe::Probe>) -> Result<(), SimError> {
        let n = self.nodes.len();
        let node = self.nodes.get_mut(index).ok_or(SimError::NoNode { index, n })?;
        node.add_probe(probe);
        Ok(())
    }

    /// Put `stage` in front of node `index` in place of the scenario's outsiders ([`crate::medium::Ingress`]; an
    /// example at [`crate::node::Node::set_ingress`]).
    pub fn set_ingress(
        &mut self,
        index: usize,
        stage: Option<Box<dyn crate::medium::Ingress>>,
    ) -> Result<(), SimError> {
        let n = self.nodes.len();
        let node = self.nodes.get_mut(index).ok_or(SimError::NoNode { index, n })?;
        node.set_ingress(stage);
        Ok(())
    }

    /// Steps run so far.
    pub fn steps_done(&self) -> u64 {
        self.next
    }

    /// One lockstep step: every node steps, the datagrams the link layer delivers by the deadline move to their
    /// receivers, every node closes the step, the observer fuses. `None` once the run is over; else the estimates
    /// of the nodes that estimate.
    pub fn step(&mut self) -> Option<Vec<StepEstimate>> {
        self.advance(true)
    }

    /// One step; the estimates are handed back only when `keep` (else they go to the observer without a copy).
    fn advance(&mut self, keep: bool) -> Option<Vec<StepEstimate>> {
        let steps = self.scenario.sim().steps();
        let k = self.next;
        if k >= steps {
            return None;
        }
        // As on the virtual clock over sockets: the last window also flushes everything still queued.
        let window_end = if k + 1 == steps {
            Time::MAX
        } else {
            self.scenario.deadline(k)
        };
        let estimates = lockstep(&mut self.nodes, &mut *self.medium, k, window_end);
        let mut rows = Vec::new();
        let mut measurements = Vec::new();
        let feeds: Vec<_> = self.nodes.iter_mut().filter_map(Node::take_feed).collect();
        if let Some(o) = self.observer.as_mut() {
            o.push_feeds(feeds);
        }
        for n in &mut self.nodes {
            rows.append(&mut n.take_trace());
            measurements.append(&mut n.take_measurements());
            let imu = n.take_imu();
            if let Some(t) = self.trace.as_mut() {
                t.imu(n.id(), &imu);
            }
        }
        if let Some(t) = self.trace.as_mut() {
            measurements.sort_by_key(|m| m.node);
            t.measurements(&measurements);
        }
        let returned = if keep { estimates.clone() } else { Vec::new() };
        if let Some(o) = self.observer.as_mut() {
            o.push(estimates);
        }
        if let Some(t) = self.trace.as_mut() {
            rows.sort_by_key(|r| (r.node, r.filter));
            t.rows(rows);
            if let Some(o) = self.observer.as_mut() {
                t.fused(o.drain_rows());
                t.estimators(&o.drain_estimator_rows());
            }
        }
        self.next = k + 1;
        if let Some(p) = &self.progress {
            p(self.next, steps);
        }
        Some(returned)
    }

    /// The rest of the run, and its results.
    pub fn run(mut self) -> Result<RunResults, SimError> {
        while self.advance(false).is_some() {}
        Ok(self.finish())
    }

    /// The results of the steps run so far.
    pub fn finish(mut self) -> RunResults {
        if let Some(o) = self.observer.as_mut() {
            o.finish();
            if let Some(t) = self.trace.as_mut() {
                t.fused(o.drain_rows());
            }
        }
        let lmi = if self.record_lmi {
            self.nodes.iter_mut().map(Node::take_lmi_log).collect()
        } else {
            Vec::new()
        };
        let steps = self.scenario.sim().steps();
        RunResults {
            reports: self.nodes.iter_mut().map(|n| n.report(&*self.medium)).collect(),
            observer: self.observer,
            steps_done: self.next,
            interrupted: self.next < steps,
            // Sim reads no clock: a caller that times the run sets it.
            wall_s: 0.0,
            socket_losses: 0,
            frames_resent: 0,
            trace: self.trace,
            lmi,
            schedule: None,
            clock: Clock::Virtual,
            scenario: self.scenario,
        }
    }
}

/// Step `k` of nodes wired together in memory: at each instant a node waits for (its step's start, each round's
/// close, its deadline), what they sent goes to the medium and the datagrams it delivers by then reach their
/// receivers, then every node handles the instant ([`Node::handle_timeout`]). The deadline's deliveries run to
/// `window_end` (the run's last window flushes everything).
pub(crate) fn lockstep(nodes: &mut [Node], medium: &mut dyn Medium, k: u64, window_end: Time) -> Vec<StepEstimate> {
    let Some(close) = nodes.first().map(|n| n.scenario().deadline(k)) else {
        return Vec::new();
    };
    let mut estimates = Vec::new();
    // The nodes share one timeline: every node waits for the same instants.
    while let Some(t) = nodes
        .iter()
        .filter_map(Node::poll_timeout)
        .min()
        .filter(|t| *t <= close)
    {
        let until = if t == close { window_end } else { t };
        // Every node's transmissions reach the medium before any delivery is asked of it: a shared channel
        // decides a frame's fate only once every frame that could overlap it is known.
        for n in nodes.iter_mut() {
            n.send_to(medium);
        }
        let mut moved = Vec::new();
        for n in nodes.iter() {
            while let Some(d) = medium.poll_delivery(n.index(), until) {
                moved.push(d);
            }
        }
        for d in moved {
            nodes[d.to].handle_datagram(Some(d.from), &d.bytes);
        }
        let mut closed = false;
        for n in nodes.iter_mut() {
            if let Some(c) = n.handle_timeout(t) {
                closed = true;
                estimates.extend(c.estimate);
            }
        }
        // The next step may begin at this very instant (D = Δt): it is the next call's.
        if closed {
            break;
        }
    }
    estimates
}

/// The observer of a run of `scenario`, whichever driver runs it (in memory or over UDP): the fusion observer, with
/// the distributed estimators' observer when the run holds any; `record` keeps every step's estimates for the plots.
pub fn observer_for(scenario: &Scenario, record: bool) -> Observer {
    let o = Observer::new(scenario.sim().burn_in_steps(), scenario.model().get().fusion(), record);
    if scenario.estimators().run.is_empty() {
        o
    } else {
        o.with_schemes(crate::observe::schemes::SchemeObserver::new(scenario, record))
    }
}

#[cfg(test)]
mod tests {
    /// Two runs of one scenario under one key seal under different epochs: no (source, epoch, counter) of the first
    /// is used again by the second (every in-process run was sealed under epoch 0, so two runs shared every nonce).
    #[test]
    fn every_run_seals_under_its_own_epoch() {
        let topo = crate::Scenario::resolve("ring3")
            .unwrap()
            .with(&crate::Overrides {
                auth: Some(true),
                ..Default::default()
            })
            .unwrap();
        let epochs: Vec<u64> = (0..2)
            .map(|_| {
                let sim = super::Sim::new(&topo).unwrap();
                let e: Vec<u64> = sim
                    .nodes
                    .iter()
                    .map(|n| n.endpoint().sealing_epoch().unwrap())
                    .collect();
                assert!(e.iter().all(|n| *n == e[0]), "{e:?}");
                e[0]
            })
            .collect();
        assert_ne!(epochs[0], epochs[1]);
    }
}
