//! The wall clock: one worker thread per core owns a block of the nodes and their sockets, waits on all of them in
//! one poll set, and runs its nodes' timelines from a common start; delay and jitter are real waits. No task and no
//! timer per node: a worker sleeps until the next thing due — a step's start, a delayed datagram, a deadline — or
//! until a socket has something. Each step is fused once every worker has handed it in, and the run reports how far
//! the nodes fell behind their schedule.

use std::collections::HashMap;
use std::io::ErrorKind;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use mio::net::UdpSocket;
use mio::{Events, Interest, Poll, Token};
use tokio::sync::{mpsc, watch};

use super::collect::{blocks, observe, StepOut};
use super::{NetError, RunOptions};
use simnet_engine::medium::{Capture, Medium, PairwiseMedium};
use simnet_engine::node::{Node, NodeReport};
use simnet_engine::report::summary::Schedule;
use simnet_engine::scenario::Scenario;
use simnet_engine::sim::{Clock, RunResults};
use simnet_engine::time::Time;
use simnet_engine::wire::MAX_DATAGRAM;

/// The longest a worker waits before looking at the stop flag again.
const STOP_CHECK: Duration = Duration::from_millis(50);

/// Which steps the workers have started, and the step at which a shutdown stops them: one past the furthest any had
/// started, so that every worker ends after the same step.
struct Pace {
    started: Vec<u64>,
    stop_at: u64,
}

struct Shared {
    addrs: Vec<SocketAddr>,
    index_of: HashMap<SocketAddr, usize>,
    t0: Instant,
    steps: u64,
    dt: f64,
    topo: Arc<Scenario>,
    pace: Mutex<Pace>,
}

impl Shared {
    fn at(&self, t: Time) -> Instant {
        self.t0 + t.as_duration()
    }

    /// May worker `w` start step `k`? It is then recorded as started.
    fn start(&self, w: usize, k: u64) -> bool {
        let mut p = self.pace.lock().unwrap_or_else(|e| e.into_inner());
        if k >= p.stop_at {
            return false;
        }
        p.started[w] = p.started[w].max(k + 1);
        true
    }

    fn stopping_at(&self) -> u64 {
        self.pace.lock().unwrap_or_else(|e| e.into_inner()).stop_at
    }

    fn stop(&self) {
        let mut p = self.pace.lock().unwrap_or_else(|e| e.into_inner());
        p.stop_at = p.stop_at.min(p.started.iter().copied().max().unwrap_or(0));
    }
}

struct WorkerEnd {
    reports: Vec<NodeReport>,
    done: u64,
    schedule: Schedule,
}

struct Slot {
    node: Node,
    /// The node's out-links: what becomes of what it sends.
    medium: Capture<PairwiseMedium>,
    socket: UdpSocket,
}

/// Read everything queued on `slot`'s socket into its node (the poll set is edge-triggered: drain to the end).
fn drain(slot: &mut Slot, buf: &mut [u8], index_of: &HashMap<SocketAddr, usize>) {
    // A UDP socket reports some errors per datagram (an ICMP "port unreachable" from a peer that has gone): read
    // on past them, but not forever.
    let mut errors = 0;
    loop {
        match slot.socket.recv_from(buf) {
            Ok((len, from)) => {
                slot.node.handle_datagram(index_of.get(&from).copied(), &buf[..len]);
            }
            Err(e) if e.kind() == ErrorKind::WouldBlock => return,
            Err(e) if e.kind() == ErrorKind::Interrupted => {}
            Err(e) => {
                tracing::warn!(node = slot.node.id(), "recv_from failed: {e}");
                errors += 1;
                if errors >= 64 {
                    return;
                }
            }
        }
    }
}

