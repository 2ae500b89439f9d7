//! (k) The binary: bad input exits with code 2 and names what is wrong; every built-in validates; a run prints its
//! table and writes its files.

use std::process::Command;

fn simnet() -> Command {
    Command::new(env!("CARGO_BIN_EXE_simnet"))
}

fn tmp(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("simnet-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn broken_topology_exits_2_naming_the_key() {
    let d = tmp("broken");
    // 16 states: one more than a round's message carries.
    let eye = |n: usize| {
        let rows: Vec<String> = (0..n)
            .map(|i| {
                format!(
                    "[{}]",
                    (0..n)
                        .map(|j| if i == j { "1.0" } else { "0.0" })
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            })
            .collect();
        format!("[{}]", rows.join(", "))
    };
    let wide = format!(
        "[model]\nkind = \"linear\"\na = {0}\nc = {0}\nq = {0}\nr = {0}\n[estimators]\nrun = [\"icf\"]\n[[node]]\nid = 0\n",
        eye(16)
    );
    let cases = [
        ("[sim]\nrate_hz = -5\n[[node]]\nid = 0\n", "sim.rate_hz"),
        ("[sim]\nrat_hz = 5\n[[node]]\nid = 0\n", "rat_hz"),
        (
            "[[node]]\nid = 0\n[[node]]\nid = 1\n[[edge]]\nnodes = [0, 7]\n",
            "edge[0].nodes",
        ),
        (
            "[link]\nloss = { model = \"bernoulli\", p = 1.5 }\n[[node]]\nid = 0\n",
            "link.loss.p",
        ),
        (
            "[model]\nkind = \"linear\"\na = [[1.0, 0.0]]\nc = [[1.0]]\nq = [[1.0]]\nr = [[1.0]]\n[[node]]\nid = 0\n",
            "model.a",
        ),
        (
            "[[node]]\nid = 0\n[[fault]]\nkind = \"crash\"\nnode = 3\nat_s = 1.0\n",
            "fault[0].node",
        ),
        (
            "[estimators]\nrun = [\"icf\", \"kalman\"]\n[[node]]\nid = 0\n",
            "estimators.run",
        ),
        ("[estimators]\nrounds = 0\n[[node]]\nid = 0\n", "estimators.rounds"),
        ("[estimators]\nsink = 7\n[[node]]\nid = 0\n", "estimators.sink"),
        (
            "[estimators]\nsink = 1\n[[node]]\nid = 0\n[[node]]\nid = 1\nrole = \"estimator\"\n[[edge]]\nnodes = [0, 1]\n",
            "estimators.sink",
        ),
        (wide.as_str(), "estimators.run"),
        ("this is not toml", "test.toml"),
    ];
    for (i, (text, key)) in cases.iter().enumerate() {
        let f = d.join(format!("t{i}.toml"));
        std::fs::write(&f, text).unwrap();
        for args in [
            vec!["validate", f.to_str().unwrap()],
            vec!["--topology", f.to_str().unwrap()],
        ] {
            let out = simnet().args(&args).output().unwrap();
            let err = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
            let key = if *key == "test.toml" {
                format!("t{i}.toml")
            } else {
                key.to_string()
            };
            assert!(err.contains(&key), "{args:?}: message does not name `{key}`:\n{err}");
        }
    }
}

/// A node's IMU file that cannot be read, is malformed, or ends before the run: exit 2 naming the node's key and the
/// file (with its line for a malformed one). A file that covers the run at the topology's duration but not at
/// `--duration` is caught after the override.
#[test]
fn bad_imu_files_exit_2_naming_node_and_line() {
    let d = tmp("imu");
    let head = "t,ax,ay,az,gx,gy,gz\n";
    let rows: String = (0..=100)
        .map(|k| format!("{},0,0,9.81,0,0,0\n", k as f64 * 0.01))
        .collect();
    std::fs::write(d.join("good.csv"), format!("{head}{rows}")).unwrap();
    std::fs::write(
        d.join("bad.csv"),
        format!("{head}0,0,0,9.81,0,0,0\n0.01,0,0,9.81,0,zero,0\n"),
    )
    .unwrap();
    let topo = |file: &str| {
        format!(
            "[sim]\nduration_s = 1.0\nburn_in_s = 0.1\n[model]\nkind = \"attitude\"\n[[node]]\nid = 0\n\
             [[node]]\nid = 1\nimu_csv = \"{file}\"\n[[edge]]\nnodes = [0, 1]\n"
        )
    };
    let cases = [
        ("missing.csv", vec![], "cannot read"),
        ("bad.csv", vec![], "bad.csv:3: `zero` in column `gy`"),
        (
            "good.csv",
            vec!["--duration", "2"],
            "covers 1.000 s, the run needs 1.990 s",
        ),
    ];
    for (file, extra, needle) in cases {
        let f = d.join(format!("{file}.toml"));
        std::fs::write(&f, topo(file)).unwrap();
        let out = simnet()
            .args(["run", "-t", f.to_str().unwrap()])
            .args(&extra)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{file}: {err}");
        assert!(err.contains("node[1].imu_csv") && err.contains(needle), "{file}: {err}");
    }
    // The good file at the topology's own duration runs, node 1 on the recording (no reference: no error figure).
    let f = d.join("good.csv.toml");
    let out = simnet()
        .args(["run", "-t", f.to_str().unwrap(), "--json"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let s: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(s["nodes"][1]["networked"]["mean_error"].is_null());
    assert!(s["nodes"][0]["networked"]["mean_error"].as_f64().is_some());
}

#[test]
fn bad_options_exit_2() {
    for args in [
        vec!["--topology", "ring3", "--loss", "1.5"],
        vec!["--topology", "ring3", "--rate", "0"],
        vec!["--topology", "ring3", "--duration", "1e9"],
        vec!["--topology", "ring3", "--loss", "0.2", "--burst", "3"],
        vec!["--topology", "no-such-topology"],
        vec![
            "--topology",
            "ring3",
            "--loss",
            "0.9",
            "--loss-model",
            "gilbert-elliott",
            "--burst",
            "1",
        ],
    ] {
        let out = simnet().args(&args).output().unwrap();
        assert_eq!(
            out.status.code(),
            Some(2),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(!out.stderr.is_empty());
    }
}

#[test]
fn every_builtin_validates_and_is_listed() {
    let out = simnet().arg("topologies").output().unwrap();
    assert!(out.status.success());
    let listing = String::from_utf8_lossy(&out.stdout);
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("topologies");
    let mut files: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().path()).collect();
    files.sort();
    assert!(files.len() >= 8);
    for f in &files {
        let name = f.file_stem().unwrap().to_str().unwrap();
        assert!(listing.contains(name), "`simnet topologies` does not list {name}");
        let out = simnet().arg("validate").arg(f).output().unwrap();
        assert!(out.status.success(), "{name}: {}", String::from_utf8_lossy(&out.stderr));
    }
}

/// Bad estimator options are usage errors naming the option, before any run.
#[test]
fn bad_estimator_options_exit_2() {
    let mut cases = vec![
        (vec!["-t", "ring3", "--estimators", "icf,kalman"], "kalman"),
        (vec!["-t", "ring3", "--rounds", "0"], "--rounds"),
        (vec!["-t", "ring3", "--rounds", "101"], "--rounds"),
        (vec!["compare", "-t", "ring3", "--estimators", "kalman"], "kalman"),
        (
            vec!["node", "-t", "ring3", "--id", "0", "--estimators", "icf,centralized"],
            "--estimators centralized",
        ),
    ];
    // A build without Parquet refuses it before running.
    if !cfg!(feature = "parquet") {
        cases.push((
            vec!["-t", "ring3", "--format", "parquet", "--out", "/tmp/never"],
            "parquet",
        ));
    }
    for (args, names) in cases {
        let out = simnet().args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(names), "{args:?}: does not name {names}: {err}");
    }
}

/// `simnet -t rgg50 --estimators all --rounds 3` prints one column per estimator and their summary rows.
#[test]
fn the_table_has_a_column_per_estimator() {
    let out = simnet()
        .args([
            "-t",
            "rgg50",
            "--loss",
            "0.1",
            "--estimators",
            "all",
            "--rounds",
            "3",
            "--duration",
            "2",
            "-q",
        ])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let table = String::from_utf8_lossy(&out.stdout);
    let header = table
        .lines()
        .find(|l| l.trim_start().starts_with("node │") && l.contains("centralized"))
        .unwrap_or_else(|| panic!("no estimator columns:\n{table}"));
    for s in simnet::estimators::schemes() {
        assert!(header.contains(s.name), "{} has no column: {header}", s.name);
        assert!(
            table
                .lines()
                .any(|l| l.trim_start().starts_with(&format!("{} │", s.name))),
            "{} has no summary row",
            s.name
        );
    }
}

/// `simnet compare` prints one markdown row per loss × rounds cell, a column per estimator, and Sequeira's rank; the
/// ratios are those of single runs with the same settings.
#[test]
fn compare_prints_the_findings_table() {
    // ring3 at 20 % loss, seeds 1 and 2, 1 s each: (stdout, stderr).
    let compare_with = |extra: &[&str]| {
        let out = simnet()
            .args([
                "compare",
                "-t",
                "ring3",
                "--seeds",
                "2",
                "--duration",
                "1",
                "--loss",
                "0.2",
            ])
            .args(extra)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        (
            String::from_utf8_lossy(&out.stdout).into_owned(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let compare = |extra: &[&str]| compare_with(extra).0;
    let table = compare(&["--rounds", "1,2"]);
    let rows: Vec<&str> = table.lines().filter(|l| l.starts_with("| 20 %")).collect();
    assert_eq!(rows.len(), 2, "{table}");
    let header = table.lines().find(|l| l.starts_with("| loss")).unwrap();
    for s in simnet::estimators::schemes()
        .into_iter()
        .filter(|s| s.name != "centralized")
    {
        assert!(header.contains(&format!(" {} |", s.name)), "{}: {header}", s.name);
    }
    // The cell of L = 1 is the mean over seeds 1 and 2 of each run's own ratio.
    let ratio = |seed: u64| {
        let o = simnet()
            .args([
                "-t",
                "ring3",
                "--duration",
                "1",
                "--loss",
                "0.2",
                "--estimators",
                "all",
                "--json",
                "--seed",
            ])
            .arg(seed.to_string())
            .output()
            .unwrap();
        let s: simnet::Summary = serde_json::from_slice(&o.stdout).unwrap();
        s.estimators["icf"].ratio_to_centralized.unwrap()
    };
    let mean = (ratio(1) + ratio(2)) / 2.0;
    let col = header.split('|').position(|c| c.trim() == "icf").unwrap();
    let cell = rows[0].split('|').nth(col).unwrap().trim();
    assert!(cell.starts_with(&format!("{mean:.3} ±")), "icf: {cell} vs {mean:.3}");

    // A subset compares only those, with the reference, and the same figures: the estimators do not see each other.
    let sub = compare(&["--rounds", "1", "--estimators", "icf,sequeira"]);
    let sub_header = sub.lines().find(|l| l.starts_with("| loss")).unwrap();
    assert_eq!(
        sub_header,
        "| loss | L | centralized error | sequeira | icf | sequeira's rank |"
    );
    let sub_row = sub.lines().find(|l| l.starts_with("| 20 %")).unwrap();
    assert_eq!(sub_row.split('|').nth(5).unwrap().trim(), cell, "{sub}");
    // The reference alone: header, separator and rows have one cell per column each (were 5, 4 and 5), and no
    // rank of a sequeira that did not run.
    let alone = compare(&["--rounds", "1", "--estimators", "centralized"]);
    let cells = |l: &str| l.matches('|').count() - 1;
    let lines: Vec<&str> = alone.lines().filter(|l| l.starts_with('|')).collect();
    assert_eq!(lines.len(), 3, "{alone}");
    assert!(lines.iter().all(|l| cells(l) == 3), "{alone}");

    // With --out it is a campaign: the sweep's files, resumable; --json prints the same figures as the table.
    let dir = std::env::temp_dir().join(format!("simnet-test-{}-compare-out", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let d = dir.to_str().unwrap();
    let with_out = |json: bool| {
        let mut extra = vec!["--rounds", "1,2", "--out", d];
        if json {
            extra.push("--json");
        }
        compare_with(&extra)
    };
    let (first, _) = with_out(false);
    assert_eq!(first, table, "the table with --out is the table without");
    for f in ["runs.csv", "points.csv", "sweep.svg", "report.html", "manifest.json"] {
        assert!(dir.join(f).is_file(), "{f} missing from {}", dir.display());
    }
    let runs = std::fs::read_to_string(dir.join("runs.csv")).unwrap();
    assert_eq!(runs.lines().count(), 1 + 4, "{runs}");
    let (json, err) = with_out(true);
    assert!(err.contains("0 run now, 4 already in"), "{err}");
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let rows = v["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 2);
    assert_eq!(
        (rows[0]["loss"].as_f64(), rows[1]["rounds"].as_u64()),
        (Some(0.2), Some(2))
    );
    let icf = rows[0]["ratio_to_centralized"]["icf"]["mean"].as_f64().unwrap();
    assert!(cell.starts_with(&format!("{icf:.3} ±")), "icf: {cell} vs {icf}");
    assert_eq!(rows[0]["ratio_to_centralized"]["icf"]["n"], 2);
    let _ = std::fs::remove_dir_all(&dir);
}

/// `simnet estimators` lists every scheme with its reference.
#[test]
fn every_estimator_is_listed_with_its_reference() {
    let out = simnet().arg("estimators").output().unwrap();
    assert!(out.status.success());
    let listing = String::from_utf8_lossy(&out.stdout);
    for s in simnet::estimators::schemes() {
        let entry = listing
            .split("\n")
            .position(|l| l.starts_with(s.name))
            .unwrap_or_else(|| panic!("{} is not listed", s.name));
        let lines: Vec<&str> = listing.lines().skip(entry).take(4).collect();
        assert!(lines[1].contains(s.reference), "{}: {lines:?}", s.name);
    }
}

#[test]
fn run_prints_the_table_and_writes_files() {
    let d = tmp("out");
    let out = simnet()
        .args(["--topology", "ring3", "--loss", "0.2", "--duration", "5", "-q", "--out"])
        .arg(&d)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(
        stdout.contains("net err") && stdout.contains("0 → 1") && stdout.contains("fused"),
        "{stdout}"
    );
    for f in [
        "summary.json",
        "trace.csv",
        "links.csv",
        "trajectory.svg",
        "error.svg",
        "trace_p.svg",
    ] {
        let p = d.join(f);
        assert!(
            p.metadata().map(|m| m.len() > 100).unwrap_or(false),
            "{f} missing or empty"
        );
    }
    let summary: serde_json::Value = serde_json::from_slice(&std::fs::read(d.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["topology"], "ring3");
    assert_eq!(summary["steps"], 500);
    assert_eq!(summary["nodes"].as_array().unwrap().len(), 3);
    let trace = std::fs::read_to_string(d.join("trace.csv")).unwrap();
    // Header plus 500 steps × 3 nodes × 2 filters, and per step the fused estimate and its median.
    let kinds = |k: &str| trace.lines().filter(|l| l.split(',').nth(3) == Some(k)).count();
    assert_eq!(kinds("networked") + kinds("independent"), 500 * 3 * 2);
    assert_eq!((kinds("fused"), kinds("fused_median")), (500, 500));
    assert_eq!(trace.lines().count(), 1 + 500 * 3 * 2 + 2 * 500);
    assert!(trace
        .lines()
        .next()
        .unwrap()
        .starts_with("step,t,node,estimator,true_x"));
    let svg = std::fs::read_to_string(d.join("error.svg")).unwrap();
    assert!(svg.contains("<svg") && svg.contains("networked"));

    let json = simnet()
        .args(["--topology", "pair2-paper", "--duration", "2", "--json"])
        .output()
        .unwrap();
    let v: serde_json::Value = serde_json::from_slice(&json.stdout).expect("--json prints summary.json");
    assert_eq!(v["topology"], "pair2-paper");
}

/// The committed docker-compose.yml is what `simnet compose --topology ring3` prints: it writes a network key
/// readable by its owner alone when there is none, keeps the one it finds, and hands it to every node as a Docker
/// secret; `--insecure` gives nodes without one.
#[test]
fn committed_compose_file_is_generated() {
    let d = tmp("compose");
    let compose = |extra: &[&str]| {
        simnet()
            .current_dir(&d)
            .arg("compose")
            .args(["--topology", "ring3"])
            .args(extra)
            .output()
            .unwrap()
    };
    let out = compose(&[]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let committed =
        std::fs::read_to_string(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docker-compose.yml")).unwrap();
    assert_eq!(
        String::from_utf8_lossy(&out.stdout),
        committed,
        "regenerate: simnet compose --topology ring3 > docker-compose.yml"
    );
    let key = std::fs::read_to_string(d.join("simnet.key")).unwrap();
    assert!(key.contains("simnet-key-v1 "));
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(d.join("simnet.key")).unwrap().permissions().mode();
        assert_eq!(mode & 0o077, 0, "the key is readable by others: {mode:o}");
    }
    assert_eq!(
        committed.matches("\"--key-file\", \"/run/secrets/simnet_key\"").count(),
        3
    );
    assert!(committed.contains("secrets:\n  simnet_key:\n    file: ./simnet.key"));
    assert!(compose(&[]).status.success());
    assert_eq!(
        std::fs::read_to_string(d.join("simnet.key")).unwrap(),
        key,
        "compose replaced the key"
    );
    // A key file that is not one is refused, not replaced.
    use std::os::unix::fs::PermissionsExt;
    let private = |name: &str, text: &str, mode: u32| {
        std::fs::write(d.join(name), text).unwrap();
        std::fs::set_permissions(d.join(name), std::fs::Permissions::from_mode(mode)).unwrap();
    };
    private("bad.key", "hunter2\n", 0o600);
    let bad = compose(&["--key-file", "bad.key"]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("bad.key: not a simnet key file"));
    assert!(!String::from_utf8_lossy(&bad.stderr).contains("hunter2"));
    // Keys as ssh takes them: readable by the owner alone, strict hex, sizes in bytes.
    let good = std::fs::read_to_string(d.join("simnet.key")).unwrap();
    for (name, text, mode, says) in [
        ("open.key", good.clone(), 0o644, "mode 0644: chmod 600"),
        ("all.key", good.clone(), 0o666, "mode 0666: chmod 600"),
        (
            "none.key",
            good.clone(),
            0o000,
            "its owner cannot read it (mode 0000): chmod 600",
        ),
        (
            "plus.key",
            format!("simnet-key-v1 {}\n", "+f".repeat(16)),
            0o600,
            "not a simnet key file",
        ),
        (
            "big.key",
            format!("{good}{}", "#".repeat(5000)),
            0o600,
            "more than the 4096 bytes",
        ),
    ] {
        private(name, &text, mode);
        let out = compose(&["--key-file", name]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{name}: {err}");
        assert!(err.contains(name) && err.contains(says), "{name}: {err}");
        let out = Command::new(env!("CARGO_BIN_EXE_simnet"))
            .current_dir(&d)
            .args(["-t", "ring3", "--duration", "0.1", "--key-file", name])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "run with {name}: {err}");
        assert!(err.contains(says), "run with {name}: {err}");
    }
    // A relative --key-file is the working directory's, and a missing one is named there.
    let out = Command::new(env!("CARGO_BIN_EXE_simnet"))
        .current_dir(&d)
        .args(["-t", "ring3", "--duration", "0.1", "--key-file", "missing.key"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains(&d.join("missing.key").display().to_string()), "{err}");
    // keygen --force makes a new file of mode 0600, and replaces a link rather than writing through it.
    private("old.key", &good, 0o644);
    let victim = d.join("victim.txt");
    std::fs::write(&victim, "not a key").unwrap();
    std::os::unix::fs::symlink(&victim, d.join("link.key")).unwrap();
    for name in ["old.key", "link.key"] {
        let out = Command::new(env!("CARGO_BIN_EXE_simnet"))
            .current_dir(&d)
            .args(["keygen", "--force", name])
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let meta = std::fs::symlink_metadata(d.join(name)).unwrap();
        assert!(meta.is_file(), "{name} is still a link");
        assert_eq!(meta.permissions().mode() & 0o777, 0o600, "{name}");
    }
    assert_eq!(std::fs::read_to_string(&victim).unwrap(), "not a key");
    // Crafted names never become YAML structure: an address is HOST:PORT or an error naming it; a topology path is
    // a quoted string; an image is an image reference.
    let ring = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/topologies/ring3.toml")).unwrap();
    let crafted = ring.replacen(
        "id = 0\n",
        "id = 0\naddr = \"x, privileged: true, pid: host:7000\"\n",
        1,
    );
    std::fs::write(d.join("crafted.toml"), crafted).unwrap();
    let out = simnet()
        .current_dir(&d)
        .args(["compose", "--insecure", "--topology", "crafted.toml"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("node[0].addr") && err.contains("is not HOST:PORT"),
        "{err}"
    );
    std::fs::write(d.join("a b'\"#x.toml"), &ring).unwrap();
    let out = simnet()
        .current_dir(&d)
        .args(["compose", "--insecure", "--topology", "a b'\"#x.toml"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let yaml = String::from_utf8(out.stdout).unwrap();
    assert!(
        yaml.contains(r##"    - "./a b'\"#x.toml:/topology.toml:ro""##),
        "{yaml}"
    );
    assert!(!yaml.contains("privileged"));
    let out = compose(&["--insecure", "--image", "x\n    privileged: true"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--image"));
    let wide = ring.replacen("id = 0\n", "id = 0\naddr = \"0.0.0.0:7000\"\n", 1);
    std::fs::write(d.join("wide.toml"), wide).unwrap();
    let out = simnet()
        .current_dir(&d)
        .args(["compose", "--insecure", "--topology", "wide.toml"])
        .output()
        .unwrap();
    assert!(out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("binds every interface"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let open = String::from_utf8(compose(&["--insecure"]).stdout).unwrap();
    assert_eq!(open.matches("\"--insecure\"").count(), 3);
    assert!(!open.contains("secrets"));
}

/// Free loopback ports: bind ephemeral sockets, note the ports, release them.
fn free_ports(n: usize) -> Vec<u16> {
    (0..n).map(|_| super::common::free_port()).collect()
}

/// `--peer` arguments naming every other node's loopback port.
fn peers(ports: &[u16], me: usize) -> Vec<String> {
    ports
        .iter()
        .enumerate()
        .filter(|(j, _)| *j != me)
        .flat_map(|(j, p)| ["--peer".to_string(), format!("{j}=127.0.0.1:{p}")])
        .collect()
}

/// Three `simnet node` processes on loopback (no Docker): handshake, one node starting late, parts, `collect`.
#[test]
fn node_processes_run_a_network_and_collect_merges_it() {
    let d = tmp("hosts");
    let key = super::common::network_key(&d);
    let ports = free_ports(3);
    let mut children: Vec<std::process::Child> = Vec::new();
    for i in 0..3usize {
        let mut c = simnet();
        c.args([
            "node",
            "--topology",
            "ring3",
            "--id",
            &i.to_string(),
            "--duration",
            "3",
            "--out",
        ])
        .arg(&d)
        .args(["--bind", &format!("127.0.0.1:{}", ports[i])])
        .arg("--key-file")
        .arg(&key);
        // Node 0 logs at info level: the test waits for the line that says it has started stepping.
        if i > 0 {
            c.arg("-q");
        } else {
            c.arg("-v").stderr(std::process::Stdio::piped());
        }
        if i < 2 {
            // Nodes 0 and 1 stop waiting for node 2 and start without it.
            c.args(["--handshake-timeout", "0.3"]);
        }
        c.args(peers(&ports, i));
        if i == 2 {
            // The third node starts late: only once node 0 is stepping (its handshake timed out, or it joined node 1), an
            // event rather than a time, so a loaded machine cannot reorder it.
            use std::io::BufRead;
            let err = children[0].stderr.take().unwrap();
            let mut lines = std::io::BufReader::new(err).lines();
            let started = lines.by_ref().map_while(Result::ok).any(|l| l.contains("stepping"));
            assert!(started, "node 0 never started stepping");
            // Keep draining node 0's stderr so that it never blocks on a full pipe.
            std::thread::spawn(move || lines.for_each(drop));
        }
        children.push(c.stdout(std::process::Stdio::null()).spawn().unwrap());
    }
    for mut c in children {
        assert!(c.wait().unwrap().success());
    }
    let out = simnet().arg("collect").arg(&d).arg("--json").output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["clock"], "multi-host");
    assert_eq!(v["nodes"].as_array().unwrap().len(), 3);
    assert_eq!(v["links"].as_array().unwrap().len(), 6);
    // Node 2 joined the running network at its current step, with fresh filters.
    let part: serde_json::Value = serde_json::from_slice(&std::fs::read(d.join("node-2.json")).unwrap()).unwrap();
    let first = part["part"]["first_step"].as_u64().unwrap();
    assert!(first >= 1, "node 2 joined the running network, at step {first}");
    assert_eq!(part["part"]["steps_done"], 300);
    for l in v["links"].as_array().unwrap() {
        let (sent, delivered) = (l["sent"].as_u64().unwrap(), l["delivered"].as_u64().unwrap());
        // Into node 2, nothing sent before it joined is delivered (accepted into a step); everything else arrives.
        // Arriving after its step closed (late) depends on how busy the machine is, so late datagrams count as
        // arrived.
        let arrived = delivered + l["late"].as_u64().unwrap();
        let absent = if l["to"] == 2 { first } else { 0 };
        assert!(
            sent >= 150 && (arrived + absent) * 100 >= sent * 97 && delivered + absent <= sent + 1,
            "node 2 joined at step {first}: {l}"
        );
    }
    for n in v["nodes"].as_array().unwrap() {
        assert_eq!(n["networked"]["diverged"], false);
    }
    assert!(v["fused"]["mean_error"].as_f64().unwrap() < 0.1);
    for f in ["summary.json", "trace.csv", "links.csv", "error.svg"] {
        assert!(d.join(f).exists(), "{f}");
    }
}

/// Three `simnet node` processes on loopback running ICF and KCF over two consensus rounds: every node sends each
/// round's ICF message (and KCF's round 0) on both out-links in every step it ran, and `collect` joins the nodes'
/// figures of each estimator, with the median error, disagreement and fused error from their estimates files.
#[test]
fn node_processes_run_the_distributed_estimators() {
    let d = tmp("hosts-estimators");
    let key = super::common::network_key(&d);
    let ports = free_ports(3);
    let children: Vec<std::process::Child> = (0..3usize)
        .map(|i| {
            let mut c = simnet();
            c.args(["node", "-q", "--topology", "ring3", "--id", &i.to_string()])
                .args(["--duration", "2", "--estimators", "icf,kcf", "--rounds", "2", "--out"])
                .arg(&d)
                .args(["--bind", &format!("127.0.0.1:{}", ports[i])])
                .arg("--key-file")
                .arg(&key);
            c.args(peers(&ports, i));
            c.stdout(std::process::Stdio::null()).spawn().unwrap()
        })
        .collect();
    for mut c in children {
        assert!(c.wait().unwrap().success());
    }
    let out = simnet().arg("collect").arg(&d).arg("--json").output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let mut steps_run = 0;
    for i in 0..3 {
        let part: serde_json::Value =
            serde_json::from_slice(&std::fs::read(d.join(format!("node-{i}.json"))).unwrap()).unwrap();
        steps_run += part["part"]["steps_done"].as_u64().unwrap() - part["part"]["first_step"].as_u64().unwrap();
    }
    assert!(steps_run >= 3 * 150, "{steps_run}");
    for (name, rounds) in [("icf", 2), ("kcf", 1)] {
        let e = &v["estimators"][name];
        assert_eq!(e["messages"].as_u64(), Some(steps_run * rounds * 2), "{name}: {e}");
        // From the nodes' estimates files, step by step.
        for f in ["median_error", "disagreement", "fused_error"] {
            assert!(
                e[f].as_f64().is_some_and(|x| x.is_finite() && x >= 0.0),
                "{name}.{f}: {e}"
            );
        }
        let nodes = e["nodes"].as_array().unwrap();
        assert_eq!(nodes.len(), 3, "{name}");
        for n in nodes {
            assert_eq!(n["diverged"], false, "{name}: {n}");
            assert!(
                n["mean_error"].as_f64().is_some_and(|x| x.is_finite() && x < 1.0),
                "{name}: {n}"
            );
        }
    }
}

/// `simnet bounds`: Sinopoli's scalar example from the command line, the measured mean inside the bounds, bad
/// matrices refused with exit 2.
#[test]
fn bounds_of_the_scalar_example() {
    let out = simnet()
        .args([
            "bounds",
            "--a",
            "[[-1.25]]",
            "--c",
            "[[1.0]]",
            "--q",
            "[[1.0]]",
            "--r",
            "[[2.5]]",
            "--lambda",
            "0.5",
        ])
        .output()
        .unwrap();
    let s = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(s.contains("λ_min = 0.360000") && s.contains("λ̄     = 0.3600"), "{s}");
    assert!(s.contains("trace S̄ = 4.5714") && s.contains("trace V̄ = 11.9559"), "{s}");

    let out = simnet()
        .args(["bounds", "-t", "sinopoli-scalar", "--lambda", "0.8", "--measure"])
        .output()
        .unwrap();
    let s = String::from_utf8_lossy(&out.stdout);
    assert!(s.contains("(within the bounds)"), "{s}");

    for args in [
        vec![
            "bounds",
            "--a",
            "[[1.0, 2.0]]",
            "--c",
            "[[1.0]]",
            "--q",
            "[[1.0]]",
            "--r",
            "[[1.0]]",
        ],
        vec![
            "bounds", "--a", "[[1.0]]", "--c", "[[1.0]]", "--q", "[[1.0]]", "--r", "[[-1.0]]",
        ],
        vec!["bounds", "-t", "ring3"],
        vec![
            "bounds", "--a", "oops", "--c", "[[1.0]]", "--q", "[[1.0]]", "--r", "[[1.0]]",
        ],
    ] {
        let out = simnet().args(&args).output().unwrap();
        assert_eq!(
            out.status.code(),
            Some(2),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}

/// SIGTERM (what `docker stop` sends) stops a node cleanly: exit 143, and a complete part marked interrupted.
#[test]
fn node_stops_cleanly_on_sigterm() {
    let d = tmp("sigterm");
    let port = free_ports(1)[0];
    let mut node = simnet();
    node.args([
        "node",
        "--topology",
        "ring3",
        "--id",
        "0",
        "--duration",
        "60",
        "-vvv",
        "--handshake-timeout",
        "0.2",
        "--insecure",
    ])
    .args([
        "--bind",
        &format!("127.0.0.1:{port}"),
        "--peer",
        "1=127.0.0.1:9",
        "--peer",
        "2=127.0.0.1:9",
        "--out",
    ])
    .arg(&d);
    // Stop it once it has closed a step (its trace log says so), however slow the machine.
    let (mut child, drain) = super::common::spawn_until(&mut node, "step closed");
    let status = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    assert_eq!(
        child.wait().unwrap().code(),
        Some(143),
        "a node stopped by SIGTERM exits 128 + 15 after writing its part"
    );
    drain.join().unwrap();
    let part: serde_json::Value = serde_json::from_slice(&std::fs::read(d.join("node-0.json")).unwrap()).unwrap();
    assert_eq!(part["interrupted"], true);
    let done = part["part"]["steps_done"].as_u64().unwrap();
    assert!(done > 0 && done < 6000, "{done} steps");
    let trace = std::fs::read_to_string(d.join("trace-0.csv")).unwrap();
    assert_eq!(
        trace.lines().count() as u64,
        1 + 2 * done,
        "the trace holds every step run, no partial file"
    );
    assert!(!std::fs::read_dir(&d)
        .unwrap()
        .any(|e| e.unwrap().path().extension().is_some_and(|x| x == "tmp")));
}

/// The annotated topology file of the book's "Topology files" is a valid topology.
#[test]
fn the_book_topology_example_validates() {
    let page = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/src/topologies.md")).unwrap();
    let at = page.find("## Topology files").unwrap();
    let start = page[at..].find("```toml").unwrap() + at + "```toml".len();
    let end = page[start..].find("```").unwrap() + start;
    let t = simnet::Scenario::from_toml(&page[start..end], "topologies.md").unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(t.attacks().len(), 1);
}

/// Every subcommand takes bad input the same way: a topology that does not exist, an option out of range and an
/// output path that is a file each exit 2, before any work, with a message that names what is wrong (README's rule;
/// `compare -t nope`, `compare --duration 0.001`, `attitude --out FILE`, `sweep --out FILE` and `reconstruct
/// --velocity-at` past the recording exited 1).
#[test]
fn every_subcommand_exits_2_naming_a_bad_topology_option_or_output() {
    let d = std::env::temp_dir().join(format!("simnet-cli-bad-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    let file = d.join("a-file");
    std::fs::write(&file, "").unwrap();
    let f = file.to_str().unwrap();
    let rec = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/recordings/xsens-mti.txt");
    let topo_cmds: [&[&str]; 7] = [
        &["run"],
        &["compare"],
        &["sweep", "--set", "link.loss.p=0,0.1"],
        &["node", "--id", "0", "--insecure"],
        &["compose"],
        &["bounds"],
        &["protocol"],
    ];
    let mut cases: Vec<(Vec<&str>, &str)> = Vec::new();
    for c in topo_cmds {
        let mut a = c.to_vec();
        a.extend(["-t", "nope"]);
        if c[0] == "sweep" {
            a.extend(["--out", d.to_str().unwrap()]);
        }
        cases.push((a, "nope"));
        if c[0] != "compose" {
            let mut a = c.to_vec();
            a.extend(["-t", "sinopoli-scalar", "--duration", "0.0001"]);
            if c[0] == "sweep" {
                a.extend(["--out", d.to_str().unwrap()]);
            }
            cases.push((a, "duration"));
        }
    }
    for c in [
        vec!["run", "-t", "ring3", "--duration", "1", "--out", f],
        vec!["sweep", "-t", "ring3", "--set", "link.loss.p=0,0.1", "--out", f],
        vec!["compare", "-t", "ring3", "--seeds", "1", "--duration", "1", "--out", f],
        vec!["node", "-t", "ring3", "--id", "0", "--insecure", "--out", f],
        vec!["bounds", "-t", "sinopoli-scalar", "--sweep", "--out", f],
        vec!["protocol", "-t", "tri3-paper", "--out", f],
        vec!["attitude", rec, "--out", f],
        vec!["reconstruct", rec, "--out", f],
    ] {
        cases.push((c, "a-file"));
    }
    cases.push((vec!["reconstruct", rec, "--velocity-at", "500:0,0,0"], "--error-model"));
    // An option that would change nothing is refused, not ignored.
    cases.push((vec!["bounds", "-t", "sinopoli-scalar", "--out", f], "--sweep"));
    cases.push((vec!["compare", "-t", "ring3", "--format", "parquet"], "--out"));
    // A node offers no option it refuses.
    let help = Command::new(env!("CARGO_BIN_EXE_simnet"))
        .args(["node", "--help"])
        .output()
        .unwrap();
    let help = String::from_utf8_lossy(&help.stdout);
    assert!(
        help.contains("--key-file") && !help.contains("--realtime") && !help.contains("--auth"),
        "{help}"
    );
    cases.push((
        vec![
            "node",
            "-t",
            "ring3",
            "--id",
            "0",
            "--insecure",
            "--peer",
            "1=999.1.1.1:99999",
        ],
        "999.1.1.1",
    ));
    for peer in ["1=nohost:x", "1=no-such-host.invalid:7000"] {
        cases.push((
            vec!["node", "-t", "ring3", "--id", "0", "--insecure", "--peer", peer],
            &peer[2..],
        ));
    }
    for (args, names) in cases {
        let out = Command::new(env!("CARGO_BIN_EXE_simnet"))
            .args(&args)
            .current_dir(&d)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(names), "{args:?} does not name `{names}`: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
    let _ = std::fs::remove_dir_all(&d);
}

/// `-q` and `-v` are global: given before a subcommand they mean what they mean after it.
#[test]
fn quiet_and_verbose_before_a_subcommand() {
    for args in [
        &["-q", "topologies"][..],
        &["-q", "bounds", "-t", "sinopoli-scalar"],
        &["-v", "estimators"],
        &["-q", "validate", "topologies/ring3.toml"],
    ] {
        let out = simnet().args(args).output().unwrap();
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(!out.stdout.is_empty(), "{args:?} printed nothing");
    }
    let out = simnet().args(["-qv", "topologies"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--quiet"));
}

/// A listing into a pipe its reader closed ends with 141, as a shell reports SIGPIPE, not with a panic.
#[test]
fn a_listing_into_a_closed_pipe_is_not_a_panic() {
    for what in ["topologies", "estimators"] {
        let mut child = simnet()
            .arg(what)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        // The reader goes away before reading a byte.
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!stderr.contains("panicked"), "{what}: {stderr}");
        assert!(
            matches!(out.status.code(), Some(0) | Some(141)),
            "{what}: {:?}",
            out.status
        );
    }
}

/// Nodes that range from where they stand run no networked filter: `--estimators all` and `compare` with no
/// `--estimators` run every scheme the model can (no sequeira), naming sequeira is refused, `protocol` and
/// `bounds` refuse with the reason, exit 2.
#[test]
fn the_commands_take_a_ranged_model_as_it_is() {
    let out = simnet()
        .args(["-t", "ranges4", "--estimators", "all", "--duration", "2", "--json"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let s: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let ran: Vec<&str> = s["estimators"]
        .as_object()
        .unwrap()
        .keys()
        .map(String::as_str)
        .collect();
    assert_eq!(ran.len(), simnet::estimators::Kind::BUILTIN.len() - 1, "{ran:?}");
    assert!(!ran.contains(&"sequeira"), "{ran:?}");
    let out = simnet()
        .args([
            "-q",
            "compare",
            "-t",
            "ranges4",
            "--duration",
            "2",
            "--seeds",
            "1",
            "--loss",
            "0",
            "--rounds",
            "1",
        ])
        .output()
        .unwrap();
    let table = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(
        table.contains("icf") && table.contains("kcf") && !table.contains("sequeira"),
        "{table}"
    );
    for (args, words) in [
        (&["protocol", "-t", "ranges4"][..], "observe differently"),
        (&["bounds", "-t", "ranges4"][..], "observed by ranges"),
        (
            &["-t", "ranges4", "--estimators", "sequeira,icf"][..],
            "observes differently",
        ),
    ] {
        let out = simnet().args(args).output().unwrap();
        let e = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {e}");
        assert!(e.contains(words), "{args:?}: {e}");
    }
}
