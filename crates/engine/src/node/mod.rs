//! One node as a sans-IO state machine: it never touches a socket or a clock, so the same node runs in memory
//! ([`crate::sim::Sim`]), over UDP on the virtual or the wall clock (`simnet-net`) and one per process
//! (`simnet node`).
//!
//! # Call order and time
//!
//! Time is [`crate::time::Time`], whole nanoseconds since the run began; step k begins at t_k = k·Δt
//! ([`Scenario::step_time`]) and closes at its deadline t_k + D (D ≤ Δt, [`Scenario::deadline`]). The order in
//! which a node acts is written once, in the node (`clock.rs`); every driver — [`crate::sim::Sim`], both clocks of
//! `simnet-net` and `simnet node` — only does this:
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
//!      what arrives and skips steps, a restart re-initialises both filters), then the step itself: the node senses,
//!      predicts both filters to t_k and sends this step's datagrams (one broadcast to its out-neighbours, or, with
//!      authentication, a copy sealed for each link) — it only says what it sends
//!      ([`crate::medium::Transmission`]s), never what becomes of them;
//!    - with L consensus rounds ([`crate::scenario::EstimatorsConfig`]), at each sub-deadline t_k + D(r+1)/L for
//!      r < L − 1: the distributed estimators combine round r and queue round r + 1;
//!    - at t_k + D: both filters update with what arrived (the estimators close their last round); each update goes
//!      to the node's [`crate::observe::Scorer`] and its probes (trace, IMU and LMI recorders when on, any
//!      [`Node::add_probe`]); the step is returned ([`Closed`]) with the networked estimate for the fusion observer.
//!      A call closes at most one step, so that a driver collects a step before the next begins.
//!
//! A node joining a running network starts its timeline at a later step ([`Node::start_at`]).
//!
//! A node whose step k is skipped (down, or joining late) keeps its counters honest: a crash drops what arrives,
//! a restart re-initialises both filters.
//!
//! | file | owns |
//! |---|---|
//! | `build.rs` | a node built from its scenario, and the prior a (re)started filter begins from |
//! | `clock.rs` | the call order: what is due next on the node's timeline, and doing it ([`Node::handle_timeout`]) |
//! | `receive.rs` | the receive path: bytes checked, authenticated, found plausible, collected ([`Node::handle_datagram`]) |
//! | `deadline.rs` | the close of a step (`handle_deadline`, at the deadline of [`Node::handle_timeout`]): both filters and the estimators updated, scored |
//! | `accessors.rs` | what drivers and the observer read and take from a node, its end-of-run report |
//! | `wire.rs` | addressing and sealing: one broadcast, or a sealed copy per out-link; opening: what is accepted |
//! | `inbox.rs` | step collection, the early buffer, receive counters |
//! | `filters.rs` | the node's two filters, `sequeira` and `independent`, as estimators |
//! | `schemes.rs` | the distributed estimators beside them: each round's messages, what arrived, their traffic |
//! | `session.rs` | neighbours heard from and the highest step they reported (the multi-host handshake) |
//! | `hello.rs` | the handshake's datagrams: hellos out and in, probes of a neighbour's new address, earlier boots |
//! | `events.rs` | what a node reports: trace rows, step estimates, counters |
//! | `trust.rs` | what it believes: plausible steps, the innovation gate, what a stage in front of it adds ([`crate::medium::Ingress`]) and each one's fate, its false-data attacks |
#![allow(non_snake_case)]

mod accessors;
mod build;
mod clock;
mod deadline;
mod events;
mod filters;
mod hello;
mod inbox;
mod receive;
mod schemes;
mod session;
mod trust;
mod wire;

use std::sync::Arc;

use nalgebra::{DMatrix, DVector};

use crate::estimate::{Gaussian, MissingChannels, Observation};
use crate::estimators::Estimator;
pub use crate::imu_csv::ImuRow;
pub use crate::link::Transmit;
use crate::link::{NodeEvent, Stream};
use crate::medium::{Dest, Medium, Transmission};
use crate::model::{Measurement, Model, Site, Truth};
use crate::observe::{
    Filter, ImuRecorder, LmiRecorder, MeasurementRecorder, Probe, Probes, Scorer, TraceRecorder, Update,
};
use crate::scenario::{Role, Scenario};
use crate::sensor::{ImuInterval, ImuSample, Sensor};
use crate::time::Time;
use crate::wire::{Datagram, Header, Payload, BROADCAST};
use filters::Filters;
use inbox::{Inbox, Received};
use schemes::Schemes;
use session::Session;

pub use crate::observe::schemes::Feed;
pub use schemes::Traffic;

