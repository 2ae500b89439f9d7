//! One node as a sans-IO state machine: it never touches a socket or a clock, so the same node runs in memory
//! ([`crate::sim::Sim`]), over UDP on the virtual or the wall clock ([`crate::net`]) and one per process
//! (`simnet node`).
//!
//! # Call order and time
//!
//! Time is simulated seconds; step k begins at t_k = k·Δt and closes at its deadline t_k + D (D ≤ Δt).
//!
//! 0. [`Node::handle_crash`] / [`Node::handle_restart`] before the step they precede, as the crash timeline
//!    ([`crate::link::FaultSchedule::node_events`]) says: the node itself never reads the fault schedule.
//! 1. [`Node::handle_step`]`(k)` at t_k: the node senses, predicts both filters to t_k, and queues this step's
//!    datagrams on its outgoing links (the link layer decides loss, delay, duplication and corruption).
//! 2. [`Node::poll_transmit`]`(now)` until it returns `None`: every queued copy whose delivery time is ≤ `now`, in
//!    delivery order; [`Node::poll_timeout`] says when the next one is due. The shell sends each to `to`.
//! 3. [`Node::handle_datagram`]`(from, bytes)` for every datagram that arrives, in any order, `from` the sender's
//!    node index when the shell knows it by address. A measurement for the open step is collected; one for a later
//!    step is held (bounded); one for a closed step counts as late.
//! 4. With L consensus rounds ([`crate::scenario::EstimatorsConfig`]), [`Node::handle_round`]`(k, r)` at each
//!    sub-deadline t_k + D(r+1)/L for r < L − 1: the distributed estimators combine round r and queue round r + 1
//!    (then steps 2 and 3 again).
//! 5. [`Node::handle_deadline`]`(k)` at t_k + D: both filters update with what arrived (and the estimators close
//!    their last round); each update goes to the node's [`crate::observe::Scorer`] and then to its probes (the
//!    trace, IMU and LMI recorders when on, any [`Node::add_probe`] added); the networked estimate is returned for
//!    the fusion observer.
//!
//! A node whose step k is skipped (down, or joining late) keeps its counters honest: a crash drops what arrives,
//! a restart re-initialises both filters.
//!
//! | file | owns |
//! |---|---|
//! | `inbox.rs` | step collection, the early buffer, receive counters |
//! | `filters.rs` | the networked and independent filters' update over any [`crate::model::Model`] |
//! | `schemes.rs` | the distributed estimators beside them: each round's messages, what arrived, their traffic |
//! | `session.rs` | neighbours heard from and the highest step they reported (the multi-host handshake) |
//! | `hello.rs` | the handshake's datagrams: hellos out and in, probes of a neighbour's new address, earlier boots |
//! | `events.rs` | what a node reports: trace rows, step estimates, counters |
//! | `trust.rs` | what it believes: plausible steps, the innovation gate, the attacks on it and their tallies |
#![allow(non_snake_case)]

mod events;
mod filters;
mod hello;
mod inbox;
mod schemes;
mod session;
mod trust;
mod wire;

use std::sync::Arc;

use nalgebra::{DMatrix, DVector};

use crate::estimate::{Gaussian, MissingChannels, Observation};
pub use crate::imu_csv::ImuRow;
pub use crate::link::Transmit;
use crate::link::{Egress, Link, NodeEvent, Stream};
use crate::model::{Measurement, Model, Truth};
use crate::observe::{
    Filter, ImuRecorder, LmiRecorder, MeasurementRecorder, Probe, Probes, Scorer, TraceRecorder, Update,
};
use crate::scenario::{Role, Scenario};
use crate::sensor::{ImuInterval, ImuSample, Sensor};
use crate::wire::{Datagram, Header, Payload};
use filters::Filters;
use inbox::{Inbox, Received};
use schemes::Schemes;
use session::Session;

pub use crate::observe::schemes::Feed;
pub use schemes::Traffic;

