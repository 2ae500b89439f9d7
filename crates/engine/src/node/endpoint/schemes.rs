//! The distributed estimators a node runs beside its two filters ([`crate::estimators`]), over L consensus rounds a
//! step: what each sends in a round, what arrived for it, and their posteriors and traffic.
//!
//! Round r of step k closes at its sub-deadline t_k + D(r+1)/L; a round's message that arrives later is late and
//! left out (each scheme's file says how it treats the gap). Messages for a later step or round wait, bounded.

use crate::estimate::{EstimateError, Gaussian, Observation};
use crate::estimators::{from_body, to_body, Estimator, Kind, Message, StepInput};
use crate::model::{Measurement, Model};
use crate::scenario::Scenario;
use crate::time::Time;
use crate::wire::{Body, Datagram, Header, Payload, BROADCAST};

use super::wire::Wire;

/// Most messages of later rounds or steps a node holds.
const HELD_CAP: usize = 1024;

/// What one scheme sent: messages (one per out-link and round) and their bytes.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Traffic {
    pub messages: u64,
    pub bytes: u64,
}

/// One scheme at one node.
struct Slot {
    kind: Kind,
    est: Box<dyn Estimator>,
    /// The estimate after this step's prediction: what a failed update falls back to.
    prior: Option<Gaussian>,
    failed: bool,
    traffic: Traffic,
}

pub(super) struct Schemes {
    slots: Vec<Slot>,
    rounds: usize,
    /// The open step and the round whose sub-deadline comes next.
    open: Option<(u64, usize)>,
    /// The open step's time: what its rounds' messages pertain to.
    open_at: Time,
    /// This step's messages by slot and round: (source, message), the first copy of each.
    arrived: Vec<Vec<Vec<(usize, Message)>>>,
    /// (step, round, slot, source, message) for a later round or step.
    held: Vec<(u64, usize, usize, usize, Message)>,
    /// Round messages that came after their round closed.
    pub late: u64,
}

impl Schemes {
    pub fn new(slots: Vec<(Kind, Box<dyn Estimator>)>, rounds: usize) -> Schemes {
        let n = slots.len();
        Schemes {
            slots: slots
                .into_iter()
                .map(|(kind, est)| Slot {
                    kind,
                    est,
                    prior: None,
                    failed: false,
                    traffic: Traffic::default(),
                })
                .collect(),
            rounds,
            open: None,
            open_at: Time::ZERO,
            arrived: vec![vec![Vec::new(); rounds]; n],
            held: Vec::new(),
            late: 0,
        }
    }

