//! The virtual clock: lockstep with no driver in between. One worker per core owns a block of the nodes and their
//! sockets. In step k every node steps, and on every out-link sends one [`Frame`] over UDP: everything the link layer
//! delivers by the deadline t_k + D on that link, in delivery order — or, when it dropped or delayed everything, an
//! empty frame, the marker. A node closes step k once it has the step-k frame of every in-neighbour, as conservative
//! parallel discrete-event simulation closes a time step on its null messages; frames of later windows wait for their
//! step. Datagrams due after the deadline go out in a later window and arrive late. Same seed, same results.
//! With L consensus rounds a step has L windows, k·L + r closing round r at t_k + D(r+1)/L.
//!
//! Workers may run ahead of each other, and of the observer that fuses each step, by at most [`LEAD`] steps: that
//! bounds the socket buffers and the estimates in flight. A frame that does not arrive within the receive timeout
//! (a real socket loss) is counted and the step closes without it.

use std::collections::{BTreeMap, HashMap};
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use bytes::Bytes;
use tokio::net::UdpSocket;
use tokio::sync::{mpsc, watch};
use tokio::time::Instant;

use super::collect::{blocks, observe, StepOut};
use super::{NetError, RunOptions};
use crate::node::{Node, NodeReport};
use crate::scenario::Scenario;
use crate::sim::{begin_step, Clock, RunResults};
use crate::wire::{Frame, FrameView, FrameWriter, MAX_FRAME};

/// How many steps a worker may run ahead of the slowest worker and of the observer.
pub const LEAD: u64 = 16;

/// Where every worker and the observer are: the steps each has closed, and the step at which a shutdown stops them.
#[derive(Debug, Clone)]
struct Pace {
    /// Steps closed by each worker, then by the observer (the last entry).
    next: Vec<u64>,
    /// No worker starts this step or a later one.
    stop_at: u64,
}

impl Pace {
    fn slowest(&self) -> u64 {
        self.next.iter().copied().min().unwrap_or(0)
    }
}

/// One node a worker owns, with its socket and what it expects each step.
struct Slot {
    node: Node,
    socket: UdpSocket,
    /// In-neighbours (node indices, sorted): one frame each per window.
    ins: Vec<usize>,
    /// Out-neighbours (node indices, sorted).
    outs: Vec<usize>,
    /// Parts received, and parts announced, from each in-neighbour in the open window.
    got: Vec<u16>,
    want: Vec<Option<u16>>,
    /// Frames of windows not open yet, by window.
    later: BTreeMap<u64, Vec<(usize, Frame)>>,
}

impl Slot {
    fn complete(&self) -> bool {
        self.got.iter().zip(&self.want).all(|(g, w)| w.is_some_and(|w| *g >= w))
    }

    /// A frame of the open window from in-neighbour `src`: its datagrams go to the node.
    fn take<'a>(&mut self, src: usize, parts: u16, datagrams: impl Iterator<Item = &'a [u8]>) {
        for d in datagrams {
            self.node.handle_datagram(Some(src), d);
        }
        // A peer that is not an in-neighbour closes nothing.
        if let Ok(pos) = self.ins.binary_search(&src) {
            self.got[pos] = self.got[pos].saturating_add(1);
            self.want[pos] = Some(parts);
        }
    }

    /// Bytes read from `from` while window `k` is open.
    fn receive(&mut self, from: Option<usize>, bytes: &[u8], k: u64) {
        let Some(src) = from else {
            // Not from a peer's socket: the node counts it.
            self.node.handle_datagram(None, bytes);
            return;
        };
        match FrameView::parse(bytes) {
            Ok(f) if f.window == k => self.take(src, f.parts, f.datagrams()),
            Ok(f) if f.window > k => self.later.entry(f.window).or_default().push((src, f.to_owned())),
            // A window closed by a timeout: its datagrams arrive after their step, late.
            Ok(f) => {
                for d in f.datagrams() {
                    self.node.handle_datagram(Some(src), d);
                }
            }
            Err(_) => {
                self.node.handle_datagram(None, bytes);
            }
        }
    }

    /// Open window `k`: nothing received yet but the frames that came early.
    fn open(&mut self, k: u64) {
        self.got.iter_mut().for_each(|g| *g = 0);
        self.want.iter_mut().for_each(|w| *w = None);
        for (src, f) in self.later.remove(&k).unwrap_or_default() {
            self.take(src, f.parts, f.datagrams.iter().map(|d| &d[..]));
        }
    }

    /// Close the open window without what did not come: the parts missing, counted as socket losses.
    fn give_up(&mut self) -> u64 {
        let mut missing = 0;
        for (g, w) in self.got.iter_mut().zip(self.want.iter_mut()) {
            let want = w.unwrap_or(g.saturating_add(1));
            missing += u64::from(want.saturating_sub(*g));
            *w = Some(*g);
        }
        missing
    }
}

