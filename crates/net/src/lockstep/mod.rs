//! The virtual clock: lockstep with no driver in between. One worker per core owns a block of the nodes and their
//! sockets. In step k every node steps, and on every out-link sends one [`Frame`] over UDP: everything the link layer
//! delivers by the deadline t_k + D on that link, in delivery order — or, when it dropped or delayed everything, an
//! empty frame, the marker. A node closes step k once it has the step-k frame of every in-neighbour, as conservative
//! parallel discrete-event simulation closes a time step on its null messages; frames of later windows wait for their
//! step. Datagrams due after the deadline go out in a later window and arrive late. Same seed, same results.
//! With L consensus rounds a step has L windows, k·L + r closing round r at t_k + D(r+1)/L. A medium that cannot be
//! split by sender (a radio channel) is one [`air::Air`] every worker shares: each worker hands it its nodes'
//! transmissions of a window, and asks it for the window's deliveries once every worker has.
//!
//! Workers may run ahead of each other, and of the observer that fuses each step, by at most [`LEAD`] steps: that
//! bounds the socket buffers and the estimates in flight.
//!
//! A frame the kernel drops (a receive buffer full) is asked for again: a node that has heard nothing for
//! [`NACK_AFTER`] while a frame is missing sends a [`Nack`] for the window to the control socket of its sender's
//! worker, and the sender resends, from its own socket, the frames it kept of that window on that link (each
//! out-link keeps its last (LEAD + 2)·L windows, all a receiver can still be waiting for). A part that comes twice
//! is taken once, so a resend changes nothing: same seed, same results, socket losses or not. A worker reads its
//! control socket while it waits in a window, at the pace barrier and after its last step until every worker is
//! done, so that a NACK is always answered. Only a frame that no resend brought within the receive timeout is
//! counted as a socket loss, and the step closes without it.

use std::collections::{BTreeMap, HashMap, VecDeque};
use std::future::Future;
use std::net::SocketAddr;
use std::sync::Arc;
use std::task::Poll;
use std::time::Duration;

use bytes::Bytes;
use tokio::net::UdpSocket;
use tokio::sync::{mpsc, watch};
use tokio::time::Instant;

use super::collect::{blocks, observe, StepOut};
use super::{NetError, RunOptions};
use simnet_engine::medium::Medium;
use simnet_engine::node::{Node, NodeReport};
use simnet_engine::scenario::Scenario;
use simnet_engine::sim::{Clock, RunResults};
use simnet_engine::time::Time;
use simnet_engine::wire::{Frame, FrameView, FrameWriter, Nack, MAX_FRAME};

mod air;
mod slot;
use slot::Slot;

/// How many steps a worker may run ahead of the slowest worker and of the observer.
pub const LEAD: u64 = 16;

/// How long a node waits with nothing to read before it asks for a missing frame again (doubling to
/// [`NACK_MAX`]).
pub const NACK_AFTER: Duration = Duration::from_millis(20);
const NACK_MAX: Duration = Duration::from_millis(320);

/// Where every worker and the observer are: the steps each has closed, and the step at which a shutdown stops them.
#[derive(Debug, Clone)]
struct Pace {
    /// Steps closed by each worker, then by the observer (the last entry).
    next: Vec<u64>,
    /// No worker starts this step or a later one.
    stop_at: u64,
    /// Workers past their last step (they go on answering NACKs until every one is).
    finished: Vec<bool>,
    /// Windows each worker has handed the shared air ([`air`]) its nodes' transmissions of.
    posted: Vec<u64>,
}

impl Pace {
    fn slowest(&self) -> u64 {
        self.next.iter().copied().min().unwrap_or(0)
    }

    /// Every worker's transmissions of `window` are on the air (or the worker has stopped).
    fn all_posted(&self, window: u64) -> bool {
        self.posted.iter().zip(&self.finished).all(|(p, f)| *p > window || *f)
    }
}

/// Marks its worker finished when dropped, also when the worker panics: no other worker waits for it forever.
struct Finished<'a>(&'a watch::Sender<Pace>, usize);

impl Drop for Finished<'_> {
    fn drop(&mut self) {
        self.0.send_modify(|s| s.finished[self.1] = true);
    }
}

/// Answer the NACKs queued on a worker's control socket: each names a receiver and one of the worker's nodes.
fn serve(control: &UdpSocket, slots: &mut [Slot], sh: &Shared) {
    let mut b = [0u8; 64];
    while let Ok((len, _)) = control.try_recv_from(&mut b) {
        let Some(n) = Nack::parse(&b[..len]) else { continue };
        let (from, to) = (n.from as usize, n.to as usize);
        if let (Some(slot), Some(addr)) = (slots.iter_mut().find(|s| s.node.index() == to), sh.addrs.get(from)) {
            slot.resend(from, n.window, *addr);
        }
    }
}

/// Ready when any of `sockets` has something to read.
fn any_readable(sockets: &[Arc<UdpSocket>]) -> impl Future<Output = ()> + Send + '_ {
    std::future::poll_fn(move |cx| {
        // Each socket registers the waker, so that the first one readable wakes the worker.
        let mut ready = false;
        for s in sockets {
            ready |= s.poll_recv_ready(cx).is_ready();
        }
        if ready {
            Poll::Ready(())
        } else {
            Poll::Pending
        }
    })
}

