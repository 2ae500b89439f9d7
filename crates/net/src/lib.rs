//! simnet's only I/O (the crate `simnet-net`, `simnet::net` through the facade): one UDP socket (127.0.0.1, port 0)
//! per node, served by one worker per core; the two clocks, and shutdown. It drives the engine's sans-IO nodes
//! (`simnet-engine`) through their call order and hands the steps to the same observer as an in-memory run.
//!
//! | file | owns |
//! |---|---|
//! | `lockstep/` | the virtual clock (default; `slot.rs`: one node a worker owns, its frames and what it keeps for a resend): every node steps in lockstep, each step closes when what the link layer delivered by the deadline is in; same seed, same results |
//! | `realtime.rs` | the wall clock: every worker paces its nodes from a common start; delay and jitter are real waits |
//! | `collect.rs` | what the workers hand in per step, and the task that fuses the steps in order |
//! | `host.rs` | one node per process (`simnet node`): the handshake, catching up, the part it writes |
//! | `socket.rs` | the kernel's side of a socket: its receive buffer, and the datagrams it dropped |

use std::future::Future;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use tokio::net::UdpSocket;
use tokio::sync::{oneshot, watch};

use simnet_engine::report::trace::TraceWriter;
use simnet_engine::scenario::Scenario;
pub use simnet_engine::sim::{Clock, Progress, RunResults};

mod collect;
pub mod host;
mod lockstep;
mod realtime;
pub mod socket;

#[derive(Debug, thiserror::Error)]
pub enum NetError {
    #[error("cannot bind a UDP socket on 127.0.0.1: {0}")]
    Bind(std::io::Error),
    /// A node process's own address (its topology `addr` or `--bind`).
    #[error("cannot bind {addr}: {source}{}", if source.kind() == std::io::ErrorKind::AddrInUse { format!(" (port {} is taken: another simnet node, or choose another with --bind)", addr.port()) } else { String::new() })]
    BindAt { addr: SocketAddr, source: std::io::Error },
    #[error("node task {0} stopped unexpectedly")]
    TaskLost(usize),
    #[error("a node task stopped before it replied")]
    NoReply,
    #[error("lockstep worker {0} stopped unexpectedly")]
    WorkerLost(usize),
    #[error(transparent)]
    Scenario(#[from] simnet_engine::scenario::ScenarioError),
    #[error("cannot start the async runtime: {0}")]
    Runtime(std::io::Error),
    /// A medium that must see every transmission at once, asked of a driver that splits the medium by sender.
    #[error(
        "topology `{0}` runs over a radio medium (medium.kind = \"radio\"), which decides each frame's fate from \
         every frame on the air at once: it runs on the virtual clock (`simnet run`, `simnet compare`), not yet on \
         wall clocks (--realtime) or one node per process (`simnet node`), where each node carries its own part of \
         the medium"
    )]
    WholeMedium(String),
}

/// The drivers on wall clocks split the medium by sender: a medium that cannot be split is refused, not replaced.
fn splittable(topo: &Scenario) -> Result<(), NetError> {
    match topo.medium() {
        simnet_engine::scenario::MediumConfig::Pairwise => Ok(()),
        simnet_engine::scenario::MediumConfig::Radio(_) => Err(NetError::WholeMedium(topo.name().to_string())),
    }
}

/// A worker's part of the medium, tapped when the run records a capture.
fn tap<M: simnet_engine::medium::Medium>(
    medium: M,
    log: &Option<simnet_engine::medium::CaptureLog>,
) -> simnet_engine::medium::Capture<M> {
    use simnet_engine::medium::Capture;
    match log {
        Some(log) => Capture::new(medium, log.clone()),
        None => Capture::off(medium),
    }
}

pub struct RunOptions {
    pub clock: Clock,
    /// Takes the per-step rows for `trace.csv` and the plots as the run goes (none: no rows are made).
    pub trace: Option<TraceWriter>,
    /// How long a virtual step waits, asking again, for a frame the link layer delivered before counting it as a
    /// socket loss.
    pub recv_timeout: Duration,
    /// The receive buffer each node's socket asks for ([`socket::RECV_BUFFER`]; the kernel caps it at
    /// `net.core.rmem_max`). A small one makes the kernel drop frames, which the virtual clock asks for again.
    pub recv_buffer: usize,
    pub progress: Option<Progress>,
    /// Receives the nodes' socket addresses once bound (tests use it to send foreign datagrams).
    pub on_bound: Option<oneshot::Sender<Vec<SocketAddr>>>,
    /// Record every datagram sent and every copy delivered into this log (a tap on each worker's part of the
    /// medium, [`simnet_engine::medium::Capture`]; it changes nothing it carries).
    pub capture: Option<simnet_engine::medium::CaptureLog>,
}

impl Default for RunOptions {
    fn default() -> Self {
        RunOptions {
            clock: Clock::Virtual,
            trace: None,
            recv_timeout: Duration::from_secs(2),
            recv_buffer: socket::RECV_BUFFER,
            progress: None,
            on_bound: None,
            capture: None,
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
    if opts.clock != Clock::Virtual {
        splittable(&topo)?;
    }
    let n = topo.nodes().len();
    let mut sockets = Vec::with_capacity(n);
    for _ in 0..n {
        let s = UdpSocket::bind("127.0.0.1:0").await.map_err(NetError::Bind)?;
        socket::size_buffers(&s, opts.recv_buffer);
        sockets.push(s);
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
        Clock::Virtual => lockstep::run(topo, sockets, addrs, &mut opts, stop_rx).await?,
        // Nodes on their own wall clocks, here in one process: the realtime run.
        Clock::Realtime | Clock::MultiHost => realtime::run(topo, sockets, addrs, &mut opts, stop_rx).await?,
    };
    out.wall_s = started.elapsed().as_secs_f64();
    Ok(out)
}

/// [`run`] on a runtime of its own, blocking this thread until the run ends: `threads` workers (1: on this thread,
/// as a campaign runs one run per core), and `stop`, polled every 50 ms, ends the run early.
pub fn run_blocking(
    topo: Arc<Scenario>,
    opts: RunOptions,
    stop: Arc<std::sync::atomic::AtomicBool>,
    threads: usize,
) -> Result<RunResults, NetError> {
    let rt = if threads <= 1 {
        tokio::runtime::Builder::new_current_thread().enable_all().build()
    } else {
        tokio::runtime::Builder::new_multi_thread()
            .worker_threads(threads)
            .enable_all()
            .build()
    }
    .map_err(NetError::Runtime)?;
    let stopped = async move {
        while !stop.load(std::sync::atomic::Ordering::Relaxed) {
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    };
    rt.block_on(run(topo, opts, stopped))
}