    pub fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }

    pub fn kinds(&self) -> impl Iterator<Item = Kind> + '_ {
        self.slots.iter().map(|s| s.kind)
    }

    pub fn slot_of(&self, kind: Kind) -> Option<usize> {
        self.slots.iter().position(|s| s.kind == kind)
    }

    /// Predict every scheme with `predict` (the node's model, IMU and process noise).
    pub fn predict(&mut self, predict: &dyn Fn(&Gaussian) -> Gaussian) {
        self.slots.iter_mut().for_each(|s| s.est.predict(predict));
    }

    /// Start every scheme again from `g` (a restart).
    pub fn reset(&mut self, g: &Gaussian) {
        self.slots.iter_mut().for_each(|s| s.est.reset(g.clone()));
    }

    /// The node is down: no step is open.
    pub fn close_down(&mut self) {
        self.open = None;
    }

    /// Open step `k` (at time `at`) with the node's own measurement; the datagrams of round 0 (one per scheme that
    /// sends, sent at `at`), addressed and sealed per link by the node.
    pub fn begin(&mut self, k: u64, at: Time, input: &StepInput<'_>, wire: &Wire) -> Vec<Datagram> {
        self.open = Some((k, 0));
        self.open_at = at;
        for (i, s) in self.slots.iter_mut().enumerate() {
            s.prior = s.est.state().cloned();
            s.failed = false;
            if let Err(e) = s.est.begin(input) {
                fail(s, &e);
            }
            self.arrived[i].iter_mut().for_each(Vec::clear);
        }
        for (step, round, slot, from, m) in std::mem::take(&mut self.held) {
            match step.cmp(&k) {
                std::cmp::Ordering::Equal => keep(&mut self.arrived[slot][round], from, m),
                std::cmp::Ordering::Greater => self.held.push((step, round, slot, from, m)),
                std::cmp::Ordering::Less => self.late += 1,
            }
        }
        self.messages(0, at, wire)
    }

    /// The datagrams of round `r` of the open step, sent at `sent`: one per scheme, for every receiver.
    fn messages(&mut self, r: usize, sent: Time, wire: &Wire) -> Vec<Datagram> {
        let mut out = Vec::new();
        for s in &mut self.slots {
            if s.failed {
                continue;
            }
            let Some(m) = s.est.message(r) else { continue };
            let body = match to_body(&m) {
                Ok(b) => b,
                Err(e) => {
                    tracing::error!(scheme = s.kind.name(), "cannot send a round's message: {e}");
                    continue;
                }
            };
            let d = Datagram {
                header: Header::round(wire.id(), BROADCAST, 0, s.kind.id(), self.open_at, sent),
                payload: Payload::Round { round: r as u8, body },
            };
            match wire.fits(&d) {
                Ok(()) => out.push(d),
                Err(e) => tracing::error!(scheme = s.kind.name(), "cannot encode a round's message: {e}"),
            }
        }
        out
    }

    /// A round's message from `src`, used in its round, held for a later one, or counted late; `states`/`rows` are
    /// the model's, for the checks. `Err`: a scheme this node does not run, a round past L, or a body of the wrong
    /// size (the node counts it malformed).
    #[allow(clippy::too_many_arguments)]
    pub fn receive(
        &mut self,
        src: usize,
        step: u64,
        round: u8,
        scheme: u8,
        body: &Body,
        states: usize,
        rows: usize,
    ) -> Result<(), ()> {
        let round = round as usize;
        let slot = Kind::from_id(scheme).and_then(|k| self.slot_of(k)).ok_or(())?;
        if round >= self.rounds {
            return Err(());
        }
        let m = from_body(body, states, rows).map_err(|_| ())?;
        match self.open {
            Some((k, next)) if step == k && round >= next => keep(&mut self.arrived[slot][round], src, m),
            Some((k, _)) if step > k && self.held.len() < HELD_CAP => self.held.push((step, round, slot, src, m)),
            None if self.held.len() < HELD_CAP => self.held.push((step, round, slot, src, m)),
            _ => self.late += 1,
        }
        Ok(())
    }

    /// Close round `r` of step `k` (its sub-deadline, at time `at`): every scheme combines what arrived; the
    /// datagrams of round r + 1, if there is one, sent at `at`. Nothing when `(k, r)` is not the round that comes
    /// next.
    pub fn close_round(&mut self, k: u64, r: usize, at: Time, input: &StepInput<'_>, wire: &Wire) -> Vec<Datagram> {
        if self.open != Some((k, r)) {
            return Vec::new();
        }
        for (i, s) in self.slots.iter_mut().enumerate() {
            if s.failed {
                continue;
            }
            let mut arrived: Vec<(usize, &Message)> = self.arrived[i][r].iter().map(|(j, m)| (*j, m)).collect();
            arrived.sort_by_key(|(j, _)| *j);
            if let Err(e) = s.est.combine(r, &arrived, input) {
                fail(s, &e);
            }
        }
        self.open = Some((k, r + 1));
        if r + 1 < self.rounds {
            self.messages(r + 1, at, wire)
        } else {
            Vec::new()
        }
    }

    /// The deadline of step `k`: the last round closes and every scheme finishes. Each scheme's (prior,
    /// posterior, failed), by slot; none when step `k` is not open.
    pub fn finish(&mut self, k: u64, input: &StepInput<'_>, wire: &Wire) -> Option<Vec<(Gaussian, Gaussian, bool)>> {
        let (open, _) = self.open?;
        if open != k {
            return None;
        }
        if let Some((_, r)) = self.open.filter(|(_, r)| *r < self.rounds) {
            // What a round closed here would send goes nowhere: the step ends.
            for r in r..self.rounds {
                self.close_round(k, r, self.open_at, input, wire);
            }
        }
        self.open = None;
        let mut out = Vec::with_capacity(self.slots.len());
        for s in &mut self.slots {
            if !s.failed {
                match s.est.finish(input) {
                    Err(e) => fail(s, &e),
                    // Back onto the model's manifold (the quaternion's unit norm), as the node's own filters.
                    Ok(()) => s.est.state_mut().into_iter().for_each(|g| input.model.normalize(g)),
                }
            }
            // Set again at the next step's begin.
            let prior = s.prior.take();
            let post = s.est.state().cloned();
            // A posterior that is not finite and symmetric positive definite is a failed update.
            let usable = post
                .as_ref()
                .is_some_and(|g| g.x.iter().chain(g.P.iter()).all(|v| v.is_finite()) && crate::estimate::is_spd(&g.P));
            if s.failed || !usable {
                s.failed = true;
                if let Some(p) = &prior {
                    s.est.reset(p.clone());
                }
            }
            match (prior, s.est.state().cloned()) {
                (Some(p), Some(q)) => out.push((p, q, s.failed)),
                _ => return None,
            }
        }
        Some(out)
    }

    /// A round's message of scheme `scheme` (its wire byte) went out as `bytes` bytes, reaching `links` out-links.
    pub fn count_sent(&mut self, scheme: u8, bytes: usize, links: usize) {
        if let Some(s) = self.slots.iter_mut().find(|s| s.kind.id() == scheme) {
            s.traffic.messages += links as u64;
            s.traffic.bytes += (bytes * links) as u64;
        }
    }

    pub fn traffic(&self) -> Vec<(Kind, Traffic)> {
        self.slots.iter().map(|s| (s.kind, s.traffic)).collect()
    }
}

fn fail(s: &mut Slot, e: &EstimateError) {
    tracing::debug!(scheme = s.kind.name(), "update failed: {e}");
    s.failed = true;
}

/// The first copy from each source (a duplicate adds nothing).
fn keep(list: &mut Vec<(usize, Message)>, from: usize, m: Message) {
    if !list.iter().any(|(j, _)| *j == from) {
        list.push((from, m));
    }
}

/// What a node hands its schemes before the step's deadline (at its begin and its rounds' sub-deadlines): its
/// model, observation, index and own measurement; the measurements heard come with the deadline.
pub(super) fn input<'a>(
    model: &'a dyn Model,
    obs: &'a Observation,
    node: usize,
    own: Option<&'a Measurement>,
    step: u64,
) -> StepInput<'a> {
    StepInput {
        model,
        obs,
        node,
        own,
        heard: &[],
        step,
    }
}

/// Node `index`'s view of the graph for the distributed estimators: Metropolis weights over the nodes it hears from
/// (computed once per scenario, [`crate::scenario::EstimatorsConfig::weights`]).
pub(super) fn context(topo: &Scenario, index: usize, model: &dyn Model) -> crate::estimators::Context {
    let weights = topo
        .estimators()
        .weights
        .get(index)
        .cloned()
        .unwrap_or((Vec::new(), 1.0));
    crate::estimators::Context::new(index, topo.nodes().len(), weights, model)
}
