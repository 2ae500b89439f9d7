//! The node's timeline: what is due next (a step's start, a round's close, a step's deadline) and the crash
//! timeline's events of a step. The order in which the node and its testbed act on it is written once, in
//! [`crate::node::Node::handle_timeout`].

#[allow(unused_imports)]
use super::*;

/// What comes next on a node's timeline.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Due {
    /// Step k begins at t_k: the crash timeline's events for it, then the step.
    Step(u64),
    /// Round r of step k closes at t_k + D(r+1)/L (r < L − 1).
    Round(u64, usize),
    /// Step k closes at t_k + D.
    Deadline(u64),
    /// The run is over.
    Done,
}

/// How a step opens, after the crash timeline's events for it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Opening {
    /// The node is down: the step is closed already.
    Down,
    /// The node runs the step; `fresh`: its filters start afresh (a restart or a late join) from the prior of this
    /// draw number ([`crate::node::Testbed::prior`]).
    Up {
        /// The prior's draw number, when the filters start afresh.
        fresh: Option<u64>,
    },
}

/// What a node's testbed gives it at the start of a step it runs.
#[derive(Debug, Clone, Default)]
pub struct Sample {
    /// The IMU sample at t_k (an IMU node).
    pub imu: Option<ImuSample>,
    /// The node's own measurement of step k (a sensing node).
    pub own: Option<Measurement>,
    /// A shift of coordinates the estimates take with the truth's (a linear model's rebase).
    pub shift: Option<DVector<f64>>,
    /// The prior its filters start from, when [`Opening::Up`] asked for one.
    pub fresh: Option<Gaussian>,
}

impl Endpoint {
    /// The node's timeline starts at step `k` (a node joining a running network); a new node starts at step 0.
    pub fn start_at(&mut self, k: u64) {
        self.due = if k < self.topo.sim().steps() {
            Due::Step(k)
        } else {
            Due::Done
        };
    }

    /// What is due next.
    pub fn due(&self) -> Due {
        self.due
    }

    /// When the next thing is due: the next step's start, round close or deadline; `None` once its last step closed.
    pub fn poll_timeout(&self) -> Option<Time> {
        let s = &self.topo;
        match self.due {
            Due::Step(k) => Some(s.step_time(k)),
            Due::Round(k, r) => Some(s.round_end(k, r)),
            Due::Deadline(k) => Some(s.deadline(k)),
            Due::Done => None,
        }
    }

    /// What was due is done: what follows it.
    pub(crate) fn advance(&mut self) {
        self.due = match self.due {
            Due::Step(k) => self.after_round(k, None),
            Due::Round(k, r) => self.after_round(k, Some(r)),
            Due::Deadline(k) if k + 1 < self.topo.sim().steps() => Due::Step(k + 1),
            Due::Deadline(_) | Due::Done => Due::Done,
        };
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

    /// The events the crash timeline has for this node at step k, applied.
    pub(crate) fn apply_events(&mut self, k: u64) {
        let s = self.topo.clone();
        for &e in s.faults().node_events(self.index, k, s.sim().dt(), self.up) {
            self.handle_event(e);
        }
    }
}
