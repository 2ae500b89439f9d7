//! One node a worker owns: its socket, the frames it expects each window, what it keeps for a resend.

use super::*;
use simnet_engine::medium::Capture;

/// One node a worker owns, with its socket and what it expects each step.
pub(super) struct Slot {
    pub(super) node: Node,
    /// What becomes of what it sends: its out-links, or its handle on the shared air.
    pub(super) medium: Capture<Box<dyn Medium>>,
    /// Shared with the worker's list of sockets it waits on.
    pub(super) socket: Arc<UdpSocket>,
    /// In-neighbours (node indices, sorted): one frame each per window.
    pub(super) ins: Vec<usize>,
    /// Out-neighbours (node indices, sorted).
    pub(super) outs: Vec<usize>,
    /// Parts received, and parts announced, from each in-neighbour in the open window.
    pub(super) got: Vec<u16>,
    pub(super) want: Vec<Option<u16>>,
    /// Which parts came, so that a resent one is taken once: parts 0–63 by bit, any later part in `seen_more`.
    pub(super) seen: Vec<u64>,
    pub(super) seen_more: std::collections::BTreeSet<(usize, u16)>,
    /// Frames of windows not open yet, by window.
    pub(super) later: BTreeMap<u64, Vec<(usize, Frame)>>,
    /// Windows closed by the receive timeout, by (window, in-neighbour): the parts that had come. A part still to
    /// come is late; one that comes again is a resend.
    pub(super) gave_up: BTreeMap<(u64, usize), Vec<u16>>,
    /// Per out-link (as `outs`): the frames of its last windows, for a resend.
    pub(super) kept: Vec<VecDeque<(u64, Vec<Vec<u8>>)>>,
    /// Frames resent on a NACK.
    pub(super) resent: u64,
}

impl Slot {
    pub(super) fn complete(&self) -> bool {
        self.got.iter().zip(&self.want).all(|(g, w)| w.is_some_and(|w| *g >= w))
    }

    /// Whether part `part` from in-neighbour `pos` came already in the open window; marks it as come.
    pub(super) fn seen_before(&mut self, pos: usize, part: u16) -> bool {
        if part < 64 {
            let bit = 1u64 << part;
            let before = self.seen[pos] & bit != 0;
            self.seen[pos] |= bit;
            before
        } else {
            !self.seen_more.insert((pos, part))
        }
    }

    /// The parts from in-neighbour `pos` that came in the open window.
    pub(super) fn parts_seen(&self, pos: usize) -> Vec<u16> {
        (0..64u16)
            .filter(|p| self.seen[pos] & (1 << p) != 0)
            .chain(self.seen_more.iter().filter(|(q, _)| *q == pos).map(|(_, p)| *p))
            .collect()
    }

