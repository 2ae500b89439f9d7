//! simnet's engine: everything between its pure core (`simnet-core`) and what is built on whole runs (the UDP
//! drivers `simnet-net`, campaigns `simnet-campaign`, studies `simnet-studies`, the CLI). A scenario becomes nodes,
//! the nodes run in memory, the observer measures them, and the results become reports. No socket, no tokio: this
//! crate cannot name the crates above it (they depend on it), so the compiler holds that layer. `report` writes
//! files, `input` reads them (bounded, never trusted); `fresh` draws from the operating system. The rest is pure:
//! randomness from seeded streams.
//!
//! # Layout
//!
//! The modules follow one step of data. The core's modules are re-exported here under the same names (marked "core").
//!
//! | module | owns |
//! |---|---|
//! | [`scenario`] | topology TOML and overrides → a validated [`scenario::Scenario`]; every error names the file and the key; built-ins |
//! | [`model`] (core) | the estimation models behind one trait made of five roles (dynamics, sensing, manifold, ground truth, report): pose, attitude (quaternion EKF), linear; one open registry |
//! | [`motion`] (core) | analytic ground-truth trajectories shared by every node |
//! | [`world`] (core) | where every node is at every time (fixed, or mounted on a moving body): [`Scenario::world`] |
//! | [`sensor`] (core) | accelerometer/gyro (noise, bias, Wiener drift), magnetometer, pose fixes, linear measurements |
//! | [`estimate`] (core) | pure maths: Kalman prediction/update, per-channel inflation, consensus (eqs. 5–10), LMI checks (17, 19), covariance intersection; the quaternion attitude EKF and the multiplicative one, Madgwick and Mahony, the rigid-pair EKF, the FEM boundary-value solver |
//! | [`estimators`] (core) | the distributed schemes behind one [`estimators::Estimator`] trait and one open registry — sequeira (the node's networked filter), independent, centralized, KCF, ICF, HCMCI, diffusion, CI — pure, per node, one message per round; the node runs them over L consensus rounds |
//! | [`time`] (core) | simulated time in whole nanoseconds: what every datagram's header stamps (the time it pertains to, the time it was sent) |
//! | [`wire`] (core) | the datagram format: a header that says who sent what to whom, when, for which scheme; postcard + CRC-32, checked decode |
//! | [`medium`] (core) | what carries the nodes' datagrams: the [`medium::Medium`] trait a driver hands every transmission to, and [`medium::PairwiseMedium`], the scenario's directed links (built by [`Scenario::pairwise_medium`], split by sender for the UDP drivers) |
//! | [`link`] (core) | per-datagram rules (outage, Bernoulli / Gilbert–Elliott loss, duplication, delay and jitter, corruption), the egress queue, fault schedules |
//! | [`attack`] (core) | the adversary model of `[[attack]]`: forge, tamper, replay, flood on the air in front of a node (a [`medium::Ingress`] stage the node takes what arrives through), false data from a compromised one; what became of each injected datagram |
//! | [`node`] | one node's sans-IO state machine with its call order written once: `poll_timeout`/`handle_timeout` (a step's start, its rounds, its deadline), `handle_datagram`, `send_to` (hands what it sent to the medium), over any [`model::Model`]; a [`node::Node`] is its [`node::Endpoint`] (the estimators, which never see the truth) and its [`node::Testbed`] (the truth, the sensor with its seeded noise — simulated or recorded IMU — and the observer that scores each update) |
//! | [`observe`] | what is measured as a run goes: the [`observe::Probe`]s a node's testbed feeds (the scorer, the trace, IMU and LMI recorders, your own), per-filter metrics, the fusion observer, the estimators' agreement and the two fusion centers (centralized, and centralized-net over lossy links) |
//! | [`sim`] | whole runs in memory: [`Sim`] steps every node in lockstep and returns [`RunResults`], the same as over UDP (`simnet-net`) |
//! | [`report`] | `summary.json` (with the settings that made it), the table, `trace.csv` and IMU files streamed as a run goes (`report::trace`), `links.csv`, SVG plots |
//! | [`compose`] | the docker compose file of a topology (one container per node) |
//!
//! Support: [`checks`] (core: the validator's shared checks, each problem keyed), [`input`] (untrusted files: regular,
//! bounded, never quoted), [`fresh`] (boot epochs, tokens and keys from the operating system), [`geom`] (Euler ZYX
//! attitude; core), [`rng`] (seeded streams; core), [`stats`] (quantiles for tests and reports; core), [`par`] (jobs
//! over every core), [`imu_csv`] (core: recorded IMU files: `simnet run --out` writes them, `imu_csv` on a node and
//! `simnet reconstruct` and `simnet attitude` read them, and makers' layouts through `imu_csv::layout`).

pub mod compose;
pub mod fresh;
pub mod input;
pub mod node;
pub mod observe;
pub mod par;
pub mod report;
pub mod scenario;
pub mod sim;

pub use simnet_core::{
    attack, checks, estimate, estimators, geom, imu_csv, link, medium, model, motion, rng, sensor, stats, text, time,
    wire, world,
};

pub use report::summary::Summary;
pub use scenario::{LinkSpec, Overrides, Scenario, ScenarioBuilder};
pub use sim::{RunResults, Sim};
