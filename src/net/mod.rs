//! The only I/O: one tokio task and one UDP socket (127.0.0.1, port 0) per node, the two clocks, and shutdown.
//!
//! - **virtual** (default): lockstep. For step k the driver tells every node task to step; each sends, over its own
//!   socket, every datagram the link layer delivers by the deadline t_k + D, in delivery order, and reports how many
//!   it sent to whom. Each receiver then reads until it has as many datagrams from its peers' addresses as were sent
//!   to it (a generous wall-clock timeout counts the rest as real socket losses) and runs its update. Datagrams due
//!   after the deadline go out in a later window and arrive late. Same seed, same results.
//! - **realtime**: every task paces itself on the wall clock from a common start; delay and jitter are real waits.

use std::collections::{BTreeMap, HashMap};
use std::future::Future;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use tokio::net::UdpSocket;
use tokio::sync::{mpsc, oneshot, watch};
use tokio::time::Instant;

use crate::node::{ImuRow, TraceRow};
use crate::node::{Node, NodeReport, StepEstimate};
use crate::observe::fusion::Observer;
use crate::report::trace::TraceWriter;
use crate::scenario::Scenario;
use crate::sim::observer_for;
pub use crate::sim::{Clock, Progress, RunResults};
use crate::wire::MAX_DATAGRAM;

pub mod host;

