//! Links and faults: loss models, delay and jitter, duplication and corruption, link-down windows, partitions and
//! crashes.

use std::collections::HashMap;

use crate::link::{FaultSchedule, Jitter, LinkConfig, LossModel, ScheduledFault};
use crate::scenario::toml::{RawFault, RawLink, RawLoss};
use crate::scenario::Validator;
use crate::time::Time;

impl Validator {
    pub(crate) fn loss(&mut self, key: &str, l: &RawLoss) -> LossModel {
        let inferred = if [l.r, l.one_minus_h, l.one_minus_k, l.burst].iter().any(Option::is_some) {
            "gilbert-elliott"
        } else {
            "bernoulli"
        };
        match l.model.as_deref().unwrap_or(inferred) {
            "bernoulli" => {
                for (k, v) in [
                    ("r", l.r),
                    ("one_minus_h", l.one_minus_h),
                    ("one_minus_k", l.one_minus_k),
                    ("burst", l.burst),
                ] {
                    if v.is_some() {
                        self.bad(format!("{key}.{k}"), "only for model = \"gilbert-elliott\"");
                    }
                }
                // `rate` is another name for p here: a problem names the key the file gave.
                let which = if l.p.is_none() && l.rate.is_some() { "rate" } else { "p" };
                let p = self.prob(&format!("{key}.{which}"), l.p.or(l.rate), 0.0);
                LossModel::Bernoulli { p }
            }
            "gilbert-elliott" => {
                if let Some(burst) = l.burst.filter(|b| b.is_nan() || *b < 1.0) {
                    self.bad(
                        format!("{key}.burst"),
                        format!("mean loss run must be at least 1 packet, got {burst}"),
                    );
                    return LossModel::Bernoulli { p: 0.0 };
                }
                if let (Some(rate), Some(burst)) = (l.rate, l.burst) {
                    let rate = self.prob(&format!("{key}.rate"), Some(rate), 0.0);
                    if burst.is_nan() || burst < 1.0 {
                        self.bad(
                            format!("{key}.burst"),
                            format!("mean loss run must be at least 1 packet, got {burst}"),
                        );
                        return LossModel::Bernoulli { p: 0.0 };
                    }
                    return match LossModel::gilbert_elliott_from(rate, burst) {
                        Ok(m) => m,
                        Err(e) => {
                            self.bad(format!("{key}.rate"), e.to_string());
                            LossModel::Bernoulli { p: 0.0 }
                        }
                    };
                }
                let p = self.prob(&format!("{key}.p"), l.p, 0.0);
                let r = self.prob(&format!("{key}.r"), l.r, 1.0);
                if l.p.is_none() || l.r.is_none() {
                    self.bad(
                        key,
                        "gilbert-elliott needs p and r (netem's `loss gemodel p r 1-h 1-k`), or rate and burst",
                    );
                }
                if p + r == 0.0 {
                    self.bad(format!("{key}.r"), "p and r cannot both be 0");
                }
                LossModel::GilbertElliott {
                    p,
                    r,
                    one_minus_h: self.prob(&format!("{key}.one_minus_h"), l.one_minus_h, 1.0),
                    one_minus_k: self.prob(&format!("{key}.one_minus_k"), l.one_minus_k, 0.0),
                }
            }
            other => {
                self.bad(
                    format!("{key}.model"),
                    format!("expected bernoulli | gilbert-elliott, got `{other}`"),
                );
                LossModel::Bernoulli { p: 0.0 }
            }
        }
    }

    pub(crate) fn link(&mut self, key: &str, raw: RawLink, base: &LinkConfig) -> LinkConfig {
        let loss = match &raw.loss {
            Some(l) => self.loss(&format!("{key}.loss"), l),
            None => base.loss,
        };
        let jitter = match raw.jitter.as_deref() {
            None => base.jitter,
            Some("uniform") => Jitter::Uniform,
            Some("normal") => Jitter::Normal,
            Some(other) => {
                self.bad(
                    format!("{key}.jitter"),
                    format!("expected uniform | normal, got `{other}`"),
                );
                base.jitter
            }
        };
        LinkConfig {
            loss,
            delay_ms: {
                let k = format!("{key}.delay_ms");
                let d = self.non_negative(&k, raw.delay_ms, base.delay_ms);
                self.at_most(&k, d, crate::link::MAX_DELAY_MS, " ms")
            },
            jitter_ms: {
                let k = format!("{key}.jitter_ms");
                let j = self.non_negative(&k, raw.jitter_ms, base.jitter_ms);
                self.at_most(&k, j, crate::link::MAX_DELAY_MS, " ms")
            },
            jitter,
            duplicate: self.prob(&format!("{key}.duplicate"), raw.duplicate, base.duplicate),
            corrupt: self.prob(&format!("{key}.corrupt"), raw.corrupt, base.corrupt),
        }
    }

