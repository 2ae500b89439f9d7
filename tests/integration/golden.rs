//! Golden summaries: every built-in, run on the virtual clock as it ships and again with every link fault and a
//! fault schedule on, must give the `summary.json` recorded in `tests/golden/` to 1e-9, in memory through the
//! library ([`simnet::Sim`]) and over UDP through the command line. Restructuring keeps these
//! green; a change that moves a figure on purpose regenerates them with `SIMNET_BLESS=1 cargo test golden` and says
//! why in its commit.

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;
use simnet::link::LossModel;
use simnet::{Overrides, Scenario, Sim};

const DURATION: &str = "6";
/// Keys that say how or when a run was made, not what it found: the machine's (`LOAD_DEPENDENT`) and the version.
fn ignored(key: &str) -> bool {
    key == "simnet_version" || key == simnet::report::summary::LOAD_DEPENDENT
}
const TOLERANCE: f64 = 1e-9;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The built-in's TOML with a crash/restart of its last node, a link-down on its first edge and a partition of its
/// first node, all inside the run.
fn with_faults(text: &str) -> String {
    let v: toml::Value = toml::from_str(text).unwrap();
    let ids: Vec<i64> = v["node"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n["id"].as_integer().unwrap())
        .collect();
    let mut s = text.to_string();
    let last = ids[ids.len() - 1];
    s.push_str(&format!(
        "\n[[fault]]\nkind = \"crash\"\nnode = {last}\nat_s = 1.5\nrestart_s = 3.0\n"
    ));
    if let Some(e) = v.get("edge").and_then(|e| e.as_array()).and_then(|e| e.first()) {
        let n = e["nodes"].as_array().unwrap();
        s.push_str(&format!(
            "\n[[fault]]\nkind = \"link-down\"\nlink = [{}, {}]\nstart_s = 2.0\nend_s = 2.5\n",
            n[0], n[1]
        ));
    }
    if ids.len() > 1 {
        s.push_str(&format!(
            "\n[[fault]]\nkind = \"partition\"\nnodes = [{}]\nstart_s = 4.0\nend_s = 4.6\n",
            ids[0]
        ));
    }
    s
}

const FAULTY: &[&str] = &[
    "--loss",
    "0.15",
    "--loss-model",
    "gilbert-elliott",
    "--burst",
    "3",
    "--delay",
    "4",
    "--jitter",
    "3",
    "--duplicate",
    "0.05",
    "--corrupt",
    "0.03",
];

/// The same run in memory through the library: [`simnet::Sim`] must give the summary the CLI's UDP run gives.
fn in_memory(topology: &Path, faulty: bool) -> Value {
    let o = if faulty {
        Overrides {
            loss: Some(LossModel::gilbert_elliott_from(0.15, 3.0).unwrap()),
            delay_ms: Some(4.0),
            jitter_ms: Some(3.0),
            duplicate: Some(0.05),
            corrupt: Some(0.03),
            ..Default::default()
        }
    } else {
        Overrides::default()
    };
    let o = Overrides {
        duration_s: Some(DURATION.parse().unwrap()),
        ..o
    };
    let scenario = Scenario::from_path(topology).and_then(|s| s.with(&o)).unwrap();
    let mut summary = Sim::new(&scenario).unwrap().run().unwrap().summary();
    if !scenario.attacks().is_empty() {
        // As `simnet run` does: beside the same seed's clean run.
        let clean = Sim::new(&scenario.without_attacks()).unwrap().run().unwrap().summary();
        summary.compare_clean(&clean);
    }
    normalised(serde_json::from_str(&summary.to_json()).unwrap())
}

/// The faulty variants live in a temporary directory: keep the file name only.
fn normalised(mut v: Value) -> Value {
    if let Some(Value::String(s)) = v.get_mut("source") {
        if let Some(f) = Path::new(s.as_str()).file_name() {
            *s = f.to_string_lossy().into_owned();
        }
    }
    v
}

fn summary(topology: &Path, extra: &[&str]) -> Value {
    let out = Command::new(env!("CARGO_BIN_EXE_simnet"))
        .args([
            "-q",
            "--topology",
            topology.to_str().unwrap(),
            "--duration",
            DURATION,
            "--json",
        ])
        .args(extra)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}: {}",
        topology.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    normalised(serde_json::from_slice(&out.stdout).unwrap())
}

