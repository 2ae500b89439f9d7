//! The attitude model over the network, and recorded IMU files driving a node.

use simnet::node::{NodeReport, TraceRow};
use simnet::report::trace::TraceWriter;
use simnet::scenario::{Overrides, Scenario};
use simnet::sim::{Sim, SimOptions};

use crate::common;

/// attitude3 over real UDP sockets at 20 % loss, accelerometer and magnetometer in separate datagrams: every node's
/// networked filter tracks the attitude to a fraction of a degree, is consistent (NEES of the 4-state below the
/// χ² mean of 4: the quaternion's norm direction carries no error), never fails (17)/(19), and beats its independent
/// twin in total over three seeds.
#[test]
fn attitude_network_over_udp_with_partial_loss() {
    let (mut net, mut ind) = (0.0, 0.0);
    for seed in 1..=3 {
        let o = Overrides {
            duration_s: Some(15.0),
            ..common::seed(seed)
        };
        let s = common::run(common::topology("attitude3", o));
        assert_eq!(s.model, simnet::model::Kind::Attitude);
        for l in &s.links {
            // Two channels, two datagrams per step on every link.
            assert_eq!(l.sent, 2 * s.steps, "{} → {}", l.from, l.to);
            let rate = l.lost as f64 / l.sent as f64;
            let sd = (0.2 * 0.8 / l.sent as f64).sqrt();
            assert!((rate - 0.2).abs() < 4.0 * sd, "{} → {}: loss {rate}", l.from, l.to);
        }
        for n in &s.nodes {
            let (a, b) = (n.networked.as_ref().unwrap(), n.independent.as_ref().unwrap());
            let (ea, eb) = (a.mean_error.unwrap(), b.mean_error.unwrap());
            let nees = a.nees_mean.unwrap();
            println!(
                "seed {seed} node {}: networked {ea:.4}°, independent {eb:.4}°, NEES {nees:.2}",
                n.id
            );
            assert!(ea < 0.25 && eb < 0.25, "node {}: {ea}°, {eb}°", n.id);
            assert!(nees < 4.0, "node {}: NEES {nees}", n.id);
            assert_eq!(a.lmi_infeasible_steps, Some(0));
            net += ea;
            ind += eb;
        }
    }
    println!("sum of mean errors: networked {net:.4}°, independent {ind:.4}°");
    assert!(net < ind, "networked {net} vs independent {ind}");
}

/// The first `steps` steps in memory: each node's report with its trace rows; `imu_dir` receives `imu-ID.csv`.
fn run_in_memory(topo: Scenario, steps: u64, imu_dir: Option<&std::path::Path>) -> Vec<(NodeReport, Vec<TraceRow>)> {
    let mut rec = TraceWriter::for_topology(&topo).keep_all();
    if let Some(dir) = imu_dir {
        let dir = dir.to_path_buf();
        rec = rec.with_imu(Box::new(move |id| {
            let f = std::fs::File::create(dir.join(format!("imu-{id}.csv")))?;
            Ok(Box::new(f) as Box<dyn std::io::Write + Send>)
        }));
    }
    let opts = SimOptions {
        trace: Some(rec),
        ..Default::default()
    };
    let mut sim = Sim::with_options(&topo, opts).unwrap();
    for _ in 0..steps {
        sim.step().unwrap();
    }
    let results = sim.finish();
    let (rows, _) = results.trace.unwrap().finish().unwrap();
    results
        .reports
        .into_iter()
        .map(|r| {
            let mine = rows.iter().filter(|t| t.node == r.id).cloned().collect();
            (r, mine)
        })
        .collect()
}

fn estimates(r: &(NodeReport, Vec<TraceRow>)) -> Vec<&TraceRow> {
    r.1.iter()
        .filter(|t| t.filter == simnet::observe::Filter::Networked)
        .collect()
}

fn largest_gap(a: &(NodeReport, Vec<TraceRow>), b: &(NodeReport, Vec<TraceRow>)) -> f64 {
    estimates(a)
        .iter()
        .zip(estimates(b))
        .flat_map(|(x, y)| x.est.iter().zip(&y.est).map(|(u, v)| (u - v).abs()))
        .fold(0.0, f64::max)
}

