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

/// The `simnet` command line with `args`, the first the program's name, as the binary runs it (a usage error clap
/// finds ends the process with exit 2, as the binary does). A program that registers estimators
/// ([`estimators::register`]) or models ([`model::register`]) of its own and then hands its arguments here is the
/// whole `simnet` command line with them: `--estimators`, `[estimators] run`, `simnet estimators`, `simnet node`.
/// Every process of a multi-host run must be that program.
///
/// This one registers the node's own Kalman filter as `own` and runs ring3 over UDP with it, as
/// `simnet run -t ring3 --estimators own` would; `own` is `independent` to the last digit:
///
/// ```
/// use std::sync::Arc;
/// use simnet::estimate::{EstimateError, Gaussian, MissingChannels};
/// use simnet::estimators::{register, Estimator, Message, Scheme, StepInput};
///
/// struct Own { g: Gaussian, policy: MissingChannels }
///
/// impl Estimator for Own {
///     fn name(&self) -> &'static str { "own" }
///     fn state(&self) -> Option<&Gaussian> { Some(&self.g) }
///     fn state_mut(&mut self) -> Option<&mut Gaussian> { Some(&mut self.g) }
///     fn message(&self, _round: usize) -> Option<Message> { None }
///     fn combine(&mut self, _: usize, _: &[(usize, &Message)], _: &StepInput<'_>) -> Result<(), EstimateError> {
///         Ok(())
///     }
///     fn finish(&mut self, input: &StepInput<'_>) -> Result<(), EstimateError> {
///         if let Some(m) = input.own {
///             self.g = input.update(&self.g, input.node, m, self.policy)?;
///         }
///         Ok(())
///     }
/// }
///
/// let scheme = Scheme { name: "own", reference: "the own filter", messages: "none", parameters: "-" };
/// register(scheme, |_, _| Arc::new(|_, g, policy| Box::new(Own { g, policy })))?;
/// let out = std::env::temp_dir().join(format!("simnet-cli-with-{}", std::process::id()));
/// let args = ["simnet", "run", "-q", "-t", "ring3", "--duration", "2", "--estimators", "independent,own", "--out"];
/// let mut args: Vec<std::ffi::OsString> = args.iter().map(Into::into).collect();
/// args.push(out.clone().into());
/// assert_eq!(simnet::cli_main_with(args), std::process::ExitCode::SUCCESS);
/// let summary: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("summary.json"))?)?;
/// let errors = |scheme: &str| -> Vec<f64> {
///     let nodes = summary["estimators"][scheme]["nodes"].as_array().cloned().unwrap_or_default();
///     nodes.iter().map(|n| n["mean_error"].as_f64().unwrap()).collect()
/// };
/// assert_eq!(errors("own").len(), 3);
/// assert_eq!(errors("own"), errors("independent"));
/// std::fs::remove_dir_all(&out)?;
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn cli_main_with(args: Vec<std::ffi::OsString>) -> std::process::ExitCode {
    cli::main_with(args)
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
