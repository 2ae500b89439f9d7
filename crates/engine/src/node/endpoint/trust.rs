//! What a node believes of what arrives: a claimed step only inside a window of its own clock, a neighbour's
//! measurement only through the innovation gate; what a stage in front of it adds ([`Ingress`], the scenario's
//! outsiders when they attack it) goes through its whole receive path, and the stage learns each one's fate
//! ([`Tally`]); a compromised node's own measurements are moved by its false-data attacks.

use std::collections::BTreeMap;

use nalgebra::DVector;

use super::Endpoint;
use crate::attack::{Attack, AttackKind, Injection, Tally};
use crate::estimate::{Gaussian, Observation};
use crate::medium::Ingress;
use crate::model::{Measurement, Model, Site};
use crate::scenario::Scenario;
use crate::time::Time;

/// A compromised node's false-data attacks and its innovation gate.
pub(super) struct Trust {
    /// The false-data attacks this node carries out (it is compromised), by index in the scenario.
    false_data: Vec<(usize, Attack)>,
    /// What the false-data attacks sent, by attack index.
    tallies: BTreeMap<usize, Tally>,
    /// The gate's χ² quantile by degrees of freedom (index: rows present), when the run gates.
    gate: Option<Vec<f64>>,
}

impl Trust {
    pub fn new(topo: &Scenario, index: usize, rows: usize) -> Trust {
        let attacks = topo.attacks();
        Trust {
            false_data: attacks
                .iter()
                .enumerate()
                .filter(|(_, a)| a.kind == AttackKind::FalseData && a.node == Some(index))
                .map(|(i, a)| (i, a.clone()))
                .collect(),
            tallies: BTreeMap::new(),
            gate: topo
                .consensus()
                .gate
                .map(|p| (0..=rows).map(|k| crate::stats::chi2_quantile(p, k as f64)).collect()),
        }
    }

    /// The measurement a compromised node sends at `t`: its own moved by every false-data attack under way, and
    /// those attacks (to count what they send).
    pub fn tainted(&self, own: &Measurement, t: Time) -> Option<(Measurement, Vec<usize>)> {
        let active: Vec<&(usize, Attack)> = self.false_data.iter().filter(|(_, a)| a.active(t)).collect();
        if active.is_empty() {
            return None;
        }
        let mut m = own.clone();
        for (_, a) in &active {
            a.taint(&mut m.z, t);
        }
        Some((m, active.iter().map(|(i, _)| *i).collect()))
    }

    pub fn count_sent(&mut self, attack: usize, n: u64) {
        self.tallies.entry(attack).or_default().sent += n;
    }

    /// The false-data attacks' tallies with `more` (a stage's, by attack index), by attack index.
    pub fn tallies(&self, more: Vec<(usize, Tally)>) -> Vec<(usize, Tally)> {
        let mut all = self.tallies.clone();
        for (i, t) in more {
            all.entry(i).or_default().add(&t);
        }
        all.into_iter().collect()
    }

    /// Whether the gate leaves `m`, taken at `site`, out of an update from `prior`: its normalised innovation squared
    /// νᵀS⁻¹ν, S = HPHᵀ + R over the rows present, exceeds the χ² quantile of as many degrees of freedom.
    pub fn gates(&self, model: &dyn Model, obs: &Observation, prior: &Gaussian, site: Site, m: &Measurement) -> bool {
        let Some(q) = &self.gate else { return false };
        match nis(model, obs, prior, site, m) {
            Some((d2, dof)) => q.get(dof).is_some_and(|q| d2 > *q),
            None => false,
        }
    }
}

/// The normalised innovation squared of `m`, taken at `site`, against `prior`, and its degrees of freedom (none when no row is
/// present or S is not positive definite).
pub(super) fn nis(
    model: &dyn Model,
    obs: &Observation,
    prior: &Gaussian,
    site: Site,
    m: &Measurement,
) -> Option<(f64, usize)> {
    let (o, z) = model.linearize_at(obs, prior, site, &[&m.z]);
    let rows: Vec<usize> = (0..o.dim()).filter(|&r| m.present[r]).collect();
    if rows.is_empty() {
        return None;
    }
    let full = o.innovation(&z[0], &prior.x);
    let nu = DVector::from_iterator(rows.len(), rows.iter().map(|&r| full[r]));
    let H = o.H.select_rows(rows.iter());
    let R = o.R.select_rows(rows.iter()).select_columns(rows.iter());
    let S = &H * &prior.P * H.transpose() + R;
    let w = S.cholesky()?.solve(&nu);
    Some((nu.dot(&w), rows.len()))
}

