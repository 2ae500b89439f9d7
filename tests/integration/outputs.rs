//! (o) What a run leaves behind: every built-in writes its files and plots even when a covariance overflows; a bad
//! `--out` fails before the run; files are written before stdout, so a closed pipe loses none; Ctrl-C keeps the
//! partial results and exits 130.

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn simnet() -> Command {
    Command::new(env!("CARGO_BIN_EXE_simnet"))
}

fn tmp(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("simnet-out-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// Waits for the child; a hang (the bug this guards against: plotters looping on an infinite axis) fails the test
/// instead of blocking it forever.
fn wait_bounded(mut child: std::process::Child, what: &str) -> std::process::ExitStatus {
    let start = Instant::now();
    loop {
        if let Some(s) = child.try_wait().unwrap() {
            return s;
        }
        if start.elapsed() > Duration::from_secs(300) {
            let _ = child.kill();
            panic!("{what} did not finish in 300 s");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

const FILES: [&str; 6] = [
    "summary.json",
    "trace.csv",
    "links.csv",
    "trajectory.svg",
    "error.svg",
    "trace_p.svg",
];

#[test]
fn every_builtin_writes_its_plots_even_when_a_covariance_overflows() {
    let list = simnet().arg("topologies").output().unwrap();
    let names: Vec<String> = String::from_utf8_lossy(&list.stdout)
        .lines()
        .filter_map(|l| l.split_whitespace().next().map(String::from))
        .collect();
    assert!(names.len() >= 10, "{names:?}");
    for name in &names {
        let d = tmp(&format!("all-{name}"));
        // Heavy loss so that the prediction-only and starved filters drift as far as they will in a short run (a
        // radio's loss is its channel's).
        let radio = simnet::Scenario::resolve(name).unwrap().radio_medium().is_some();
        let loss: &[&str] = if radio { &[] } else { &["--loss", "0.9"] };
        let child = simnet()
            .args(["-t", name, "--duration", "1", "-q"])
            .args(loss)
            .arg("--out")
            .arg(&d)
            .stdout(Stdio::null())
            .spawn()
            .unwrap();
        let status = wait_bounded(child, name);
        assert!(status.success(), "{name}: {status}");
        for f in FILES {
            assert!(d.join(f).metadata().is_ok_and(|m| m.len() > 0), "{name}: {f} missing");
        }
        let _ = std::fs::remove_dir_all(&d);
    }
    // Sinopoli's unstable scalar system: the estimator's prediction-only twin reaches trace P ≈ 1.7e308 in 20 s.
    let d = tmp("sinopoli");
    let child = simnet()
        .args(["-t", "sinopoli-scalar", "--duration", "20", "-q", "--out"])
        .arg(&d)
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    assert!(wait_bounded(child, "sinopoli-scalar").success());
    let summary: serde_json::Value = serde_json::from_slice(&std::fs::read(d.join("summary.json")).unwrap()).unwrap();
    assert_eq!(
        summary["nodes"][1]["independent"]["diverged"], true,
        "the twin must overflow for this test"
    );
    let svg = std::fs::read_to_string(d.join("trace_p.svg")).unwrap();
    assert!(
        svg.contains("clipped, not in scale"),
        "the diverged twin is named in the legend"
    );
    // Its axis is the networked filter's: ticks of order 1, not 1e308.
    assert!(!svg.contains("e30"), "the diverged twin set the scale");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn a_bad_out_fails_before_the_run_with_exit_2() {
    let d = tmp("badout");
    std::fs::create_dir_all(&d).unwrap();
    let file = d.join("a-file");
    std::fs::write(&file, "x").unwrap();
    let ro = d.join("read-only");
    std::fs::create_dir_all(&ro).unwrap();
    let mut cases = vec![
        (file.clone(), "is not a directory"),
        (file.join("sub"), "cannot create"),
    ];
    // root may write anywhere: the read-only case only means something for other users.
    let root = Command::new("id")
        .arg("-u")
        .output()
        .map(|o| o.stdout == b"0\n")
        .unwrap_or(true);
    if !root {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o555)).unwrap();
        cases.push((ro.clone(), "cannot write"));
    }
    for (out, what) in cases {
        // 1e6 steps: a check made after the run would take minutes, not return at once with nothing printed.
        let o = simnet()
            .args(["-t", "ring3", "--duration", "10000", "-q", "--out"])
            .arg(&out)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{}: {err}", out.display());
        assert!(err.contains("--out") && err.contains(what), "{err}");
        assert!(
            o.stdout.is_empty(),
            "nothing ran: {}",
            String::from_utf8_lossy(&o.stdout)
        );
    }
    // The same check for every command that writes a directory.
    let f = file.to_str().unwrap();
    for args in [
        vec!["reproduce", "nieminen", "--out", f],
        vec!["protocol", "-t", "tri3-paper", "--out", f],
        vec!["bounds", "-t", "sinopoli-scalar", "--sweep", "--out", f],
    ] {
        let o = simnet().args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains("is not a directory"), "{args:?}: {err}");
    }
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn a_closed_stdout_loses_no_file_and_is_not_success() {
    let d = tmp("pipe");
    let mut child = simnet()
        .args(["-t", "ring3", "--duration", "2", "-q", "--out"])
        .arg(&d)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    // The reader goes away before anything is printed (as `| head -1` does once it has its line).
    drop(child.stdout.take());
    let status = wait_bounded(child, "ring3 with stdout closed");
    for f in FILES {
        assert!(d.join(f).metadata().is_ok_and(|m| m.len() > 0), "{f} missing");
    }
    assert_eq!(
        status.code(),
        Some(141),
        "a failed write to stdout is 128 + SIGPIPE, not success"
    );
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn ctrl_c_keeps_partial_results_and_exits_130() {
    let d = tmp("sigint");
    let mut child = simnet()
        .args(["-t", "ring3", "--duration", "100000", "-q", "--out"])
        .arg(&d)
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    // Wait for rows on disk (the run is under way and its signal handler installed), not for a time.
    // The run streams `trace.csv` into its staging directory until the end.
    let streamed = || -> u64 {
        std::fs::read_dir(&d)
            .into_iter()
            .flatten()
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().starts_with(".simnet-stage-"))
            .filter_map(|e| e.path().join("trace.csv").metadata().ok())
            .map(|m| m.len())
            .sum()
    };
    let start = Instant::now();
    while streamed() < 100_000 {
        if start.elapsed() > Duration::from_secs(300) {
            // A run of 100 000 s left behind would fill the disk.
            let _ = child.kill();
            panic!("no rows streamed");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let ok = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(ok.success());
    let status = wait_bounded(child, "interrupted ring3");
    assert_eq!(status.code(), Some(130), "{status}");
    let summary: serde_json::Value = serde_json::from_slice(&std::fs::read(d.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["interrupted"], true);
    let steps = summary["steps"].as_u64().unwrap();
    assert!(steps > 0 && steps < 10_000_000);
    let trace = std::fs::read_to_string(d.join("trace.csv")).unwrap();
    let rows = trace
        .lines()
        .filter(|l| l.contains(",networked,") || l.contains(",independent,"))
        .count() as u64;
    assert_eq!(rows, steps * 3 * 2, "every step run is in trace.csv");
    assert_eq!(streamed(), 0, "the staging directory is gone");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn result_files_say_how_they_were_made_and_their_counts_add_up() {
    let d = tmp("provenance");
    let o = simnet()
        .args([
            "-t",
            "ring3",
            "--loss",
            "0.3",
            "--duplicate",
            "0.05",
            "--duration",
            "6",
            "--seed",
            "7",
            "-q",
            "--out",
        ])
        .arg(&d)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s: serde_json::Value = serde_json::from_slice(&std::fs::read(d.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s["simnet_version"], env!("CARGO_PKG_VERSION"));
    let set = &s["settings"];
    assert_eq!(set["overrides"]["duration_s"], 6.0);
    assert_eq!(set["overrides"]["seed"], 7);
    assert_eq!(set["overrides"]["loss"]["p"], 0.3);
    assert!(
        set["overrides"].get("delay_ms").is_none(),
        "unset overrides are left out"
    );
    assert_eq!(set["duration_s"], 6.0);
    assert_eq!(set["links"].as_array().unwrap().len(), 6);
    assert_eq!(set["links"][0]["loss"]["model"], "bernoulli");
    assert_eq!(set["links"][0]["duplicate"], 0.05);
    let steps = s["steps"].as_u64().unwrap();
    for l in s["links"].as_array().unwrap() {
        let n = |k: &str| l[k].as_u64().unwrap();
        assert_eq!(
            n("sent"),
            n("delivered") + n("late") + n("corrupted") + n("lost"),
            "{l}"
        );
        assert!(n("duplicated") > 0);
        // One datagram per step (no split channels): γ is the delivered fraction, 1 − 0.3 within 3σ.
        let gamma = l["arrival_rate"].as_f64().unwrap();
        let sigma = (0.3f64 * 0.7 / steps as f64).sqrt();
        assert!((gamma - 0.7).abs() < 3.0 * sigma, "γ = {gamma}");
        assert!((gamma - n("delivered") as f64 / n("sent") as f64).abs() < 1e-9, "{l}");
    }
    let links = std::fs::read_to_string(d.join("links.csv")).unwrap();
    assert!(links.lines().next().unwrap().contains(",arrival_rate,"));
    let trace = std::fs::read_to_string(d.join("trace.csv")).unwrap();
    let header: Vec<&str> = trace.lines().next().unwrap().split(',').collect();
    for c in ["estimator", "var_x", "var_yaw", "error", "diverged"] {
        assert!(header.contains(&c), "{c} missing from {header:?}");
    }
    assert!(!header.contains(&"filter"), "`filter` shadows DataFrame.filter");
    // The error column is the distance the node scored (position error for pose).
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    for line in trace.lines().skip(1).filter(|l| l.contains(",networked,")).take(50) {
        let f: Vec<&str> = line.split(',').collect();
        let v = |name: &str| f[col(name)].parse::<f64>().unwrap();
        let e = ((v("true_x") - v("est_x")).powi(2)
            + (v("true_y") - v("est_y")).powi(2)
            + (v("true_z") - v("est_z")).powi(2))
        .sqrt();
        assert!((e - v("error")).abs() <= 1e-12 * e.max(1.0), "{line}");
        assert!(v("var_x") > 0.0);
    }
    let _ = std::fs::remove_dir_all(&d);

    // A linear model's huge states in shortest round-trip form, not 94 fixed-point digits.
    let d = tmp("linear-numbers");
    let o = simnet()
        .args(["-t", "sinopoli-scalar", "--duration", "20", "-q", "--out"])
        .arg(&d)
        .output()
        .unwrap();
    assert!(o.status.success());
    let trace = std::fs::read_to_string(d.join("trace.csv")).unwrap();
    let longest = trace.lines().flat_map(|l| l.split(',')).map(str::len).max().unwrap();
    assert!(longest <= 24, "a cell of {longest} characters");
    let _ = std::fs::remove_dir_all(&d);
}

/// Every distributed estimator of a run has its rows in `trace.csv`, one per node and step, from which its figures in
/// `summary.json` are recomputed: per node, the mean error and the mean NEES over the steps after the burn-in.
#[test]
fn every_scheme_has_its_rows_in_trace_csv() {
    let d = tmp("scheme-rows");
    let o = simnet()
        .args([
            "-t",
            "rgg50",
            "--estimators",
            "kcf,ci",
            "--rounds",
            "2",
            "--loss",
            "0.1",
        ])
        .args(["--duration", "3", "-q", "--out"])
        .arg(&d)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s: serde_json::Value = serde_json::from_slice(&std::fs::read(d.join("summary.json")).unwrap()).unwrap();
    let (steps, burn_in) = (s["steps"].as_u64().unwrap(), s["burn_in_steps"].as_u64().unwrap());
    let trace = std::fs::read_to_string(d.join("trace.csv")).unwrap();
    let mut lines = trace.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    // (scheme, node) → (rows, Σ error, Σ NEES, counted) after the burn-in.
    let mut by: std::collections::BTreeMap<(String, u64), (u64, f64, f64, u64)> = Default::default();
    for line in lines {
        let f: Vec<&str> = line.split(',').collect();
        let scheme = f[col("estimator")];
        if !["kcf", "ci"].contains(&scheme) {
            continue;
        }
        assert_eq!(f[col("received")], "", "{line}");
        let e = by
            .entry((scheme.to_string(), f[col("node")].parse().unwrap()))
            .or_default();
        e.0 += 1;
        if f[col("step")].parse::<u64>().unwrap() >= burn_in {
            e.1 += f[col("error")].parse::<f64>().unwrap();
            e.2 += f[col("nees")].parse::<f64>().unwrap();
            e.3 += 1;
        }
    }
    assert_eq!(by.len(), 2 * 50, "a row set per scheme and node");
    for ((scheme, node), (rows, error, nees, n)) in &by {
        assert_eq!(*rows, steps, "{scheme} node {node}");
        let reported = s["estimators"][scheme.as_str()]["nodes"]
            .as_array()
            .unwrap()
            .iter()
            .find(|r| r["id"] == *node)
            .unwrap();
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * b.abs().max(1e-12);
        let (mean, nees_mean) = (error / *n as f64, nees / *n as f64);
        assert!(
            close(mean, reported["mean_error"].as_f64().unwrap()),
            "{scheme} node {node}: {mean} vs {reported}"
        );
        assert!(
            close(nees_mean, reported["nees_mean"].as_f64().unwrap()),
            "{scheme} node {node}: {nees_mean} vs {reported}"
        );
    }
    let _ = std::fs::remove_dir_all(&d);
}

/// What the command line says: range errors for negative values, what is missing, warnings, counted nouns.
#[test]
fn the_command_line_says_what_is_wrong() {
    let run = |args: &[&str]| {
        let o = simnet().args(args).output().unwrap();
        (
            o.status.code(),
            String::from_utf8_lossy(&o.stderr).to_string(),
            String::from_utf8_lossy(&o.stdout).to_string(),
        )
    };
    let (code, err, _) = run(&["-t", "ring3", "--loss", "-0.1"]);
    assert_eq!(code, Some(2));
    assert!(err.contains("must be a probability in [0, 1], got -0.1"), "{err}");
    let (code, err, _) = run(&["--loss", "0.2"]);
    assert_eq!(code, Some(2));
    assert!(err.contains("--topology"), "{err}");
    let (_, err, _) = run(&["-t", "nosuch.toml"]);
    assert!(
        err.contains("./topologies/nosuch.toml,") && !err.contains(".toml.toml"),
        "{err}"
    );

    let d = tmp("messages");
    std::fs::create_dir_all(&d).unwrap();
    let one = d.join("one.toml");
    std::fs::write(&one, "name = \"one\"\n[[node]]\nid = 0\n").unwrap();
    let (code, _, out) = run(&["validate", one.to_str().unwrap()]);
    assert_eq!(code, Some(0));
    assert!(out.contains("1 node,") && out.contains("0 directed links"), "{out}");
    let bad = d.join("bad.toml");
    std::fs::write(&bad, "[sim]\nrate_hz = -5\n[[node]]\nid = 0\n").unwrap();
    let (_, err, _) = run(&["validate", bad.to_str().unwrap()]);
    assert!(err.contains("1 problem:"), "{err}");

    let late = d.join("late.toml");
    std::fs::write(
        &late,
        "name = \"late\"\n[sim]\nduration_s = 2.0\nburn_in_s = 0.5\n[[node]]\nid = 0\n[[node]]\nid = 1\n[[edge]]\nnodes = [0, 1]\n\
         [[fault]]\nkind = \"crash\"\nnode = 1\nat_s = 5.0\n",
    )
    .unwrap();
    let (code, err, _) = run(&["-t", late.to_str().unwrap()]);
    assert_eq!(code, Some(0));
    assert!(
        err.contains("1 fault starts after the run ends at 2 s (at 5 s)"),
        "{err}"
    );
    let (_, err, _) = run(&["-t", "ring3", "--duration", "1"]);
    assert!(err.contains("shorter than the burn-in"), "{err}");
    let (_, err, _) = run(&["-t", "ring3", "--duration", "1", "-q"]);
    assert!(err.is_empty(), "-q keeps warnings quiet: {err}");
    let _ = std::fs::remove_dir_all(&d);
}

/// `measurements.csv` holds what each node measured, so that a filter can be recomputed outside simnet: each node's
/// independent Kalman filter of a scalar system, rerun here from the file (prior from `trace.csv`'s previous row),
/// gives every posterior `trace.csv` reports.
#[test]
fn measurements_csv_recomputes_the_independent_filter() {
    let d = tmp("measurements");
    std::fs::create_dir_all(&d).unwrap();
    let (a, q, r) = (0.95, 0.1, 0.5);
    let toml = format!(
        "name = \"scalar2\"\n[sim]\nrate_hz = 100.0\nduration_s = 2.0\nburn_in_s = 0.0\nseed = 3\n\
         [model]\nkind = \"linear\"\na = [[{a}]]\nc = [[1.0]]\nq = [[{q}]]\nr = [[{r}]]\nx0 = [1.0]\np0 = [[1.0]]\n\
         [[node]]\nid = 0\n[[node]]\nid = 1\n[[edge]]\nnodes = [0, 1]\n"
    );
    let file = d.join("scalar2.toml");
    std::fs::write(&file, toml).unwrap();
    let out = d.join("out");
    let o = simnet()
        .arg("-t")
        .arg(&file)
        .args(["--loss", "0.3", "-q", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let read = |name: &str| std::fs::read_to_string(out.join(name)).unwrap();
    let measurements = read("measurements.csv");
    let mut lines = measurements.lines();
    assert_eq!(lines.next(), Some("step,t,node,channel,rows,values,r"));
    let mut z = std::collections::HashMap::new();
    for l in lines {
        let f: Vec<&str> = l.split(',').collect();
        assert_eq!((f[3], f[4], f[6]), ("0", "0", "0.5"), "{l}");
        z.insert(
            (f[0].parse::<u64>().unwrap(), f[2].to_string()),
            f[5].parse::<f64>().unwrap(),
        );
    }
    assert_eq!(z.len(), 2 * 200, "one measurement per node and step");
    let trace = read("trace.csv");
    let header: Vec<&str> = trace.lines().next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (est, var) = (col("est_x0"), col("var_x0"));
    let mut last: std::collections::HashMap<String, (f64, f64)> = Default::default();
    let mut checked = 0;
    for l in trace.lines().skip(1).filter(|l| l.contains(",independent,")) {
        let f: Vec<&str> = l.split(',').collect();
        let (k, node) = (f[0].parse::<u64>().unwrap(), f[2].to_string());
        let post = (f[est].parse::<f64>().unwrap(), f[var].parse::<f64>().unwrap());
        if let Some((x, p)) = last.get(&node) {
            let (xp, pp) = (a * x, a * a * p + q);
            let kg = pp / (pp + r);
            let want = (xp + kg * (z[&(k, node.clone())] - xp), (1.0 - kg) * pp);
            assert!(
                (want.0 - post.0).abs() < 1e-9 * (1.0 + want.0.abs()) && (want.1 - post.1).abs() < 1e-9 * want.1,
                "node {node}, step {k}: recomputed {want:?}, trace {post:?}"
            );
            checked += 1;
        }
        last.insert(node, post);
    }
    assert_eq!(checked, 2 * 199);
    let _ = std::fs::remove_dir_all(&d);
}

/// An output directory holds one run's files as a set: a run without estimators into the directory of a run with
/// them leaves no `estimators.csv` behind; files simnet did not write stay (an IMU file of a node the run does not
/// have, notes), and a run refused for bad input changes nothing. `.simnet-outputs` lists the set and says it is
/// complete.
#[test]
fn a_rerun_removes_only_what_an_earlier_run_wrote() {
    let d = tmp("stale");
    let run = |extra: &[&str]| {
        simnet()
            .args(["-q", "-t", "ring3", "--duration", "1", "--out"])
            .arg(&d)
            .args(extra)
            .output()
            .unwrap()
    };
    assert!(run(&["--estimators", "icf"]).status.success());
    for f in ["estimators.csv", "estimators.svg", "imu-0.csv"] {
        assert!(d.join(f).exists(), "{f}");
    }
    std::fs::write(d.join("imu-99.csv"), "an earlier, larger network's node\n").unwrap();
    std::fs::write(d.join("notes.txt"), "mine\n").unwrap();
    let listing = || {
        let mut v: Vec<_> = std::fs::read_dir(&d)
            .unwrap()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    };
    let before = listing();
    let refused = run(&["--loss", "2"]);
    assert_eq!(refused.status.code(), Some(2));
    assert_eq!(before, listing(), "a refused run changed the directory");
    assert!(run(&[]).status.success());
    for gone in ["estimators.csv", "estimators.svg"] {
        assert!(!d.join(gone).exists(), "{gone} was left behind");
    }
    for kept in [
        "notes.txt",
        "imu-99.csv",
        "imu-0.csv",
        "summary.json",
        "trace.csv",
        "measurements.csv",
        "report.html",
    ] {
        assert!(d.join(kept).exists(), "{kept} is missing");
    }
    assert_eq!(
        std::fs::read_to_string(d.join("imu-99.csv")).unwrap(),
        "an earlier, larger network's node\n"
    );
    let list: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join(".simnet-outputs")).unwrap()).unwrap();
    assert_eq!(list["complete"], true);
    let files: Vec<&str> = list["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f.as_str().unwrap())
        .collect();
    assert!(files.contains(&"trace.csv") && !files.contains(&"imu-99.csv") && !files.contains(&"estimators.csv"));
    // No staging directory or temporary file is left.
    assert!(
        listing()
            .iter()
            .all(|n| !n.contains(".tmp") && !n.starts_with(".simnet-stage-")),
        "{:?}",
        listing()
    );
    let _ = std::fs::remove_dir_all(d);
}

/// The recordings a run reads are never its outputs: a folder holding `imu-0.csv` … `imu-5.csv` and a topology that
/// replays `imu-0.csv` refuses `--out` into that folder (exit 2, every file as it was); into another folder the run
/// goes, and a later run there removes none of the recordings it did not write.
#[test]
fn a_run_never_removes_or_overwrites_the_recordings_it_reads() {
    let made = tmp("recordings-made");
    let out = simnet()
        .args(["-q", "-t", "attitude3", "--duration", "2", "--out"])
        .arg(&made)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let d = tmp("recordings");
    std::fs::create_dir_all(&d).unwrap();
    for i in 0..6 {
        std::fs::copy(made.join(format!("imu-{}.csv", i % 3)), d.join(format!("imu-{i}.csv"))).unwrap();
    }
    let toml = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/topologies/attitude3.toml"))
        .unwrap()
        .replacen("id = 0\n", "id = 0\nimu_csv = \"imu-0.csv\"\n", 1);
    assert!(toml.contains("imu_csv"));
    std::fs::write(d.join("two.toml"), toml).unwrap();
    let bytes = |p: &std::path::Path| std::fs::read(p).unwrap();
    let originals: Vec<Vec<u8>> = (0..6).map(|i| bytes(&d.join(format!("imu-{i}.csv")))).collect();
    let run = |out: &std::path::Path| {
        simnet()
            .current_dir(&d)
            .args(["-q", "-t", "two.toml", "--duration", "2", "--out"])
            .arg(out)
            .output()
            .unwrap()
    };
    let refused = run(std::path::Path::new("."));
    let err = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(2), "{err}");
    assert!(err.contains("imu-0.csv") && err.contains("node[0].imu_csv"), "{err}");
    for (i, b) in originals.iter().enumerate() {
        assert_eq!(&bytes(&d.join(format!("imu-{i}.csv"))), b, "imu-{i}.csv changed");
    }
    // Into a subfolder: the run goes; twice, and the recordings beside it stay as they were.
    for _ in 0..2 {
        let ok = run(std::path::Path::new("out"));
        assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    }
    assert!(
        !d.join("out/imu-0.csv").exists(),
        "a node fed from a file writes no IMU file"
    );
    assert!(d.join("out/imu-1.csv").exists());
    for (i, b) in originals.iter().enumerate() {
        assert_eq!(&bytes(&d.join(format!("imu-{i}.csv"))), b, "imu-{i}.csv changed");
    }
    for dir in [made, d] {
        let _ = std::fs::remove_dir_all(dir);
    }
}

/// What a killed run leaves is cleared by the next one without following a planted link: a staging directory of a
/// run that died (with its temporary files) is removed; a link planted under a name simnet writes is replaced, its
/// target untouched; two runs into one directory at once are refused, not mixed.
#[test]
fn leftovers_are_cleared_and_links_are_not_followed() {
    let d = tmp("leftovers");
    std::fs::create_dir_all(d.join(".simnet-stage-0123456789abcdef")).unwrap();
    std::fs::write(d.join(".simnet-stage-0123456789abcdef/trace.csv"), "half a run").unwrap();
    let victim = tmp("victim");
    std::fs::write(&victim, "not simnet's").unwrap();
    std::os::unix::fs::symlink(&victim, d.join("trace.csv")).unwrap();
    std::os::unix::fs::symlink(&victim, d.join("trace.csv.tmp")).unwrap();
    let out = simnet()
        .args(["-q", "-t", "ring3", "--duration", "1", "--out"])
        .arg(&d)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(std::fs::read_to_string(&victim).unwrap(), "not simnet's");
    assert!(!d.join(".simnet-stage-0123456789abcdef").exists());
    assert!(std::fs::symlink_metadata(d.join("trace.csv")).unwrap().is_file());
    assert!(std::fs::read_to_string(d.join("trace.csv"))
        .unwrap()
        .starts_with("step,"));
    // Another process holding the directory: refused with exit 2, nothing written.
    let lock = std::fs::OpenOptions::new()
        .write(true)
        .open(d.join(".simnet-lock"))
        .unwrap();
    lock.lock().unwrap();
    let summary = std::fs::read(d.join("summary.json")).unwrap();
    let out = simnet()
        .args(["-q", "-t", "ring3", "--duration", "1", "--seed", "7", "--out"])
        .arg(&d)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("another simnet is writing"));
    assert_eq!(std::fs::read(d.join("summary.json")).unwrap(), summary);
    drop(lock);
    // A fifo planted as the lock would block an open: refused, exit 2, naming it.
    std::fs::remove_file(d.join(".simnet-lock")).unwrap();
    assert!(Command::new("mkfifo")
        .arg(d.join(".simnet-lock"))
        .status()
        .unwrap()
        .success());
    let out = simnet()
        .args(["-q", "-t", "ring3", "--duration", "1", "--out"])
        .arg(&d)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains(".simnet-lock there is not a regular file"));
    let _ = std::fs::remove_file(victim);
    let _ = std::fs::remove_dir_all(d);
}

/// A full disk (a 2 MB tmpfs the test mounts, as root) fails the run with exit 1 after its table is printed, and
/// leaves the directory as it was: the earlier run's files whole, no staging directory, no temporary file.
#[test]
fn a_full_disk_leaves_the_earlier_run_whole() {
    let d = tmp("full-disk");
    std::fs::create_dir_all(&d).unwrap();
    let mounted = Command::new("mount")
        .args(["-t", "tmpfs", "-o", "size=2m", "tmpfs"])
        .arg(&d)
        .output()
        .is_ok_and(|o| o.status.success());
    if !mounted {
        eprintln!("SKIPPED a_full_disk_leaves_the_earlier_run_whole: cannot mount a tmpfs here (needs root)");
        let _ = std::fs::remove_dir_all(&d);
        return;
    }
    let out_dir = d.join("run");
    let run = |duration: &str| {
        simnet()
            .args(["-t", "ring3", "--duration", duration, "--out"])
            .arg(&out_dir)
            .output()
            .unwrap()
    };
    let first = run("0.3");
    assert!(first.status.success(), "{}", String::from_utf8_lossy(&first.stderr));
    let listing = || {
        let mut v: Vec<(String, Vec<u8>)> = std::fs::read_dir(&out_dir)
            .unwrap()
            .flatten()
            .map(|e| {
                (
                    e.file_name().to_string_lossy().into_owned(),
                    std::fs::read(e.path()).unwrap(),
                )
            })
            .collect();
        v.sort();
        v
    };
    let before = listing();
    let full = run("30");
    let err = String::from_utf8_lossy(&full.stderr);
    let stdout = String::from_utf8_lossy(&full.stdout);
    let after = listing();
    let _ = Command::new("umount").arg(&d).status();
    assert_eq!(full.status.code(), Some(1), "{err}");
    assert!(err.contains("No space left") && err.contains("is as it was"), "{err}");
    assert!(stdout.contains("fused"), "the table is printed: {stdout}");
    assert_eq!(
        before.iter().map(|(n, _)| n).collect::<Vec<_>>(),
        after.iter().map(|(n, _)| n).collect::<Vec<_>>()
    );
    assert!(before == after, "the earlier run's files changed");
    let _ = std::fs::remove_dir_all(&d);
}

/// A JSON document's leaf fields as paths: `nodes[].networked.mean_error`, a list of tables as `[]`.
fn leaves(v: &serde_json::Value, path: &str, out: &mut std::collections::BTreeSet<String>) {
    let join = |k: &str| {
        if path.is_empty() {
            k.to_string()
        } else {
            format!("{path}.{k}")
        }
    };
    match v {
        // An empty map (no kernel drops) has no field to name.
        serde_json::Value::Object(m) if m.is_empty() => {}
        serde_json::Value::Object(m) => {
            for (k, x) in m {
                leaves(x, &join(k), out);
            }
        }
        serde_json::Value::Array(a) if a.iter().any(|x| x.is_object()) => {
            for x in a {
                leaves(x, &format!("{path}[]"), out);
            }
        }
        _ => {
            out.insert(path.to_string());
        }
    }
}

/// A file's name as the outputs table gives it: `imu-3.csv` is `imu-ID.csv`.
fn documented_name(rel: &str) -> String {
    let digits = |s: &str| !s.is_empty() && s.chars().all(|c| c.is_ascii_digit());
    if let Some(id) = rel
        .strip_prefix("imu-")
        .and_then(|r| r.strip_suffix(".csv"))
        .filter(|i| digits(i))
    {
        let _ = id;
        return "imu-ID.csv".into();
    }
    if rel.starts_with("runs/") && rel.ends_with(".json") {
        return "runs/DIGEST.json".into();
    }
    if rel.starts_with("shards/") && rel.ends_with(".json") {
        return "shards/SHARD.DIGEST.json".into();
    }
    rel.to_string()
}

/// Whether a CSV header is the documented columns: `NAME_*` takes every column with that prefix, `KEY` the swept
/// keys (the columns up to the next documented one), `ESTIMATOR.*` every remaining column with a dot, and a column
/// of some runs only may be absent.
fn header_is(header: &[&str], columns: &[simnet::report::outputs::Field]) -> Result<(), String> {
    let mut i = 0;
    for (c, col) in columns.iter().enumerate() {
        if let Some(prefix) = col.name.strip_suffix('*').filter(|p| p.ends_with('_')) {
            let start = i;
            while i < header.len() && header[i].starts_with(prefix) {
                i += 1;
            }
            if i == start {
                return Err(format!("no `{}` column at {start}", col.name));
            }
        } else if col.name == "KEY" {
            let next = columns.get(c + 1).map(|n| n.name);
            while i < header.len() && Some(header[i]) != next {
                i += 1;
            }
        } else if col.name == "ESTIMATOR.*" {
            while i < header.len() && header[i].contains('.') {
                i += 1;
            }
        } else if header.get(i) == Some(&col.name) {
            i += 1;
        } else if !col.optional {
            return Err(format!("column {i} is {:?}, documented `{}`", header.get(i), col.name));
        }
    }
    if i != header.len() {
        return Err(format!("undocumented columns from {i}: {:?}", &header[i..]));
    }
    Ok(())
}

/// The book's "Output files" chapter is generated from `simnet::report::outputs`; this holds that table to what simnet
/// writes. Runs that between them write every kind of file and field (estimators, attacks, authentication, faults, a
/// wall-clock run, the attitude model, nodes standing apart, a radio channel, a sweep): every file written is in the table with its columns in order, every
/// field of every summary.json is named by a pattern, and everything in the table is written by one of the runs —
/// except what only a multi-host run writes (its parts), and the Parquet copies.
#[test]
fn every_file_column_and_field_written_is_documented() {
    use simnet::report::outputs::{matches, FILES, SUMMARY};
    let base = tmp("documented");
    std::fs::create_dir_all(&base).unwrap();
    let faults = base.join("ring3-faults.toml");
    let ring3 = std::fs::read_to_string("topologies/ring3.toml").unwrap();
    std::fs::write(
        &faults,
        format!(
            "{ring3}\n[[fault]]\nkind = \"crash\"\nnode = 2\nat_s = 1.0\n[[fault]]\nkind = \"link-down\"\n\
             link = [0, 1]\ndirected = true\nstart_s = 0.5\nend_s = 1.5\n"
        ),
    )
    .unwrap();
    let runs: [(&str, Vec<&str>); 7] = [
        (
            "attacked",
            vec![
                "-t",
                "ring3-attacked",
                "--duration",
                "22",
                "--estimators",
                "all",
                "--auth",
            ],
        ),
        (
            "faults",
            vec!["-t", faults.to_str().unwrap(), "--duration", "2", "--capture"],
        ),
        ("attitude", vec!["-t", "attitude3", "--duration", "2"]),
        // Nodes that stand apart: the map.
        ("rgg50", vec!["-t", "rgg50", "--duration", "0.5"]),
        // One radio channel, sealed: unicasts with ACKs.
        ("radio", vec!["-t", "ring3-radio", "--duration", "1", "--auth"]),
        (
            "realtime",
            vec!["-t", "ring3", "--duration", "0.5", "--realtime", "--capture"],
        ),
        (
            "sweep",
            vec![
                "sweep",
                "-t",
                "ring3",
                "--set",
                "link.loss.p=0,0.2",
                "--seeds",
                "2",
                "--duration",
                "1",
                "--estimators",
                "sequeira",
            ],
        ),
    ];
    let mut files_seen = std::collections::BTreeSet::new();
    let mut fields_seen = std::collections::BTreeSet::new();
    let mut problems = Vec::new();
    for (name, args) in &runs {
        let dir = base.join(name);
        let out = simnet().arg("-q").args(args).arg("--out").arg(&dir).output().unwrap();
        assert!(out.status.success(), "{name}: {}", String::from_utf8_lossy(&out.stderr));
        let mut stack = vec![dir.clone()];
        while let Some(d) = stack.pop() {
            for e in std::fs::read_dir(&d).unwrap() {
                let p = e.unwrap().path();
                if p.is_dir() {
                    stack.push(p);
                    continue;
                }
                let rel = p.strip_prefix(&dir).unwrap().to_string_lossy().replace('\\', "/");
                let doc = documented_name(&rel);
                let Some(file) = FILES.iter().find(|f| f.name == doc) else {
                    problems.push(format!("{name}: `{rel}` is written but not documented"));
                    continue;
                };
                files_seen.insert(file.name);
                if rel.ends_with(".csv") {
                    let text = std::fs::read_to_string(&p).unwrap();
                    let header: Vec<&str> = text.lines().next().unwrap_or_default().split(',').collect();
                    if let Err(e) = header_is(&header, file.columns) {
                        problems.push(format!("{name}: `{rel}`: {e}"));
                    }
                }
                if rel == "summary.json" {
                    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
                    let mut paths = Default::default();
                    leaves(&v, "", &mut paths);
                    for path in paths {
                        let named: Vec<&str> = SUMMARY
                            .iter()
                            .filter(|f| matches(f.name, &path))
                            .map(|f| f.name)
                            .collect();
                        if named.is_empty() {
                            problems.push(format!("{name}: summary field `{path}` is not documented"));
                        }
                        fields_seen.extend(named);
                    }
                }
            }
        }
    }
    // Only a multi-host run writes these, and only the parquet feature the Parquet copies.
    let elsewhere = ["NAME.parquet", "node-ID.json", "trace-ID.csv", "estimates-ID.csv"];
    for f in FILES {
        if !files_seen.contains(f.name) && !elsewhere.contains(&f.name) {
            problems.push(format!("`{}` is documented but no run wrote it", f.name));
        }
    }
    for f in SUMMARY {
        if !fields_seen.contains(f.name) && !["part.*", "transport.kernel_drops.*"].contains(&f.name) {
            problems.push(format!("summary field `{}` is documented but no run wrote it", f.name));
        }
    }
    let _ = std::fs::remove_dir_all(&base);
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// `simnet run --capture` (over UDP, on the virtual clock) writes capture.csv, and what it records agrees with the
/// links' own counters in summary.json: per directed link, the datagrams sent (a broadcast once per out-link), the
/// copies delivered (sent − lost on the link + duplicated) and the corrupted copies (those that match nothing sent). The same run
/// in memory captures the same lines. Delays of 1 to 3 ms, within the 5 ms deadline: the last step's copies arrive
/// before the run ends, so none is left in flight. (No consensus rounds: a link's counters count a measurement and the round-0
/// messages beside it as one fate, a capture each datagram.)
#[test]
fn a_capture_agrees_with_the_link_table_and_memory() {
    let dir = tmp("capture");
    let args = [
        "run",
        "-t",
        "ring3",
        "--duration",
        "3",
        "--loss",
        "0.2",
        "--duplicate",
        "0.1",
        "--corrupt",
        "0.05",
        "--delay",
        "2",
        "--jitter",
        "1",
    ];
    let status = simnet()
        .args(args)
        .args(["--capture", "--out"])
        .arg(&dir)
        .stdout(Stdio::null())
        .status()
        .unwrap();
    assert!(status.success());
    let text = std::fs::read_to_string(dir.join("capture.csv")).unwrap();
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    let lines: Vec<Vec<&str>> = text.lines().skip(1).map(|l| l.split(',').collect()).collect();
    assert_eq!(text.lines().next(), Some(simnet::report::capture::HEADER));
    let links = summary["links"].as_array().unwrap();
    let mut checked = 0;
    for l in links {
        let (from, to) = (l["from"].to_string(), l["to"].to_string());
        let n = |k: &str| l[k].as_u64().unwrap();
        let sent = lines
            .iter()
            .filter(|c| c[1] == "sent" && c[2] == from && (c[3] == to || c[3].is_empty()))
            .count() as u64;
        let copies: Vec<&Vec<&str>> = lines
            .iter()
            .filter(|c| c[1] == "delivered" && c[2] == from && c[3] == to)
            .collect();
        let corrupted = copies.iter().filter(|c| c[4].is_empty()).count() as u64;
        assert_eq!(sent, n("sent"), "{from} → {to}: sent");
        assert_eq!(
            copies.len() as u64,
            n("sent") - n("lost_random") - n("lost_down") + n("duplicated"),
            "{from} → {to}: delivered copies"
        );
        assert_eq!(corrupted, n("corrupted"), "{from} → {to}: corrupted copies");
        assert!(n("lost_random") > 0 && n("duplicated") > 0 && corrupted > 0, "{l}");
        checked += 1;
    }
    assert_eq!(checked, 6);
    // Delays are real: every copy is due after it was sent, and never before.
    assert!(lines.iter().any(|c| c[1] == "delivered" && c[0] != "0.000000000"));
    // In memory, the same scenario (the same options, as values) captures the same lines.
    let flags = simnet::scenario::Flags {
        duration: Some(3.0),
        loss: Some(0.2),
        duplicate: Some(0.1),
        corrupt: Some(0.05),
        delay: Some(2.0),
        jitter: Some(1.0),
        ..Default::default()
    };
    let scenario = flags.apply(&simnet::Scenario::resolve("ring3").unwrap()).unwrap();
    let log = simnet::medium::CaptureLog::new();
    let opts = simnet::sim::SimOptions {
        capture: Some(log.clone()),
        ..Default::default()
    };
    simnet::Sim::with_options(&scenario, opts).unwrap().run().unwrap();
    assert_eq!(simnet::report::capture::csv(&log.take(), &scenario), text);
    let _ = std::fs::remove_dir_all(&dir);
}
