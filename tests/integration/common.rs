//! Helpers: run a topology over real sockets (virtual clock) and build its summary.

use std::sync::Arc;

use simnet::net::{self, RunOptions, RunResults};
use simnet::report::summary::Summary;
use simnet::scenario::{Overrides, Scenario};

pub fn topology(name_or_toml: &str, o: Overrides) -> Scenario {
    let t = if name_or_toml.contains('[') {
        Scenario::from_toml(name_or_toml, "test.toml").unwrap_or_else(|e| panic!("{e}"))
    } else {
        Scenario::resolve(name_or_toml).unwrap_or_else(|e| panic!("{e}"))
    };
    t.with(&o).unwrap_or_else(|e| panic!("{e}"))
}

pub fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap()
}

pub fn run_with(topo: Scenario, opts: RunOptions) -> (Summary, RunResults) {
    let topo = Arc::new(topo);
    let out = runtime()
        .block_on(net::run(topo.clone(), opts, std::future::pending()))
        .expect("run");
    let s = out.summary();
    (s, out)
}

/// A whole run in memory ([`simnet::Sim`]): the same figures as over sockets, for properties of the estimators.
pub fn simulate(topo: Scenario) -> Summary {
    simnet::Sim::new(&topo)
        .expect("a valid scenario")
        .run()
        .expect("run")
        .summary()
}

/// A whole run over loopback UDP sockets (virtual clock).
pub fn run(topo: Scenario) -> Summary {
    run_with(topo, RunOptions::default()).0
}

pub fn seed(s: u64) -> Overrides {
    Overrides {
        seed: Some(s),
        ..Default::default()
    }
}

pub fn bernoulli(p: f64, s: u64) -> Overrides {
    Overrides {
        loss: Some(simnet::link::LossModel::Bernoulli { p }),
        seed: Some(s),
        ..Default::default()
    }
}

/// A fresh network key file in `dir`, written by `simnet keygen`: multi-host nodes authenticate by default.
pub fn network_key(dir: &std::path::Path) -> std::path::PathBuf {
    let path = dir.join("simnet.key");
    let _ = std::fs::remove_file(&path);
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_simnet"))
        .arg("keygen")
        .arg(&path)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    path
}

/// Start `cmd` with its log piped and wait for the line that contains `line` (an event, not a time, so that a
/// loaded machine cannot reorder the test); its log is then read to the end in a thread, so that the pipe never
/// fills. Panics if the process ends without logging the line.
/// A loopback UDP port free a moment ago (the socket that found it is closed).
pub fn free_port() -> u16 {
    std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

pub fn spawn_until(cmd: &mut std::process::Command, line: &str) -> (std::process::Child, std::thread::JoinHandle<()>) {
    use std::io::BufRead;
    let mut child = cmd
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = std::io::BufReader::new(child.stderr.take().unwrap()).lines();
    assert!(
        lines.by_ref().map_while(Result::ok).any(|l| l.contains(line)),
        "the process ended without logging `{line}`"
    );
    (child, std::thread::spawn(move || lines.for_each(drop)))
}