    pub(crate) fn faults(&mut self, raw: &[RawFault], ids: &HashMap<i64, usize>, n: usize) -> FaultSchedule {
        let mut out = Vec::new();
        for (f, r) in raw.iter().enumerate() {
            let key = format!("fault[{f}]");
            let idx = |v: &mut Validator, k: &str, id: i64| -> Option<usize> {
                let r = ids.get(&id).copied();
                if r.is_none() {
                    v.bad(format!("{key}.{k}"), format!("no [[node]] has id {id}"));
                }
                r
            };
            let window = |v: &mut Validator| -> Option<(Time, Time)> {
                let (Some(s), Some(e)) = (r.start_s, r.end_s) else {
                    v.bad(key.clone(), "needs start_s and end_s");
                    return None;
                };
                if !(s >= 0.0 && e > s && e.is_finite()) {
                    let which = if s >= 0.0 { "end_s" } else { "start_s" };
                    v.bad(
                        format!("{key}.{which}"),
                        format!("need 0 ≤ start_s < end_s, got {s}..{e}"),
                    );
                    return None;
                }
                Some((Time::from_secs(s), Time::from_secs(e)))
            };
            // A key of another kind would be silently ignored: refused instead.
            let given = [
                ("link", r.link.is_some()),
                ("directed", r.directed.is_some()),
                ("nodes", r.nodes.is_some()),
                ("node", r.node.is_some()),
                ("start_s", r.start_s.is_some()),
                ("end_s", r.end_s.is_some()),
                ("at_s", r.at_s.is_some()),
                ("restart_s", r.restart_s.is_some()),
            ];
            let own: &[&str] = match r.kind.as_str() {
                "link-down" => &["link", "directed", "start_s", "end_s"],
                "partition" => &["nodes", "start_s", "end_s"],
                "crash" => &["node", "at_s", "restart_s"],
                _ => &[],
            };
            if !own.is_empty() {
                for (field, _) in given.iter().filter(|(f, g)| *g && !own.contains(f)) {
                    self.bad(
                        format!("{key}.{field}"),
                        format!("{} takes no {field} (its keys: {})", r.kind, own.join(", ")),
                    );
                }
            }
            match r.kind.as_str() {
                "link-down" => {
                    let Some(link) = &r.link else {
                        self.bad(format!("{key}.link"), "link-down needs link = [from, to]");
                        continue;
                    };
                    if link.len() != 2 {
                        self.bad(format!("{key}.link"), "must list two node ids");
                        continue;
                    }
                    let (a, b) = (idx(self, "link", link[0]), idx(self, "link", link[1]));
                    let (Some(a), Some(b), Some((s, e))) = (a, b, window(self)) else {
                        continue;
                    };
                    out.push(ScheduledFault::LinkDown {
                        from: a,
                        to: b,
                        both_ways: !r.directed.unwrap_or(false),
                        start: s,
                        end: e,
                    });
                }
                "partition" => {
                    let Some(ns) = &r.nodes else {
                        self.bad(
                            format!("{key}.nodes"),
                            "partition needs nodes = [ids cut off from the rest]",
                        );
                        continue;
                    };
                    let set: Vec<usize> = ns.iter().filter_map(|&id| idx(self, "nodes", id)).collect();
                    if set.is_empty() || set.len() >= n {
                        self.bad(format!("{key}.nodes"), "must name some but not all nodes");
                    }
                    let Some((s, e)) = window(self) else { continue };
                    out.push(ScheduledFault::Partition {
                        nodes: set,
                        start: s,
                        end: e,
                    });
                }
                "crash" => {
                    let Some(id) = r.node else {
                        self.bad(format!("{key}.node"), "crash needs node = ID");
                        continue;
                    };
                    let Some(node) = idx(self, "node", id) else { continue };
                    let Some(at) = r.at_s.filter(|a| *a >= 0.0 && a.is_finite()) else {
                        self.bad(format!("{key}.at_s"), "crash needs at_s ≥ 0");
                        continue;
                    };
                    if let Some(rs) = r.restart_s {
                        if rs.is_nan() || rs <= at {
                            self.bad(
                                format!("{key}.restart_s"),
                                format!("must be after at_s ({at}), got {rs}"),
                            );
                            continue;
                        }
                    }
                    out.push(ScheduledFault::Crash {
                        node,
                        at: Time::from_secs(at),
                        restart: r.restart_s.map(Time::from_secs),
                    });
                }
                other => self.bad(
                    format!("{key}.kind"),
                    format!("expected link-down | partition | crash, got `{other}`"),
                ),
            }
        }
        FaultSchedule::new(out)
    }
}