    /// A part of the open window from `src`: its datagrams go to the node, once.
    pub(super) fn take<'a>(&mut self, src: usize, part: u16, parts: u16, datagrams: impl Iterator<Item = &'a [u8]>) {
        if let Ok(pos) = self.ins.binary_search(&src) {
            if self.seen_before(pos, part) {
                return;
            }
            self.got[pos] = self.got[pos].saturating_add(1);
            self.want[pos] = Some(parts);
        }
        // A peer that is not an in-neighbour closes nothing.
        for d in datagrams {
            self.node.handle_datagram(Some(src), d);
        }
    }

    /// Bytes read from `from`: `k` is the open window, or the next to open when `open` is false.
    pub(super) fn receive(&mut self, from: Option<usize>, bytes: &[u8], k: u64, open: bool) {
        let Some(src) = from else {
            // Not from a peer's socket: the node counts it.
            self.node.handle_datagram(None, bytes);
            return;
        };
        match FrameView::parse(bytes) {
            Ok(f) if open && f.window == k => self.take(src, f.part, f.parts, f.datagrams()),
            Ok(f) if f.window >= k => {
                let held = self.later.entry(f.window).or_default();
                if !held.iter().any(|(s, h)| *s == src && h.part == f.part) {
                    held.push((src, f.to_owned()));
                }
            }
            // A window closed by a timeout: what had not come arrives after its step, late; what had come, or a
            // whole window's resend, is dropped.
            Ok(f) => {
                if let Some(seen) = self.gave_up.get_mut(&(f.window, src)) {
                    if !seen.contains(&f.part) {
                        seen.push(f.part);
                        for d in f.datagrams() {
                            self.node.handle_datagram(Some(src), d);
                        }
                    }
                }
            }
            Err(_) => {
                self.node.handle_datagram(None, bytes);
            }
        }
    }

    /// Read what is queued on the socket — all of it, or, with `until_complete`, until the open window is whole
    /// (later windows' frames wait in the socket rather than being copied); whether anything was read.
    pub(super) fn drain(&mut self, buf: &mut [u8], sh: &Shared, k: u64, open: bool, until_complete: bool) -> bool {
        let mut any = false;
        while !(until_complete && self.complete()) {
            let Ok((len, from)) = self.socket.try_recv_from(buf) else {
                break;
            };
            any = true;
            let from = sh.index_of.get(&from).copied();
            self.receive(from, &buf[..len], k, open);
        }
        any
    }

    /// The frames kept of `window` on the link to `to`, again (none when it has not been sent yet: it will be).
    pub(super) fn resend(&mut self, to: usize, window: u64, addr: SocketAddr) {
        let Ok(j) = self.outs.binary_search(&to) else { return };
        let Some((_, parts)) = self.kept[j].iter().find(|(w, _)| *w == window) else {
            return;
        };
        for p in parts {
            // Best effort: a full send buffer loses this resend, and the receiver asks again.
            if self.socket.try_send_to(p, addr).is_ok() {
                self.resent += 1;
            }
        }
    }

    /// Ask every in-neighbour whose frames of window `k` are not all in for them again, at its worker's control
    /// socket.
    pub(super) fn nack(&self, k: u64, control: &UdpSocket, sh: &Shared) {
        let me = self.node.index() as u32;
        for (pos, &src) in self.ins.iter().enumerate() {
            if self.want[pos].is_none_or(|w| self.got[pos] < w) {
                let n = Nack {
                    window: k,
                    from: me,
                    to: src as u32,
                };
                let _ = control.try_send_to(&n.encode(), sh.controls[sh.worker_of[src]]);
            }
        }
    }

    /// Open window `k`: nothing received yet but the frames that came early.
    pub(super) fn open(&mut self, k: u64, keep: u64) {
        self.got.iter_mut().for_each(|g| *g = 0);
        self.want.iter_mut().for_each(|w| *w = None);
        self.seen.iter_mut().for_each(|s| *s = 0);
        self.seen_more.clear();
        for (src, f) in self.later.remove(&k).unwrap_or_default() {
            self.take(src, f.part, f.parts, f.datagrams.iter().map(|d| &d[..]));
        }
        // What a resend of a window this old could still bring is no longer waited for.
        let oldest = k.saturating_sub(keep);
        while self.gave_up.first_key_value().is_some_and(|((w, _), _)| *w < oldest) {
            self.gave_up.pop_first();
        }
    }

    /// Close the open window `k` without what did not come: the parts missing, counted as socket losses.
    pub(super) fn give_up(&mut self, k: u64) -> u64 {
        let mut missing = 0;
        for pos in 0..self.ins.len() {
            let g = self.got[pos];
            let want = self.want[pos].unwrap_or(g.saturating_add(1));
            if g < want {
                missing += u64::from(want - g);
                let seen = self.parts_seen(pos);
                self.gave_up.insert((k, self.ins[pos]), seen);
            }
            self.want[pos] = Some(g);
        }
        missing
    }

    /// Buffers for the next window's frames to `outs[j]`: those of the oldest window kept once `keep` are (it is
    /// let go as the next is kept), so that a run past its first windows allocates no frame.
    pub(super) fn frames_for(&mut self, j: usize, keep: u64) -> Vec<Vec<u8>> {
        let q = &mut self.kept[j];
        if keep > 0 && q.len() as u64 >= keep {
            q.pop_front().map(|(_, frames)| frames).unwrap_or_default()
        } else {
            Vec::new()
        }
    }

    /// Window `window`'s frames to `outs[j]`, kept for a resend.
    pub(super) fn keep(&mut self, j: usize, window: u64, parts: Vec<Vec<u8>>, keep: u64) {
        let q = &mut self.kept[j];
        q.push_back((window, parts));
        while q.len() as u64 > keep {
            q.pop_front();
        }
    }
}