#[derive(Debug, thiserror::Error)]
pub enum NetError {
    #[error("cannot bind a UDP socket on 127.0.0.1: {0}")]
    Bind(std::io::Error),
    #[error("node task {0} stopped unexpectedly")]
    TaskLost(usize),
    #[error("a node task stopped before it replied")]
    NoReply,
    #[error(transparent)]
    Scenario(#[from] crate::scenario::ScenarioError),
}

pub struct RunOptions {
    pub clock: Clock,
    /// Takes the per-step rows for `trace.csv` and the plots as the run goes (none: no rows are made).
    pub trace: Option<TraceWriter>,
    /// How long a virtual step waits for datagrams the link layer delivered before counting them as socket losses.
    pub recv_timeout: Duration,
    pub progress: Option<Progress>,
    /// Receives the nodes' socket addresses once bound (tests use it to send foreign datagrams).
    pub on_bound: Option<oneshot::Sender<Vec<SocketAddr>>>,
}

impl Default for RunOptions {
    fn default() -> Self {
        RunOptions {
            clock: Clock::Virtual,
            trace: None,
            recv_timeout: Duration::from_secs(2),
            progress: None,
            on_bound: None,
        }
    }
}

/// Run a whole topology in this process. `shutdown` ends the run early (the results so far are kept).
pub async fn run(
    topo: Arc<Scenario>,
    mut opts: RunOptions,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> Result<RunResults, NetError> {
    topo.check_recordings()?;
    let n = topo.nodes().len();
    let mut sockets = Vec::with_capacity(n);
    for _ in 0..n {
        sockets.push(UdpSocket::bind("127.0.0.1:0").await.map_err(NetError::Bind)?);
    }
    let addrs: Vec<SocketAddr> = sockets
        .iter()
        .map(|s| s.local_addr().map_err(NetError::Bind))
        .collect::<Result<_, _>>()?;
    if let Some(tx) = opts.on_bound.take() {
        let _ = tx.send(addrs.clone());
    }
    let (stop_tx, stop_rx) = watch::channel(false);
    tokio::spawn(async move {
        shutdown.await;
        let _ = stop_tx.send(true);
    });
    let started = std::time::Instant::now();
    let mut out = match opts.clock {
        Clock::Virtual => run_virtual(topo, sockets, addrs, &mut opts, stop_rx).await?,
        // Nodes on their own wall clocks, here in one process: the realtime run.
        Clock::Realtime | Clock::MultiHost => run_realtime(topo, sockets, addrs, &mut opts, stop_rx).await?,
    };
    out.wall_s = started.elapsed().as_secs_f64();
    Ok(out)
}

enum Cmd {
    Step { k: u64, window_end: f64 },
    Collect { k: u64, expect: u64 },
    Finish,
}

enum Reply {
    Sent {
        counts: Vec<(usize, u64)>,
    },
    Closed {
        estimate: Option<StepEstimate>,
        timed_out: u64,
        rows: Vec<TraceRow>,
        /// The node's id and its IMU rows of the step.
        imu: (u32, Vec<ImuRow>),
    },
    Report(Box<NodeReport>),
}

/// Receive one datagram; the sender's node index if its address is one of ours.
pub(crate) async fn recv(
    socket: &UdpSocket,
    buf: &mut [u8],
    index_of: &HashMap<SocketAddr, usize>,
) -> std::io::Result<(usize, Option<usize>)> {
    let (len, from) = socket.recv_from(buf).await?;
    Ok((len, index_of.get(&from).copied()))
}

async fn virtual_task(
    mut node: Node,
    socket: UdpSocket,
    addrs: Arc<Vec<SocketAddr>>,
    recv_timeout: Duration,
    mut cmds: mpsc::Receiver<Cmd>,
    replies: mpsc::Sender<Reply>,
) {
    let index_of: HashMap<SocketAddr, usize> = addrs.iter().enumerate().map(|(i, a)| (*a, i)).collect();
    let mut buf = vec![0u8; MAX_DATAGRAM + 1];
    // Datagrams from our peers' addresses counted so far (the driver's expectation is cumulative too).
    let mut from_peers: u64 = 0;
    while let Some(cmd) = cmds.recv().await {
        let reply = match cmd {
            Cmd::Step { k, window_end } => {
                crate::sim::begin_step(&mut node, k);
                let mut counts: BTreeMap<usize, u64> = BTreeMap::new();
                while let Some(tx) = node.poll_transmit(window_end) {
                    match socket.send_to(&tx.bytes, addrs[tx.to]).await {
                        Ok(_) => *counts.entry(tx.to).or_default() += 1,
                        Err(e) => tracing::warn!(node = node.id(), "send_to failed: {e}"),
                    }
                }
                Reply::Sent {
                    counts: counts.into_iter().collect(),
                }
            }
            Cmd::Collect { k, expect } => {
                let deadline = Instant::now() + recv_timeout;
                let mut timed_out = 0;
                while from_peers < expect {
                    match tokio::time::timeout_at(deadline, recv(&socket, &mut buf, &index_of)).await {
                        Ok(Ok((len, from))) => {
                            if from.is_some() {
                                from_peers += 1;
                            }
                            node.handle_datagram(from, &buf[..len]);
                        }
                        Ok(Err(e)) => tracing::warn!(node = node.id(), "recv_from failed: {e}"),
                        Err(_) => {
                            timed_out = expect - from_peers;
                            tracing::warn!(
                                node = node.id(),
                                step = k,
                                "{} did not arrive within {recv_timeout:?}",
                                crate::scenario::count(timed_out as usize, "datagram")
                            );
                            from_peers = expect;
                        }
                    }
                }
                // Foreign datagrams that are already queued are read too, so they are counted.
                while let Ok((len, from)) = socket.try_recv_from(&mut buf) {
                    let from = index_of.get(&from).copied();
                    if from.is_some() {
                        from_peers += 1;
                    }
                    node.handle_datagram(from, &buf[..len]);
                }
                let estimate = node.handle_deadline(k);
                Reply::Closed {
                    estimate,
                    timed_out,
                    rows: node.take_trace(),
                    imu: (node.id(), node.take_imu()),
                }
            }
            Cmd::Finish => {
                let _ = replies.send(Reply::Report(Box::new(node.report()))).await;
                return;
            }
        };
        if replies.send(reply).await.is_err() {
            return;
        }
    }
}

async fn run_virtual(
    topo: Arc<Scenario>,
    sockets: Vec<UdpSocket>,
    addrs: Vec<SocketAddr>,
    opts: &mut RunOptions,
    stop: watch::Receiver<bool>,
) -> Result<RunResults, NetError> {
    let n = topo.nodes().len();
    let addrs_arc = Arc::new(addrs.clone());
    let (reply_tx, mut reply_rx) = mpsc::channel::<Reply>(n.max(1) * 2);
    let mut cmd_txs = Vec::with_capacity(n);
    let mut handles = Vec::with_capacity(n);
    for (i, socket) in sockets.into_iter().enumerate() {
        let (tx, rx) = mpsc::channel(2);
        let node = Node::new(topo.clone(), i, opts.trace.is_some());
        handles.push(tokio::spawn(virtual_task(
            node,
            socket,
            addrs_arc.clone(),
            opts.recv_timeout,
            rx,
            reply_tx.clone(),
        )));
        cmd_txs.push(tx);
    }
    drop(reply_tx);
    let steps = topo.sim().steps();
    let dt = topo.sim().dt();
    let mut expected = vec![0u64; n];
    let mut trace = opts.trace.take();
    let mut observer = observer_for(&topo, trace.is_some());
    let mut socket_losses = 0;
    let mut done = 0;
    let mut interrupted = false;
    for k in 0..steps {
        if *stop.borrow() {
            interrupted = true;
            break;
        }
        // The last window also flushes everything still queued, so late datagrams are counted as late.
        let window_end = if k + 1 == steps {
            f64::INFINITY
        } else {
            k as f64 * dt + topo.sim().deadline_s
        };
        for (i, tx) in cmd_txs.iter().enumerate() {
            tx.send(Cmd::Step { k, window_end })
                .await
                .map_err(|_| NetError::TaskLost(i))?;
        }
        for _ in 0..n {
            match reply_rx.recv().await {
                Some(Reply::Sent { counts, .. }) => {
                    for (to, c) in counts {
                        expected[to] += c;
                    }
                }
                _ => return Err(NetError::NoReply),
            }
        }
        for (i, tx) in cmd_txs.iter().enumerate() {
            tx.send(Cmd::Collect { k, expect: expected[i] })
                .await
                .map_err(|_| NetError::TaskLost(i))?;
        }
        let mut estimates = Vec::new();
        let mut step_rows = Vec::new();
        for _ in 0..n {
            match reply_rx.recv().await {
                Some(Reply::Closed {
                    estimate,
                    timed_out,
                    mut rows,
                    imu,
                }) => {
                    socket_losses += timed_out;
                    estimates.extend(estimate);
                    step_rows.append(&mut rows);
                    if let Some(t) = trace.as_mut() {
                        t.imu(imu.0, &imu.1);
                    }
                }
                _ => return Err(NetError::NoReply),
            }
        }
        observer.push(estimates);
        if let Some(t) = trace.as_mut() {
            step_rows.sort_by_key(|r| (r.node, !r.networked));
            t.rows(step_rows);
            t.fused(observer.drain_rows());
        }
        done = k + 1;
        if let Some(p) = &opts.progress {
            p(done, steps);
        }
    }
    let reports = finish(&cmd_txs, &mut reply_rx, n).await?;
    for h in handles {
        let _ = h.await;
    }
    observer.finish();
    if let Some(t) = trace.as_mut() {
        t.fused(observer.drain_rows());
    }
    Ok(RunResults {
        scenario: topo,
        clock: Clock::Virtual,
        reports,
        observer: Some(observer),
        steps_done: done,
        interrupted,
        wall_s: 0.0,
        socket_losses,
        trace,
        lmi: Vec::new(),
    })
}

async fn finish(
    cmd_txs: &[mpsc::Sender<Cmd>],
    reply_rx: &mut mpsc::Receiver<Reply>,
    n: usize,
) -> Result<Vec<NodeReport>, NetError> {
    for (i, tx) in cmd_txs.iter().enumerate() {
        tx.send(Cmd::Finish).await.map_err(|_| NetError::TaskLost(i))?;
    }
    let mut reports = Vec::with_capacity(n);
    while reports.len() < n {
        match reply_rx.recv().await {
            Some(Reply::Report(r)) => reports.push(*r),
            Some(_) => {}
            None => return Err(NetError::NoReply),
        }
    }
    reports.sort_by_key(|r| r.index);
    Ok(reports)
}

/// What a realtime task hands the driver at each step's deadline.
struct StepOut {
    step: u64,
    estimate: Option<StepEstimate>,
    rows: Vec<TraceRow>,
    imu: (u32, Vec<ImuRow>),
}

/// Realtime: each node task runs its own timeline on the wall clock from the common start `t0`.
#[allow(clippy::too_many_arguments)]
async fn realtime_task(
    mut node: Node,
    socket: UdpSocket,
    addrs: Arc<Vec<SocketAddr>>,
    t0: Instant,
    steps: u64,
    dt: f64,
    deadline: f64,
    mut stop: watch::Receiver<bool>,
    estimates: mpsc::UnboundedSender<StepOut>,
    progress: Option<Progress>,
) -> (NodeReport, u64) {
    let index_of: HashMap<SocketAddr, usize> = addrs.iter().enumerate().map(|(i, a)| (*a, i)).collect();
    let mut buf = vec![0u8; MAX_DATAGRAM + 1];
    let at = |s: f64| t0 + Duration::from_secs_f64(s.max(0.0));
    let mut done = 0;
    'steps: for k in 0..steps {
        let t_k = k as f64 * dt;
        tokio::select! {
            _ = tokio::time::sleep_until(at(t_k)) => {}
            _ = stop.changed() => break 'steps,
        }
        crate::sim::begin_step(&mut node, k);
        let close = at(t_k + deadline);
        loop {
            // Send whatever is due now.
            let now_sim = (Instant::now() - t0).as_secs_f64();
            while let Some(tx) = node.poll_transmit(now_sim) {
                if let Err(e) = socket.send_to(&tx.bytes, addrs[tx.to]).await {
                    tracing::warn!(node = node.id(), "send_to failed: {e}");
                }
            }
            let next_tx = node.poll_timeout().map(at).unwrap_or(close).min(close);
            tokio::select! {
                r = recv(&socket, &mut buf, &index_of) => match r {
                    Ok((len, from)) => {
                        node.handle_datagram(from, &buf[..len]);
                    }
                    Err(e) => tracing::warn!(node = node.id(), "recv_from failed: {e}"),
                },
                _ = tokio::time::sleep_until(next_tx) => {
                    if Instant::now() >= close {
                        break;
                    }
                }
                _ = stop.changed() => break 'steps,
            }
        }
        let estimate = node.handle_deadline(k);
        let _ = estimates.send(StepOut {
            step: k,
            estimate,
            rows: node.take_trace(),
            imu: (node.id(), node.take_imu()),
        });
        done = k + 1;
        if node.index() == 0 {
            if let Some(p) = &progress {
                p(done, steps);
            }
        }
    }
    (node.report(), done)
}

async fn run_realtime(
    topo: Arc<Scenario>,
    sockets: Vec<UdpSocket>,
    addrs: Vec<SocketAddr>,
    opts: &mut RunOptions,
    stop: watch::Receiver<bool>,
) -> Result<RunResults, NetError> {
    let n = topo.nodes().len();
    let addrs_arc = Arc::new(addrs.clone());
    let steps = topo.sim().steps();
    let (est_tx, mut est_rx) = mpsc::unbounded_channel();
    // A short lead so that every task is waiting before step 0.
    let t0 = Instant::now() + Duration::from_millis(50);
    let mut handles = Vec::with_capacity(n);
    for (i, socket) in sockets.into_iter().enumerate() {
        let node = Node::new(topo.clone(), i, opts.trace.is_some());
        handles.push(tokio::spawn(realtime_task(
            node,
            socket,
            addrs_arc.clone(),
            t0,
            steps,
            topo.sim().dt(),
            topo.sim().deadline_s,
            stop.clone(),
            est_tx.clone(),
            opts.progress.clone(),
        )));
    }
    drop(est_tx);
    let mut trace = opts.trace.take();
    let mut observer = observer_for(&topo, trace.is_some());
    // Steps are fused (and their rows written) in order once every task is well past them: the tasks share one
    // wall clock, so a step this far behind the newest has all its estimates.
    let lag = (2.0 * topo.sim().rate_hz).ceil().max(100.0) as usize;
    let mut by_step: BTreeMap<u64, Vec<StepOut>> = BTreeMap::new();
    let close = |outs: Vec<StepOut>, observer: &mut Observer, trace: &mut Option<TraceWriter>| {
        let mut rows = Vec::new();
        let mut estimates = Vec::new();
        for o in outs {
            estimates.extend(o.estimate);
            rows.extend(o.rows);
            if let Some(t) = trace.as_mut() {
                t.imu(o.imu.0, &o.imu.1);
            }
        }
        observer.push(estimates);
        if let Some(t) = trace.as_mut() {
            rows.sort_by_key(|r| (r.node, !r.networked));
            t.rows(rows);
            t.fused(observer.drain_rows());
        }
    };
    // The newest step already fused: the observer takes steps in order only (its median streams).
    let mut fused_up_to: Option<u64> = None;
    while let Some(o) = est_rx.recv().await {
        if fused_up_to.is_some_and(|f| o.step <= f) {
            // A task stalled for longer than the lag: its rows still go to the trace, its estimate misses the
            // fusion of a step already closed.
            tracing::warn!(
                step = o.step,
                "estimate arrived after its step was fused: left out of the fusion"
            );
            if let Some(t) = trace.as_mut() {
                t.rows(o.rows);
                t.imu(o.imu.0, &o.imu.1);
            }
            continue;
        }
        by_step.entry(o.step).or_default().push(o);
        while by_step.len() > lag {
            let Some((step, outs)) = by_step.pop_first() else { break };
            fused_up_to = Some(step);
            close(outs, &mut observer, &mut trace);
        }
    }
    while let Some((_, outs)) = by_step.pop_first() {
        close(outs, &mut observer, &mut trace);
    }
    let mut reports = Vec::with_capacity(n);
    let mut done = u64::MAX;
    for (i, h) in handles.into_iter().enumerate() {
        let (r, d) = h.await.map_err(|_| NetError::TaskLost(i))?;
        done = done.min(d);
        reports.push(r);
    }
    observer.finish();
    if let Some(t) = trace.as_mut() {
        t.fused(observer.drain_rows());
    }
    let done = if n == 0 { 0 } else { done };
    Ok(RunResults {
        scenario: topo,
        clock: Clock::Realtime,
        reports,
        observer: Some(observer),
        steps_done: done,
        interrupted: done < steps,
        wall_s: 0.0,
        socket_losses: 0,
        trace,
        lmi: Vec::new(),
    })
}