fn worker(w: usize, mut slots: Vec<Slot>, sh: Arc<Shared>, out: mpsc::UnboundedSender<StepOut>) -> WorkerEnd {
    let mut schedule = Schedule::default();
    let mut done = 0;
    let mut buf = vec![0u8; MAX_DATAGRAM + 1];
    let mut events = Events::with_capacity(1024);
    let poll = Poll::new().and_then(|poll| {
        for (i, s) in slots.iter_mut().enumerate() {
            poll.registry().register(&mut s.socket, Token(i), Interest::READABLE)?;
        }
        Ok(poll)
    });
    let mut poll = match poll {
        Ok(p) => p,
        Err(e) => {
            tracing::error!(worker = w, "cannot poll the nodes' sockets: {e}");
            return WorkerEnd {
                reports: slots.iter_mut().map(|s| s.node.report(&s.medium)).collect(),
                done,
                schedule,
            };
        }
    };
    'steps: for k in 0..sh.steps {
        let start = sh.at(sh.topo.step_time(k));
        // Sleep to the step's start; datagrams that come meanwhile wait in the sockets, as they would for a node.
        loop {
            if sh.stopping_at() <= k {
                break 'steps;
            }
            let now = Instant::now();
            if now >= start {
                break;
            }
            std::thread::sleep((start - now).min(STOP_CHECK));
        }
        if !sh.start(w, k) {
            break;
        }
        for slot in &mut slots {
            schedule.record(Instant::now().saturating_duration_since(start).as_secs_f64(), sh.dt);
            slot.node.handle_timeout(sh.topo.step_time(k));
        }
        // What the nodes' timelines hold next (each round's close, then the deadline that closes the step), waited
        // for while the medium's datagrams go out and the sockets are drained.
        let mut step = StepOut::new(k);
        while let Some(due) = slots.iter().filter_map(|s| s.node.poll_timeout()).min() {
            let close = sh.at(due);
            loop {
                // Send whatever is due now; the next thing due bounds the wait.
                let now = Instant::now();
                let now_sim = Time::since_start(now.saturating_duration_since(sh.t0));
                let mut next = close;
                for slot in &mut slots {
                    slot.node.send_to(&mut slot.medium);
                    let i = slot.node.index();
                    while let Some(tx) = slot.medium.poll_delivery(i, now_sim) {
                        match slot.socket.send_to(&tx.bytes, sh.addrs[tx.to]) {
                            Ok(_) => {}
                            Err(e) => tracing::warn!(node = slot.node.id(), "send_to failed: {e}"),
                        }
                    }
                    if let Some(t) = slot.medium.poll_timeout(i) {
                        next = next.min(sh.at(t));
                    }
                }
                if now >= close {
                    break;
                }
                let wait = next.saturating_duration_since(Instant::now()).min(STOP_CHECK);
                match poll.poll(&mut events, Some(wait)) {
                    Ok(()) => {}
                    Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                    Err(e) => {
                        tracing::error!(worker = w, "poll failed: {e}");
                        break 'steps;
                    }
                }
                for ev in events.iter() {
                    if let Some(slot) = slots.get_mut(ev.token().0) {
                        drain(slot, &mut buf, &sh.index_of);
                    }
                }
            }
            let mut closed = false;
            for slot in &mut slots {
                if let Some(c) = slot.node.handle_timeout(due) {
                    step.take(&mut slot.node, Some(c));
                    closed = true;
                }
            }
            if closed {
                break;
            }
        }
        if out.send(step).is_err() {
            break;
        }
        done = k + 1;
    }
    super::socket::record_drops(slots.iter_mut().map(|s| (&mut s.node, &s.socket)));
    WorkerEnd {
        reports: slots.iter_mut().map(|s| s.node.report(&s.medium)).collect(),
        done,
        schedule,
    }
}

pub(super) async fn run(
    topo: Arc<Scenario>,
    sockets: Vec<tokio::net::UdpSocket>,
    addrs: Vec<SocketAddr>,
    opts: &mut RunOptions,
    mut stop: watch::Receiver<bool>,
) -> Result<RunResults, NetError> {
    let n = topo.nodes().len();
    let blocks = blocks(n);
    let workers = blocks.len();
    let steps = topo.sim().steps();
    let sh = Arc::new(Shared {
        index_of: addrs.iter().enumerate().map(|(i, a)| (*a, i)).collect(),
        addrs,
        // A short lead so that every worker is waiting before step 0.
        t0: Instant::now() + Duration::from_millis(50),
        steps,
        dt: topo.sim().dt(),
        topo: topo.clone(),
        pace: Mutex::new(Pace {
            started: vec![0; workers],
            stop_at: u64::MAX,
        }),
    });
    let stopper = {
        let sh = sh.clone();
        tokio::spawn(async move {
            if stop.wait_for(|s| *s).await.is_ok() {
                sh.stop();
            }
        })
    };
    let (out_tx, out_rx) = mpsc::unbounded_channel();
    let record = opts.trace.is_some();
    let observer = tokio::spawn(observe(
        topo.clone(),
        workers,
        opts.trace.take(),
        opts.progress.clone(),
        |_| {},
        out_rx,
    ));
    let mut sockets = sockets.into_iter();
    // Every run seals under its own epoch: no nonce of an earlier run under the same key comes again.
    let epoch = simnet_engine::fresh::boot_epoch();
    let mut handles = Vec::with_capacity(workers);
    for (w, block) in blocks.into_iter().enumerate() {
        let mut slots = Vec::with_capacity(block.len());
        for i in block {
            let Some(socket) = sockets.next() else { break };
            // The socket leaves tokio's reactor for this worker's poll set (it stays non-blocking).
            let socket = UdpSocket::from_std(socket.into_std().map_err(NetError::Bind)?);
            let mut node = Node::new(topo.clone(), i, record);
            node.endpoint_mut().boot(epoch);
            slots.push(Slot {
                node,
                medium: crate::tap(topo.pairwise_medium([i]), &opts.capture),
                socket,
            });
        }
        let (sh, out) = (sh.clone(), out_tx.clone());
        handles.push(tokio::task::spawn_blocking(move || worker(w, slots, sh, out)));
    }
    drop(out_tx);
    let mut reports = Vec::with_capacity(n);
    let mut done = u64::MAX;
    let mut schedule = Schedule::default();
    for (w, h) in handles.into_iter().enumerate() {
        let end = h.await.map_err(|_| NetError::WorkerLost(w))?;
        reports.extend(end.reports);
        done = done.min(end.done);
        schedule.merge(&end.schedule);
    }
    stopper.abort();
    reports.sort_by_key(|r| r.index);
    let (observer, trace) = observer.await.map_err(|_| NetError::NoReply)?;
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
        frames_resent: 0,
        trace,
        lmi: Vec::new(),
        schedule: Some(schedule),
    })
}
