//! Faults over simulated time: link-down windows, partitions, node crashes with optional restart.

use crate::time::Time;

/// A fault window of `[[fault]]`, nodes by index.
#[derive(Debug, Clone, PartialEq)]
pub enum ScheduledFault {
    /// The link from → to (and back, if `both_ways`) carries nothing in [start, end).
    LinkDown {
        /// Sending node.
        from: usize,
        /// Receiving node.
        to: usize,
        /// Down both ways.
        both_ways: bool,
        /// Start.
        start: Time,
        /// End.
        end: Time,
    },
    /// Nodes in `nodes` cannot talk to nodes outside it in [start, end).
    Partition {
        /// One side of the partition.
        nodes: Vec<usize>,
        /// Start.
        start: Time,
        /// End.
        end: Time,
    },
    /// The node stops at `at`; at `restart` (if any) it comes back with its filters re-initialised.
    Crash {
        /// The node.
        node: usize,
        /// When it stops.
        at: Time,
        /// When it comes back (none: never).
        restart: Option<Time>,
    },
}

/// A change of a node's state between two steps: the crash timeline a driver feeds to the node
/// (the node's `handle_crash` and `handle_restart`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NodeEvent {
    /// The node stops.
    Crash,
    /// The node comes back, its filters re-initialised.
    Restart,
}

/// One fault as a window of time: `crash` (one node), `link-down` (its two ends; from the first to the second only
/// when `directed`) or `partition` (the nodes cut off from the rest).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FaultWindow {
    /// `link-down`, `partition` or `crash`.
    pub kind: String,
    /// The nodes it touches, by id.
    pub nodes: Vec<u32>,
    /// A link down one way only.
    #[serde(skip_serializing_if = "std::ops::Not::not", default)]
    pub directed: bool,
    /// Start, s.
    pub start_s: f64,
    /// Absent for a crash without a restart: down to the end of the run.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub end_s: Option<f64>,
}

impl FaultWindow {
    /// `crash of node 2`, `link 0–1 down`, `partition of nodes 1, 3`.
    pub fn label(&self) -> String {
        let ids = |sep: &str| self.nodes.iter().map(|n| n.to_string()).collect::<Vec<_>>().join(sep);
        match self.kind.as_str() {
            "crash" => format!("node {} crashed", ids(", ")),
            "partition" => format!(
                "partition of node{} {}",
                if self.nodes.len() == 1 { "" } else { "s" },
                ids(", ")
            ),
            _ if self.directed => format!("link {} down", ids("→")),
            _ => format!("link {} down", ids("–")),
        }
    }
}

/// A run's fault windows: which links carry nothing and which nodes are down, at any time.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FaultSchedule {
    faults: Vec<ScheduledFault>,
}

impl FaultSchedule {
    /// The schedule of these faults.
    pub fn new(faults: Vec<ScheduledFault>) -> FaultSchedule {
        FaultSchedule { faults }
    }

    /// Node `node` is running at time `t`.
    pub fn node_up(&self, node: usize, t: Time) -> bool {
        !self.faults.iter().any(|f| match f {
            ScheduledFault::Crash { node: n, at, restart } => *n == node && t >= *at && restart.is_none_or(|r| t < r),
            _ => false,
        })
    }

    /// Whether a datagram sent at `t` can cross from → to: both ends up, no window or partition in the way.
    pub fn link_up(&self, from: usize, to: usize, t: Time) -> bool {
        if !self.node_up(from, t) || !self.node_up(to, t) {
            return false;
        }
        !self.faults.iter().any(|f| match f {
            ScheduledFault::LinkDown {
                from: a,
                to: b,
                both_ways,
                start,
                end,
            } => t >= *start && t < *end && ((*a == from && *b == to) || (*both_ways && *a == to && *b == from)),
            ScheduledFault::Partition { nodes, start, end } => {
                t >= *start && t < *end && (nodes.contains(&from) != nodes.contains(&to))
            }
            ScheduledFault::Crash { .. } => false,
        })
    }

