//! Campaigns (`simnet sweep`): a sweep killed mid-way and run again writes the bytes an uninterrupted one writes;
//! shards merged are the unsharded sweep; the confidence intervals cover the true mean at their nominal rate; over
//! UDP and in memory the same records.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::AtomicBool;

use simnet::campaign::{self, Axis, Plan, PlanFile, Store};
use simnet::scenario::Overrides;
use simnet::stats::MeanCi;
use simnet::Scenario;

fn simnet() -> Command {
    Command::new(env!("CARGO_BIN_EXE_simnet"))
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("simnet-campaign-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// A small campaign: ring3 for 2 s, loss × self weight, `seeds` seeds.
fn sweep_args(out: &Path, seeds: u64) -> Vec<String> {
    [
        "sweep",
        "-q",
        "-t",
        "ring3",
        "--set",
        "link.loss.p=0:0.3:0.1",
        "--set",
        "consensus.self=0.6,0.7",
        "--seeds",
        &seeds.to_string(),
        "--duration",
        "2",
        "--estimators",
        "sequeira,independent,kcf",
        "--out",
        out.to_str().unwrap(),
    ]
    .iter()
    .map(|s| s.to_string())
    .collect()
}

fn sweep(args: &[String]) {
    let out = simnet().args(args).output().unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn read(dir: &Path, file: &str) -> String {
    std::fs::read_to_string(dir.join(file)).unwrap_or_else(|e| panic!("{}: {e}", dir.join(file).display()))
}

fn records(dir: &Path) -> usize {
    std::fs::read_dir(dir.join("runs"))
        .map(|d| {
            d.flatten()
                .filter(|e| e.path().extension().is_some_and(|x| x == "json"))
                .count()
        })
        .unwrap_or(0)
}

/// SIGKILL once a few runs are stored, then the same command again: only the missing runs run, and runs.csv and
/// points.csv are byte for byte those of a sweep that was never stopped.
#[test]
fn a_killed_sweep_resumes_to_the_same_files() {
    let (whole, killed) = (tmp("whole"), tmp("killed"));
    sweep(&sweep_args(&whole, 6));
    let total = 4 * 2 * 6;
    assert_eq!(read(&whole, "runs.csv").lines().count(), total + 1);
    let mut child = simnet().args(sweep_args(&killed, 6)).spawn().unwrap();
    // Wait for the event counted (stored runs), not for time.
    while records(&killed) < 3 {
        if let Some(status) = child.try_wait().unwrap() {
            panic!("the sweep ended ({status}) before it could be killed");
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let stored = records(&killed);
    assert!(stored < total, "the kill came after every run ({stored})");
    assert!(!killed.join("runs.csv").exists(), "a killed sweep left its tables");
    // No partial record: every file there reads as a record.
    for e in std::fs::read_dir(killed.join("runs")).unwrap().flatten() {
        let text = std::fs::read_to_string(e.path()).unwrap();
        if e.path().extension().is_some_and(|x| x == "json") {
            serde_json::from_str::<campaign::RunRecord>(&text).unwrap();
        }
    }
    let out = simnet().args(sweep_args(&killed, 6)).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for f in ["runs.csv", "points.csv"] {
        assert_eq!(read(&killed, f), read(&whole, f), "{f}");
    }
    // A third time nothing runs, and nothing changes.
    let quiet: Vec<String> = sweep_args(&killed, 6).into_iter().filter(|a| a != "-q").collect();
    let out = simnet().args(&quiet).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains(&format!("0 run now, {total} already")), "{err}");
    assert_eq!(read(&killed, "points.csv"), read(&whole, "points.csv"));
    for d in [whole, killed] {
        let _ = std::fs::remove_dir_all(d);
    }
}

/// Shards 1/3, 2/3 and 3/3 in their own directories, merged, are the unsharded sweep; shards sharing one directory
/// write the files when the last one finishes.
#[test]
fn shards_merged_are_the_whole_sweep() {
    let whole = tmp("unsharded");
    sweep(&sweep_args(&whole, 3));
    let shards: Vec<PathBuf> = (1..=3).map(|i| tmp(&format!("shard{i}"))).collect();
    for (i, d) in shards.iter().enumerate() {
        let mut a = sweep_args(d, 3);
        a.extend(["--shard".into(), format!("{}/3", i + 1)]);
        sweep(&a);
        assert!(!d.join("runs.csv").exists(), "shard {} alone wrote the tables", i + 1);
    }
    // A merge of two of the three names the runs still missing: the directories given are incomplete input (2).
    let merged = tmp("merged");
    let out = simnet()
        .args(["sweep", "merge"])
        .args(&shards[..2])
        .arg("--out")
        .arg(&merged)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("8 of 24 runs are missing"));
    let out = simnet()
        .args(["sweep", "merge", "-q"])
        .args(&shards)
        .arg("--out")
        .arg(&merged)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for f in ["runs.csv", "points.csv"] {
        assert_eq!(read(&merged, f), read(&whole, f), "{f}");
    }
    let manifest: serde_json::Value = serde_json::from_str(&read(&merged, "manifest.json")).unwrap();
    assert_eq!(
        manifest["made_by"].as_array().unwrap().len(),
        4,
        "three shards and the merge"
    );
    // One shared directory: the last shard writes the files.
    let shared = tmp("shared");
    for i in 1..=3 {
        let mut a = sweep_args(&shared, 3);
        a.extend(["--shard".into(), format!("{i}/3")]);
        sweep(&a);
    }
    assert_eq!(read(&shared, "points.csv"), read(&whole, "points.csv"));
    // Another campaign's shard is refused.
    let other = tmp("other");
    sweep(
        &[
            "sweep",
            "-q",
            "-t",
            "ring3",
            "--set",
            "link.loss.p=0.1",
            "--seeds",
            "1",
            "--duration",
            "1",
            "--out",
            other.to_str().unwrap(),
        ]
        .map(String::from),
    );
    let out = simnet()
        .args(["sweep", "merge"])
        .arg(&shards[0])
        .arg(&other)
        .arg("--out")
        .arg(tmp("refused"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stderr).contains("not shards of one campaign"));
    for d in shards.into_iter().chain([whole, merged, shared, other]) {
        let _ = std::fs::remove_dir_all(d);
    }
}

/// 200 replications of a 10-seed estimate of a Bernoulli link's loss rate: the 95 % Student-t interval covers the
/// link's p in 95 % of them, within 3σ of the binomial count (σ = √(0.95 · 0.05 / 200)).
#[test]
fn the_confidence_interval_covers_the_true_loss_rate_at_its_nominal_rate() {
    let p = 0.3;
    let base = Scenario::from_toml(
        "[sim]\nrate_hz = 100.0\nduration_s = 0.5\nburn_in_s = 0.1\n[model]\nkind = \"linear\"\n\
         a = [[1.0]]\nc = [[1.0]]\nq = [[1.0]]\nr = [[1.0]]\n[[node]]\nid = 0\n[[node]]\nid = 1\n\
         [[edge]]\nnodes = [0, 1]\n",
        "pair.toml",
    )
    .unwrap();
    let plan = Plan::new(base, vec![Axis::parse(&format!("link.loss.p={p}")).unwrap()], 2000).unwrap();
    let dir = tmp("coverage");
    let file = PlanFile::of(&plan);
    let store = Store::open(&dir, &file).unwrap();
    let runs = plan.runs();
    let ran = campaign::run_missing(
        &plan,
        &runs,
        &store,
        &campaign::in_memory,
        &|| {},
        &AtomicBool::new(false),
    );
    assert!(ran.failed.is_empty(), "{:?}", ran.failed);
    let rates: Vec<f64> = runs
        .iter()
        .map(|r| store.get(r, &file).unwrap().unwrap().get("loss_rate").unwrap())
        .collect();
    let covered = rates
        .chunks(10)
        .filter(|c| {
            let ci = MeanCi::of(c, 0.95);
            ci.low <= p && p <= ci.high
        })
        .count();
    let sigma = (0.95f64 * 0.05 / 200.0).sqrt();
    let rate = covered as f64 / 200.0;
    println!("the 95 % interval covered p = {p} in {covered} of 200 replications");
    assert!(
        (rate - 0.95).abs() <= 3.0 * sigma,
        "coverage {rate} (3σ = {:.3})",
        3.0 * sigma
    );
    let _ = std::fs::remove_dir_all(dir);
}

/// `--transport udp` runs over sockets: the same records as in memory.
#[test]
fn a_sweep_over_udp_gives_the_records_of_memory() {
    let (mem, udp) = (tmp("mem"), tmp("udp"));
    let args = |d: &Path| {
        [
            "sweep",
            "-q",
            "-t",
            "ring3",
            "--set",
            "link.loss.p=0,0.2",
            "--seeds",
            "2",
            "--duration",
            "1",
            "--estimators",
            "all",
            "--rounds",
            "2",
            "--out",
            d.to_str().unwrap(),
        ]
        .map(String::from)
        .to_vec()
    };
    sweep(&args(&mem));
    let mut a = args(&udp);
    a.extend(["--transport".into(), "udp".into()]);
    sweep(&a);
    assert_eq!(read(&udp, "runs.csv"), read(&mem, "runs.csv"));
    // Each scheme's fused error is a figure of every run; the fusion centers have none.
    let runs = read(&mem, "runs.csv");
    let header: Vec<&str> = runs.lines().next().unwrap().split(',').collect();
    let col = |name: &str| {
        header
            .iter()
            .position(|h| *h == name)
            .unwrap_or_else(|| panic!("no {name}"))
    };
    for line in runs.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let fused: f64 = f[col("kcf.fused_error")].parse().unwrap();
        assert!(fused.is_finite() && fused > 0.0, "{line}");
        assert_eq!(f[col("centralized.fused_error")], "", "{line}");
    }
    for d in [mem, udp] {
        let _ = std::fs::remove_dir_all(d);
    }
}

/// Bad keys, values and options exit 2 naming them, before any run; every run's summary records its scenario.
#[test]
fn bad_sweeps_exit_2_naming_what_is_wrong() {
    let d = tmp("bad");
    for (args, named) in [
        (vec!["--set", "link.loss.p=0,1.5"], "link.loss.p = 1.5"),
        (vec!["--set", "sim.rate_hzz=5"], "rate_hzz"),
        (vec!["--set", "link.loss.p"], "--set"),
        (vec!["--set", "link.loss.p=0:1:0"], "step"),
        (vec!["--set", "sim.seed=1,2"], "--seeds"),
        (vec!["--set", "link.loss.p=0.1", "--shard", "4/3"], "--shard"),
        (vec!["--set", "link.loss.p=0.1", "--seeds", "0"], "--seeds"),
        (vec!["--set", "link.loss.p=0.1,0.1,0.2"], "given twice"),
        (vec!["--set", "estimators.rounds=1,2,1.0"], "given twice"),
    ] {
        let out = simnet()
            .args(["sweep", "-t", "ring3", "--out", d.to_str().unwrap()])
            .args(&args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(named), "{args:?} does not name {named}: {err}");
        assert!(!d.join("runs").exists() || records(&d) == 0, "{args:?} ran something");
    }
    let s = simnet::Sim::new(
        &Scenario::resolve("ring3")
            .unwrap()
            .with(&Overrides {
                duration_s: Some(0.5),
                ..Default::default()
            })
            .unwrap(),
    )
    .unwrap()
    .run()
    .unwrap()
    .summary();
    let settings = s.settings.unwrap();
    let again = Scenario::from_toml(&settings.scenario, "again.toml").unwrap();
    assert_eq!(again.digest(), settings.scenario_sha256);
    assert_eq!(again.sim().duration_s, 0.5);
    let _ = std::fs::remove_dir_all(d);
}

/// A small sweep of ring3 over `axes` into `dir`, in memory.
fn sweep_of(dir: &Path, axes: &[&str]) -> std::process::Output {
    let mut a: Vec<String> = ["sweep", "-t", "ring3", "--duration", "1", "--seeds", "2", "--out"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    a.push(dir.to_str().unwrap().into());
    for x in axes {
        a.extend(["--set".to_string(), x.to_string()]);
    }
    simnet().args(&a).output().unwrap()
}

/// `runs.csv`'s rows as (swept values by column, measured loss rate).
fn rows_of(dir: &Path) -> Vec<(std::collections::BTreeMap<String, String>, f64)> {
    let text = read(dir, "runs.csv");
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let loss = head.iter().position(|h| *h == "loss_rate").unwrap();
    lines
        .map(|l| {
            let cells: Vec<&str> = l.split(',').collect();
            let values = head
                .iter()
                .zip(&cells)
                .filter(|(h, _)| h.contains('.'))
                .map(|(h, c)| (h.to_string(), c.to_string()))
                .collect();
            (values, cells[loss].parse().unwrap())
        })
        .collect()
}

/// The store files each record under the point its own plan gives the run, and checks what a record says against
/// it: the same runs swept with the axes in another order (the plan removed) keep their values; a smaller campaign in
/// the same directory takes the records it shares; a record or a plan that was altered is an error naming the file
/// (exit 2), never a panic or an abort.
#[test]
fn records_are_filed_by_their_values_and_crafted_store_files_are_named() {
    let d = tmp("reorder");
    let out = sweep_of(&d, &["consensus.self=0.6,0.7", "link.loss.p=0,0.2"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let check = |dir: &Path| {
        for (values, loss) in rows_of(dir) {
            let p: f64 = values["link.loss.p"].parse().unwrap();
            if p == 0.0 {
                assert_eq!(loss, 0.0, "{values:?}");
            } else {
                assert!((loss - p).abs() < 0.1, "{values:?}: measured loss {loss}");
            }
        }
    };
    check(&d);
    std::fs::remove_file(d.join("plan.json")).unwrap();
    let out = sweep_of(&d, &["link.loss.p=0,0.2", "consensus.self=0.6,0.7"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("0 run now, 8 already"), "{err}");
    check(&d);
    // A smaller campaign, its one point the last of the first one's.
    std::fs::remove_file(d.join("plan.json")).unwrap();
    let out = sweep_of(&d, &["link.loss.p=0.2", "consensus.self=0.7"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(rows_of(&d).len(), 2);
    check(&d);
    // A record altered to claim another point, or another index.
    let plan: serde_json::Value = serde_json::from_str(&read(&d, "plan.json")).unwrap();
    let record = std::fs::read_dir(d.join("runs"))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .find(|p| {
            let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap();
            r["values"]["link.loss.p"] == 0.2 && r["values"]["consensus.self"] == 0.7
        })
        .unwrap();
    let text = std::fs::read_to_string(&record).unwrap();
    let mut r: serde_json::Value = serde_json::from_str(&text).unwrap();
    r["point"] = 999.into();
    std::fs::write(&record, serde_json::to_string(&r).unwrap()).unwrap();
    let out = sweep_of(&d, &["link.loss.p=0.2", "consensus.self=0.7"]);
    assert!(
        out.status.success(),
        "the index is the plan's: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    r["values"]["link.loss.p"] = 0.0.into();
    std::fs::write(&record, serde_json::to_string(&r).unwrap()).unwrap();
    for out in [
        sweep_of(&d, &["link.loss.p=0.2", "consensus.self=0.7"]),
        simnet().args(["sweep", "merge"]).arg(&d).output().unwrap(),
    ] {
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert!(
            err.contains(&record.display().to_string()) && err.contains("link.loss.p = 0"),
            "{err}"
        );
    }
    std::fs::write(&record, text).unwrap();
    // Crafted plans: a seed count that would allocate terabytes, points that are not the axes' product.
    let good = read(&d, "plan.json");
    for (change, named) in [
        (("seeds", serde_json::json!(1_000_000_000_000u64)), "seeds"),
        (("seeds", serde_json::json!(0)), "seeds"),
        (("points", serde_json::json!([])), "points"),
        (("axes", serde_json::json!([])), "point 0"),
    ] {
        let mut p = plan.clone();
        p[change.0] = change.1.clone();
        std::fs::write(d.join("plan.json"), serde_json::to_string(&p).unwrap()).unwrap();
        for out in [
            sweep_of(&d, &["link.loss.p=0.2", "consensus.self=0.7"]),
            simnet().args(["sweep", "merge"]).arg(&d).output().unwrap(),
        ] {
            let err = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(2), "{change:?}: {err}");
            assert!(err.contains("plan.json") && err.contains(named), "{change:?}: {err}");
        }
    }
    std::fs::write(d.join("plan.json"), good).unwrap();
    let _ = std::fs::remove_dir_all(d);
}

/// A campaign stopped and resumed lists every process that made its runs in `manifest.json`, their runs adding up.
#[test]
fn the_manifest_lists_every_process_that_made_runs() {
    let d = tmp("processes");
    let out = sweep_of(&d, &["link.loss.p=0"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // A second process with more seeds would be another campaign; remove one record so that a resume runs it.
    let first = std::fs::read_dir(d.join("runs"))
        .unwrap()
        .flatten()
        .next()
        .unwrap()
        .path();
    std::fs::remove_file(first).unwrap();
    let out = sweep_of(&d, &["link.loss.p=0"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let m: serde_json::Value = serde_json::from_str(&read(&d, "manifest.json")).unwrap();
    let made_by = m["made_by"].as_array().unwrap();
    assert_eq!(made_by.len(), 2, "{made_by:?}");
    let ran: u64 = made_by.iter().map(|p| p["ran"].as_u64().unwrap()).sum();
    assert_eq!(ran, 3, "2 runs, then the one removed");
    let _ = std::fs::remove_dir_all(d);
}
