//! The multi-host handshake's view of a node: its neighbours, each one's boot as its hellos give it, which of them
//! have shown themselves fresh (a hello that echoes this node's boot), and the highest step a fresh one reported (a
//! node that starts late or restarts joins at that step). Nothing a neighbour not yet fresh claims counts: a datagram
//! recorded in an earlier run and replayed can neither start this node, nor make it join at its step.

use crate::scenario::Scenario;

#[derive(Debug, Clone)]
pub(super) struct Session {
    /// Neighbours in either direction (node indices).
    pub neighbours: Vec<usize>,
    /// Each neighbour's boot epoch, as its last hello gave it (echoed in this node's hellos to it).
    boots: Vec<Option<u64>>,
    /// The neighbour's boot (its sealing epoch, or its boot unauthenticated) of the last hello that echoed this
    /// node's boot.
    fresh: Vec<Option<u64>>,
    /// The last probe each neighbour sent (answered in this node's hellos to it; 0: none).
    probes: Vec<u64>,
    /// The highest step a fresh neighbour reported (in a measurement or a hello).
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
            boots: vec![None; neighbours.len()],
            fresh: vec![None; neighbours.len()],
            probes: vec![0; neighbours.len()],
            neighbours,
            max_peer_step: None,
        }
    }

    /// A hello from `src` (a neighbour) of boot `boot`; `fresh`: it echoed this node's boot, and came sealed under
    /// this epoch (its boot, unauthenticated). Whether its boot is new here (no hello of this node echoed it yet).
    pub fn hello_from(&mut self, src: usize, boot: u64, fresh: Option<u64>) -> bool {
        let Ok(i) = self.neighbours.binary_search(&src) else {
            return false;
        };
        let new = self.boots[i] != Some(boot);
        self.boots[i] = Some(boot);
        if fresh.is_some() {
            self.fresh[i] = fresh;
        }
        new
    }

    /// Whether a datagram of `src` sealed under `epoch` (none unauthenticated) comes from the boot a fresh hello of
    /// it vouched for.
    pub fn vouched(&self, src: usize, epoch: Option<u64>) -> bool {
        self.neighbours
            .binary_search(&src)
            .is_ok_and(|i| self.fresh[i].is_some_and(|b| epoch.is_none_or(|e| e == b)))
    }

    /// The boot of `src` a fresh hello vouched for.
    pub fn vouched_boot(&self, src: usize) -> Option<u64> {
        self.neighbours.binary_search(&src).ok().and_then(|i| self.fresh[i])
    }

    /// A datagram from `src` that reported `step`, if any: counted when `src` has shown itself fresh.
    pub fn heard_from(&mut self, src: usize, step: Option<u64>) {
        let fresh = self
            .neighbours
            .binary_search(&src)
            .is_ok_and(|i| self.fresh[i].is_some());
        if let (Some(p), true) = (step, fresh) {
            self.max_peer_step = Some(self.max_peer_step.map_or(p, |m| m.max(p)));
        }
    }

    /// Whether any neighbour's hello was taken (its boot known), fresh or not.
    pub fn heard_a_hello(&self) -> bool {
        self.boots.iter().any(Option::is_some)
    }

    /// Every neighbour has shown itself fresh.
    pub fn heard_all(&self) -> bool {
        self.fresh.iter().all(Option::is_some)
    }

    /// Neighbour `j`'s boot as its last hello gave it.
    pub fn boot(&self, j: usize) -> Option<u64> {
        self.neighbours.binary_search(&j).ok().and_then(|i| self.boots[i])
    }

    /// A probe from neighbour `src` to answer (0: none). Whether it is new.
    pub fn probed(&mut self, src: usize, probe: u64) -> bool {
        match self.neighbours.binary_search(&src) {
            Ok(i) if probe != 0 && self.probes[i] != probe => {
                self.probes[i] = probe;
                true
            }
            _ => false,
        }
    }

    /// (neighbour, the boot to echo to it: 0 before its first hello, the probe to answer).
    pub fn echoes(&self) -> impl Iterator<Item = (usize, u64, u64)> + '_ {
        self.neighbours
            .iter()
            .zip(&self.boots)
            .zip(&self.probes)
            .map(|((&j, b), p)| (j, b.unwrap_or(0), *p))
    }
}