/// A node fed the `imu-0.csv` its simulated run wrote reproduces that run: every node's estimates agree to 1e-9 rad.
/// Without the file's reference columns node 0 starts from a levelled attitude and reports no error, while the
/// others, which only see its accelerometer and magnetometer, are unchanged; node 0 still ends within 0.3° of the
/// truth.
#[test]
fn a_recorded_imu_replays_the_run_that_wrote_it() {
    let steps = 1000;
    let ten_seconds = || Overrides {
        duration_s: Some(10.0),
        ..common::seed(4)
    };
    let dir = std::env::temp_dir().join(format!("simnet-replay-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let original = run_in_memory(common::topology("attitude3", ten_seconds()), steps, Some(&dir));
    let with_ref = dir.join("imu-0.csv");
    let text = std::fs::read_to_string(&with_ref).unwrap();
    assert!(text.starts_with("t,ax,ay,az,gx,gy,gz,mx,my,mz,x,y,z,roll,pitch,yaw"));
    std::fs::write(&with_ref, &text).unwrap();
    let bare = dir.join("raw-0.csv");
    let stripped: String = text
        .lines()
        .map(|l| l.split(',').take(10).collect::<Vec<_>>().join(",") + "\n")
        .collect();
    std::fs::write(&bare, stripped).unwrap();

    let (base, _) = Scenario::resolve_text("attitude3").unwrap();
    let fed = |file: &std::path::Path| {
        let toml = base.replacen(
            "[[node]]\nid = 0\n",
            &format!("[[node]]\nid = 0\nimu_csv = {:?}\n", file),
            1,
        );
        assert!(toml.contains("imu_csv"));
        // The file covers 10 s: shorten the run before it is checked.
        let toml = toml.replace("duration_s = 30.0", "duration_s = 10.0");
        let t = Scenario::from_toml(&toml, "fed.toml")
            .and_then(|t| t.with(&ten_seconds()))
            .unwrap_or_else(|e| panic!("{e}"));
        run_in_memory(t, steps, None)
    };

    let replay = fed(&with_ref);
    for (a, b) in original.iter().zip(&replay) {
        let gap = largest_gap(a, b);
        assert!(gap < 1e-9, "node {}: {gap:e}", a.0.id);
        assert_eq!(
            a.0.networked.as_ref().unwrap().summary(true),
            b.0.networked.as_ref().unwrap().summary(true)
        );
    }

    let raw = fed(&bare);
    assert!(raw[0].0.networked.as_ref().unwrap().summary(true).mean_error.is_none());
    for i in 1..3 {
        // Node 0's measurements are the file's: identical whatever node 0 itself estimates.
        let gap = largest_gap(&original[i], &raw[i]);
        assert!(gap < 1e-9, "node {i}: {gap:e}");
    }
    let last = |r: &(NodeReport, Vec<TraceRow>)| estimates(r).last().map(|t| t.est.clone()).unwrap();
    let (truth, est) = (estimates(&original[0]).last().unwrap().truth.clone(), last(&raw[0]));
    let q = |e: &[f64]| simnet::estimate::attitude::from_euler(&nalgebra::Vector3::new(e[0], e[1], e[2]));
    let err = simnet::estimate::attitude::angle_between(&q(&truth), &q(&est)).to_degrees();
    println!("node 0 from the bare file: final error {err:.4}°");
    assert!(err < 0.3, "{err}°");
    std::fs::remove_dir_all(&dir).ok();
}

fn recording(name: &str) -> String {
    format!("{}/tests/data/recordings/{name}", env!("CARGO_MANIFEST_DIR"))
}

/// `simnet attitude … --json`: (exit code, stdout, stderr).
fn attitude_cli(args: &[&str]) -> (i32, serde_json::Value, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_simnet"))
        .arg("attitude")
        .args(args)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    let v = serde_json::from_slice(&out.stdout).unwrap_or(serde_json::Value::Null);
    (out.status.code().unwrap_or(-1), v, stderr)
}

fn score<'a>(v: &'a serde_json::Value, filter: &str, which: &str) -> &'a serde_json::Value {
    let s = v["scores"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["filter"] == filter)
        .unwrap();
    &s[which]
}

