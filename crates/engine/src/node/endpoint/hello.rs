//! The multi-host handshake's datagrams (the endpoint's part of it; [`super::session`] keeps what they established):
//! hellos out, each echoing the neighbour's boot and answering its last probe; hellos in, of which only a fresh one
//! (echoing this boot) may start, join or name the run; probes of an address a neighbour's datagrams newly came
//! from; and sealed datagrams of a neighbour's earlier boot, refused unopened.

use super::{Endpoint, Transmit};
use crate::time::Time;
use crate::wire::{Datagram, Header, Payload};

impl Endpoint {
    /// Hello datagrams for every neighbour (control traffic of the start handshake: not subject to the link layer).
    pub fn hello(&mut self, running: Option<u64>) -> Vec<Transmit> {
        let echoes: Vec<(usize, u64, u64)> = self.session.echoes().collect();
        // One per neighbour: each echoes that neighbour's boot and answers its last probe.
        echoes
            .into_iter()
            .filter_map(|(to, echo, answer)| self.hello_to(to, running, echo, 0, answer))
            .collect()
    }

    /// A hello to neighbour `j` carrying `probe`, for the address its datagrams newly came from: `j` answers it in
    /// its next hello, from where it really is.
    pub fn probe(&mut self, j: usize, running: Option<u64>, probe: u64) -> Option<Transmit> {
        let (echo, answer) = self
            .session
            .echoes()
            .find(|(to, ..)| *to == j)
            .map(|(_, e, a)| (e, a))?;
        self.hello_to(j, running, echo, probe, answer)
    }

    fn hello_to(&mut self, to: usize, running: Option<u64>, echo: u64, probe: u64, answer: u64) -> Option<Transmit> {
        let payload = Payload::Hello {
            running,
            run: self.run,
            boot: self.booted,
            echo,
            probe,
            answer,
        };
        let sent = running.map_or(Time::ZERO, |k| self.topo.step_time(k));
        let (id, to_id) = (self.id, self.topo.nodes()[to].id);
        let d = Datagram {
            header: Header::hello(id, to_id, 0, sent),
            payload,
        };
        let bytes = self.wire.encode(&d, to_id, echo).ok()?;
        Some(Transmit { to, bytes })
    }

    /// Whether any neighbour's hello was taken here, fresh or not (one that opened, in an authenticated run).
    pub fn heard_a_hello(&self) -> bool {
        self.session.heard_a_hello()
    }

    /// A hello from neighbour `src`, sealed under `epoch` (none unauthenticated): the probe it carries is answered
    /// and, when it is fresh, its boot vouched for and its run taken in. Its answer to this node's probe (0: none).
    pub(super) fn on_hello(&mut self, src: usize, epoch: Option<u64>, payload: &Payload) -> u64 {
        let Payload::Hello {
            run,
            boot,
            echo,
            probe,
            answer,
            ..
        } = *payload
        else {
            return 0;
        };
        // A probe of where this node's datagrams come from: answered at once.
        self.hello_due |= self.session.probed(src, probe);
        // Fresh: sent after this boot began (it echoes it). Only a fresh hello names a running step or a run:
        // one recorded in an earlier run, replayed, neither starts, joins nor renames this one.
        let fresh = self.booted != 0 && echo == self.booted;
        let new = self
            .session
            .hello_from(src, boot, fresh.then_some(epoch.unwrap_or(boot)));
        // The neighbour has not heard this boot, or this node has not yet echoed its boot: answer at once.
        self.hello_due |= !fresh || new;
        if fresh {
            // Min-consensus over fresh hellos, also while running: one hop per hello period.
            self.run = self.run.min(run);
        }
        answer
    }

    /// A sealed datagram whose clear part names an earlier boot of a neighbour than the one a fresh hello of it
    /// vouched for.
    pub(super) fn claims_an_earlier_boot(&self, bytes: &[u8]) -> bool {
        crate::wire::secure::claimed(bytes).is_ok_and(|(h, epoch, _)| {
            self.topo
                .index_of(h.src)
                .and_then(|j| self.session.vouched_boot(j))
                .is_some_and(|b| epoch < b)
        })
    }
}
