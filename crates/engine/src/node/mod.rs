//! One node as a sans-IO state machine: it never touches a socket or a clock, so the same node runs in memory
//! ([`crate::sim::Sim`]), over UDP on the virtual or the wall clock (`simnet-net`) and one per process
//! (`simnet node`).
//!
//! A [`Node`] is two parts the compiler keeps apart: its [`Endpoint`], which estimates from what it senses and what
//! it hears and never sees the truth, and its [`Testbed`], the world around it (the truth it senses, its IMU and
//! sensor with their seeded noise) and the observer that watches it (the [`crate::observe::Scorer`] and the
//! probes), which scores each update the endpoint hands out against the truth.
//!
//! # Call order and time
//!
//! Time is [`crate::time::Time`], whole nanoseconds since the run began; step k begins at t_k = k·Δt
//! ([`Scenario::step_time`]) and closes at its deadline t_k + D (D ≤ Δt, [`Scenario::deadline`]). The order in
//! which a node acts is written once, here ([`Node::handle_timeout`]); every driver — [`crate::sim::Sim`], both
//! clocks of `simnet-net` and `simnet node` — only does this:
//!
//! 1. [`Node::poll_timeout`] says when the node next needs a call (`None` once its last step closed).
//! 2. [`Node::send_to`]`(medium)` hands everything the node sent to the [`crate::medium::Medium`] (the scenario's
//!    links: [`crate::Scenario::pairwise_medium`]), which decides loss, delay, duplication and corruption;
//!    `medium.poll_delivery(node, now)` until `None` gives every copy due by `now`, in delivery order, and
//!    `medium.poll_timeout(node)` when the next is due. The shell carries each to `to`.
//! 3. [`Node::handle_datagram`]`(from, bytes)` for every datagram that arrives by then, in any order, `from` the
//!    sender's node index when the shell knows it by address. A measurement for the open step is collected; one for
//!    a later step is held (bounded); one for a closed step counts as late.
//! 4. [`Node::handle_timeout`]`(now)`, which does in order what is due:
//!    - at t_k, the crash timeline's events for step k ([`crate::link::FaultSchedule::node_events`]: a crash drops
//!      what arrives and skips steps, a restart re-initialises both filters); the world moves to t_k; then, if the
//!      node is up, the step itself: the testbed hands the endpoint its IMU sample and measurement (and a fresh
//!      prior after a restart), and the endpoint predicts its filters to t_k and sends this step's datagrams (one
//!      broadcast to its out-neighbours, or, with authentication, a copy sealed for each link) — it only says what
//!      it sends ([`crate::medium::Transmission`]s), never what becomes of them;
//!    - with L consensus rounds ([`crate::scenario::EstimatorsConfig`]), at each sub-deadline t_k + D(r+1)/L for
//!      r < L − 1: the distributed estimators combine round r and queue round r + 1;
//!    - at t_k + D: every estimator updates with what arrived (the distributed ones close their last round); the
//!      endpoint hands out each update ([`Closing`]), which the testbed scores against the truth and gives to its
//!      probes (trace, IMU and LMI recorders when on, any [`Node::add_probe`]); the step is returned ([`Closed`])
//!      with the estimates for the fusion observer. A call closes at most one step, so that a driver collects a
//!      step before the next begins.
//!
//! A node joining a running network starts its timeline at a later step ([`Node::start_at`]).
//!
//! A node whose step k is skipped (down, or joining late) keeps its counters honest: a crash drops what arrives,
//! a restart re-initialises both filters.
//!
//! | file | owns |
//! |---|---|
//! | `mod.rs` | the node: its endpoint and its testbed, the call order ([`Node::handle_timeout`]), what drivers call |
//! | `endpoint/` | the node proper ([`Endpoint`]): receive path, wire, inbox, filters, schemes, handshake, trust |
//! | `testbed.rs` | the world around it and its observer ([`Testbed`]): the truth, the sensor, the scorer, the probes |

mod endpoint;
mod testbed;

use std::sync::Arc;

use crate::observe::{Filter, Probe};
use crate::scenario::Scenario;
use crate::time::Time;

pub use crate::imu_csv::ImuRow;
pub use crate::link::Transmit;
pub use crate::observe::schemes::Feed;
pub use crate::observe::{LmiStep, MeasurementRow, StepEstimate, TraceRow};
pub use endpoint::{
    Arrival, Closing, Due, Endpoint, Listening, NodeCounters, NodeReport, Opening, Rejections, Sample, Traffic, Updated,
};
pub use testbed::Testbed;

/// One node: the endpoint, and the testbed around it.
pub struct Node {
    endpoint: Endpoint,
    testbed: Testbed,
}

/// A step the node closed: which one, and its estimates (none from a node that does not estimate, or was down).
#[derive(Debug)]
pub struct Closed {
    pub step: u64,
    pub estimate: Option<StepEstimate>,
}

impl Node {
    /// Node `index` of `topo`; `record_trace` keeps one row per step and filter (needed for `trace.csv` and the
    /// plots).
    pub fn new(topo: Arc<Scenario>, index: usize, record_trace: bool) -> Node {
        let testbed = Testbed::new(topo.clone(), index, record_trace);
        let endpoint = Endpoint::new(topo, index, testbed.prior(0, 0));
        let mut node = Node { endpoint, testbed };
        node.listen();
        node
    }

    /// The node proper.
    pub fn endpoint(&self) -> &Endpoint {
        &self.endpoint
    }

    /// The node proper, to drive (what it receives, its handshake).
    pub fn endpoint_mut(&mut self) -> &mut Endpoint {
        &mut self.endpoint
    }

