//! simnet: a wireless IMU sensor network over real UDP sockets, with a seeded fault layer and networked Kalman
//! estimation (intermittent observations, per-channel inflation, β-weighted consensus with an LMI guard,
//! covariance-intersection fusion).
//!
//! # Layout
//!
//! A workspace of crates that follow the data, each depending only on those below it, so that the compiler holds the
//! layers (a crate cannot name one that depends on it):
//!
//! | crate | folder | owns |
//! |---|---|---|
//! | `simnet-core` | `crates/core` | the pure layer: estimation maths, models and estimators and their registries, sensors and motion, seeded streams, time, the link rules, media and the wire; no tokio, no filesystem, no clock |
//! | `simnet-engine` | `crates/engine` | scenarios, the sans-IO node, the observer, runs in memory ([`Sim`]), their reports; no sockets |
//! | `simnet-net` | `crates/net` | the only sockets and clocks: one UDP socket per node, the virtual and wall clocks, one node per process ([`net`]) |
//! | `simnet-campaign` | `crates/campaign` | sweeps of thousands of runs, stored, resumed, summarised ([`campaign`]; the CLI's `simnet sweep` and Python's `simnet.sweep`) |
//! | `simnet-studies` | `crates/studies` | studies over whole runs and recordings: [`analysis`] (bounds, attitude on recordings), [`protocol`] (β search), [`reconstruct`] (FEM), [`reproduce`] (the source documents' experiments) |
//! | `simnet` | `.` | this facade (every module of the crates below, under one name) and the `simnet` command line (`cli`, crate-private) |
//! | `simnet-python` | `python` | the Python package (pyo3) on this crate's calls |
//!
//! The modules of the engine and the core are re-exported here under their names ([`scenario`], [`node`],
//! [`estimators`], …): `simnet-engine`'s own documentation maps them.
//!
//! The library API: build or load a [`Scenario`] ([`Scenario::builder`], [`Scenario::resolve`], [`Scenario::with`]),
//! run it with [`Sim`] (in memory) or [`net::run`] (over UDP), read [`RunResults::summary`]. [`scenario::Flags`] holds
//! `simnet run`'s options as values; the Python package (`python/`, pyo3) is built on these calls alone.

mod cli;

pub use simnet_campaign as campaign;
pub use simnet_engine::{
    attack, checks, compose, estimate, estimators, fresh, geom, imu_csv, input, link, medium, model, motion, node,
    observe, par, report, rng, scenario, sensor, sim, stats, text, time, wire, world,
};
pub use simnet_net as net;
pub use simnet_studies::{analysis, protocol, reconstruct, reproduce};

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
