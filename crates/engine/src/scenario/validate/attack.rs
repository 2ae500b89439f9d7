//! `[[attack]]` → [`Attack`]: who attacks whom, when, and with what.

use std::collections::{HashMap, HashSet};

use super::super::toml::RawAttack;
use crate::attack::{Attack, AttackKind};
use crate::checks::num;
use crate::scenario::Validator;

/// The fastest flood an in-process run simulates (datagrams per second).
pub const MAX_FLOOD_HZ: f64 = 1e6;

impl Validator {
    /// `rows`: the rows of a measurement (bias and ramp have at most that many); `linked`: (from, to) of every link.
    pub(crate) fn attacks(
        &mut self,
        raw: &[RawAttack],
        ids: &HashMap<i64, usize>,
        linked: &HashSet<(usize, usize)>,
        rows: usize,
        duration_s: f64,
    ) -> Vec<Attack> {
        let mut out = Vec::new();
        for (a, r) in raw.iter().enumerate() {
            let key = format!("attack[{a}]");
            let Some(kind) = AttackKind::parse(&r.kind) else {
                let known: Vec<&str> = AttackKind::ALL.iter().map(|k| k.as_str()).collect();
                self.bad(
                    format!("{key}.kind"),
                    format!("unknown attack `{}`: expected {}", r.kind, known.join(" | ")),
                );
                continue;
            };
            let node = |v: &mut Validator, field: &str, id: Option<i64>, wanted: bool| -> Option<usize> {
                match (id, wanted) {
                    (None, true) => {
                        v.bad(
                            format!("{key}.{field}"),
                            format!("{} needs {field} = a node id", kind.as_str()),
                        );
                        None
                    }
                    (Some(_), false) => {
                        v.bad(format!("{key}.{field}"), format!("{} takes no {field}", kind.as_str()));
                        None
                    }
                    (Some(id), true) => {
                        let i = ids.get(&id).copied();
                        if i.is_none() {
                            v.bad(format!("{key}.{field}"), format!("no [[node]] has id {id}"));
                        }
                        i
                    }
                    (None, false) => None,
                }
            };
            let on_path = matches!(kind, AttackKind::Forge | AttackKind::Tamper | AttackKind::Replay);
            let target = node(self, "target", r.target, kind.outsider());
            let claim = node(self, "claim", r.claim, on_path);
            let compromised = node(self, "node", r.node, kind == AttackKind::FalseData);
            if let (Some(t), Some(c)) = (target, claim) {
                if !linked.contains(&(c, t)) {
                    self.bad(
                        format!("{key}.claim"),
                        format!(
                            "no link carries node {}'s datagrams to node {}: an attacker claims a source its target hears",
                            r.claim.unwrap_or_default(),
                            r.target.unwrap_or_default()
                        ),
                    );
                }
            }
            let start_s = self.non_negative(&format!("{key}.start_s"), r.start_s, 0.0);
            let end_s = match r.end_s {
                None => f64::INFINITY,
                Some(e) if e.is_finite() && e > start_s => e,
                Some(e) => {
                    self.bad(
                        format!("{key}.end_s"),
                        format!("must be a finite time after start_s = {}, got {e}", num(start_s)),
                    );
                    f64::INFINITY
                }
            };
            let moves = matches!(kind, AttackKind::Forge | AttackKind::Tamper | AttackKind::FalseData);
            let vector = |v: &mut Validator, field: &str, given: &Option<Vec<f64>>, takes: bool| -> Vec<f64> {
                let Some(x) = given else { return Vec::new() };
                if !takes {
                    v.bad(format!("{key}.{field}"), format!("{} takes no {field}", kind.as_str()));
                } else if x.len() > rows {
                    v.bad(
                        format!("{key}.{field}"),
                        format!("a measurement has {rows} rows, got {} values", x.len()),
                    );
                } else if let Some(bad) = x.iter().find(|b| !b.is_finite()) {
                    v.bad(format!("{key}.{field}"), format!("must be finite, got {bad}"));
                } else {
                    return x.clone();
                }
                Vec::new()
            };
            let bias = vector(self, "bias", &r.bias, moves);
            let ramp = vector(self, "ramp", &r.ramp, kind == AttackKind::FalseData);
            let only = |v: &mut Validator, field: &str, given: Option<f64>, for_kind: AttackKind| {
                if given.is_some() && kind != for_kind {
                    v.bad(
                        format!("{key}.{field}"),
                        format!("{field} is for {} only", for_kind.as_str()),
                    );
                }
            };
            only(self, "delay_s", r.delay_s, AttackKind::Replay);
            only(self, "rate_hz", r.rate_hz, AttackKind::Flood);
            let delay_s = self.non_negative(&format!("{key}.delay_s"), r.delay_s, 1.0);
            let delay_s = self.at_most(&format!("{key}.delay_s"), delay_s, duration_s, " s (the run's length)");
            let rate_hz = self.positive(&format!("{key}.rate_hz"), r.rate_hz, 1000.0);
            let rate_hz = self.at_most(&format!("{key}.rate_hz"), rate_hz, MAX_FLOOD_HZ, " Hz");
            out.push(Attack {
                kind,
                target,
                claim,
                node: compromised,
                start_s,
                end_s,
                bias,
                ramp,
                delay_s,
                rate_hz,
            });
        }
        out
    }
}
