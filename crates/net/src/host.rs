//! One node per process (`simnet node`): the node binds its own address, finds its neighbours by name, and paces
//! itself by its own monotonic clock. No clock is shared between hosts: steps follow the step numbers carried by the
//! datagrams.
//!
//! - **Handshake.** The node sends a hello to every neighbour every 100 ms, carrying its boot epoch and echoing the
//!   neighbour's (answered at once when a neighbour has not heard this boot). Only a hello that echoes this node's
//!   own boot counts — nothing recorded in an earlier run carries it: if such a hello reports a running step, the
//!   network is already up and the node joins at the step after, with fresh filters. Otherwise it starts step 0
//!   once every neighbour has sent one, after a short grace so that they hear it too; after `handshake_timeout` it
//!   starts alone. A neighbour's measurements and rounds are used only from the boot such a hello came from.
//! - **Catch-up.** Whenever a neighbour is ahead, the node runs the missing steps at once (its own measurements only;
//!   their datagrams still go out and arrive late) and continues from the neighbour's step.
//! - **Rounds.** With distributed estimators, round r of L closes at its sub-deadline t_k + D(r+1)/L on this host's
//!   clock; a catch-up closes them all at once.
//! - **Phase lock.** Each arrival of a step-j measurement is compared with the local start of step j; the local
//!   schedule moves by a fifth of the mean offset, so that neighbours' step boundaries converge.

use std::collections::HashMap;
use std::future::Future;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use tokio::net::UdpSocket;
use tokio::sync::watch;
use tokio::time::Instant;

use super::{NetError, Progress};
use simnet_engine::medium::Medium;
use simnet_engine::node::{Node, NodeReport, StepEstimate};
use simnet_engine::scenario::Scenario;
use simnet_engine::time::Time;
use simnet_engine::wire::MAX_DATAGRAM;

pub struct HostConfig {
    pub bind: SocketAddr,
    /// "host:port" of each neighbour, by node index.
    pub peers: HashMap<usize, String>,
    pub handshake_timeout: Duration,
    pub record_trace: bool,
    pub progress: Option<Progress>,
    /// This boot's epoch (its time with random low bits): larger than every earlier boot's, so that an
    /// authenticated node never seals two datagrams under one nonce across restarts.
    pub boot_epoch: u64,
}

pub struct HostOutput {
    pub report: NodeReport,
    /// The networked estimate of every step run (kept when recording, for fusion by `simnet collect`).
    pub estimates: Vec<StepEstimate>,
    pub steps_done: u64,
    pub interrupted: bool,
    pub wall_s: f64,
    /// How far the steps run on this host's clock fell behind their schedule.
    pub schedule: simnet_engine::report::summary::Schedule,
    /// The run the node ended on ([`simnet_engine::node::Endpoint::run_id`]).
    pub run: u64,
    /// Whether any neighbour's hello opened here (fresh or not): with none, and tags failing, the keys differ.
    pub heard_a_hello: bool,
}

/// A `--peer ID=HOST:PORT` that names no neighbour.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PeerError {
    #[error("--peer {0}=…: no [[node]] has id {0}")]
    Unknown(u32),
    #[error("--peer {id}=…: node {id} is not a neighbour of node {of}")]
    NotNeighbour { id: u32, of: u32 },
}

/// Where node `index` finds its neighbours: each at its `addr` (or `node<ID>:7000`), unless `given` (id →
/// "host:port") says otherwise. The node's own id is passed over, so that every node can take one shared list; any
/// other id that is not a neighbour is an error naming it.
pub fn neighbour_addrs(
    topo: &Scenario,
    index: usize,
    given: &[(u32, String)],
) -> Result<HashMap<usize, String>, PeerError> {
    let mut peers: HashMap<usize, String> = HashMap::new();
    for l in topo.links() {
        for j in [l.from, l.to] {
            if (l.from == index || l.to == index) && j != index {
                peers.insert(j, simnet_engine::compose::node_addr(topo, j));
            }
        }
    }
    for (id, addr) in given {
        let j = topo.index_of(*id).ok_or(PeerError::Unknown(*id))?;
        if j == index {
            continue;
        }
        if !peers.contains_key(&j) {
            return Err(PeerError::NotNeighbour {
                id: *id,
                of: topo.nodes()[index].id,
            });
        }
        peers.insert(j, addr.clone());
    }
    Ok(peers)
}

