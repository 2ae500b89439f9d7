//! Each node's receiver ([`crate::medium::air::Listener`]), fed lazily: the frames it hears and its own transmissions wait in its
//! inbox until a question about an instant needs them, then are taken in time order ([`crate::medium::air::Event`]'s at an
//! instant; frames in the order they went on the air). A frame costs each node that hears it two events, whatever
//! else is on the air, where working out a fate over the frames around it costs every frame back to the last
//! silence.

use std::cmp::{Ordering, Reverse};
use std::collections::{BinaryHeap, VecDeque};

use crate::medium::air::{Event, Listener, Reception};
use crate::medium::csma;
use crate::time::Time;

/// One node's receiver and what it has not yet heard: frames' starts and its own transmissions come in the
/// order they happen (frames go on the air in the order they begin); a frame's end waits among those of the
/// frames it has begun to hear.
#[derive(Debug, Clone)]
pub(super) struct Ear {
    listener: Listener,
    starts: VecDeque<Heard>,
    ends: BinaryHeap<Reverse<Heard>>,
    own: VecDeque<(Time, Event)>,
    /// The end of the frame it is locked onto, and whether it is meant for it.
    locked: (Time, bool),
    /// Fates settled of frames meant for it, until asked for (a few at a time).
    fates: Vec<(u64, Reception)>,
    /// Frames it was receiving when it began to transmit, until they end (an assessment still counts them).
    aborted: Vec<Time>,
    /// Frames begun and not ended an assessment ago, in the order they began: what its energy detection sums.
    around: Vec<Heard>,
}

/// A frame as this node hears it, on the air from `start` to `end`: waiting to start, or (`begun`) to end.
#[derive(Debug, Clone, Copy)]
struct Heard {
    begun: bool,
    start: Time,
    id: u64,
    end: Time,
    power_w: f64,
    wanted: bool,
}

impl Heard {
    fn event(&self) -> (Time, Event) {
        if self.begun {
            (self.end, Event::FrameEnd(self.id))
        } else {
            (self.start, Event::FrameStart(self.id))
        }
    }
}

impl PartialEq for Heard {
    fn eq(&self, other: &Heard) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}
impl Eq for Heard {}
impl PartialOrd for Heard {
    fn partial_cmp(&self, other: &Heard) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Heard {
    fn cmp(&self, other: &Heard) -> Ordering {
        self.event().cmp(&other.event())
    }
}

impl Ear {
    pub(super) fn new(noise_w: f64) -> Ear {
        Ear {
            listener: Listener::new(noise_w),
            starts: VecDeque::new(),
            ends: BinaryHeap::new(),
            own: VecDeque::new(),
            locked: (Time::ZERO, false),
            fates: Vec::new(),
            aborted: Vec::new(),
            around: Vec::new(),
        }
    }

    /// Frame `id` reaches this node from `start` to `end` (after every frame told before it) at `power_w` watts;
    /// its fate is kept if `wanted`. `now`, the medium's time, is no later than any question still to come: a node
    /// nobody asks about hears what is queued up to it once a thousand frames wait, so that its inbox stays bounded.
    pub(super) fn frame(&mut self, id: u64, (start, end): (Time, Time), power_w: f64, wanted: bool, now: Time) {
        if self.starts.len() >= 1024 {
            self.run_to(now);
        }
        debug_assert!(self.starts.back().is_none_or(|h| h.start <= start));
        self.starts.push_back(Heard {
            begun: false,
            start,
            id,
            end,
            power_w,
            wanted,
        });
    }

    /// This node transmits from `start` to `end` (after its transmissions told before).
    pub(super) fn transmit(&mut self, (start, end): (Time, Time)) {
        self.own.extend([(start, Event::TxStart), (end, Event::TxEnd)]);
    }

    /// Everything up to and at `t` heard, in [`Event`]'s order.
    fn run_to(&mut self, t: Time) {
        loop {
            let start = self.starts.front().map(Heard::event);
            let end = self.ends.peek().map(|h| h.0.event());
            let own = self.own.front().copied();
            let Some(next) = [start, end, own].into_iter().flatten().filter(|e| e.0 <= t).min() else {
                break;
            };
            let (h, event) = if Some(next) == own {
                self.own.pop_front();
                (None, next.1)
            } else if Some(next) == end {
                let h = self.ends.pop().expect("an end").0;
                (Some(h), next.1)
            } else {
                let h = self.starts.pop_front().expect("a start");
                self.ends.push(Reverse(Heard { begun: true, ..h }));
                self.around.push(h);
                (Some(h), next.1)
            };
            let (power_w, wanted) = h.map_or((0.0, false), |h| (h.power_w, h.wanted));
            match (event, self.listener.hear(next.0, event, power_w, wanted)) {
                (Event::FrameStart(id), None) if self.listener.locked() == Some(id) => {
                    self.locked = (h.map_or(next.0, |h| h.end), wanted);
                }
                (Event::TxStart, Some((id, r))) => {
                    self.aborted.push(self.locked.0);
                    self.keep(self.locked.1, id, r);
                }
                (_, Some((id, r))) => self.keep(wanted, id, r),
                _ => {}
            }
        }
        if !self.aborted.is_empty() {
            self.aborted.retain(|end| *end > t);
        }
        // An assessment from now on begins at t − CCA at the earliest.
        let horizon = Time::from_nanos(t.as_nanos().saturating_sub(csma::CCA.as_nanos() as u64));
        if self.around.first().is_some_and(|h| h.end <= horizon) || self.around.len() > 32 {
            self.around.retain(|h| h.end > horizon);
        }
    }

    /// The frames it hears on the air at some time in `(from, t]` or at `from` (begun by `t`, not ended by
    /// `from`), in the order they began: start, end and power.
    pub(super) fn heard_during(&mut self, from: Time, t: Time) -> Vec<(Time, Time, f64)> {
        self.run_to(t);
        (self.around.iter())
            .filter(|h| h.start <= t && h.end > from)
            .map(|h| (h.start, h.end, h.power_w))
            .collect()
    }

    /// Frames told and not yet begun to be heard.
    #[cfg(test)]
    pub(super) fn queued(&self) -> usize {
        self.starts.len()
    }

    fn keep(&mut self, wanted: bool, id: u64, r: Reception) {
        if wanted {
            self.fates.push((id, r));
        }
    }

    /// The fate here of frame `id`, meant for this node and ended at `end` (weak if it was not heard).
    pub(super) fn fate(&mut self, id: u64, end: Time) -> Reception {
        self.run_to(end);
        match self.fates.iter().position(|f| f.0 == id) {
            Some(k) => self.fates.swap_remove(k).1,
            None => Reception::Weak { sinr: 0.0 },
        }
    }

    /// Whether, at `t`, it is receiving a frame: locked onto one, or one it was locked onto when it began to
    /// transmit is still on the air.
    pub(super) fn receiving(&mut self, t: Time) -> bool {
        self.run_to(t);
        self.listener.locked().is_some() || !self.aborted.is_empty()
    }
}
