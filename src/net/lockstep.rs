//! The virtual clock: lockstep. For step k the driver tells every node task to step; each sends, over its own socket,
//! every datagram the link layer delivers by the deadline t_k + D, in delivery order, and reports how many it sent to
//! whom. Each receiver then reads until it has as many datagrams from its peers' addresses as were sent to it (a
//! generous wall-clock timeout counts the rest as real socket losses) and runs its update. Datagrams due after the
//! deadline go out in a later window and arrive late. Same seed, same results.

use std::collections::{BTreeMap, HashMap};
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use tokio::net::UdpSocket;
use tokio::sync::{mpsc, watch};
use tokio::time::Instant;

use super::{recv, NetError, RunOptions};
use crate::node::{ImuRow, Node, NodeReport, StepEstimate, TraceRow};
use crate::scenario::Scenario;
use crate::sim::{observer_for, Clock, RunResults};
use crate::wire::MAX_DATAGRAM;

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

pub(super) async fn run(
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
