//! The fault layer: one pure decision per datagram and directed link, with its own seeded RNG and counters.
//!
//! Loss follows Bernoulli(p) or Gilbert–Elliott as Linux netem parameterises it (`loss gemodel p r 1-h 1-k`: start
//! in Good; a packet's fate is drawn in the state it meets, then the chain moves). Delay plus uniform or normal
//! jitter, duplication and one-bit corruption follow; [`FaultSchedule`] adds link-down windows, partitions and
//! node crashes over simulated time.

mod egress;
pub mod rules;
mod schedule;

pub use egress::{Egress, Stream, Transmit};

/// The longest delay or jitter of a link, ms (about 2.8 hours): past any run, short of overflowing a clock.
pub const MAX_DELAY_MS: f64 = 1e7;
use rules::{rules_of, Context};
pub use rules::{Delivery, Rule};
pub use schedule::{FaultSchedule, FaultWindow, NodeEvent, ScheduledFault};

use crate::rng::Rng;
use crate::time::Time;

/// How a link loses datagrams.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "model", rename_all = "kebab-case")]
pub enum LossModel {
    /// Each datagram lost with probability `p`, independently.
    Bernoulli {
        /// Loss probability.
        p: f64,
    },
    /// netem's gemodel: p = P(Good→Bad), r = P(Bad→Good), loss 1−h in Bad and 1−k in Good.
    GilbertElliott {
        /// P(Good → Bad).
        p: f64,
        /// P(Bad → Good).
        r: f64,
        /// Loss probability in Bad.
        one_minus_h: f64,
        /// Loss probability in Good.
        one_minus_k: f64,
    },
}

/// A Gilbert–Elliott channel that target loss and burst cannot make.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LossError {
    /// The target loss is outside [0, 1).
    #[error("loss must be in [0, 1) for gilbert-elliott, got {0}")]
    Loss(f64),
    /// The mean burst is under one datagram.
    #[error("mean burst must be ≥ 1 packet, got {0}")]
    Burst(f64),
    #[error("loss {loss} with burst {burst} needs P(Good→Bad) = {p:.3} > 1; use a longer burst")]
    /// The burst is too short for the loss: P(Good→Bad) would exceed 1.
    BurstTooShort {
        /// The target loss.
        loss: f64,
        /// The mean burst.
        burst: f64,
        /// The P(Good→Bad) they need.
        p: f64,
    },
}

impl LossModel {
    /// Target loss L and mean burst B: r = 1/B, p = L·r/(1−L), 1−h = 1, 1−k = 0.
    pub fn gilbert_elliott_from(loss: f64, burst: f64) -> Result<LossModel, LossError> {
        if !(0.0..1.0).contains(&loss) {
            return Err(LossError::Loss(loss));
        }
        if burst.is_nan() || burst < 1.0 {
            return Err(LossError::Burst(burst));
        }
        let r = 1.0 / burst;
        let p = loss * r / (1.0 - loss);
        if p > 1.0 {
            return Err(LossError::BurstTooShort { loss, burst, p });
        }
        Ok(LossModel::GilbertElliott {
            p,
            r,
            one_minus_h: 1.0,
            one_minus_k: 0.0,
        })
    }

    /// Stationary loss probability: (r(1−k) + p(1−h)) / (p + r) for Gilbert–Elliott.
    pub fn stationary_loss(&self) -> f64 {
        match *self {
            LossModel::Bernoulli { p } => p,
            LossModel::GilbertElliott {
                p,
                r,
                one_minus_h,
                one_minus_k,
            } => (r * one_minus_k + p * one_minus_h) / (p + r),
        }
    }
}

/// The distribution of a datagram's extra delay.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Jitter {
    /// Uniform on ±jitter.
    Uniform,
    /// Normal with standard deviation jitter (delay clipped at 0).
    Normal,
}

/// A directed link's rules, as configured.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LinkConfig {
    /// How it loses datagrams.
    pub loss: LossModel,
    /// Fixed delay, ms.
    pub delay_ms: f64,
    /// Jitter on top of the delay, ms.
    pub jitter_ms: f64,
    /// The jitter's distribution.
    pub jitter: Jitter,
    /// Probability that a datagram is delivered twice.
    pub duplicate: f64,
    /// Probability that a delivered copy has a bit flipped.
    pub corrupt: f64,
}

impl Default for LinkConfig {
    fn default() -> Self {
        LinkConfig {
            loss: LossModel::Bernoulli { p: 0.0 },
            delay_ms: 0.0,
            jitter_ms: 0.0,
            jitter: Jitter::Uniform,
            duplicate: 0.0,
            corrupt: 0.0,
        }
    }
}

