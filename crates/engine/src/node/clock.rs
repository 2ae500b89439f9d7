//! The call order, written once: what a node does at each instant of its timeline. A driver only asks when the node
//! next needs it ([`Node::poll_timeout`]) and calls [`Node::handle_timeout`] then — in memory, over UDP on either
//! clock, one node per process — with the datagrams due by that instant handed in first.

#[allow(unused_imports)]
use super::*;

/// What comes next on a node's timeline.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Due {
    /// Step k begins at t_k: the crash timeline's events for it, then [`Node::handle_step`].
    Step(u64),
    /// Round r of step k closes at t_k + D(r+1)/L (r < L − 1): [`Node::handle_round`].
    Round(u64, usize),
    /// Step k closes at t_k + D: [`Node::handle_deadline`].
    Deadline(u64),
    /// The run is over.
    Done,
}

/// A step the node closed: which one, and its estimate (none from a node that does not estimate, or was down).
#[derive(Debug)]
pub struct Closed {
    pub step: u64,
    pub estimate: Option<StepEstimate>,
}

impl Node {
    /// The node's timeline starts at step `k` (a node joining a running network); a new node starts at step 0.
    pub fn start_at(&mut self, k: u64) {
        self.due = if k < self.topo.sim().steps() {
            Due::Step(k)
        } else {
            Due::Done
        };
    }

    /// When the node next needs [`Node::handle_timeout`]: the next step's start, round close or deadline; `None`
    /// once its last step closed.
    pub fn poll_timeout(&self) -> Option<Time> {
        let s = &self.topo;
        match self.due {
            Due::Step(k) => Some(s.step_time(k)),
            Due::Round(k, r) => Some(s.round_end(k, r)),
            Due::Deadline(k) => Some(s.deadline(k)),
            Due::Done => None,
        }
    }

    /// Do, in order, what is due by `now`: a step's start (the crash timeline's events for it first), its rounds'
    /// closes, its deadline. A call closes at most one step and returns it, so that a driver collects a step's
    /// results before the next begins: call again while [`Node::poll_timeout`] is at or before `now`.
    pub fn handle_timeout(&mut self, now: Time) -> Option<Closed> {
        while self.poll_timeout().is_some_and(|t| t <= now) {
            match self.due {
                Due::Step(k) => {
                    self.begin_step(k);
                    self.due = self.after_round(k, None);
                }
                Due::Round(k, r) => {
                    self.handle_round(k, r);
                    self.due = self.after_round(k, Some(r));
                }
                Due::Deadline(k) => {
                    let estimate = self.handle_deadline(k);
                    self.start_at(k + 1);
                    return Some(Closed { step: k, estimate });
                }
                Due::Done => break,
            }
        }
        None
    }

    /// What follows round `r` of step k (`None`: the step's start): the next round's close, or the deadline.
    fn after_round(&self, k: u64, r: Option<usize>) -> Due {
        let next = r.map_or(0, |r| r + 1);
        if next + 1 < self.topo.estimators().rounds.max(1) {
            Due::Round(k, next)
        } else {
            Due::Deadline(k)
        }
    }

    /// Step k, after the events the crash timeline has for this node.
    fn begin_step(&mut self, k: u64) {
        let s = self.topo.clone();
        for &e in s.faults().node_events(self.index, k, s.sim().dt(), self.up) {
            self.handle_event(e);
        }
        self.handle_step(k);
    }
}
