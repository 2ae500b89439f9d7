#![warn(missing_docs)]
//! simnet's pure layer: the estimation maths, sensors and motion, seeded random streams, recorded IMU files as text,
//! the estimation models, the distributed estimators, the medium with its per-datagram link rules, and the wire
//! format. Nothing here opens a socket or a file, reads a clock or draws from the operating system: every input is
//! an argument, every random draw comes from a stream named by a seed. The `simnet` crate builds nodes, runs,
//! drivers and reports on top of it and re-exports every module under its own name (`simnet::estimate` is
//! [`estimate`]).
//!
//! # Layout
//!
//! | module | owns |
//! |---|---|
//! | [`geom`] | Euler ZYX attitude: rotation matrices, angle wrapping |
//! | [`rng`] | seeded streams, one per (seed, stream, from, to) |
//! | [`stats`] | quantiles for tests and reports (normal, chi-square, Student's t) |
//! | [`motion`] | analytic ground-truth trajectories shared by every node |
//! | [`world`] | where every node is at every time: fixed in place, or mounted on a body that follows a trajectory |
//! | [`sensor`] | accelerometer/gyro (noise, bias, Wiener drift), magnetometer, pose fixes, linear measurements |
//! | [`estimate`] | Kalman prediction/update, per-channel inflation, consensus (eqs. 5–10), LMI checks (17, 19), covariance intersection; the quaternion attitude EKFs, Madgwick and Mahony, the rigid-pair EKF, the FEM boundary-value solver |
//! | [`text`] | untrusted text as a message shows it (clipped) |
//! | [`time`] | simulated time: whole nanoseconds since the run began, a step's time and back |
//! | [`imu_csv`] | recorded IMU files from their text: simnet's columns, and makers' layouts through `imu_csv::layout` |
//! | [`checks`] | the validator's shared checks: each problem keyed, a usable default returned |
//! | [`model`] | the estimation models: [`model::Model`] = [`model::Dynamics`] + [`model::Sensing`] + [`model::Manifold`] + [`model::GroundTruth`] + [`model::Report`] — pose, attitude (quaternion EKF), linear, and any a program registers ([`model::register`]); an observation may depend on the [`model::Site`] that measured |
//! | [`wire`] | the datagram format: postcard + CRC-32, checked decode; authenticated frames (AES-128-CCM); a link's sequence gaps as its receiver counts them |
//! | [`medium`] | what carries a node's transmissions to their receivers: the [`medium::Medium`] trait, and [`medium::PairwiseMedium`] (every directed link deciding alone, split by sender); [`medium::Ingress`], a stage in front of one receiver that adds datagrams and learns their fate; [`medium::phy`], the IEEE 802.15.4 O-QPSK radio's arithmetic (path loss, noise floor, BER and PER at an SINR, airtime), equal to ns-3's; [`medium::air`], what one receiver makes of the frames around it (lock, interference stretch by stretch, half-duplex); [`medium::csma`], unslotted CSMA/CA; [`medium::frame`], the frames a message takes (headers, security, 6LoWPAN fragments) and their airtime; [`medium::radio::RadioMedium`], one shared 802.15.4 channel built of them (whole: not split by sender) |
//! | [`link`] | per-datagram rules (outage, Bernoulli / Gilbert–Elliott loss, duplication, delay and jitter, corruption), the egress queue, fault schedules |
//! | [`estimators`] | the distributed schemes behind one [`estimators::Estimator`] trait — sequeira (the node's networked filter), independent, centralized, KCF, ICF, HCMCI, diffusion, CI — per node, one message per round; the registry by name and the wire form of their messages |
//! | [`attack`] | the adversary model of `[[attack]]`: forge, tamper, replay, flood on the air in front of a node (an [`medium::Ingress`]), false data from a compromised one |
//!
//! Dependencies point down the table's order and never back up (`model` uses `estimate`, `imu_csv`, `checks`,
//! `sensor`; `estimators` uses `model` and `wire`; `attack` uses `wire` and `medium`); `tests/integration/layering.rs` holds it. The crate has no tokio and no filesystem dependency, so
//! the compiler holds the rest.

pub mod attack;
pub mod checks;
pub mod estimate;
pub mod estimators;
pub mod geom;
pub mod imu_csv;
pub mod link;
pub mod medium;
pub mod model;
pub mod motion;
pub mod rng;
pub mod sensor;
pub mod stats;
pub mod text;
pub mod time;
pub mod wire;
pub mod world;