pub use crate::observe::{LmiStep, MeasurementRow, StepEstimate, TraceRow};
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
    /// The outgoing links and the copies they have yet to deliver.
    egress: Egress,
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
    /// The attacks around this node and its innovation gate.
    trust: trust::Trust,
}

impl Node {
    /// `record_trace` keeps one row per step and filter (needed for `trace.csv` and the plots).
    pub fn new(topo: Arc<Scenario>, index: usize, record_trace: bool) -> Node {
        let cfg = &topo.nodes()[index];
        let seed = topo.sim().seed;
        let dt = topo.sim().dt();
        let model = topo.model().shared();
        let Q = model.process_noise(cfg.role.senses().then_some(&cfg.sensor), dt);
        let obs = model.observation();
        let policy = MissingChannels::for_noise(&obs.R, topo.consensus().inflation);
        let sensor = cfg.role.senses().then(|| {
            Sensor::new(
                cfg.sensor.clone(),
                crate::rng::stream(seed, "sensor", index as u64, 0),
                dt,
            )
        });
        let link_on = |l: &crate::scenario::DirectedLink, stream: &str| {
            Link::new(
                l.from,
                l.to,
                l.config,
                crate::rng::stream(seed, stream, l.from as u64, l.to as u64),
            )
        };
        let links = topo.out_links(index).map(|l| link_on(l, "link")).collect();
        let in_node = topo.estimators().any_in_node();
        // One stream per round and link: round r meets the same fates whatever L is.
        let rounds = if in_node { topo.estimators().rounds } else { 0 };
        let round_links = (0..rounds)
            .map(|r| {
                topo.out_links(index)
                    .map(|l| link_on(l, &format!("link-round-{r}")))
                    .collect()
            })
            .collect();
        let out_degree = topo.out_links(index).count();
        // The IMU file that replaces the simulated IMU, read at this run's steps.
        let recorded = cfg
            .recording
            .as_ref()
            .filter(|_| cfg.role.senses())
            .map(|r| Arc::new(r.data.at_steps(dt, topo.sim().steps())));
        let truth = model.truth(topo.sim().trajectory, dt, seed, recorded);
        let obs_dim = obs.dim();
        let trust = trust::Trust::new(&topo, index, obs_dim);
        let mut node = Node {
            index,
            id: cfg.id,
            role: cfg.role,
            truth,
            sensor,
            Q,
            obs,
            policy,
            filters: None,
            initial: Gaussian {
                x: DVector::zeros(1),
                P: DMatrix::identity(1, 1),
            },
            last_imu: None,
            egress: Egress::with_rounds(links, round_links),
            wire: Wire::new(topo.nodes()[index].id, topo.security().key.as_ref(), 0),
            up: true,
            restarting: false,
            inbox: Inbox::new(topo.in_links(index).map(|l| l.from), obs_dim),
            counters: NodeCounters::default(),
            scorer: Scorer::new(model.clone(), topo.sim().burn_in_steps(), topo.sim().divergence_trace),
            probes: Probes {
                trace: record_trace.then(|| TraceRecorder::new(model.clone())),
                imu: record_trace.then(ImuRecorder::default),
                measurements: record_trace.then(MeasurementRecorder::default),
                ..Default::default()
            },
            model,
            started: false,
            session: Session::new(&topo, index),
            in_sources: topo
                .in_links(index)
                .map(|l| l.from)
                .filter(|&j| topo.nodes()[j].role.senses())
                .collect(),
            schemes: Schemes::new(Vec::new(), 1, 0),
            feed: None,
            star_sink: topo.estimators().sink == Some(index)
                && topo.estimators().run.contains(&crate::estimators::Kind::CentralizedNet),
            last_step: None,
            run: u64::MAX,
            booted: 0,
            handshake: false,
            hello_due: false,
            trust,
            topo,
        };
        node.initial = node.initial_estimate(0, 0);
        node.filters = node.role.estimates().then(|| Filters {
            networked: node.initial.clone(),
            independent: node.initial.clone(),
        });
        if in_node {
            let ctx = schemes::context(&node.topo, index, &*node.model);
            let e = node.topo.estimators();
            let slots = e
                .run
                .iter()
                .filter(|k| k.in_node())
                .filter_map(|&k| {
                    crate::estimators::build(k, ctx.clone(), node.initial.clone(), node.policy, &e.params)
                        .map(|est| (k, est))
                })
                .collect();
            node.schemes = Schemes::new(slots, e.rounds, out_degree);
        }
        node
    }

