//! Each sender's MAC: unslotted CSMA/CA ([`crate::medium::csma`]) over one agenda of every sender's next step,
//! in time order.

use std::cmp::Reverse;

use super::{Next, RadioMedium};
use crate::medium::csma::{self, Attempt, Csma};
use crate::medium::phy;
use crate::time::Time;

impl Next {
    /// Its place on the agenda of sender `i`: in time order, at one instant a frame's end, then an ACK wait's
    /// end, then an assessment; senders in index order.
    fn key(self, i: usize) -> Option<(Time, u8, usize)> {
        match self {
            Next::TxEnd(t) => Some((t, 0, i)),
            Next::AckWait(t) => Some((t, 1, i)),
            Next::Cca(t) => Some((t, 2, i)),
            Next::Idle => None,
        }
    }
}

impl RadioMedium {
    /// Run the channel to `until`: every assessment and every frame's end up to it, in time order (a frame's end
    /// before an assessment at the same instant; senders in index order).
    pub(super) fn advance(&mut self, until: Time) {
        while let Some(&Reverse((t, kind, i))) = self.agenda.peek().filter(|e| e.0 .0 <= until) {
            self.agenda.pop();
            if self.macs[i].next.key(i) != Some((t, kind, i)) {
                continue;
            }
            self.clock = self.clock.max(t);
            match kind {
                0 => self.end_frame(i, t),
                1 => self.ack_wait(i, t),
                _ => self.assess(i, t),
            }
            // Only the sender whose event it was has a new next step.
            self.schedule(i);
        }
    }

    /// Sender `i`'s next step goes on the agenda (its access begun if it is idle with a frame queued). Called when
    /// its next step changed: an event of its own, or a frame queued while it was idle.
    pub(super) fn schedule(&mut self, i: usize) {
        self.begin_access(i);
        if let Some(key) = self.macs[i].next.key(i) {
            self.agenda.push(Reverse(key));
        }
    }

    /// A sender with a frame queued and nothing under way backs off before its first assessment.
    fn begin_access(&mut self, i: usize) {
        let mac = &mut self.macs[i];
        let (Next::Idle, Some(head)) = (mac.next, mac.queue.front()) else {
            return;
        };
        let csma = Csma::new(self.radio.csma);
        let from = head.ready.max(mac.free_at);
        mac.next = Next::Cca(from + csma.backoff(&mut mac.rng) + csma::CCA);
        mac.csma = Some(csma);
    }

    /// Sender `i`'s assessment ends at `t`: busy (ED over the threshold, or a frame it would be receiving), or
    /// clear and the frame goes on the air after the turnaround.
    fn assess(&mut self, i: usize, t: Time) {
        let from = Time::from_nanos(t.as_nanos().saturating_sub(csma::CCA.as_nanos() as u64));
        let threshold = phy::dbm_to_w(self.radio.receiver.sensitivity_dbm + 10.0);
        let heard = self.ears[i].heard_during(from, t);
        // The peak energy over the assessment: the sum at its start and at each frame's start within it.
        let peak = std::iter::once(from)
            .chain(heard.iter().map(|h| h.0).filter(|s| *s > from))
            .map(|at| heard.iter().filter(|h| h.0 <= at && h.1 > at).map(|h| h.2).sum::<f64>())
            .fold(0.0, f64::max);
        // Receiving: a frame still on the air that it locked onto as it began (what it makes of the frames around it,
        // as at any receiver).
        let receiving = self.ears[i].receiving(t);
        #[cfg(test)]
        if let Some(want) = self.receiving_by_chain(i, t) {
            assert_eq!(receiving, want, "node {i} at {t:?}");
        }
        let mac = &mut self.macs[i];
        let mut csma = mac.csma.take().expect("an assessment belongs to an access");
        if peak >= threshold || receiving {
            self.nodes[i].busy += 1;
            match csma.busy() {
                Attempt::BackOff => {
                    mac.next = Next::Cca(t + csma.backoff(&mut mac.rng) + csma::CCA);
                    mac.csma = Some(csma);
                }
                Attempt::Fail => {
                    // The frame is abandoned, and with it the rest of its message: lost wherever it was going.
                    let q = mac.queue.pop_front().expect("a queued frame");
                    while mac.queue.front().is_some_and(|r| r.message == q.message) {
                        mac.queue.pop_front();
                    }
                    self.nodes[i].csma_failures += 1;
                    mac.next = Next::Idle;
                    mac.free_at = t;
                    for j in self.receivers(i, q.to) {
                        self.lost.remove(&(q.message, j));
                        if !self.down.remove(&(q.message, j)) {
                            self.links[i].entry(j).or_default().lost_random += 1;
                        }
                    }
                }
            }
            return;
        }
        let q = mac.queue.front().expect("a queued frame").clone();
        let start = t + csma::TURNAROUND;
        let end = start + phy::airtime(q.psdu);
        mac.next = Next::TxEnd(end);
        self.nodes[i].frames += 1;
        self.nodes[i].airtime_ns += end.since(start).as_nanos() as u64;
        self.nodes[i].last_end_ns = end.as_nanos();
        let seq = self.put_on_air(i, (start, end), (q.message, q.to, q.bytes));
        self.macs[i].on_air = Some(seq);
    }
}