/// What a worker returns at the end.
struct WorkerEnd {
    reports: Vec<NodeReport>,
    done: u64,
    socket_losses: u64,
}

struct Shared {
    addrs: Vec<SocketAddr>,
    index_of: HashMap<SocketAddr, usize>,
    steps: u64,
    /// Consensus rounds per step: windows per step.
    rounds: usize,
    topo: Arc<Scenario>,
    recv_timeout: Duration,
    sync: watch::Sender<Pace>,
}

async fn worker(w: usize, mut slots: Vec<Slot>, sh: Arc<Shared>, out: mpsc::UnboundedSender<StepOut>) -> WorkerEnd {
    let mut buf = vec![0u8; MAX_FRAME + 1];
    let mut sync = sh.sync.subscribe();
    let mut socket_losses = 0;
    let mut done = 0;
    // Per out-link of a slot: the datagrams of this window; the frames they go out in.
    let mut bundles: Vec<Vec<Bytes>> = Vec::new();
    let mut writer = FrameWriter::default();
    for k in 0..sh.steps {
        let stop_at = match sync.wait_for(|s| s.stop_at <= k || k <= s.slowest() + LEAD).await {
            Ok(s) => s.stop_at,
            Err(_) => break,
        };
        if stop_at <= k {
            break;
        }
        for r in 0..sh.rounds {
            // Window k·L + r closes round r of step k at t_k + D(r+1)/L; the last window also flushes everything
            // still queued, so late datagrams are counted as late.
            let window = k * sh.rounds as u64 + r as u64;
            let last = r + 1 == sh.rounds;
            let window_end = if last && k + 1 == sh.steps {
                f64::INFINITY
            } else {
                crate::sim::round_end(&sh.topo, k, r)
            };
            for slot in &mut slots {
                if r == 0 {
                    begin_step(&mut slot.node, k);
                }
                bundles.resize_with(slot.outs.len(), Vec::new);
                while let Some(tx) = slot.node.poll_transmit(window_end) {
                    if let Ok(j) = slot.outs.binary_search(&tx.to) {
                        bundles[j].push(tx.bytes);
                    }
                }
                for (j, &to) in slot.outs.iter().enumerate() {
                    let parts = writer.pack(window, bundles[j].iter().map(|b| &b[..]));
                    bundles[j].clear();
                    for i in 0..parts {
                        if let Err(e) = slot.socket.send_to(writer.part(i), sh.addrs[to]).await {
                            tracing::warn!(node = slot.node.id(), "send_to failed: {e}");
                        }
                    }
                }
            }
            for slot in &mut slots {
                slot.open(window);
            }
            // Read every owned socket until each node has its in-neighbours' frames of window k.
            let mut waited_since = Instant::now();
            loop {
                let mut progressed = false;
                for slot in slots.iter_mut().filter(|s| !s.complete()) {
                    while let Ok((len, from)) = slot.socket.try_recv_from(&mut buf) {
                        progressed = true;
                        let from = sh.index_of.get(&from).copied();
                        slot.receive(from, &buf[..len], window);
                        if slot.complete() {
                            break;
                        }
                    }
                }
                let Some(slot) = slots.iter_mut().find(|s| !s.complete()) else {
                    break;
                };
                if progressed {
                    waited_since = Instant::now();
                }
                match tokio::time::timeout_at(waited_since + sh.recv_timeout, slot.socket.readable()).await {
                    Ok(Ok(())) => {}
                    Ok(Err(e)) => tracing::warn!(node = slot.node.id(), "socket not readable: {e}"),
                    Err(_) => {
                        let missing: u64 = slots.iter_mut().filter(|s| !s.complete()).map(Slot::give_up).sum();
                        tracing::warn!(
                            step = k,
                            round = r,
                            "{} did not arrive within {:?}",
                            crate::scenario::count(missing as usize, "frame"),
                            sh.recv_timeout
                        );
                        socket_losses += missing;
                    }
                }
            }
            if !last {
                for slot in &mut slots {
                    slot.node.handle_round(k, r);
                }
            }
        }
        if out
            .send(StepOut::close(k, slots.iter_mut().map(|s| &mut s.node)))
            .is_err()
        {
            break;
        }
        done = k + 1;
        sh.sync.send_modify(|s| s.next[w] = done);
    }
    // What is still queued (foreign datagrams sent late in the run) is read, so that it is counted.
    for slot in &mut slots {
        while let Ok((len, from)) = slot.socket.try_recv_from(&mut buf) {
            let from = sh.index_of.get(&from).copied();
            slot.receive(from, &buf[..len], done * sh.rounds as u64);
        }
    }
    for slot in &mut slots {
        if let Some(n) = super::socket::kernel_drops(&slot.socket) {
            slot.node.handle_kernel_drops(n);
        }
    }
    WorkerEnd {
        reports: slots.iter_mut().map(|s| s.node.report()).collect(),
        done,
        socket_losses,
    }
}