/// Every key of `golden` is in `got` with an equal value (numbers to [`TOLERANCE`], absolute or relative); keys
/// `got` adds are new fields and allowed.
fn compare(path: &str, golden: &Value, got: &Value, diffs: &mut Vec<String>) {
    match (golden, got) {
        (Value::Object(g), Value::Object(o)) => {
            for (k, gv) in g {
                if ignored(k) {
                    continue;
                }
                match o.get(k) {
                    Some(ov) => compare(&format!("{path}.{k}"), gv, ov, diffs),
                    None => diffs.push(format!("{path}.{k}: missing")),
                }
            }
        }
        (Value::Array(g), Value::Array(o)) => {
            if g.len() != o.len() {
                diffs.push(format!("{path}: {} items, golden {}", o.len(), g.len()));
                return;
            }
            for (i, (gv, ov)) in g.iter().zip(o).enumerate() {
                compare(&format!("{path}[{i}]"), gv, ov, diffs);
            }
        }
        (Value::Number(g), Value::Number(o)) => {
            let (g, o) = (g.as_f64().unwrap(), o.as_f64().unwrap());
            if (g - o).abs() > TOLERANCE * g.abs().max(1.0) {
                diffs.push(format!("{path}: {o}, golden {g}"));
            }
        }
        (g, o) if g == o => {}
        (g, o) => diffs.push(format!("{path}: {o}, golden {g}")),
    }
}

/// Every built-in's name, sorted.
fn builtins() -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(root().join("topologies"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert!(names.len() >= 10, "{names:?}");
    names
}

/// Each golden run: (golden file, the topology file, whether the link faults are on), the faulty variants (the fault
/// schedule, and the link faults where the medium has links) written into `tmp`.
fn golden_runs(tmp: &Path) -> Vec<(String, PathBuf, bool)> {
    std::fs::create_dir_all(tmp).unwrap();
    let mut runs = Vec::new();
    for name in builtins() {
        let plain = root().join(format!("topologies/{name}.toml"));
        let faulty = tmp.join(format!("{name}-faults.toml"));
        std::fs::write(&faulty, with_faults(&std::fs::read_to_string(&plain).unwrap())).unwrap();
        // A radio decides its frames' fates itself: its faulty variant has the fault schedule, no link rules.
        let radio = Scenario::from_path(&plain).unwrap().radio_medium().is_some();
        runs.push((format!("{name}.json"), plain, false));
        runs.push((format!("{name}-faults.json"), faulty, !radio));
    }
    runs
}

fn golden(file: &str) -> Value {
    let path = root().join("tests/golden").join(file);
    match std::fs::read(&path) {
        Ok(b) => serde_json::from_slice(&b).unwrap(),
        Err(e) => panic!("{}: {e} (record it with SIMNET_BLESS=1)", path.display()),
    }
}

/// The library's run in memory of every built-in gives its golden summary (the fast suite's check; the run over
/// UDP is checked against the same files by the long suite).
#[test]
fn every_builtin_keeps_its_golden_summary() {
    let bless = std::env::var_os("SIMNET_BLESS").is_some();
    let tmp = std::env::temp_dir().join(format!("simnet-golden-{}", std::process::id()));
    let mut diffs = Vec::new();
    for (file, toml, faults) in golden_runs(&tmp) {
        let got = in_memory(&toml, faults);
        if bless {
            std::fs::write(
                root().join("tests/golden").join(&file),
                serde_json::to_string_pretty(&got).unwrap() + "\n",
            )
            .unwrap();
            continue;
        }
        compare(&format!("{file} (in memory)"), &golden(&file), &got, &mut diffs);
    }
    let _ = std::fs::remove_dir_all(&tmp);
    assert!(diffs.is_empty(), "{} differences:\n{}", diffs.len(), diffs.join("\n"));
}

/// The same runs (two per built-in) through the command line over UDP on the virtual clock give the golden summaries too.
#[test]
#[ignore = "long suite: two runs per built-in over UDP (.ci/run runs it)"]
fn every_builtin_keeps_its_golden_summary_over_udp() {
    let tmp = std::env::temp_dir().join(format!("simnet-golden-udp-{}", std::process::id()));
    let mut diffs = Vec::new();
    for (file, toml, faults) in golden_runs(&tmp) {
        let got = summary(&toml, if faults { FAULTY } else { &[] });
        compare(&format!("{file} (over UDP)"), &golden(&file), &got, &mut diffs);
    }
    let _ = std::fs::remove_dir_all(&tmp);
    assert!(diffs.is_empty(), "{} differences:\n{}", diffs.len(), diffs.join("\n"));
}