/// The three real recordings of tests/data/recordings run as they come, with no flag beyond the reference file:
/// every filter's error against the on-board orientation stays within a bound a little above what was measured
/// (README, "Real recordings"), the noise model the Xsens recording gives is within a factor 3 of what its reference
/// shows, and the accelerometer gate's count equals an independent count of the samples
/// whose |a| is more than 10 % off the median |a|.
#[test]
fn real_recordings_run_as_they_come() {
    let xsens = recording("xsens-mti.txt");
    let (code, v, err) = attitude_cli(&[&xsens, "--json"]);
    assert_eq!(code, 0, "{err}");
    assert!((v["rate_hz"].as_f64().unwrap() - 50.0).abs() < 1e-9);
    assert!(
        v["estimated"]["still_s"].is_null(),
        "the Xsens recording moves throughout"
    );
    for (filter, bound) in [
        ("ekf", 3.4),
        ("mekf", 2.9),
        ("madgwick", 3.5),
        ("mahony", 8.0),
        ("gyro", 3.0),
    ] {
        let m = score(&v, filter, "as_recorded")["mean"].as_f64().unwrap();
        assert!(m < bound, "xsens {filter}: {m}°");
    }
    // VQF settles over its first 5 s from a start 8.8° off in heading: bounded with the offset removed, and its
    // tilt, which is the best here (1.36°).
    let vqf = score(&v, "vqf", "offset_removed");
    assert!(vqf["mean"].as_f64().unwrap() < 3.6, "xsens vqf: {vqf}");
    assert!(vqf["tilt_mean"].as_f64().unwrap() < 1.6, "xsens vqf: {vqf}");
    assert!(score(&v, "vqf", "gated").is_null() && score(&v, "vqf", "consistency").is_null());
    // The filters that keep a covariance report their innovations' consistency, with the χ² band around 1.
    for filter in ["ekf", "mekf"] {
        for sensor in ["accel", "field"] {
            let n = &score(&v, filter, "consistency")[sensor];
            let (lo, hi) = (n["band"][0].as_f64().unwrap(), n["band"][1].as_f64().unwrap());
            assert!(
                n["per_dof"].as_f64().unwrap() > 0.0 && lo < 1.0 && hi > 1.0,
                "{filter} {sensor}: {n}"
            );
        }
    }
    assert!(score(&v, "madgwick", "consistency").is_null());
    // The noise model, from the recording alone, within a factor 3 of what the reference shows, across g and
    // across the field (README, "Real recordings": 1.23× and 2.83×).
    let across = &v["estimated"]["across"];
    let check = &v["noise_check"];
    for (model, shown) in [
        (&across["accel"], &check["accel_across"]),
        (&across["field"], &check["field"]["across_horizontal"]),
    ] {
        let r = shown["white_equivalent"].as_f64().unwrap() / model["white_equivalent"].as_f64().unwrap();
        assert!((1.0 / 3.0..3.0).contains(&r), "xsens: {shown} against {model}");
    }
    let text = std::fs::read_to_string(&xsens).unwrap();
    let r = simnet::imu_csv::layout::read(&text, "x", &Default::default())
        .unwrap()
        .recording;
    let mut n: Vec<f64> = r.accel.iter().map(|a| a.norm()).collect();
    n.sort_by(f64::total_cmp);
    let g = 0.5 * (n[n.len() / 2 - 1] + n[n.len() / 2]);
    let off = r.accel.iter().filter(|a| (a.norm() - g).abs() > 0.1 * g).count();
    for filter in ["ekf", "mekf"] {
        let gated = score(&v, filter, "gated");
        assert_eq!(gated["accel"].as_u64().unwrap() as usize, off, "{filter}");
        assert!(gated["field"].as_u64().unwrap() > 0, "{filter}");
    }
    // Its field varies by disturbance, not by iron: the ellipsoid fit is refused and the readings kept.
    let (code, c, err) = attitude_cli(&[&xsens, "--calibrate-mag", "--json"]);
    assert_eq!(code, 0, "{err}");
    let refused = c["mag_calibration"]["refused"].as_str().unwrap();
    assert!(refused.contains("explains too little"), "{refused}");
    assert_eq!(c["scores"], v["scores"]);
    // Open, nothing is refused; the noise model alone then weighs the disturbances.
    let (code, o, err) = attitude_cli(&[&xsens, "--gates", "off", "--json"]);
    assert_eq!(code, 0, "{err}");
    let ekf = o["scores"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["filter"] == "ekf")
        .unwrap();
    assert_eq!(
        (ekf["gated"]["accel"].as_u64(), ekf["gated"]["field"].as_u64()),
        (Some(0), Some(0))
    );
    assert!(o["gates"]["accel"].is_null());
    let m = ekf["as_recorded"]["mean"].as_f64().unwrap();
    assert!(m < 3.4, "xsens ekf, gates open: {m}°");
    // The field must pass for 0.5 s on end before it corrects; without that wait it refuses fewer samples.
    assert_eq!(v["gates"]["settle_s"].as_f64(), Some(0.5));
    let (code, u, err) = attitude_cli(&[&xsens, "--gates", "settle=0", "--json"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(u["gates"]["settle_s"].as_f64(), Some(0.0));
    for filter in ["ekf", "mekf"] {
        let (now, then) = (score(&v, filter, "gated"), score(&u, filter, "gated"));
        assert_eq!(now["accel"], then["accel"], "{filter}");
        assert!(
            then["field"].as_u64().unwrap() < now["field"].as_u64().unwrap(),
            "{filter}: {then} against {now}"
        );
    }

    let (code, v, err) = attitude_cli(&[
        &recording("xio3-inertial.csv"),
        "--reference",
        &recording("xio3-quaternion.csv"),
        "--json",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(v["estimated"]["field"].is_null(), "no magnetometer");
    for filter in ["ekf", "mekf", "madgwick", "mahony", "gyro", "vqf"] {
        // Without a magnetometer heading is the gyro's alone: scored with the constant offset removed.
        let e = score(&v, filter, "offset_removed");
        assert!(e["mean"].as_f64().unwrap() < 3.5, "xio3 {filter}: {e}");
        assert!(e["tilt_mean"].as_f64().unwrap() < 1.5, "xio3 {filter}: {e}");
    }

    let (code, v, err) = attitude_cli(&[
        &recording("ngimu-sensors.csv"),
        "--reference",
        &recording("ngimu-quaternion.csv"),
        "--json",
    ]);
    assert_eq!(code, 0, "{err}");
    for filter in ["ekf", "mekf", "madgwick", "mahony", "gyro", "vqf"] {
        let m = score(&v, filter, "offset_removed")["mean"].as_f64().unwrap();
        assert!(m < 13.0, "ngimu {filter}: {m}°");
    }
}

/// A filter run outside simnet is scored as simnet's own are: the EKF's attitudes, written to `attitude.csv` and
/// given back row for row as `--compare mine=…`, score exactly the EKF's figures; the NGIMU's own quaternion file,
/// turned z down (NED) and given with its time column, is matched by time and turned back, and scores zero.
#[test]
fn a_filter_run_elsewhere_is_scored_like_simnets_own() {
    let dir = std::env::temp_dir().join(format!("simnet-test-{}-attitude-compare", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let xsens = recording("xsens-mti.txt");
    let out = dir.join("out");
    let (code, v, err) = attitude_cli(&[&xsens, "--json", "--out", out.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let table = std::fs::read_to_string(out.join("attitude.csv")).unwrap();
    let mut lines = table.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let at = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let cols = ["ekf_qw", "ekf_qx", "ekf_qy", "ekf_qz"].map(at);
    let mut mine = String::from("W,X,Y,Z\n");
    for line in lines {
        let f: Vec<&str> = line.split(',').collect();
        mine.push_str(&cols.map(|c| f[c]).join(","));
        mine.push('\n');
    }
    let mine_path = dir.join("mine.csv");
    std::fs::write(&mine_path, mine).unwrap();
    let (code, w, err) = attitude_cli(&[&xsens, "--json", "--compare", &format!("mine={}", mine_path.display())]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(w["scores"].as_array().unwrap().len(), 7);
    for which in ["as_recorded", "offset_removed"] {
        for field in ["mean", "rms", "max", "heading_mean", "tilt_mean"] {
            let (a, b) = (
                score(&v, "ekf", which)[field].as_f64().unwrap(),
                score(&w, "mine", which)[field].as_f64().unwrap(),
            );
            assert!((a - b).abs() < 1e-9, "{which}.{field}: ekf {a}, mine {b}");
        }
    }
    assert_eq!(score(&w, "mine", "outside"), true);
    assert_eq!(score(&w, "ekf", "outside"), false);

    // The reference itself, z down: each (w, x, y, z) turned by π about x is (−x, w, −z, y) up to sign.
    let (ngimu, ngimuq) = (recording("ngimu-sensors.csv"), recording("ngimu-quaternion.csv"));
    let text = std::fs::read_to_string(&ngimuq).unwrap();
    let mut ned = String::from("Time (s),W,X,Y,Z\n");
    for line in text.lines().skip(1) {
        let f: Vec<f64> = line.split(',').map(|x| x.trim().parse().unwrap()).collect();
        ned.push_str(&format!("{},{},{},{},{}\n", f[0], -f[2], f[1], -f[4], f[3]));
    }
    let ned_path = dir.join("ned.csv");
    std::fs::write(&ned_path, ned).unwrap();
    let (code, n, err) = attitude_cli(&[
        &ngimu,
        "--reference",
        &ngimuq,
        "--json",
        "--compare",
        &format!("ned={}", ned_path.display()),
    ]);
    assert_eq!(code, 0, "{err}");
    let m = score(&n, "ned", "as_recorded")["max"].as_f64().unwrap();
    assert!(m < 1e-5, "the reference scored against itself: max {m}°");
    // The table names it as the closest, both ways.
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_simnet"))
        .args(["attitude", &ngimu, "--reference", &ngimuq, "--compare"])
        .arg(format!("ned={}", ned_path.display()))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("closest to the reference: ned (0.00°) as recorded, ned (0.00°) with the offset removed"),
        "{text}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Bad input gets exit 2 and a message naming what is wrong.
#[test]
fn attitude_bad_input_is_named() {
    let dir = std::env::temp_dir().join(format!("simnet-test-{}-attitude-bad", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bare = dir.join("bare.csv");
    std::fs::write(
        &bare,
        "t,ax,ay,az,gx,gy,gz\n0,0,0,9.8,0,0,0\n0.01,0,0,9.8,0,0,0\n0.02,0,0,9.8,0,0,0\n",
    )
    .unwrap();
    let bad_row = dir.join("bad.csv");
    std::fs::write(
        &bad_row,
        "t,ax,ay,az,gx,gy,gz,qw,qx,qy,qz\n0,0,0,9.8,0,0,0,1,0,0,0\n0.01,0,0,x9,0,0,0,1,0,0,0\n",
    )
    .unwrap();
    let late = dir.join("late.csv");
    std::fs::write(&late, "t,qw,qx,qy,qz\n1000,1,0,0,0\n1001,1,0,0,0\n1002,1,0,0,0\n").unwrap();
    let tiny = dir.join("tiny.csv");
    std::fs::write(
        &tiny,
        "t,ax,ay,az,gx,gy,gz,qw,qx,qy,qz\n0,0,0,9.8,0,0,0,1,0,0,0\n1e-310,0,0,9.8,0,0,0,1,0,0,0\n\
         2e-310,0,0,9.8,0,0,0,1,0,0,0\n",
    )
    .unwrap();
    let few = dir.join("few.csv");
    std::fs::write(&few, "qw,qx,qy,qz\n1,0,0,0\n1,0,0,0\n1,0,0,0\n").unwrap();
    let xsens = recording("xsens-mti.txt");
    let (xio3, xio3q) = (recording("xio3-inertial.csv"), recording("xio3-quaternion.csv"));
    let bare_s = bare.to_str().unwrap();
    let late_s = late.to_str().unwrap();
    let missing = dir.join("nope.txt");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec![missing.to_str().unwrap()], "cannot read"),
        (vec![bare_s], "no reference orientation"),
        (vec![bad_row.to_str().unwrap()], ":3: `x9` in column `az`"),
        (vec![&xsens, "--units", "gyro=furlong/s"], "not a unit of gyro"),
        (vec![&xsens, "--units", "speed=m/s"], "not a quantity with a unit"),
        (vec![&xsens, "--columns", "ax=Nope"], "no column `Nope`"),
        (vec![&xsens, "--columns", "wx=Acc_X"], "not a column simnet reads"),
        (vec![&xsens, "--rate=-5"], "must be a positive number"),
        (vec![bare_s, "--reference", late_s], "hardly overlap"),
        (vec![bare_s, "--reference", bare_s], "no reference orientation columns"),
        (
            vec![&xio3, "--reference", &xio3q, "--calibrate-mag"],
            "has no magnetometer",
        ),
        (vec![&xsens, "--gates", "accel=0"], "not a positive number"),
        (vec![&xsens, "--gates", "heading=0.1"], "not a gate"),
        (vec![&xsens, "--gates", "settle=-0.5"], "not a duration"),
        (vec![tiny.to_str().unwrap()], "sample rate (inf Hz)"),
    ];
    let c = |name: &str, file: &str| vec![xsens.clone(), "--compare".into(), format!("{name}={file}")];
    let few_s = few.to_str().unwrap();
    let compared: Vec<(Vec<String>, &str)> = vec![
        (
            vec![xsens.clone(), "--compare".into(), "vqf".into()],
            "expected NAME=FILE",
        ),
        (c("ekf", &xsens), "`ekf` is taken"),
        (c("a b", late_s), "letters, digits"),
        (
            [c("x", late_s), c("x", late_s)[1..].to_vec()].concat(),
            "`x` is given twice",
        ),
        (c("x", late_s), "do not cover the recording's"),
        (c("x", few_s), "3 rows and no time column"),
        (c("x", missing.to_str().unwrap()), "cannot read"),
        (c("x", bare_s), "no reference orientation columns"),
    ];
    let cases = cases.into_iter().chain(
        compared
            .iter()
            .map(|(a, says)| (a.iter().map(String::as_str).collect(), *says)),
    );
    for (args, says) in cases {
        let (code, _, err) = attitude_cli(&args);
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: `{err}` does not say `{says}`");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A recording simnet wrote (attitude3, node 0, 20 s) read back by `simnet attitude`: against the true attitude
/// every filter stays within a degree, the EKF within half of one; a maker's file goes through `simnet reconstruct`
/// too, with its quaternion as the attitude.
#[test]
fn simnet_recordings_and_maker_files_go_through_both_commands() {
    let dir = std::env::temp_dir().join(format!("simnet-test-{}-attitude-own", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let d = dir.to_str().unwrap();
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_simnet"))
        .args(["-q", "-t", "attitude3", "--duration", "20", "--out", d])
        .stdout(std::process::Stdio::null())
        .status()
        .unwrap();
    assert!(status.success());
    let (code, v, err) = attitude_cli(&[dir.join("imu-0.csv").to_str().unwrap(), "--json"]);
    assert_eq!(code, 0, "{err}");
    for (filter, bound) in [("ekf", 0.5), ("mekf", 0.5), ("madgwick", 1.0), ("mahony", 1.0)] {
        let m = score(&v, filter, "as_recorded")["mean"].as_f64().unwrap();
        assert!(m < bound, "{filter}: {m}°");
    }
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_simnet"))
        .args([
            "reconstruct",
            &recording("xsens-mti.txt"),
            "--start-position",
            "0,0,0",
            "--end-velocity",
            "0,0,0",
        ])
        .args(["--out", dir.join("r").to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stdout).contains("attitude from the reference columns"));
    let csv = std::fs::read_to_string(dir.join("r/reconstruction.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 953);
    let _ = std::fs::remove_dir_all(&dir);
}