pub use crate::observe::{LmiStep, MeasurementRow, StepEstimate, TraceRow};
pub use clock::Closed;
pub use events::{Arrival, NodeCounters, NodeReport};
pub use wire::Rejections;
use wire::{Refused, Wire};

pub struct Node {
    index: usize,
    id: u32,
    role: Role,
    topo: Arc<Scenario>,
    model: Arc<dyn Model>,
    truth: Truth,
    sensor: Option<Sensor>,
    /// The process noise of this node's filters (from its own IMU's noise densities).
    Q: DMatrix<f64>,
    /// The observation; for the attitude model a template (dimensions, R, channels) linearised about each prior.
    obs: Observation,
    policy: MissingChannels,
    filters: Option<Filters>,
    initial: Gaussian,
    last_imu: Option<ImuSample>,
    /// Out-neighbours (node indices), in the order of the scenario's out-links.
    outs: Vec<usize>,
    /// What the node has sent and the driver has not yet handed to the medium, in order.
    outbox: std::collections::VecDeque<Transmission>,
    /// Encoding and sealing what goes out, checking and authenticating what comes in.
    wire: Wire,
    up: bool,
    /// Restarted since the last step: the next step re-initialises the filters.
    restarting: bool,
    inbox: Inbox,
    counters: NodeCounters,
    /// The truth against every update: the figures of both filters.
    scorer: Scorer,
    probes: Probes,
    started: bool,
    /// Neighbours, which of them were heard from, the highest step they reported.
    session: Session,
    /// Sources whose measurements this node expects each step.
    in_sources: Vec<usize>,
    /// The distributed estimators beside the two filters.
    schemes: Schemes,
    /// What the observer's fusion centers need of this step (when the run holds one).
    feed: Option<Feed>,
    /// The fusion center of a run that holds centralized-net: hands on what it heard.
    star_sink: bool,
    /// The last step begun, for the plausibility of the steps datagrams claim.
    last_step: Option<u64>,
    /// The run this node takes part in (one node per process): its boot epoch, then the smallest one a neighbour's
    /// hello carried, so that the parts of one run share it and `simnet collect` refuses to mix runs.
    run: u64,
    /// This boot's epoch (0 before [`Node::boot`]): neighbours echo it in their hellos to show them fresh.
    booted: u64,
    /// One node per process ([`Node::handshake`]): a neighbour's data is used only from the boot a fresh hello of
    /// it vouched for.
    handshake: bool,
    /// A neighbour's hello did not echo this node's boot: it has not heard this boot yet ([`Node::take_hello_due`]).
    hello_due: bool,
    /// Its false-data attacks (when compromised) and its innovation gate.
    trust: trust::Trust,
    /// What stands in front of it (the outsiders attacking it), taken ahead of what arrives.
    ingress: Option<Box<dyn crate::medium::Ingress>>,
    /// What comes next on its timeline ([`Node::handle_timeout`]).
    due: clock::Due,
}

impl Node {
    pub fn scenario(&self) -> &Arc<Scenario> {
        &self.topo
    }

    pub fn index(&self) -> usize {
        self.index
    }
    pub fn id(&self) -> u32 {
        self.id
    }

    /// The node stops: it drops what arrives and skips its steps until [`Node::handle_restart`].
    pub fn handle_crash(&mut self) {
        self.up = false;
    }

    /// The node comes back: its next step starts both filters from a fresh prior.
    pub fn handle_restart(&mut self) {
        self.up = true;
        self.restarting = true;
        self.wire.reboot();
    }

    /// A datagram came from an address that is not a neighbour's and could not be authenticated (one process per
    /// node): counted, never used.
    pub fn handle_unknown_address(&mut self) {
        self.counters.unknown_address += 1;
    }

    /// The kernel dropped `n` datagrams on this node's socket in all (its receive buffer was full).
    pub fn handle_kernel_drops(&mut self, n: u64) {
        self.counters.kernel_drops = n;
    }

    /// Whether this node authenticates its datagrams: then one from an unknown address that opens is a neighbour
    /// that moved.
    pub fn authenticates(&self) -> bool {
        self.topo.security().key.is_some()
    }

    /// This process booted at `epoch` (its boot time with random low bits): an authenticated node's datagrams
    /// are sealed under this boot's key, never a key an earlier boot used.
    pub fn boot(&mut self, epoch: u64) {
        self.wire.boot(epoch);
        self.run = self.run.min(epoch);
        self.booted = epoch;
    }

    /// This node runs in its own process and starts by the handshake of hellos: its neighbours' measurements and
    /// rounds count only from the boot that a hello echoing this node's boot came from.
    pub fn handshake(&mut self) {
        self.handshake = true;
    }

