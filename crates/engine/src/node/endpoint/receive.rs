//! The receive path of a node: bytes checked, authenticated, found plausible and collected for their step.

#[allow(unused_imports)]
use super::*;

impl Endpoint {
    /// Bytes through the whole receive path: checked, authenticated, plausible, collected.
    pub(super) fn receive(&mut self, from: Option<usize>, bytes: &[u8]) -> Option<Arrival> {
        self.counters.datagrams_in += 1;
        if self.handshake && self.authenticates() && self.claims_an_earlier_boot(bytes) {
            // An earlier boot of a neighbour than the one a fresh hello vouched for (an earlier run's datagram,
            // replayed): refused as that without opening it.
            self.wire.rejected.too_old += 1;
            return None;
        }
        let (topo, session) = (&self.topo, &self.session);
        let known = |id: u32| {
            topo.index_of(id)
                .is_some_and(|j| session.neighbours.binary_search(&j).is_ok())
        };
        let (dg, epoch) = match self.wire.decode(bytes, known) {
            Ok(d) => d,
            Err(Refused::Corrupted) if from.is_some() => {
                // A peer's datagram damaged on the way: the link layer's corruption, caught.
                self.counters.corrupted += 1;
                if let Some(f) = from {
                    self.inbox.rx.get_mut(f).corrupted += 1;
                }
                return None;
            }
            Err(Refused::Rejected(r)) => {
                tracing::debug!(node = self.id, "rejected datagram: {r}");
                return None;
            }
            Err(Refused::Corrupted) => {
                self.counters.malformed += 1;
                return None;
            }
            Err(Refused::Malformed(e)) => {
                tracing::debug!(node = self.id, "malformed datagram: {e}");
                self.counters.malformed += 1;
                return None;
            }
        };
        let Some(src) = self.topo.index_of(dg.header.src) else {
            self.counters.malformed += 1;
            return None;
        };
        if from.is_some_and(|f| f != src) || src == self.index || !dg.header.is_for(self.id) {
            // The header names a different node than the socket it came from, or is addressed to another node.
            self.counters.malformed += 1;
            return None;
        }
        let step = dg.header.pertains.step(self.topo.sim().dt());
        let peer_step = match &dg.payload {
            Payload::Hello { running, .. } => *running,
            Payload::Measurement { .. } | Payload::Round { .. } => Some(step),
        };
        if [Some(step), peer_step]
            .into_iter()
            .flatten()
            .any(|s| !self.plausible_step(s))
        {
            self.counters.implausible_step += 1;
            return None;
        }
        let mut answer = 0;
        if let Payload::Hello { .. } = &dg.payload {
            answer = self.on_hello(src, epoch, &dg.payload);
        } else if self.handshake && !self.session.vouched(src, epoch) {
            // A measurement or round of a boot no fresh hello vouched for: an earlier run's, replayed (or a
            // neighbour's new boot before its first fresh hello). Never used.
            self.wire.rejected.too_old += 1;
            return None;
        }
        self.session.heard_from(src, peer_step);
        // A process's later boot numbers afresh; the boot its hellos vouch for tells them apart.
        let boot = if self.handshake {
            self.session.vouched_boot(src).unwrap_or(0)
        } else {
            0
        };
        self.inbox
            .numbered(src, dg.header.dst == crate::wire::BROADCAST, boot, dg.header.seq);
        let arrival = Arrival {
            src,
            step,
            measurement: matches!(dg.payload, Payload::Measurement { .. }),
            answer,
        };
        if let Payload::Round { round, body } = &dg.payload {
            if !self.up {
                return None;
            }
            let (states, rows) = (self.initial.x.len(), self.obs.dim());
            if self
                .schemes
                .receive(src, step, *round, dg.header.scheme, body, states, rows)
                .is_err()
            {
                // A round this run does not hold, a scheme it does not run, or a message of the wrong size.
                self.counters.malformed += 1;
                return None;
            }
            return Some(arrival);
        }
        let Payload::Measurement { rows, values } = dg.payload else {
            return Some(arrival);
        };
        if !self.up {
            self.inbox.rx.get_mut(src).while_down += 1;
            return None;
        }
        let m = self.obs.dim();
        if m < 64 && rows >> m != 0 {
            self.counters.malformed += 1;
            return None;
        }
        if self.inbox.receive(src, step, rows, values) == Received::Held {
            self.counters.early += 1;
        }
        Some(arrival)
    }
}
