//! The multi-host handshake's view of a node: its neighbours, which of them it has heard from, and the highest
//! step any of them reported (a node that starts late or restarts joins at that step).

use crate::scenario::Scenario;

#[derive(Debug, Clone)]
pub(super) struct Session {
    /// Neighbours in either direction (node indices).
    pub neighbours: Vec<usize>,
    heard: Vec<bool>,
    /// The highest step a neighbour reported (in a measurement or a hello).
    pub max_peer_step: Option<u64>,
}

impl Session {
    pub fn new(topo: &Scenario, index: usize) -> Session {
        let mut neighbours: Vec<usize> = topo
            .links()
            .iter()
            .filter_map(|l| {
                if l.from == index {
                    Some(l.to)
                } else if l.to == index {
                    Some(l.from)
                } else {
                    None
                }
            })
            .collect();
        neighbours.sort_unstable();
        neighbours.dedup();
        Session {
            neighbours,
            heard: vec![false; topo.nodes().len()],
            max_peer_step: None,
        }
    }

    /// A datagram from `src` (a neighbour) that reported `step`, if any.
    pub fn heard_from(&mut self, src: usize, step: Option<u64>) {
        self.heard[src] = true;
        if let Some(p) = step {
            self.max_peer_step = Some(self.max_peer_step.map_or(p, |m| m.max(p)));
        }
    }

    pub fn heard_all(&self) -> bool {
        self.neighbours.iter().all(|&j| self.heard[j])
    }
}
