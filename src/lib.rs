//! simnet: a wireless IMU sensor network over real UDP sockets, with a seeded fault layer and networked Kalman
//! estimation (intermittent observations, per-channel inflation, β-weighted consensus with an LMI guard,
//! covariance-intersection fusion).
//!
//! # Layout
//!
//! The modules follow one step of data. The lowest layer is a crate of its own, `simnet-core` (`crates/core`):
//! `geom`, `rng`, `stats`, `motion`, `world`, `sensor`, `estimate`, `imu_csv`, `checks`, `model`, `estimators`, `time`,
//! `wire`, `link` and `attack`, re-exported here under the same names (marked "core" below). It depends on no tokio and no filesystem crate and, being below this one, cannot name anything above
//! it: the compiler holds that layer. Above it, only `net` touches sockets and clocks; `report`, `campaign` and
//! `cli` write files, `input` reads them (bounded, never trusted); `fresh` draws from the operating system. The rest
//! is pure: randomness from seeded streams.
//!
//! | module | owns |
//! |---|---|
//! | [`scenario`] | topology TOML and overrides → a validated [`scenario::Scenario`]; every error names the file and the key; built-ins |
//! | [`model`] (core) | the estimation models behind one trait made of five roles (dynamics, sensing, manifold, ground truth, report): pose, attitude (quaternion EKF), linear |
//! | [`motion`] (core) | analytic ground-truth trajectories shared by every node |
//! | [`world`] (core) | where every node is at every time (fixed, or mounted on a moving body): [`Scenario::world`] |
//! | [`sensor`] (core) | accelerometer/gyro (noise, bias, Wiener drift), magnetometer, pose fixes, linear measurements |
//! | [`estimate`] (core) | pure maths: Kalman prediction/update, per-channel inflation, consensus (eqs. 5–10), LMI checks (17, 19), covariance intersection; the quaternion attitude EKF and the multiplicative one, Madgwick and Mahony (VQF through `vqf-rs`), the rigid-pair EKF, the FEM boundary-value solver |
//! | [`estimators`] (core) | the distributed schemes behind one [`estimators::Estimator`] trait — independent, centralized, KCF, ICF, HCMCI, diffusion, CI — pure, per node, one message per round; the node runs them over L consensus rounds |
//! | [`time`] (core) | simulated time in whole nanoseconds: what every datagram's header stamps (the time it pertains to, the time it was sent) |
//! | [`wire`] (core) | the datagram format: a header that says who sent what to whom, when, for which scheme; postcard + CRC-32, checked decode |
//! | [`medium`] (core) | what carries the nodes' datagrams: the [`medium::Medium`] trait a driver hands every transmission to, and [`medium::PairwiseMedium`], the scenario's directed links (built by [`Scenario::pairwise_medium`], split by sender for the UDP drivers) |
//! | [`link`] (core) | per-datagram rules (outage, Bernoulli / Gilbert–Elliott loss, duplication, delay and jitter, corruption), the egress queue, fault schedules |
//! | [`attack`] (core) | the adversary model of `[[attack]]`: forge, tamper, replay, flood on the air in front of a node, false data from a compromised one; what became of each injected datagram |
//! | [`node`] | one node's sans-IO state machine with its call order written once: `poll_timeout`/`handle_timeout` (a step's start, its rounds, its deadline), `handle_datagram`, `send_to` (hands what it sent to the medium), over any [`model::Model`]; simulated or recorded IMU |
//! | [`observe`] | what is measured as a run goes: the [`observe::Probe`]s a node feeds (the scorer, the trace, IMU and LMI recorders, your own), per-filter metrics, the fusion observer, the estimators' agreement and the two fusion centers (centralized, and centralized-net over lossy links) |
//! | [`sim`] | whole runs in memory: [`Sim`] steps every node in lockstep and returns [`RunResults`], the same as over UDP |
//! | [`net`] | the only I/O: one UDP socket per node served by one worker per core, virtual and realtime clocks, shutdown; `net::host` runs one node per process (`simnet node`) |
//! | [`report`] | `summary.json` (with the settings that made it), the table, `trace.csv` and IMU files streamed as a run goes (`report::trace`), `links.csv`, SVG plots |
//! | [`analysis`] | studies over whole runs: Sinopoli's covariance bounds against runs measured at each arrival rate; attitude filters on a real recording against its own reference (noise, gates and magnetometer calibration read off the recording; the noise model checked against the reference) |
//! | [`protocol`] | β protocol search over whole in-memory runs: the paper's family by bisection on (17)/(19); all β by SDP (feature `sdp`) |
//! | [`reconstruct`] | position from a recorded IMU file as a boundary value problem (FEM), trapezoid for comparison, sensor-error model |
//! | [`reproduce`] | the source documents' experiments rerun: claims tables with simnet's figures, and plots |
//! | `cli` (crate-private) | clap definitions, exit codes, tracing setup |
//! | `compose` (crate-private) | the docker compose file of a topology (one container per node) |
//!
//! Support: [`checks`] (core: the validator's shared checks, each problem keyed), [`input`] (untrusted files: regular,
//! bounded, never quoted), [`geom`] (Euler ZYX attitude; core),
//! [`rng`] (seeded streams; core), [`stats`] (quantiles for tests and reports; core), `par` (jobs over every core,
//! crate-private), [`imu_csv`] (core: recorded IMU files: `simnet run --out` writes them, `imu_csv` on a node and
//! `simnet reconstruct` and `simnet attitude` read them, and makers' layouts through `imu_csv::layout`).
//!
//! The library API: build or load a [`Scenario`] ([`Scenario::builder`], [`Scenario::resolve`], [`Scenario::with`]),
//! run it with [`Sim`] (in memory) or [`net::run`] (over UDP), read [`RunResults::summary`]. [`scenario::Flags`] holds
//! `simnet run`'s options as values; the Python package (`python/`, pyo3) is built on these calls alone.

pub mod analysis;
pub mod campaign;
mod cli;
mod compose;
pub mod fresh;
pub mod input;
pub mod net;
pub mod node;
pub mod observe;
mod par;
pub mod protocol;
pub mod reconstruct;
pub mod report;
pub mod reproduce;
pub mod scenario;
pub mod sim;

pub use simnet_core::{
    attack, checks, estimate, estimators, geom, imu_csv, link, medium, model, motion, rng, sensor, stats, text, time,
    wire, world,
};

pub use report::summary::Summary;

/// The `simnet` command line (the binary's `main`).
pub fn cli_main() -> std::process::ExitCode {
    cli::main()
}
pub use scenario::{LinkSpec, Overrides, Scenario, ScenarioBuilder};
pub use sim::{RunResults, Sim};

/// The Rust examples of README and the book run as doctests.
#[cfg(doctest)]
mod doc_examples {
    #[doc = include_str!("../README.md")]
    pub struct Readme;
    #[doc = include_str!("../docs/src/library.md")]
    pub struct Library;
}