/// Why a datagram was not delivered.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DropCause {
    /// The loss model (Bernoulli or Gilbert–Elliott).
    Random,
    /// A link-down window, a partition, or a crashed endpoint.
    Down,
}

/// The fate of one datagram on one link.
#[derive(Debug, Clone, PartialEq)]
pub enum Verdict {
    /// Not delivered, and why.
    Drop(DropCause),
    /// One copy, or two when duplicated.
    Deliver(Vec<Delivery>),
}

/// What the sender side of a link saw.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LinkCounters {
    /// Datagrams sent.
    pub sent: u64,
    /// Bytes of the datagrams sent (one copy each).
    #[serde(default)]
    pub bytes: u64,
    /// Lost to the loss model.
    pub lost_random: u64,
    /// Lost to a link-down window, a partition or a crash.
    pub lost_down: u64,
    /// Delivered twice.
    pub duplicated: u64,
    /// Delivered with a bit flipped.
    pub corrupted: u64,
    /// Completed runs of consecutive losses and their total length.
    pub loss_runs: u64,
    /// Datagrams in the completed loss runs.
    pub loss_run_total: u64,
    /// The longest loss run.
    pub longest_loss_run: u64,
    /// The loss run still open (datagrams).
    pub current_run: u64,
}

impl LinkCounters {
    /// Mean length of the loss runs, counting a run still open at the end.
    pub fn mean_loss_run(&self) -> f64 {
        let runs = self.loss_runs + (self.current_run > 0) as u64;
        if runs == 0 {
            0.0
        } else {
            (self.loss_run_total + self.current_run) as f64 / runs as f64
        }
    }
}

/// A directed link: its rules ([`rules::rules_of`]), its seeded stream, its counters.
#[derive(Debug)]
pub struct Link {
    /// Sending node, by index.
    pub from: usize,
    /// Receiving node, by index.
    pub to: usize,
    rules: Vec<Box<dyn Rule>>,
    rng: Rng,
    counters: LinkCounters,
}

impl Link {
    /// The link `from` → `to` with `config`'s rules, drawing from `rng`.
    pub fn new(from: usize, to: usize, config: LinkConfig, rng: Rng) -> Link {
        Link {
            from,
            to,
            rules: rules_of(&config),
            rng,
            counters: LinkCounters::default(),
        }
    }

    /// What it has done so far.
    pub fn counters(&self) -> &LinkCounters {
        &self.counters
    }

    /// Decide the fate of one datagram of `len` bytes sent at simulated time `now`: the first rule that drops it
    /// wins; otherwise every copy is shaped by every rule, copy after copy.
    pub fn verdict(&mut self, now: Time, len: usize, faults: &FaultSchedule) -> Verdict {
        let cx = Context {
            from: self.from,
            to: self.to,
            now,
            len,
            faults,
        };
        self.counters.sent += 1;
        self.counters.bytes += len as u64;
        for rule in &mut self.rules {
            if let Some(cause) = rule.admit(&cx, &mut self.rng) {
                self.counters.current_run += 1;
                match cause {
                    DropCause::Down => self.counters.lost_down += 1,
                    DropCause::Random => self.counters.lost_random += 1,
                }
                return Verdict::Drop(cause);
            }
        }
        self.end_run();
        let mut copies = 1;
        for rule in &mut self.rules {
            copies += rule.copies(&cx, &mut self.rng);
        }
        if copies > 1 {
            self.counters.duplicated += 1;
        }
        let out = (0..copies)
            .map(|_| {
                let mut d = Delivery {
                    delay: core::time::Duration::ZERO,
                    flip_bit: None,
                };
                for rule in &mut self.rules {
                    rule.shape(&cx, &mut d, &mut self.rng);
                }
                if d.flip_bit.is_some() {
                    self.counters.corrupted += 1;
                }
                d
            })
            .collect();
        Verdict::Deliver(out)
    }

    fn end_run(&mut self) {
        let c = &mut self.counters;
        if c.current_run > 0 {
            c.loss_runs += 1;
            c.loss_run_total += c.current_run;
            c.longest_loss_run = c.longest_loss_run.max(c.current_run);
            c.current_run = 0;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn duplicate_and_corrupt_are_counted() {
        let cfg = LinkConfig {
            duplicate: 1.0,
            corrupt: 1.0,
            ..Default::default()
        };
        let mut l = Link::new(0, 1, cfg, crate::rng::stream(3, "link", 0, 1));
        let v = l.verdict(Time::ZERO, 10, &FaultSchedule::default());
        match v {
            Verdict::Deliver(c) => {
                assert_eq!(c.len(), 2);
                assert!(c.iter().all(|d| d.flip_bit.is_some_and(|b| b < 80)));
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(l.counters().duplicated, 1);
        assert_eq!(l.counters().corrupted, 2);
    }
}