impl HostOutput {
    /// This node's part of a multi-host run (`node-ID.json`): its summary with the counters `simnet collect` joins
    /// into per-link figures. One end of a link cannot tell its loss, so the part carries no link table.
    pub fn part(&self, topo: &Scenario, index: usize) -> simnet_engine::report::summary::Summary {
        let mut s = simnet_engine::report::summary::Summary::build(
            topo,
            simnet_engine::sim::Clock::Realtime,
            std::slice::from_ref(&self.report),
            None,
            self.steps_done,
            self.interrupted,
            self.wall_s,
            0,
        );
        let id_of = |j: usize| topo.nodes()[j].id;
        s.part = Some(simnet_engine::report::parts::PartInfo {
            node: topo.nodes()[index].id,
            first_step: self.report.counters.first_step,
            steps_done: self.steps_done,
            links_out: self.report.links_out.iter().map(|(to, c)| (id_of(*to), *c)).collect(),
            rx: topo
                .in_links(index)
                .map(|l| (id_of(l.from), self.report.rx.get(l.from)))
                .collect(),
            fusion: topo.model().get().fusion(),
            run: Some(self.run),
        });
        s.links.clear();
        s.transport.schedule = Some(self.schedule);
        // This node's figures of each estimator; `simnet collect` joins the nodes.
        s.estimators =
            simnet_engine::report::summary::EstimatorSummary::of_run(topo, std::slice::from_ref(&self.report), None);
        s
    }
}

const HELLO_PERIOD: Duration = Duration::from_millis(100);
const GRACE: Duration = Duration::from_millis(300);
/// The least time between two hellos sent at once in answer to a neighbour that has not heard this boot.
const REPLY_GAP: Duration = Duration::from_millis(50);
/// How long a probe of a neighbour's new address waits for its answer before another may be sent.
const PROBE_RENEW: Duration = Duration::from_secs(1);
/// Fraction of the measured phase offset corrected per step.
const PHASE_GAIN: f64 = 0.2;

/// Neighbour addresses: resolved by name in a task of their own ([`resolver`]: containers come up in any order, and
/// a restarted one may come back with another address), and, in an authenticated run, moved to a new address only
/// when a hello from there answers a probe sent there — never on a datagram alone, which anyone who captured it can
/// send again from anywhere.
struct Peers {
    names: HashMap<usize, String>,
    addrs: HashMap<usize, SocketAddr>,
    resolved: tokio::sync::mpsc::UnboundedReceiver<(usize, SocketAddr)>,
    /// By neighbour: the address a probe went to, the probe, and when.
    probes: HashMap<usize, (SocketAddr, u64, Instant)>,
    /// Probes to send: (address, bytes).
    outbox: Vec<(SocketAddr, bytes::Bytes)>,
}

/// Resolve every neighbour's name off the node's loop (a lookup can take seconds where a name is gone): a missing
/// one every 500 ms, all of them every 5 s; only changes are sent. Ends when the node drops its end.
fn resolver(names: HashMap<usize, String>) -> tokio::sync::mpsc::UnboundedReceiver<(usize, SocketAddr)> {
    let (tx, rx) = tokio::sync::mpsc::unbounded_channel();
    tokio::spawn(async move {
        let mut known: HashMap<usize, SocketAddr> = HashMap::new();
        let mut last_full: Option<Instant> = None;
        loop {
            let all = last_full.is_none_or(|t| t.elapsed() >= Duration::from_secs(5));
            if all {
                last_full = Some(Instant::now());
            }
            for (j, name) in &names {
                if known.contains_key(j) && !all {
                    continue;
                }
                let found = tokio::time::timeout(Duration::from_secs(2), tokio::net::lookup_host(name.as_str())).await;
                match found {
                    Ok(Ok(mut it)) => {
                        if let Some(a) = it.find(|a| a.is_ipv4()) {
                            if known.insert(*j, a) != Some(a) {
                                tracing::info!(peer = j, %a, "resolved {name}");
                                if tx.send((*j, a)).is_err() {
                                    return;
                                }
                            }
                        }
                    }
                    Ok(Err(e)) => tracing::debug!(peer = j, "cannot resolve {name} yet: {e}"),
                    Err(_) => tracing::debug!(peer = j, "resolving {name} timed out"),
                }
            }
            if tx.is_closed() {
                return;
            }
            tokio::time::sleep(Duration::from_millis(500)).await;
        }
    });
    rx
}

