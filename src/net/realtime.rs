//! The wall clock: every node task paces itself from a common start; delay and jitter are real waits. The driver
//! fuses each step as soon as every task has handed it in (or, for a straggler, once the others are well past it),
//! and reports how far the tasks fell behind their schedule.

use std::collections::{BTreeMap, HashMap};
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use tokio::net::UdpSocket;
use tokio::sync::{mpsc, watch};
use tokio::time::Instant;

use super::{recv, NetError, RunOptions};
use crate::node::{ImuRow, Node, NodeReport, StepEstimate, TraceRow};
use crate::observe::fusion::Observer;
use crate::report::summary::Schedule;
use crate::report::trace::TraceWriter;
use crate::scenario::Scenario;
use crate::sim::{observer_for, Clock, Progress, RunResults};
use crate::wire::MAX_DATAGRAM;

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
    index_of: Arc<HashMap<SocketAddr, usize>>,
    t0: Instant,
    steps: u64,
    dt: f64,
    deadline: f64,
    mut stop: watch::Receiver<bool>,
    estimates: mpsc::UnboundedSender<StepOut>,
    progress: Option<Progress>,
) -> (NodeReport, u64, Schedule) {
    let mut schedule = Schedule::default();
    let mut buf = vec![0u8; MAX_DATAGRAM + 1];
    let at = |s: f64| t0 + Duration::from_secs_f64(s.max(0.0));
    let mut done = 0;
    'steps: for k in 0..steps {
        let t_k = k as f64 * dt;
        tokio::select! {
            _ = tokio::time::sleep_until(at(t_k)) => {}
            _ = stop.changed() => break 'steps,
        }
        schedule.record(Instant::now().saturating_duration_since(at(t_k)).as_secs_f64(), dt);
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
    (node.report(), done, schedule)
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
    let index_of: Arc<HashMap<SocketAddr, usize>> = Arc::new(addrs.iter().enumerate().map(|(i, a)| (*a, i)).collect());
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
            index_of.clone(),
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
    // Steps are fused (and their rows written) in order, each once every task has handed it in, or else once the
    // tasks are well past it: they share one wall clock, so a step this far behind the newest has all it will get.
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
        // A step is fused as soon as every task has handed it in; one the lag has passed, without the stragglers.
        while by_step
            .first_key_value()
            .is_some_and(|(_, outs)| outs.len() == n || by_step.len() > lag)
        {
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
    let mut schedule = Schedule::default();
    for (i, h) in handles.into_iter().enumerate() {
        let (r, d, s) = h.await.map_err(|_| NetError::TaskLost(i))?;
        done = done.min(d);
        schedule.merge(&s);
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
        schedule: Some(schedule),
    })
}