pub(super) async fn run(
    topo: Arc<Scenario>,
    sockets: Vec<UdpSocket>,
    addrs: Vec<SocketAddr>,
    opts: &mut RunOptions,
    mut stop: watch::Receiver<bool>,
) -> Result<RunResults, NetError> {
    let n = topo.nodes().len();
    let blocks = blocks(n);
    let workers = blocks.len();
    let steps = topo.sim().steps();
    let (sync, _) = watch::channel(Pace {
        next: vec![0; workers + 1],
        stop_at: u64::MAX,
    });
    let sh = Arc::new(Shared {
        index_of: addrs.iter().enumerate().map(|(i, a)| (*a, i)).collect(),
        addrs,
        steps,
        rounds: topo.estimators().rounds,
        topo: topo.clone(),
        recv_timeout: opts.recv_timeout,
        sync: sync.clone(),
    });
    // A shutdown stops every worker after the same step: one past the furthest any has started.
    let stopper = {
        let sync = sync.clone();
        tokio::spawn(async move {
            if stop.wait_for(|s| *s).await.is_ok() {
                sync.send_modify(|s| s.stop_at = s.next.iter().copied().max().unwrap_or(0) + 1);
            }
        })
    };
    let (out_tx, out_rx) = mpsc::unbounded_channel();
    let record = opts.trace.is_some();
    let on_fused = {
        let sync = sync.clone();
        move |next| {
            sync.send_modify(|s| {
                if let Some(o) = s.next.last_mut() {
                    *o = next;
                }
            })
        }
    };
    let observer = tokio::spawn(observe(
        topo.clone(),
        workers,
        opts.trace.take(),
        opts.progress.clone(),
        on_fused,
        out_rx,
    ));
    let mut sockets = sockets.into_iter();
    let mut handles = Vec::with_capacity(workers);
    for (w, block) in blocks.into_iter().enumerate() {
        let slots: Vec<Slot> = block
            .filter_map(|i| {
                let socket = sockets.next()?;
                let node = Node::new(topo.clone(), i, record);
                let mut ins: Vec<usize> = topo.in_links(i).map(|l| l.from).collect();
                ins.sort_unstable();
                ins.dedup();
                let mut outs: Vec<usize> = topo.out_links(i).map(|l| l.to).collect();
                outs.sort_unstable();
                Some(Slot {
                    got: vec![0; ins.len()],
                    want: vec![None; ins.len()],
                    node,
                    socket,
                    ins,
                    outs,
                    later: BTreeMap::new(),
                })
            })
            .collect();
        handles.push(tokio::spawn(worker(w, slots, sh.clone(), out_tx.clone())));
    }
    drop(out_tx);
    let mut reports = Vec::with_capacity(n);
    let mut done = u64::MAX;
    let mut socket_losses = 0;
    for (w, h) in handles.into_iter().enumerate() {
        let end = h.await.map_err(|_| NetError::WorkerLost(w))?;
        reports.extend(end.reports);
        done = done.min(end.done);
        socket_losses += end.socket_losses;
    }
    stopper.abort();
    reports.sort_by_key(|r| r.index);
    let (observer, trace) = observer.await.map_err(|_| NetError::NoReply)?;
    let done = if n == 0 { 0 } else { done };
    Ok(RunResults {
        scenario: topo,
        clock: Clock::Virtual,
        reports,
        observer: Some(observer),
        steps_done: done,
        interrupted: done < steps,
        wall_s: 0.0,
        socket_losses,
        trace,
        lmi: Vec::new(),
        schedule: None,
    })
}