impl Peers {
    /// Take the addresses the resolver found since the last call (never waits).
    fn refresh(&mut self) {
        while let Ok((j, a)) = self.resolved.try_recv() {
            self.addrs.insert(j, a);
        }
    }

    fn index_of(&self, a: &SocketAddr) -> Option<usize> {
        self.addrs.iter().find(|(_, x)| *x == a).map(|(j, _)| *j)
    }

    /// Send the probes [`deliver`] queued.
    async fn flush(&mut self, socket: &UdpSocket) {
        for (a, bytes) in std::mem::take(&mut self.outbox) {
            if let Err(e) = socket.send_to(&bytes, a).await {
                tracing::debug!("send_to {a} failed: {e}");
            }
        }
    }

    async fn send(&self, socket: &UdpSocket, to: usize, bytes: &[u8]) {
        if let Some(a) = self.addrs.get(&to) {
            if let Err(e) = socket.send_to(bytes, a).await {
                tracing::debug!(peer = to, "send_to {a} failed: {e}");
            }
        }
    }
}

/// Hand a datagram to the node. From an address that is not a neighbour's it is used only if it authenticates;
/// without authentication it is counted and dropped. An authenticated one is probed (a hello with a random
/// challenge, sent to that address), and the neighbour's address moves there when a hello from there answers the
/// probe (a neighbour that came back with another address). Returns (step, is a measurement) of an accepted
/// datagram.
fn deliver(node: &mut Node, peers: &mut Peers, from: SocketAddr, bytes: &[u8]) -> Option<(u64, bool)> {
    let index = peers.index_of(&from);
    if index.is_none() && !node.endpoint().authenticates() {
        node.endpoint_mut().handle_unknown_address();
        return None;
    }
    let a = node.handle_datagram(index, bytes)?;
    if index != Some(a.src) && peers.names.contains_key(&a.src) {
        match peers.probes.get(&a.src) {
            Some((at, probe, _)) if *at == from && a.answer == *probe => {
                tracing::info!(peer = a.src, %from, "peer address moved: it answered a probe sent there");
                peers.addrs.insert(a.src, from);
                peers.probes.remove(&a.src);
            }
            // One probe per neighbour at a time, renewed (lost, or a new address) at most every PROBE_RENEW.
            Some((_, _, sent)) if sent.elapsed() < PROBE_RENEW => {}
            _ => {
                let probe = u64::from_le_bytes(simnet_engine::fresh::token_bytes()) | 1;
                if let Some(tx) = node.endpoint_mut().probe(a.src, None, probe) {
                    tracing::debug!(peer = a.src, %from, "authenticated datagram from a new address: probing it");
                    peers.outbox.push((from, tx.bytes));
                    peers.probes.insert(a.src, (from, probe, Instant::now()));
                }
            }
        }
    }
    Some((a.step, a.measurement))
}