    /// When the node next needs [`Node::handle_timeout`]: the next step's start, round close or deadline; `None`
    /// once its last step closed.
    pub fn poll_timeout(&self) -> Option<Time> {
        self.endpoint.poll_timeout()
    }

    /// The node's timeline starts at step `k` (a node joining a running network); a new node starts at step 0.
    pub fn start_at(&mut self, k: u64) {
        self.endpoint.start_at(k)
    }

    /// Do, in order, what is due by `now`: a step's start (the crash timeline's events for it first), its rounds'
    /// closes, its deadline. A call closes at most one step and returns it, so that a driver collects a step's
    /// results before the next begins: call again while [`Node::poll_timeout`] is at or before `now`.
    pub fn handle_timeout(&mut self, now: Time) -> Option<Closed> {
        while self.poll_timeout().is_some_and(|t| t <= now) {
            let due = self.endpoint.due();
            self.endpoint.advance();
            match due {
                Due::Step(k) => self.begin_step(k),
                Due::Round(k, r) => self.endpoint.handle_round(k, r),
                Due::Deadline(k) => {
                    let estimate = self.endpoint.handle_deadline(k).map(|c| self.testbed.observe(k, c));
                    return Some(Closed { step: k, estimate });
                }
                Due::Done => break,
            }
        }
        None
    }

    /// Step k begins: the crash timeline's events for it, the world moves to t_k, and a node that is up runs the
    /// step on what its testbed senses.
    fn begin_step(&mut self, k: u64) {
        self.endpoint.apply_events(k);
        self.open_step(k);
    }

    /// Step k, after the crash timeline's events for it.
    fn open_step(&mut self, k: u64) {
        let opening = self.endpoint.open_step(k);
        let shift = self.testbed.advance_to(k);
        if let Opening::Up { fresh } = opening {
            let sample = Sample {
                shift,
                fresh: fresh.map(|draw| self.testbed.prior(draw, k)),
                ..self.testbed.sense(k)
            };
            self.endpoint.step(k, sample);
            if let Some(feed) = self.endpoint.feed_mut() {
                feed.truth = self.testbed.truth();
            }
        }
    }

    /// Bytes arrived; `from` is the sender's node index when the shell knows it by address.
    pub fn handle_datagram(&mut self, from: Option<usize>, bytes: &[u8]) -> Option<Arrival> {
        self.endpoint.handle_datagram(from, bytes)
    }

    /// Hand everything sent so far to `medium` (under the run's fault windows).
    pub fn send_to(&mut self, medium: &mut dyn crate::medium::Medium) {
        self.endpoint.send_to(medium)
    }

    pub fn scenario(&self) -> &Arc<Scenario> {
        self.endpoint.scenario()
    }

    pub fn index(&self) -> usize {
        self.endpoint.index()
    }

    pub fn id(&self) -> u32 {
        self.endpoint.id()
    }

    /// What the centralized reference needs of the last step (none unless the run holds it).
    pub fn take_feed(&mut self) -> Option<Feed> {
        self.endpoint.take_feed()
    }

    /// Put `stage` in front of this node ([`Endpoint::set_ingress`]).
    pub fn set_ingress(&mut self, stage: Option<Box<dyn crate::medium::Ingress>>) {
        self.endpoint.set_ingress(stage)
    }

    /// Feed `p` every update, IMU sample and set of LMI terms from now on.
    pub fn add_probe(&mut self, p: Box<dyn Probe>) {
        self.testbed.probes.added.push(p);
        self.listen();
    }

    /// Keep the LMI terms of every networked update from now on (for a protocol search; costs one extra
    /// gain computation per step).
    pub fn record_lmi(&mut self) {
        self.testbed.record_lmi();
        self.listen();
    }

    /// The endpoint builds for the updates it hands out what the testbed's probes read.
    fn listen(&mut self) {
        let probes = &self.testbed.probes;
        self.endpoint.listen(Listening {
            sources: !probes.is_empty(),
            lmi: probes.lmi.is_some(),
        });
    }

    pub fn take_lmi_log(&mut self) -> Vec<LmiStep> {
        let lmi = self.testbed.probes.lmi.as_mut();
        lmi.map(crate::observe::LmiRecorder::take).unwrap_or_default()
    }

    /// The node's own measurements recorded since the last call.
    pub fn take_measurements(&mut self) -> Vec<MeasurementRow> {
        let m = self.testbed.probes.measurements.as_mut();
        m.map(crate::observe::MeasurementRecorder::take).unwrap_or_default()
    }

    /// The IMU rows recorded since the last call.
    pub fn take_imu(&mut self) -> Vec<ImuRow> {
        let imu = self.testbed.probes.imu.as_mut();
        imu.map(crate::observe::ImuRecorder::take).unwrap_or_default()
    }

    /// The trace rows recorded since the last call (a shell streams them out step by step).
    pub fn take_trace(&mut self) -> Vec<TraceRow> {
        let trace = self.testbed.probes.trace.as_mut();
        trace.map(crate::observe::TraceRecorder::take).unwrap_or_default()
    }

    /// The node's figures of the run, its out-links' as `medium` carried them.
    pub fn report(&mut self, medium: &dyn crate::medium::Medium) -> NodeReport {
        let mut r = self.endpoint.report(medium);
        let scorer = &self.testbed.scorer;
        let estimates = r.role.estimates();
        r.networked = self
            .endpoint
            .has_networked()
            .then(|| scorer.metrics(Filter::Networked).clone());
        r.independent = estimates.then(|| scorer.metrics(Filter::Independent).clone());
        if estimates {
            r.schemes = scorer.scheme_metrics().to_vec();
        }
        r.trace = self.take_trace();
        r.imu = self.take_imu();
        r
    }
}