    pub fn scenario(&self) -> &Arc<Scenario> {
        &self.topo
    }

    pub fn index(&self) -> usize {
        self.index
    }
    pub fn id(&self) -> u32 {
        self.id
    }

    /// The prior a (re)started filter begins from ([`Model::initial`]), from the node's own stream.
    fn initial_estimate(&self, restart: u64, k: u64) -> Gaussian {
        let k = k as usize;
        let first = self.truth.recording().and_then(|(rec, _)| {
            let mag = rec.mag.as_ref().and_then(|v| v.get(k));
            rec.imu.get(k).map(|s| (s, mag))
        });
        let mut rng = crate::rng::stream(self.topo.sim().seed, "init", self.index as u64, restart);
        self.model.initial(&self.truth.state(&*self.model), first, &mut rng)
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
    pub fn handle_event(&mut self, e: NodeEvent) {
        match e {
            NodeEvent::Crash => self.handle_crash(),
            NodeEvent::Restart => self.handle_restart(),
        }
    }

    pub fn is_up(&self) -> bool {
        self.up
    }

    /// Step k begins at t = k·Δt: sense, predict, queue this step's datagrams, open collection for step k.
    pub fn handle_step(&mut self, k: u64) {
        let dt = self.topo.sim().dt();
        let t = k as f64 * dt;
        self.truth.advance_to(k);
        self.last_step = Some(k);
        let shift = self.truth.take_shift();
        if !self.up {
            self.counters.steps_down += 1;
            self.inbox.close_down();
            self.schemes.close_down();
            self.air_on_step(k);
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
                f.networked = g.clone();
                f.independent = g;
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
            if !self.schemes.is_empty() {
                let (model, Q) = (&self.model, &self.Q);
                self.schemes.predict(&|g: &Gaussian| {
                    let mut p = model.predict(g, u.as_ref(), Q, dt);
                    if let Some(s) = &shift {
                        p.x += s;
                    }
                    p
                });
            }
            if let Some(f) = &mut self.filters {
                f.networked = self.model.predict(&f.networked, u.as_ref(), &self.Q, dt);
                f.independent = self.model.predict(&f.independent, u.as_ref(), &self.Q, dt);
                if let Some(s) = &shift {
                    f.networked.x += s;
                    f.independent.x += s;
                }
            }
        }
        self.last_imu = imu;
        let round0 = if self.schemes.is_empty() {
            Vec::new()
        } else {
            self.schemes.begin(
                k,
                &schemes::input(&*self.model, &self.obs, own.as_ref()),
                &mut self.wire,
            )
        };
        self.send(k, t, own.as_ref(), &round0);
        self.inbox.open(k, own);
        self.air_on_step(k);
    }

    /// The sub-deadline of round `r` of step k, t_k + D(r+1)/L, for r < L − 1 (the last round closes at
    /// [`Node::handle_deadline`]): every distributed estimator combines round r's messages and queues round r + 1's.
    pub fn handle_round(&mut self, k: u64, r: usize) {
        if self.schemes.is_empty() || !self.up {
            return;
        }
        let input = schemes::input(&*self.model, &self.obs, self.inbox.own());
        let out = self.schemes.close_round(k, r, &input, &mut self.wire);
        if out.is_empty() {
            return;
        }
        let t = self.topo.round_end(k, r);
        for (li, group) in self.per_link(&out).into_iter().enumerate() {
            self.egress
                .push_group(li, t, &group, self.topo.faults(), Stream::Round(r + 1));
        }
    }

    /// `ds` as bytes for every out-link: sealed for each receiver when the run is authenticated, else encoded once
    /// and shared.
    fn per_link(&mut self, ds: &[Datagram]) -> Vec<Vec<bytes::Bytes>> {
        let links = self.egress.len();
        if self.wire.seals() {
            (0..links).map(|li| self.seal_for(li, ds)).collect()
        } else if links == 0 {
            Vec::new()
        } else {
            vec![self.seal_for(0, ds); links]
        }
    }

    /// The boot node `j` is bound to in what this node seals for it: its boot as its hellos give it (one node per
    /// process; 0 before the first, which it refuses), or the run's boot that every node of an in-process run
    /// shares.
    fn boot_of(&self, j: usize) -> u64 {
        if self.handshake {
            self.session.boot(j).unwrap_or(0)
        } else {
            self.booted
        }
    }

    /// `ds` as bytes for the receiver of out-link `li`: sealed for it when the run is authenticated.
    fn seal_for(&mut self, li: usize, ds: &[Datagram]) -> Vec<bytes::Bytes> {
        let j = self.egress.to(li);
        let (to, boot) = (self.topo.nodes()[j].id, self.boot_of(j));
        ds.iter()
            .filter_map(|d| {
                self.wire
                    .encode(d, to, boot)
                    .inspect_err(|e| tracing::error!(node = self.id, "cannot encode a datagram: {e}"))
                    .ok()
            })
            .collect()
    }

    /// This step's IMU sample and the node's own measurement ([`Model::sense`]).
    fn sense(&mut self, t: f64) -> (Option<ImuSample>, Option<Measurement>) {
        let Some(sensor) = self.sensor.as_mut() else {
            return (None, None);
        };
        let sensed = self.model.sense(sensor, &self.truth, t);
        if let Some(row) = &sensed.row {
            self.probes.each().for_each(|p| p.on_imu(row));
        }
        (sensed.imu, sensed.z)
    }

    /// The step's measurement datagrams on every out-link, and `round0` (the estimators' round-0 messages) under
    /// the verdict of the first of them, or under their own from the round stream when there is no measurement.
    fn send(&mut self, k: u64, t: f64, own: Option<&Measurement>, round0: &[Datagram]) {
        let Some(own) = own else {
            if !round0.is_empty() {
                for (li, group) in self.per_link(round0).into_iter().enumerate() {
                    self.egress
                        .push_group(li, t, &group, self.topo.faults(), Stream::Round(0));
                }
            }
            return;
        };
        // A compromised node sends its measurement moved by the false-data attacks under way.
        let tainted = self.trust.tainted(own, t);
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
        for (li, round0) in self.per_link(round0).into_iter().enumerate() {
            let mut first = true;
            for rows in &groups {
                let values: Vec<f64> = (0..m).filter(|r| rows & (1 << r) != 0).map(|r| z[r]).collect();
                let id = self.id;
                let d = self
                    .wire
                    .datagram(|seq| Header::new(id, seq, k), Payload::measurement(*rows, values));
                match self.seal_for(li, std::slice::from_ref(&d)).pop() {
                    Some(bytes) if first && rides => {
                        let mut group = vec![bytes];
                        group.extend_from_slice(&round0);
                        self.egress
                            .push_group(li, t, &group, self.topo.faults(), Stream::Measurement);
                    }
                    Some(bytes) => self.egress.push(li, t, &bytes, self.topo.faults()),
                    None => {}
                }
                first = false;
            }
            if groups.is_empty() && rides {
                self.egress
                    .push_group(li, t, &round0, self.topo.faults(), Stream::Round(0));
            }
        }
        for i in tainted.map(|(_, attacks)| attacks).unwrap_or_default() {
            self.trust.count_sent(i, (self.egress.len() * groups.len()) as u64);
        }
    }

    /// The next datagram due at or before `now` (simulated seconds), in delivery order.
    pub fn poll_transmit(&mut self, now: f64) -> Option<Transmit> {
        self.egress.poll_transmit(now)
    }

    /// When the next queued datagram is due.
    pub fn poll_timeout(&self) -> Option<f64> {
        self.egress.poll_timeout()
    }

    /// Bytes arrived; `from` is the sender's node index when the shell knows it by address.
    pub fn handle_datagram(&mut self, from: Option<usize>, bytes: &[u8]) -> Option<Arrival> {
        self.air_on_arrival(from, bytes);
        self.receive(from, bytes)
    }

    /// Bytes through the whole receive path: checked, authenticated, plausible, collected.
    fn receive(&mut self, from: Option<usize>, bytes: &[u8]) -> Option<Arrival> {
        self.counters.datagrams_in += 1;
        if self.handshake && self.authenticates() && self.claims_an_earlier_boot(bytes) {
            // An earlier boot of a neighbour than the one a fresh hello vouched for (an earlier run's datagram,
            // replayed): refused as that without opening it.
            self.wire.rejected.too_old += 1;
            return None;
        }
        let (topo, session) = (&self.topo, &self.session);
        let known = |id: u32| {
            topo.index_of(id)
                .is_some_and(|j| session.neighbours.binary_search(&j).is_ok())
        };
        let (dg, epoch) = match self.wire.decode(bytes, known) {
            Ok(d) => d,
            Err(Refused::Corrupted) if from.is_some() => {
                // A peer's datagram damaged on the way: the link layer's corruption, caught.
                self.counters.corrupted += 1;
                if let Some(f) = from {
                    self.inbox.rx.get_mut(f).corrupted += 1;
                }
                return None;
            }
            Err(Refused::Rejected(r)) => {
                tracing::debug!(node = self.id, "rejected datagram: {r}");
                return None;
            }
            Err(Refused::Corrupted) => {
                self.counters.malformed += 1;
                return None;
            }
            Err(Refused::Malformed(e)) => {
                tracing::debug!(node = self.id, "malformed datagram: {e}");
                self.counters.malformed += 1;
                return None;
            }
        };
        let Some(src) = self.topo.index_of(dg.header.src) else {
            self.counters.malformed += 1;
            return None;
        };
        if from.is_some_and(|f| f != src) || src == self.index {
            // The header names a different node than the socket it came from.
            self.counters.malformed += 1;
            return None;
        }
        let peer_step = match &dg.payload {
            Payload::Hello { running, .. } => *running,
            Payload::Measurement { .. } | Payload::Round { .. } => Some(dg.header.step),
        };
        if [Some(dg.header.step), peer_step]
            .into_iter()
            .flatten()
            .any(|s| !self.plausible_step(s))
        {
            self.counters.implausible_step += 1;
            return None;
        }
        let mut answer = 0;
        if let Payload::Hello { .. } = &dg.payload {
            answer = self.on_hello(src, epoch, &dg.payload);
        } else if self.handshake && !self.session.vouched(src, epoch) {
            // A measurement or round of a boot no fresh hello vouched for: an earlier run's, replayed (or a
            // neighbour's new boot before its first fresh hello). Never used.
            self.wire.rejected.too_old += 1;
            return None;
        }
        self.session.heard_from(src, peer_step);
        let arrival = Arrival {
            src,
            step: dg.header.step,
            measurement: matches!(dg.payload, Payload::Measurement { .. }),
            answer,
        };
        if let Payload::Round { round, scheme, body } = &dg.payload {
            if !self.up {
                return None;
            }
            let (states, rows) = (self.initial.x.len(), self.obs.dim());
            if self
                .schemes
                .receive(src, dg.header.step, *round, *scheme, body, states, rows)
                .is_err()
            {
                // A round this run does not hold, a scheme it does not run, or a message of the wrong size.
                self.counters.malformed += 1;
                return None;
            }
            return Some(arrival);
        }
        let Payload::Measurement { rows, values } = dg.payload else {
            return Some(arrival);
        };
        if !self.up {
            self.inbox.rx.get_mut(src).while_down += 1;
            return None;
        }
        let m = self.obs.dim();
        if m < 64 && rows >> m != 0 {
            self.counters.malformed += 1;
            return None;
        }
        if self.inbox.receive(src, dg.header.step, rows, values) == Received::Held {
            self.counters.early += 1;
        }
        Some(arrival)
    }

    /// The deadline of step k: update both filters with what arrived, record metrics.
    pub fn handle_deadline(&mut self, k: u64) -> Option<StepEstimate> {
        let inbox = self.inbox.close(k, &self.in_sources)?;
        if let Some(f) = self.feed.as_mut().filter(|_| self.star_sink) {
            f.heard = Some(inbox.clone());
        }
        let mut schemes = self.finish_schemes(k);
        let filters = self.filters.as_mut()?;
        let topo = &self.topo;
        let c = topo.consensus();
        let beta = c.beta.row(self.index);
        let priors = filters.clone();

        // A neighbour's measurement too far from what this node predicts is left out (the innovation gate).
        let gated: Vec<usize> = inbox
            .iter()
            .filter(|(_, p)| self.trust.gates(&*self.model, &self.obs, &priors.networked, p))
            .map(|(s, _)| *s)
            .collect();
        for s in &gated {
            self.counters.gated += 1;
            self.inbox.rx.get_mut(*s).gated += 1;
        }
        // Networked: consensus over own + received, in source order (deterministic sums).
        let mut used: Vec<(usize, &Measurement)> = Vec::new();
        if let Some(own) = self.inbox.own() {
            used.push((self.index, own));
        }
        used.extend(inbox.iter().filter(|(s, _)| !gated.contains(s)).map(|(s, p)| (*s, p)));
        used.sort_by_key(|(s, _)| *s);
        let updated = filters::update(
            &filters::Inputs {
                model: &*self.model,
                obs: &self.obs,
                policy: self.policy,
                consensus: c,
                beta,
                index: self.index,
                k,
            },
            &priors,
            &used,
            self.probes.lmi.is_some(),
        );
        if let Some(terms) = updated.lmi {
            match terms {
                Ok(Some(terms)) => {
                    let step = LmiStep {
                        k,
                        sources: used.iter().map(|(s, _)| *s).collect(),
                        terms,
                    };
                    self.probes.each().for_each(|p| p.on_lmi(&step));
                }
                Ok(None) => {}
                Err(e) => {
                    self.counters.lmi_failures += 1;
                    tracing::debug!(node = self.id, step = k, "LMI terms not computed: {e}");
                }
            }
        }
        let feasible = updated.feasible;
        let truth = self.truth.state(&*self.model);
        // The sources' ids are for the probes (the trace's `received` column); none are built when there is no probe.
        let (received, own_only): (Vec<u32>, Vec<u32>) = if self.probes.is_empty() {
            Default::default()
        } else {
            let r: Vec<u32> = used.iter().map(|(s, _)| topo.nodes()[*s].id).collect();
            let own = r.iter().copied().filter(|r| *r == self.id).collect();
            (r, own)
        };
        let t = k as f64 * topo.sim().dt();
        for (filter, post, prior, slot) in [
            (
                Filter::Networked,
                updated.networked,
                &priors.networked,
                &mut filters.networked,
            ),
            (
                Filter::Independent,
                updated.independent,
                &priors.independent,
                &mut filters.independent,
            ),
        ] {
            // A failed update keeps stepping from the prior, so that the run finishes and the rest of the figures stand.
            let (post, failed) = match post {
                Ok(g) => (g, false),
                Err(_) => (prior.clone(), true),
            };
            let networked = filter == Filter::Networked;
            let u = Update {
                node: self.id,
                step: k,
                t,
                filter,
                truth: &truth,
                prior,
                post: &post,
                failed,
                feasible: !networked || feasible,
                received: if networked { &received } else { &own_only },
            };
            let score = self.scorer.score(&u);
            self.probes.each().for_each(|p| p.on_update(&u, &score));
            *slot = if post.x.iter().chain(post.P.iter()).all(|v| v.is_finite()) {
                post
            } else {
                self.initial.clone()
            };
        }
        let run = &self.topo.estimators().run;
        for (kind, g) in [
            (crate::estimators::Kind::Independent, &filters.independent),
            (crate::estimators::Kind::Sequeira, &filters.networked),
        ] {
            if run.contains(&kind) {
                schemes.push((kind, g.x.clone()));
            }
        }
        Some(StepEstimate {
            node: self.index,
            step: k,
            truth,
            frame: self.truth.frame(),
            networked: filters.networked.clone(),
            diverged: self.scorer.metrics(Filter::Networked).diverged,
            schemes,
        })
    }

    /// What the centralized reference needs of the last step (none unless the run holds it).
    pub fn take_feed(&mut self) -> Option<Feed> {
        self.feed.take()
    }

    /// Every distributed estimator's traffic from this node.
    pub fn scheme_traffic(&self) -> Vec<(crate::estimators::Kind, Traffic)> {
        self.schemes.traffic()
    }

    /// Keep the LMI terms of every networked update from now on (for a protocol search; costs one extra
    /// gain computation per step).
    pub fn record_lmi(&mut self) {
        self.probes.lmi.get_or_insert_with(LmiRecorder::default);
    }

    /// Feed `p` every update, IMU sample and set of LMI terms from now on.
    pub fn add_probe(&mut self, p: Box<dyn Probe>) {
        self.probes.added.push(p);
    }

    pub fn take_lmi_log(&mut self) -> Vec<LmiStep> {
        self.probes.lmi.as_mut().map(LmiRecorder::take).unwrap_or_default()
    }

    /// Sources whose measurements this node expects each step (node indices; own excluded).
    pub fn in_sources(&self) -> &[usize] {
        &self.in_sources
    }

    /// Neighbours in either direction (node indices).
    pub fn neighbours(&self) -> &[usize] {
        &self.session.neighbours
    }

    /// Whether every neighbour has been heard from (a hello or a measurement).
    pub fn heard_all(&self) -> bool {
        self.session.heard_all()
    }

    /// The highest step any neighbour has reported.
    pub fn max_peer_step(&self) -> Option<u64> {
        self.session.max_peer_step
    }

    /// The node's own measurements recorded since the last call.
    pub fn take_measurements(&mut self) -> Vec<MeasurementRow> {
        self.probes
            .measurements
            .as_mut()
            .map(MeasurementRecorder::take)
            .unwrap_or_default()
    }

    /// The IMU rows recorded since the last call.
    pub fn take_imu(&mut self) -> Vec<ImuRow> {
        self.probes.imu.as_mut().map(ImuRecorder::take).unwrap_or_default()
    }

    /// The trace rows recorded since the last call (a shell streams them out step by step).
    pub fn take_trace(&mut self) -> Vec<TraceRow> {
        self.probes.trace.as_mut().map(TraceRecorder::take).unwrap_or_default()
    }

    pub fn report(&mut self) -> NodeReport {
        let est = self.role.estimates();
        NodeReport {
            index: self.index,
            id: self.id,
            role: self.role,
            networked: est.then(|| self.scorer.metrics(Filter::Networked).clone()),
            independent: est.then(|| self.scorer.metrics(Filter::Independent).clone()),
            schemes: if est {
                self.scorer.scheme_metrics().to_vec()
            } else {
                Vec::new()
            },
            traffic: self.schemes.traffic(),
            rounds_late: self.schemes.late,
            links_out: self.egress.counters(),
            rx: self.inbox.rx.clone(),
            counters: NodeCounters {
                rejected: self.wire.rejected,
                ..self.counters
            },
            trace: self.take_trace(),
            imu: self.take_imu(),
            attacks: self.trust.tallies(),
        }
    }
}

#[cfg(test)]
mod tests;