/// Run node `index` of `topo` as its own process until the configured duration or `shutdown`.
pub async fn run_node(
    topo: Arc<Scenario>,
    index: usize,
    cfg: HostConfig,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> Result<HostOutput, NetError> {
    super::splittable(&topo)?;
    let socket = UdpSocket::bind(cfg.bind)
        .await
        .map_err(|source| NetError::BindAt { addr: cfg.bind, source })?;
    super::socket::size_buffers(&socket, super::socket::RECV_BUFFER);
    tracing::info!(node = topo.nodes()[index].id, bind = %cfg.bind, "listening");
    let (stop_tx, mut stop) = watch::channel(false);
    tokio::spawn(async move {
        shutdown.await;
        let _ = stop_tx.send(true);
    });
    let started = std::time::Instant::now();
    let mut node = Node::new(topo.clone(), index, cfg.record_trace);
    // The node's out-links: what becomes of what it sends.
    let mut medium = topo.pairwise_medium([index]);
    node.endpoint_mut().boot(cfg.boot_epoch);
    node.endpoint_mut().handshake();
    let mut peers = Peers {
        names: cfg.peers.clone(),
        addrs: HashMap::new(),
        resolved: resolver(cfg.peers.clone()),
        probes: HashMap::new(),
        outbox: Vec::new(),
    };
    let mut buf = vec![0u8; MAX_DATAGRAM + 1];
    let steps = topo.sim().steps();
    let dt = Duration::from_secs_f64(topo.sim().dt());

    // Handshake.
    let t_start = Instant::now();
    let mut heard_all_at: Option<Instant> = None;
    let mut next_hello = Instant::now();
    // A neighbour that has not heard this boot is answered at once, at most once per REPLY_GAP.
    let mut last_hello = Instant::now() - REPLY_GAP;
    let first_step = loop {
        if *stop.borrow() {
            return Ok(finish(node, &medium, Vec::new(), 0, true, started, Default::default()));
        }
        if let Some(k) = node.endpoint().max_peer_step() {
            tracing::info!(step = k + 1, "network already running: joining");
            break k + 1;
        }
        if node.endpoint().heard_all() && heard_all_at.is_none() {
            heard_all_at = Some(Instant::now());
        }
        if heard_all_at.is_some_and(|t| t.elapsed() >= GRACE) {
            break 0;
        }
        if t_start.elapsed() >= cfg.handshake_timeout {
            tracing::warn!(
                "handshake timed out after {:?}: starting without every neighbour",
                cfg.handshake_timeout
            );
            break 0;
        }
        if Instant::now() >= next_hello {
            peers.refresh();
            for tx in node.endpoint_mut().hello(None) {
                peers.send(&socket, tx.to, &tx.bytes).await;
            }
            last_hello = Instant::now();
            next_hello = last_hello + HELLO_PERIOD;
        }
        tokio::select! {
            r = socket.recv_from(&mut buf) => if let Ok((len, from)) = r {
                deliver(&mut node, &mut peers, from, &buf[..len]);
                peers.flush(&socket).await;
                if node.endpoint_mut().take_hello_due() {
                    next_hello = next_hello.min((last_hello + REPLY_GAP).max(Instant::now()));
                }
            },
            _ = tokio::time::sleep_until(next_hello.min(t_start + cfg.handshake_timeout)) => {}
            _ = stop.changed() => {}
        }
    };

    // Running: step k starts at base + k·Δt on this host's clock.
    tracing::info!(step = first_step, "stepping");
    let mut k = first_step.min(steps);
    node.start_at(k);
    let mut base = Instant::now().checked_sub(dt * k as u32).unwrap_or_else(Instant::now);
    let mut estimates = Vec::new();
    let mut done = 0;
    let mut next_hello = Instant::now();
    let mut interrupted = false;
    let mut schedule = simnet_engine::report::summary::Schedule::default();
    // Where this host's own clock stands: the step joined, and when. A catch-up goes no further than the clock has
    // run since, plus the window of steps a neighbour may be ahead — so that datagrams claiming later and later steps
    // (unauthenticated, or a neighbour gone wrong) cannot walk the node to the end of the run.
    let (joined_step, joined_at) = (k, Instant::now());
    let window = node.endpoint().step_window();
    while k < steps {
        // A neighbour is ahead: run the steps in between at once and continue from its step.
        let own_clock = || joined_step + (joined_at.elapsed().as_secs_f64() / dt.as_secs_f64()) as u64 + window;
        if let Some(ahead) = node.endpoint().max_peer_step().filter(|&m| m > k && own_clock() > k) {
            let target = ahead.min(own_clock()).min(steps);
            tracing::info!(from = k, to = target, "catching up with a neighbour");
            while k < target {
                node.handle_timeout(topo.deadline(k));
                // Sent all the same: the link layer counted them, and the neighbours count them late.
                node.send_to(&mut medium);
                while let Some(tx) = medium.poll_delivery(index, Time::MAX) {
                    peers.send(&socket, tx.to, &tx.bytes).await;
                }
                k += 1;
            }
            base = Instant::now().checked_sub(dt * k as u32).unwrap_or(base);
            if k >= steps {
                break;
            }
        }
        let start = base + dt * k as u32;
        tokio::select! {
            _ = tokio::time::sleep_until(start) => {}
            _ = stop.changed() => { interrupted = true; break; }
        }
        schedule.record(
            Instant::now().saturating_duration_since(start).as_secs_f64(),
            dt.as_secs_f64(),
        );
        // The node's timeline says what is due (the step's start, each round's close, and last the deadline, which
        // closes the step): done as its instant passes, while the medium's datagrams go out and the socket is read.
        let mut closed = None;
        let mut offsets: Vec<f64> = Vec::new();
        loop {
            let now = Instant::now();
            let sim_now = Time::since_start(now.saturating_duration_since(base));
            if node.poll_timeout().is_some_and(|t| t <= sim_now) {
                closed = node.handle_timeout(sim_now);
            }
            node.send_to(&mut medium);
            while let Some(tx) = medium.poll_delivery(index, sim_now) {
                peers.send(&socket, tx.to, &tx.bytes).await;
            }
            if now >= next_hello {
                peers.refresh();
                for tx in node.endpoint_mut().hello(Some(k)) {
                    peers.send(&socket, tx.to, &tx.bytes).await;
                }
                last_hello = now;
                next_hello = now + Duration::from_millis(500);
            }
            if closed.is_some() {
                break;
            }
            let wake = [medium.poll_timeout(index), node.poll_timeout()]
                .into_iter()
                .flatten()
                .min()
                .map_or(next_hello, |t| base + t.as_duration())
                .min(next_hello);
            tokio::select! {
                r = socket.recv_from(&mut buf) => if let Ok((len, from)) = r {
                    let arrived = Instant::now();
                    let got = deliver(&mut node, &mut peers, from, &buf[..len]);
                    peers.flush(&socket).await;
                    if node.endpoint_mut().take_hello_due() {
                        next_hello = next_hello.min((last_hello + REPLY_GAP).max(arrived));
                    }
                    if let Some((step, true)) = got {
                        // Where the sender's step `step` began, seen from here (transit included).
                        let local = base + dt * step as u32;
                        let off = if arrived >= local { (arrived - local).as_secs_f64() } else { -(local - arrived).as_secs_f64() };
                        if off.abs() < dt.as_secs_f64() {
                            offsets.push(off);
                        }
                    }
                },
                _ = tokio::time::sleep_until(wake) => {}
                _ = stop.changed() => { interrupted = true; break; }
            }
        }
        // Stopped within the step: it closes all the same.
        let closed = closed.or_else(|| node.handle_timeout(topo.deadline(k)));
        if let Some(e) = closed.and_then(|c| c.estimate) {
            if cfg.record_trace {
                estimates.push(e);
            }
        }
        // A part carries no measurements file (yet): the rows are not kept.
        node.take_measurements();
        tracing::trace!(step = k, "step closed");
        if !offsets.is_empty() {
            let mean = offsets.iter().sum::<f64>() / offsets.len() as f64;
            // Negative: the neighbours' step began before ours; move our schedule earlier (and vice versa).
            let shift = Duration::from_secs_f64((PHASE_GAIN * mean.abs()).min(dt.as_secs_f64() / 4.0));
            base = if mean < 0.0 {
                base.checked_sub(shift).unwrap_or(base)
            } else {
                base + shift
            };
        }
        k += 1;
        done = k;
        if let Some(p) = &cfg.progress {
            p(k, steps);
        }
        if interrupted {
            break;
        }
    }
    // What is still queued is read (as much as the buffer holds: a flood that goes on cannot keep the node here), so
    // that every datagram that reached the socket is counted; then what the kernel dropped.
    for _ in 0..super::socket::RECV_BUFFER / 32 {
        let Ok((len, from)) = socket.try_recv_from(&mut buf) else {
            break;
        };
        deliver(&mut node, &mut peers, from, &buf[..len]);
    }
    super::socket::record_drops([(&mut node, &socket)]);
    Ok(finish(node, &medium, estimates, done, interrupted, started, schedule))
}

fn finish(
    mut node: Node,
    medium: &dyn Medium,
    estimates: Vec<StepEstimate>,
    done: u64,
    interrupted: bool,
    started: std::time::Instant,
    schedule: simnet_engine::report::summary::Schedule,
) -> HostOutput {
    HostOutput {
        heard_a_hello: node.endpoint().heard_a_hello(),
        run: node.endpoint().run_id(),
        report: node.report(medium),
        estimates,
        steps_done: done,
        interrupted,
        wall_s: started.elapsed().as_secs_f64(),
        schedule,
    }
}
