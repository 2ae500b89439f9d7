//! The node proper: a sans-IO endpoint that estimates from what it senses and what it hears. It never sees the
//! truth: each step's IMU sample and measurement come from its testbed ([`super::Testbed`], the world around the
//! node), and each step's updates leave it as a [`Closing`] for the testbed's observer to score.
//!
//! | file | owns |
//! |---|---|
//! | `build.rs` | an endpoint built from its scenario and the prior its filters begin from |
//! | `timeline.rs` | what is due next on the node's timeline ([`Due`]) and the crash timeline's events of a step |
//! | `receive.rs` | the receive path: bytes checked, authenticated, found plausible, collected |
//! | `deadline.rs` | the close of a step: both filters and the estimators updated, each update handed out ([`Closing`]) |
//! | `accessors.rs` | what drivers read and take from the endpoint, its part of the end-of-run report |
//! | `wire.rs` | addressing and sealing: one broadcast, or a sealed copy per out-link; opening: what is accepted |
//! | `inbox.rs` | step collection, the early buffer, receive counters |
//! | `filters.rs` | the node's two filters, `sequeira` and `independent`, as estimators |
//! | `schemes.rs` | the distributed estimators beside them: each round's messages, what arrived, their traffic |
//! | `session.rs` | neighbours heard from and the highest step they reported (the multi-host handshake) |
//! | `hello.rs` | the handshake's datagrams: hellos out and in, probes of a neighbour's new address, earlier boots |
//! | `events.rs` | what a node reports: counters, its end-of-run report |
//! | `trust.rs` | what it believes: plausible steps, the innovation gate, what a stage in front of it adds ([`crate::medium::Ingress`]) and each one's fate, its false-data attacks |
#![allow(non_snake_case)]

mod accessors;
mod build;
mod deadline;
mod events;
mod filters;
mod hello;
mod inbox;
mod receive;
mod schemes;
mod session;
#[cfg(test)]
mod tests;
mod timeline;
mod trust;
mod wire;

use std::sync::Arc;

use nalgebra::{DMatrix, DVector};

use crate::estimate::{Gaussian, MissingChannels, Observation};
use crate::estimators::Estimator;
pub use crate::link::Transmit;
use crate::link::{NodeEvent, Stream};
use crate::medium::{Dest, Medium, Transmission};
use crate::model::{Measurement, Model, Site};
use crate::observe::Filter;
use crate::scenario::{Role, Scenario};
use crate::sensor::{ImuInterval, ImuSample};
use crate::time::Time;
use crate::wire::{Datagram, Header, Payload, BROADCAST};
use filters::Filters;
use inbox::{Inbox, Received};
use schemes::Schemes;
use session::Session;

pub use crate::observe::schemes::Feed;
pub use schemes::Traffic;

use crate::observe::LmiStep;
pub use deadline::{Closing, Updated};
pub use events::{Arrival, NodeCounters, NodeReport};
pub use timeline::{Due, Opening, Sample};
pub use wire::Rejections;
use wire::{Refused, Wire};

pub struct Endpoint {
    index: usize,
    id: u32,
    role: Role,
    topo: Arc<Scenario>,
    model: Arc<dyn Model>,
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
    /// What its testbed's observer listens to (what to build for it).
    listening: Listening,
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
    /// This boot's epoch (0 before [`Endpoint::boot`]): neighbours echo it in their hellos to show them fresh.
    booted: u64,
    /// One node per process ([`Endpoint::handshake`]): a neighbour's data is used only from the boot a fresh hello of
    /// it vouched for.
    handshake: bool,
    /// A neighbour's hello did not echo this node's boot: it has not heard this boot yet ([`Endpoint::take_hello_due`]).
    hello_due: bool,
    /// Its false-data attacks (when compromised) and its innovation gate.
    trust: trust::Trust,
    /// What stands in front of it (the outsiders attacking it), taken ahead of what arrives.
    ingress: Option<Box<dyn crate::medium::Ingress>>,
    /// What comes next on its timeline.
    due: Due,
}

/// What the testbed's observer of a node wants of each update beyond the estimates.
#[derive(Debug, Clone, Copy, Default)]
pub struct Listening {
    /// The ids of the sources each update used (the trace's `received` column).
    pub sources: bool,
    /// The β-independent LMI terms of each networked update (one extra gain computation per step).
    pub lmi: bool,
}

impl Endpoint {
    pub fn scenario(&self) -> &Arc<Scenario> {
        &self.topo
    }

    pub fn index(&self) -> usize {
        self.index
    }
    pub fn id(&self) -> u32 {
        self.id
    }

    /// The node stops: it drops what arrives and skips its steps until [`Endpoint::handle_restart`].
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

    /// Step k begins at t_k = k·Δt, after the crash timeline's events for it: a node that is down closes it at
    /// once; one that is up counts it and says whether its filters start afresh ([`Opening`]).
    pub(crate) fn open_step(&mut self, k: u64) -> Opening {
        self.last_step = Some(k);
        if !self.up {
            self.counters.steps_down += 1;
            self.inbox.close_down();
            self.schemes.close_down();
            self.ingress_on_step(k);
            return Opening::Down;
        }
        let joining = !self.started && k > 0;
        if !self.started {
            self.started = true;
            self.counters.first_step = k;
        }
        self.counters.steps_run += 1;
        let restarted = joining || (k > 0 && std::mem::take(&mut self.restarting));
        if restarted && !joining {
            self.counters.restarts += 1;
        }
        // Restart, or a late join: no state, the filters start from a fresh prior (the `restarts + k`-th draw).
        Opening::Up {
            fresh: restarted.then_some(self.counters.restarts + k),
        }
    }

    /// Step k of a node that is up, with what its testbed gave it: predict every estimator over the interval
    /// the IMU samples close, queue this step's datagrams, open collection for step k.
    pub(crate) fn step(&mut self, k: u64, sample: Sample) {
        let Sample { imu, own, shift, fresh } = sample;
        let dt = self.topo.sim().dt();
        let restarted = fresh.is_some();
        let fresh = fresh.or_else(|| (k == 0).then(|| self.initial.clone()));
        if restarted {
            let g = fresh.clone().expect("restarted");
            self.schemes.reset(&g);
            if let Some(f) = &mut self.filters {
                if let Some(n) = &mut f.networked {
                    n.reset(g.clone());
                }
                f.independent.reset(g);
            }
            self.last_imu = None;
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
                // The testbed adds the truth ([`crate::node::Node`]'s step).
                truth: DVector::zeros(0),
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
    /// [`Endpoint::handle_deadline`]): every distributed estimator combines round r's messages and queues round r + 1's.
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