/// What a worker returns at the end.
struct WorkerEnd {
    reports: Vec<NodeReport>,
    done: u64,
    socket_losses: u64,
    resent: u64,
}

struct Shared {
    addrs: Vec<SocketAddr>,
    /// Each worker's control socket, where NACKs go; the worker of each node.
    controls: Vec<SocketAddr>,
    worker_of: Vec<usize>,
    index_of: HashMap<SocketAddr, usize>,
    steps: u64,
    /// Consensus rounds per step: windows per step.
    rounds: usize,
    topo: Arc<Scenario>,
    recv_timeout: Duration,
    sync: watch::Sender<Pace>,
    /// The medium is one shared air: a window's deliveries wait until every worker has posted it.
    shared_air: bool,
}

impl Shared {
    /// Windows each out-link keeps for a resend: every window a receiver can still be waiting for.
    fn keep(&self) -> u64 {
        (LEAD + 2) * self.rounds as u64
    }
}

async fn worker(
    w: usize,
    mut slots: Vec<Slot>,
    control: UdpSocket,
    sh: Arc<Shared>,
    out: mpsc::UnboundedSender<StepOut>,
) -> WorkerEnd {
    let finished = Finished(&sh.sync, w);
    let control = Arc::new(control);
    let mut buf = vec![0u8; MAX_FRAME + 1];
    let mut sync = sh.sync.subscribe();
    let mut socket_losses = 0;
    let mut done = 0;
    let keep = sh.keep();
    // Per out-link of a slot: the datagrams of this window; the frames they go out in.
    let mut bundles: Vec<Vec<Bytes>> = Vec::new();
    let mut writer = FrameWriter::default();
    'steps: for k in 0..sh.steps {
        // The pace barrier, answering NACKs meanwhile.
        let stop_at = loop {
            tokio::select! {
                biased;
                s = sync.wait_for(|s| s.stop_at <= k || k <= s.slowest() + LEAD) => match s {
                    Ok(s) => break s.stop_at,
                    Err(_) => break 'steps,
                },
                _ = control.readable() => serve(&control, &mut slots, &sh),
            }
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
                Time::MAX
            } else {
                sh.topo.round_end(k, r)
            };
            for slot in &mut slots {
                if r == 0 {
                    slot.node.handle_timeout(sh.topo.step_time(k));
                }
                slot.node.send_to(&mut slot.medium);
            }
            if sh.shared_air {
                sh.sync.send_modify(|s| s.posted[w] = window + 1);
                loop {
                    tokio::select! {
                        biased;
                        s = sync.wait_for(|s| s.all_posted(window)) => match s {
                            Ok(_) => break,
                            Err(_) => break 'steps,
                        },
                        _ = control.readable() => serve(&control, &mut slots, &sh),
                    }
                }
            }
            for slot in &mut slots {
                bundles.resize_with(slot.outs.len(), Vec::new);
                let i = slot.node.index();
                while let Some(tx) = slot.medium.poll_delivery(i, window_end) {
                    if let Ok(j) = slot.outs.binary_search(&tx.to) {
                        bundles[j].push(tx.bytes);
                    }
                }
                for (j, bundle) in bundles.iter_mut().enumerate().take(slot.outs.len()) {
                    let n = writer.pack(window, bundle.iter().map(|b| &b[..]));
                    bundle.clear();
                    let mut parts = slot.frames_for(j, keep);
                    parts.resize_with(n, Vec::new);
                    for (i, p) in parts.iter_mut().enumerate() {
                        p.clear();
                        p.extend_from_slice(writer.part(i));
                    }
                    for p in &parts {
                        if let Err(e) = slot.socket.send_to(p, sh.addrs[slot.outs[j]]).await {
                            tracing::warn!(node = slot.node.id(), "send_to failed: {e}");
                        }
                    }
                    slot.keep(j, window, parts, keep);
                }
            }
            for slot in &mut slots {
                slot.open(window, keep);
            }
            // Read the sockets of the nodes still waiting until each has its in-neighbours' frames of window k,
            // answering NACKs; when nothing has come for a while, ask again.
            let mut progress_at = Instant::now();
            let mut backoff = NACK_AFTER;
            let mut nack_at = progress_at + backoff;
            loop {
                let mut progressed = false;
                for slot in slots.iter_mut().filter(|s| !s.complete()) {
                    progressed |= slot.drain(&mut buf, &sh, window, true, true);
                }
                serve(&control, &mut slots, &sh);
                // One waiting node's socket is enough to wake on: each pass reads them all.
                let Some(first) = slots.iter().find(|s| !s.complete()).map(|s| s.socket.clone()) else {
                    break;
                };
                let now = Instant::now();
                if progressed {
                    (progress_at, backoff) = (now, NACK_AFTER);
                    nack_at = now + backoff;
                }
                let give_up_at = progress_at + sh.recv_timeout;
                let woken = [first, control.clone()];
                if tokio::time::timeout_at(give_up_at.min(nack_at), any_readable(&woken))
                    .await
                    .is_ok()
                {
                    continue;
                }
                if Instant::now() >= give_up_at {
                    let missing: u64 = slots
                        .iter_mut()
                        .filter(|s| !s.complete())
                        .map(|s| s.give_up(window))
                        .sum();
                    tracing::warn!(
                        step = k,
                        round = r,
                        "{} did not arrive within {:?}",
                        simnet_engine::scenario::count(missing as usize, "frame"),
                        sh.recv_timeout
                    );
                    socket_losses += missing;
                    break;
                }
                for slot in slots.iter().filter(|s| !s.complete()) {
                    slot.nack(window, &control, &sh);
                }
                backoff = (backoff * 2).min(NACK_MAX);
                nack_at = Instant::now() + backoff;
            }
            if !last {
                for slot in &mut slots {
                    slot.node.handle_timeout(sh.topo.round_end(k, r));
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
    // Answer NACKs until every worker is past its last step; what is still queued (foreign datagrams sent late in
    // the run) is read, so that it is counted.
    let end = done * sh.rounds as u64;
    drop(finished);
    loop {
        tokio::select! {
            biased;
            _ = sync.wait_for(|s| s.finished.iter().all(|f| *f)) => break,
            _ = control.readable() => serve(&control, &mut slots, &sh),
        }
    }
    for slot in &mut slots {
        slot.drain(&mut buf, &sh, end, false, false);
    }
    super::socket::record_drops(slots.iter_mut().map(|s| (&mut s.node, &*s.socket)));
    WorkerEnd {
        reports: slots.iter_mut().map(|s| s.node.report(&s.medium)).collect(),
        done,
        socket_losses,
        resent: slots.iter().map(|s| s.resent).sum(),
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
        finished: vec![false; workers],
        posted: vec![0; workers],
    });
    // One control socket per worker, where the NACKs for its nodes' frames go.
    let mut controls = Vec::with_capacity(workers);
    for _ in 0..workers {
        controls.push(UdpSocket::bind("127.0.0.1:0").await.map_err(NetError::Bind)?);
    }
    let mut worker_of = vec![0; n];
    for (w, block) in blocks.clone().into_iter().enumerate() {
        for i in block {
            worker_of[i] = w;
        }
    }
    let air = topo.radio_medium().map(|m| air::Air::new(Box::new(m)));
    let sh = Arc::new(Shared {
        index_of: addrs.iter().enumerate().map(|(i, a)| (*a, i)).collect(),
        controls: controls
            .iter()
            .map(|c| c.local_addr().map_err(NetError::Bind))
            .collect::<Result<_, _>>()?,
        worker_of,
        addrs,
        steps,
        rounds: topo.estimators().rounds,
        topo: topo.clone(),
        recv_timeout: opts.recv_timeout,
        sync: sync.clone(),
        shared_air: air.is_some(),
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
    // Every run seals under its own epoch: no nonce of an earlier run under the same key comes again.
    let epoch = simnet_engine::fresh::boot_epoch();
    let mut handles = Vec::with_capacity(workers);
    for ((w, block), control) in blocks.into_iter().enumerate().zip(controls) {
        let slots: Vec<Slot> = block
            .filter_map(|i| {
                let socket = sockets.next()?;
                let mut node = Node::new(topo.clone(), i, record);
                node.endpoint_mut().boot(epoch);
                let mut ins: Vec<usize> = topo.in_links(i).map(|l| l.from).collect();
                ins.sort_unstable();
                ins.dedup();
                let mut outs: Vec<usize> = topo.out_links(i).map(|l| l.to).collect();
                outs.sort_unstable();
                Some(Slot {
                    medium: crate::tap(
                        match &air {
                            Some(air) => Box::new(air.clone()) as Box<dyn Medium>,
                            None => Box::new(topo.pairwise_medium([i])),
                        },
                        &opts.capture,
                    ),
                    got: vec![0; ins.len()],
                    want: vec![None; ins.len()],
                    seen: vec![0; ins.len()],
                    seen_more: Default::default(),
                    gave_up: BTreeMap::new(),
                    kept: vec![VecDeque::new(); outs.len()],
                    resent: 0,
                    node,
                    socket: Arc::new(socket),
                    ins,
                    outs,
                    later: BTreeMap::new(),
                })
            })
            .collect();
        handles.push(tokio::spawn(worker(w, slots, control, sh.clone(), out_tx.clone())));
    }
    drop(out_tx);
    let mut reports = Vec::with_capacity(n);
    let mut done = u64::MAX;
    let (mut socket_losses, mut resent) = (0, 0);
    for (w, h) in handles.into_iter().enumerate() {
        let end = h.await.map_err(|_| NetError::WorkerLost(w))?;
        reports.extend(end.reports);
        done = done.min(end.done);
        socket_losses += end.socket_losses;
        resent += end.resent;
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
        frames_resent: resent,
        trace,
        lmi: Vec::new(),
        schedule: None,
    })
}
