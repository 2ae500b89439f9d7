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
            .out_links(index)
            .map(|l| l.to)
            .chain(topo.in_links(index).map(|l| l.from))
            .collect();
        neighbours.sort_unstable();
        neighbours.dedup();
        Session {
            heard: vec![false; neighbours.len()],
            neighbours,
            max_peer_step: None,
        }
    }

    /// A datagram from `src` (a neighbour) that reported `step`, if any.
    pub fn heard_from(&mut self, src: usize, step: Option<u64>) {
        if let Ok(i) = self.neighbours.binary_search(&src) {
            self.heard[i] = true;
        }
        if let Some(p) = step {
            self.max_peer_step = Some(self.max_peer_step.map_or(p, |m| m.max(p)));
        }
    }

    pub fn heard_all(&self) -> bool {
        self.heard.iter().all(|h| *h)
    }
}
