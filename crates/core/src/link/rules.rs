//! The rules a link applies to each datagram, in order: outage (link-down windows, partitions, crashed ends), loss
//! (Bernoulli or Gilbert–Elliott), duplication, then per copy delay with jitter and corruption. Each rule draws from
//! the link's own seeded stream only when it is active, so a link without a fault draws nothing for it.

use core::time::Duration;

use rand::Rng as _;
use rand_distr::StandardNormal;

use super::{DropCause, FaultSchedule, Jitter, LinkConfig, LossModel};
use crate::rng::Rng;
use crate::time::Time;

/// One datagram on its way: where and when.
pub struct Context<'a> {
    /// Sending node, by index.
    pub from: usize,
    /// Receiving node, by index.
    pub to: usize,
    /// Simulated send time.
    pub now: Time,
    /// Bytes.
    pub len: usize,
    /// The run's fault windows.
    pub faults: &'a FaultSchedule,
}

/// One copy's fate so far.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Delivery {
    /// How long after sending it arrives.
    pub delay: Duration,
    /// Bit to flip, if this copy is corrupted.
    pub flip_bit: Option<usize>,
}

/// A link rule. `admit` may drop the datagram, `copies` may add copies of it, `shape` acts on each copy.
pub trait Rule: Send + Sync + std::fmt::Debug {
    /// Drop the datagram, and why (none: keep it).
    fn admit(&mut self, _cx: &Context<'_>, _rng: &mut Rng) -> Option<DropCause> {
        None
    }
    /// Extra copies beyond the first.
    fn copies(&mut self, _cx: &Context<'_>, _rng: &mut Rng) -> usize {
        0
    }
    /// Act on one copy (delay it, flip a bit).
    fn shape(&mut self, _cx: &Context<'_>, _copy: &mut Delivery, _rng: &mut Rng) {}
}

/// Link-down windows, partitions and crashed ends. Scheduled outages do not advance the loss chain: it models the
/// channel, not the outage.
#[derive(Debug)]
pub struct Outage;

impl Rule for Outage {
    fn admit(&mut self, cx: &Context<'_>, _rng: &mut Rng) -> Option<DropCause> {
        (!cx.faults.link_up(cx.from, cx.to, cx.now)).then_some(DropCause::Down)
    }
}

/// Random loss: Bernoulli, or the Gilbert–Elliott chain (netem's gemodel).
#[derive(Debug)]
pub struct Loss {
    model: LossModel,
    /// Gilbert–Elliott: currently in the Bad state.
    bad: bool,
}

impl Rule for Loss {
    fn admit(&mut self, _cx: &Context<'_>, rng: &mut Rng) -> Option<DropCause> {
        let lost = match self.model {
            LossModel::Bernoulli { p } => p > 0.0 && rng.gen::<f64>() < p,
            LossModel::GilbertElliott {
                p,
                r,
                one_minus_h,
                one_minus_k,
            } => {
                let loss_p = if self.bad { one_minus_h } else { one_minus_k };
                let lost = loss_p > 0.0 && rng.gen::<f64>() < loss_p;
                let u: f64 = rng.gen();
                self.bad = if self.bad { u >= r } else { u < p };
                lost
            }
        };
        lost.then_some(DropCause::Random)
    }
}

/// A second copy with probability `p`.
#[derive(Debug)]
pub struct Duplicate {
    p: f64,
}

impl Rule for Duplicate {
    fn copies(&mut self, _cx: &Context<'_>, rng: &mut Rng) -> usize {
        (self.p > 0.0 && rng.gen::<f64>() < self.p) as usize
    }
}

/// A constant delay plus jitter (uniform on ±j, or normal with σ = j), never negative.
#[derive(Debug)]
pub struct Delay {
    delay_ms: f64,
    jitter_ms: f64,
    jitter: Jitter,
}

impl Rule for Delay {
    fn shape(&mut self, _cx: &Context<'_>, copy: &mut Delivery, rng: &mut Rng) {
        let j = if self.jitter_ms > 0.0 {
            match self.jitter {
                Jitter::Uniform => rng.gen_range(-self.jitter_ms..=self.jitter_ms),
                Jitter::Normal => self.jitter_ms * rng.sample::<f64, _>(StandardNormal),
            }
        } else {
            0.0
        };
        // To the nearest nanosecond (ms · 10⁶); never negative.
        copy.delay += crate::time::nanos((self.delay_ms + j) * 1e6);
    }
}

/// One bit flipped with probability `p` (the receiver's checksum must catch it).
#[derive(Debug)]
pub struct Corrupt {
    p: f64,
}

impl Rule for Corrupt {
    fn shape(&mut self, cx: &Context<'_>, copy: &mut Delivery, rng: &mut Rng) {
        if self.p > 0.0 && cx.len > 0 && rng.gen::<f64>() < self.p {
            // One draw whatever the length (a range draw may take more): a link's fates do not depend on how long
            // its datagrams are, so that sealing them (24 bytes more) changes no fate.
            let bits = cx.len * 8;
            copy.flip_bit = Some(((rng.gen::<f64>() * bits as f64) as usize).min(bits - 1));
        }
    }
}

/// The rules of a link with settings `c`, in the order they apply.
pub fn rules_of(c: &LinkConfig) -> Vec<Box<dyn Rule>> {
    vec![
        Box::new(Outage),
        Box::new(Loss {
            model: c.loss,
            bad: false,
        }),
        Box::new(Duplicate { p: c.duplicate }),
        Box::new(Delay {
            delay_ms: c.delay_ms,
            jitter_ms: c.jitter_ms,
            jitter: c.jitter,
        }),
        Box::new(Corrupt { p: c.corrupt }),
    ]
}