    /// Whether a neighbour has not heard this boot yet (its hello did not echo it): the shell then sends hellos at
    /// once rather than at the next period, so that a node joining a running network is vouched for before its
    /// first measurements arrive.
    pub fn take_hello_due(&mut self) -> bool {
        std::mem::take(&mut self.hello_due)
    }

    /// The run this node takes part in (see the field).
    pub fn run_id(&self) -> u64 {
        self.run
    }

    /// The epoch this boot seals under (none unauthenticated).
    pub fn sealing_epoch(&self) -> Option<u64> {
        self.wire.sealing_epoch()
    }

    /// Apply one event of the crash timeline.
    fn handle_event(&mut self, e: NodeEvent) {
        match e {
            NodeEvent::Crash => self.handle_crash(),
            NodeEvent::Restart => self.handle_restart(),
        }
    }

    pub fn is_up(&self) -> bool {
        self.up
    }

    /// Step k begins at t = k·Δt: sense, predict, queue this step's datagrams, open collection for step k.
    pub(super) fn handle_step(&mut self, k: u64) {
        let dt = self.topo.sim().dt();
        let t = k as f64 * dt;
        self.truth.advance_to(k);
        self.last_step = Some(k);
        let shift = self.truth.take_shift();
        if !self.up {
            self.counters.steps_down += 1;
            self.inbox.close_down();
            self.schemes.close_down();
            self.ingress_on_step(k);
            return;
        }
        let joining = !self.started && k > 0;
        if !self.started {
            self.started = true;
            self.counters.first_step = k;
        }
        self.counters.steps_run += 1;
        let restarted = joining || (k > 0 && std::mem::take(&mut self.restarting));
        let mut fresh = (k == 0).then(|| self.initial.clone());
        if restarted {
            // Restart, or a late join: no state, the filters start from a fresh prior at the current truth.
            if !joining {
                self.counters.restarts += 1;
            }
            let g = self.initial_estimate(self.counters.restarts + k, k);
            self.schemes.reset(&g);
            fresh = Some(g.clone());
            if let Some(f) = &mut self.filters {
                if let Some(n) = &mut f.networked {
                    n.reset(g.clone());
                }
                f.independent.reset(g);
            }
            self.last_imu = None;
        }
        // Sense first: the IMU sample at t_k closes the interval the prediction integrates over.
        let (imu, own) = self.sense(t);
        if let (Some(m), false) = (&own, self.probes.is_empty()) {
            let rows: Vec<usize> = (0..m.z.len()).filter(|&r| m.present[r]).collect();
            let row = MeasurementRow {
                step: k,
                node: self.id,
                values: rows.iter().map(|&r| m.z[r]).collect(),
                rows,
            };
            self.probes.each().for_each(|p| p.on_measurement(&row));
        }
        // Trapezoid: the mean of the samples at both ends of the interval, second-order accurate where a
        // sample held from the start leaves an O(Δt²) error per step that the IMU noise model does not cover.
        let u = match (self.last_imu, imu) {
            (Some(start), Some(end)) => Some(ImuInterval { start, end }),
            (None, Some(end)) => Some(ImuInterval { start: end, end }),
            _ => None,
        };
        if self.topo.estimators().run.iter().any(|k| k.is_center()) {
            self.feed = Some(Feed {
                node: self.index,
                step: k,
                own: own.clone(),
                imu: u.filter(|_| k > 0 && !restarted),
                shift: shift.clone(),
                prior: (k == 0 || restarted).then(|| fresh.clone()).flatten(),
                truth: self.truth.state(&*self.model),
                heard: None,
            });
        }
        if k > 0 && !restarted {
            // Every estimator of the node predicts by its model, IMU and process noise.
            let (model, Q) = (&self.model, &self.Q);
            let predict = |g: &Gaussian| {
                let mut p = model.predict(g, u.as_ref(), Q, dt);
                if let Some(s) = &shift {
                    p.x += s;
                }
                p
            };
            if !self.schemes.is_empty() {
                self.schemes.predict(&predict);
            }
            if let Some(f) = &mut self.filters {
                if let Some(n) = &mut f.networked {
                    n.predict(&predict);
                }
                f.independent.predict(&predict);
            }
        }
        self.last_imu = imu;
        let at = self.topo.step_time(k);
        let round0 = if self.schemes.is_empty() {
            Vec::new()
        } else {
            self.schemes.begin(
                k,
                at,
                &schemes::input(&*self.model, &self.obs, self.index, own.as_ref(), k),
                &self.wire,
            )
        };
        self.send(at, own.as_ref(), &round0);
        self.inbox.open(k, own);
        self.ingress_on_step(k);
    }