    /// Every fault as a time window over node ids (`id_of` maps an index to its id): what a plot shades and a
    /// summary records. A crash without a restart lasts to the end of the run (`end_s` absent).
    pub fn windows(&self, id_of: impl Fn(usize) -> u32) -> Vec<FaultWindow> {
        self.faults
            .iter()
            .map(|f| match f {
                ScheduledFault::LinkDown {
                    from,
                    to,
                    both_ways,
                    start,
                    end,
                } => FaultWindow {
                    kind: "link-down".into(),
                    nodes: vec![id_of(*from), id_of(*to)],
                    directed: !both_ways,
                    start_s: start.as_secs(),
                    end_s: Some(end.as_secs()),
                },
                ScheduledFault::Partition { nodes, start, end } => FaultWindow {
                    kind: "partition".into(),
                    directed: false,
                    nodes: nodes.iter().map(|n| id_of(*n)).collect(),
                    start_s: start.as_secs(),
                    end_s: Some(end.as_secs()),
                },
                ScheduledFault::Crash { node, at, restart } => FaultWindow {
                    kind: "crash".into(),
                    directed: false,
                    nodes: vec![id_of(*node)],
                    start_s: at.as_secs(),
                    end_s: restart.map(Time::as_secs),
                },
            })
            .collect()
    }

    /// When each fault starts (to warn of faults that a run ends before).
    pub fn starts(&self) -> impl Iterator<Item = Time> + '_ {
        self.faults.iter().map(|f| match f {
            ScheduledFault::LinkDown { start, .. } | ScheduledFault::Partition { start, .. } => *start,
            ScheduledFault::Crash { at, .. } => *at,
        })
    }

    /// The events due to `node`, now `up` or down, before step k of period `dt`: a crash, a restart, or both when
    /// it went down and came back since the step before.
    pub fn node_events(&self, node: usize, k: u64, dt: f64, up: bool) -> &'static [NodeEvent] {
        let t = Time::at_step(k, dt);
        let up_now = self.node_up(node, t);
        match (up, up_now) {
            (true, false) => &[NodeEvent::Crash],
            (false, true) => &[NodeEvent::Restart],
            (true, true) if k > 0 && self.restarts_between(node, Time::at_step(k - 1, dt), t) => {
                &[NodeEvent::Crash, NodeEvent::Restart]
            }
            _ => &[],
        }
    }

    /// True when `node` restarts in (t0, t1]: it must re-initialise.
    pub fn restarts_between(&self, node: usize, t0: Time, t1: Time) -> bool {
        self.faults.iter().any(|f| match f {
            ScheduledFault::Crash {
                node: n,
                restart: Some(r),
                ..
            } => *n == node && *r > t0 && *r <= t1,
            _ => false,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_partitions_and_crashes() {
        let t = Time::from_secs;
        let s = FaultSchedule::new(vec![
            ScheduledFault::LinkDown {
                from: 0,
                to: 1,
                both_ways: false,
                start: t(1.0),
                end: t(2.0),
            },
            ScheduledFault::Partition {
                nodes: vec![2],
                start: t(3.0),
                end: t(4.0),
            },
            ScheduledFault::Crash {
                node: 1,
                at: t(5.0),
                restart: Some(t(6.0)),
            },
        ]);
        assert!(!s.link_up(0, 1, t(1.5)) && s.link_up(1, 0, t(1.5)) && s.link_up(0, 1, t(2.0)));
        assert!(!s.link_up(0, 2, t(3.5)) && !s.link_up(2, 1, t(3.5)) && s.link_up(0, 1, t(3.5)));
        assert!(!s.node_up(1, t(5.5)) && s.node_up(1, t(6.0)) && !s.link_up(0, 1, t(5.2)));
        assert!(s.restarts_between(1, t(5.99), t(6.0)) && !s.restarts_between(1, t(6.0), t(7.0)));
        // A window opens on the step that begins at its start whatever the rounding of k·Δt (at 30 Hz, step 111 in
        // seconds is 3.6999999999999997).
        let w = FaultSchedule::new(vec![ScheduledFault::Partition {
            nodes: vec![0],
            start: t(3.7),
            end: t(4.0),
        }]);
        let dt = 1.0 / 30.0;
        assert!(111.0 * dt < 3.7);
        assert!(w.link_up(0, 1, Time::at_step(110, dt)) && !w.link_up(0, 1, Time::at_step(111, dt)));
        assert!(!w.link_up(0, 1, Time::at_step(119, dt)) && w.link_up(0, 1, Time::at_step(120, dt)));
        use NodeEvent::{Crash, Restart};
        // At 10 Hz: down at step 50, back at step 60; nothing while it stays either way.
        let events = |k, up| s.node_events(1, k, 0.1, up);
        assert_eq!(
            (events(49, true), events(50, true), events(55, false)),
            (&[][..], &[Crash][..], &[][..])
        );
        assert_eq!((events(60, false), events(61, true)), (&[Restart][..], &[][..]));
        // Down and back between two steps (at 1 Hz, steps 5 and 6): both at once.
        assert_eq!(s.node_events(1, 6, 1.0, true), &[Crash, Restart]);
        assert_eq!(s.node_events(0, 6, 1.0, true), &[]);
    }
}