/// The counters an injected datagram can move, before and after the node took it.
#[derive(Clone, Copy)]
struct Seen {
    rejected: super::Rejections,
    malformed: u64,
    corrupted: u64,
    implausible_step: u64,
    unknown_address: u64,
    delivered: u64,
    early: u64,
}

impl Endpoint {
    /// A step is believed only inside the run and no further ahead of this node's own than a neighbour can be —
    /// two seconds of steps, at least 32: one datagram must not end the run or make the node skip to its end.
    pub(super) fn plausible_step(&self, s: u64) -> bool {
        let window = self.step_window();
        s < self.topo.sim().steps() && self.last_step.is_none_or(|k| s <= k.saturating_add(window))
    }

    /// How many steps a neighbour may be ahead of this node: two seconds of steps, at least 32.
    pub fn step_window(&self) -> u64 {
        (2.0 * self.topo.sim().rate_hz).ceil().max(32.0) as u64
    }

    fn seen(&self, from: Option<usize>) -> Seen {
        let c = &self.counters;
        Seen {
            rejected: self.wire.rejected,
            malformed: c.malformed,
            corrupted: c.corrupted,
            implausible_step: c.implausible_step,
            unknown_address: c.unknown_address,
            delivered: from.map_or(0, |f| self.inbox.rx.get(f).delivered),
            early: c.early,
        }
    }

    /// Simulated time now: the start of the last step begun.
    fn now(&self) -> Time {
        self.topo.step_time(self.last_step.unwrap_or(0))
    }

    /// What the stage in front of this node adds ahead of a datagram that reaches it, taken first.
    pub(super) fn ingress_on_arrival(&mut self, from: Option<usize>, bytes: &[u8]) {
        let Some(mut stage) = self.ingress.take() else { return };
        for inj in stage.on_arrival(self.now(), from, bytes) {
            self.inject(&mut *stage, inj);
        }
        self.ingress = Some(stage);
    }

    /// What the stage adds as step `k` begins (the outsiders' floods and the replays due).
    pub(super) fn ingress_on_step(&mut self, k: u64) {
        let Some(mut stage) = self.ingress.take() else { return };
        for inj in stage.on_step(self.topo.step_time(k), self.topo.sim().dt()) {
            self.inject(&mut *stage, inj);
        }
        self.ingress = Some(stage);
    }

    /// One added datagram through the whole receive path; the stage learns its fate.
    fn inject(&mut self, stage: &mut dyn Ingress, inj: Injection) {
        let before = self.seen(inj.from);
        let arrival = self.receive(inj.from, &inj.bytes);
        let after = self.seen(inj.from);
        let mut t = Tally {
            sent: 1,
            ..Tally::default()
        };
        let r = &mut t.rejected;
        let d = |a: u64, b: u64| b.saturating_sub(a);
        r.bad_tag += d(before.rejected.bad_tag, after.rejected.bad_tag);
        r.replay += d(before.rejected.replay, after.rejected.replay);
        r.too_old += d(before.rejected.too_old, after.rejected.too_old);
        r.unknown_source += d(before.rejected.unknown_source, after.rejected.unknown_source);
        r.malformed += d(before.malformed, after.malformed);
        r.corrupted += d(before.corrupted, after.corrupted);
        r.implausible_step += d(before.implausible_step, after.implausible_step);
        r.unknown_address += d(before.unknown_address, after.unknown_address);
        let refused = after.rejected.total() > before.rejected.total()
            || [
                (before.malformed, after.malformed),
                (before.corrupted, after.corrupted),
                (before.implausible_step, after.implausible_step),
                (before.unknown_address, after.unknown_address),
            ]
            .iter()
            .any(|(a, b)| b > a);
        if !refused {
            if arrival.is_some() && (after.delivered > before.delivered || after.early > before.early) {
                t.used += 1;
            } else {
                t.ignored += 1;
            }
        }
        stage.on_fate(inj.attack, &t);
    }
}