    /// The sub-deadline of round `r` of step k, t_k + D(r+1)/L, for r < L − 1 (the last round closes at
    /// [`Node::handle_deadline`]): every distributed estimator combines round r's messages and queues round r + 1's.
    pub(super) fn handle_round(&mut self, k: u64, r: usize) {
        if self.schemes.is_empty() || !self.up {
            return;
        }
        let at = self.topo.round_end(k, r);
        let input = schemes::input(&*self.model, &self.obs, self.index, self.inbox.own(), k);
        let out = self.schemes.close_round(k, r, at, &input, &self.wire);
        if out.is_empty() {
            return;
        }
        for (to, group) in self.addressed(&out) {
            self.queue(to, at, group, Stream::Round(r + 1));
        }
    }

    /// This step's IMU sample and the node's own measurement ([`crate::model::Sensing::sense`]).
    fn sense(&mut self, t: f64) -> (Option<ImuSample>, Option<Measurement>) {
        let Some(sensor) = self.sensor.as_mut() else {
            return (None, None);
        };
        let sensed = self.model.sense(sensor, &self.truth, Site { node: self.index }, t);
        if let Some(row) = &sensed.row {
            self.probes.each().for_each(|p| p.on_imu(row));
        }
        (sensed.imu, sensed.z)
    }

    /// The step's measurement datagrams to every out-neighbour, and `round0` (the estimators' round-0 messages)
    /// under the verdict of the first of them, or under their own from the round stream when there is no
    /// measurement.
    /// `at` is the step's time.
    fn send(&mut self, at: Time, own: Option<&Measurement>, round0: &[Datagram]) {
        let Some(own) = own else {
            for (to, group) in self.addressed(round0) {
                self.queue(to, at, group, Stream::Round(0));
            }
            return;
        };
        // A compromised node sends its measurement moved by the false-data attacks under way.
        let tainted = self.trust.tainted(own, at);
        let own = tainted.as_ref().map_or(own, |(m, _)| m);
        let (z, m) = (&own.z, own.z.len());
        let have = (0..m).filter(|&r| own.present[r]).fold(0u64, |acc, r| acc | 1 << r);
        let groups: Vec<u64> = if self.topo.sim().split_channels {
            // The channels travel separately so that loss can be partial.
            let mut g = vec![0u64; self.obs.channels()];
            for (row, ch) in self.obs.channel_of_row.iter().enumerate() {
                g[*ch] |= 1 << row;
            }
            g.into_iter()
                .map(|rows| rows & have)
                .filter(|rows| *rows != 0)
                .collect()
        } else {
            vec![have]
        };
        let rides = !round0.is_empty();
        let datagrams: Vec<Datagram> = groups
            .iter()
            .map(|rows| Datagram {
                header: Header::new(self.id, BROADCAST, 0, at),
                payload: Payload::measurement(*rows, (0..m).filter(|r| rows & (1 << r) != 0).map(|r| z[r]).collect()),
            })
            .collect();
        let measurements = self.addressed(&datagrams);
        for ((to, round0), (_, measurements)) in self.addressed(round0).into_iter().zip(measurements) {
            if measurements.is_empty() {
                self.queue(to, at, round0, Stream::Round(0));
                continue;
            }
            for (i, bytes) in measurements.into_iter().enumerate() {
                let mut group = vec![bytes];
                if i == 0 && rides {
                    group.extend_from_slice(&round0);
                }
                self.queue(to, at, group, Stream::Measurement);
            }
        }
        for i in tainted.map(|(_, attacks)| attacks).unwrap_or_default() {
            self.trust.count_sent(i, (self.outs.len() * groups.len()) as u64);
        }
    }

    /// `group` sent at `at` to `to`, for the driver to hand to the medium.
    fn queue(&mut self, to: Dest, at: Time, group: Vec<bytes::Bytes>, stream: Stream) {
        if !group.is_empty() {
            self.outbox.push_back(Transmission { to, at, group, stream });
        }
    }

    /// Hand everything sent so far to `medium` (under the run's fault windows).
    pub fn send_to(&mut self, medium: &mut dyn Medium) {
        while let Some(tx) = self.outbox.pop_front() {
            medium.transmit(self.index, tx, self.topo.faults());
        }
    }

    /// Bytes arrived; `from` is the sender's node index when the shell knows it by address.
    pub fn handle_datagram(&mut self, from: Option<usize>, bytes: &[u8]) -> Option<Arrival> {
        self.ingress_on_arrival(from, bytes);
        self.receive(from, bytes)
    }
}

#[cfg(test)]
mod tests;
