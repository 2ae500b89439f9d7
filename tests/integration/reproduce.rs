//! `simnet reproduce sequeira`: every claim of Sequeira (2023) is reported with simnet's figures, and those that
//! hold by a wide margin on every seed (see README: claims 1–4, 6–10) are asserted. Claims 5 (β 0.7/0.01/0.01,
//! ratios 0.94–1.02), 11 and 12 (median filter, three against two fused nodes) are reported, not asserted: they do
//! not hold on every seed, and that is the finding.

use std::process::Command;

#[test]
fn sequeira_claims_table_and_plots() {
    let dir = std::env::temp_dir().join(format!("simnet-test-{}-sequeira", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let out = Command::new(env!("CARGO_BIN_EXE_simnet"))
        .args([
            "reproduce",
            "sequeira",
            "--seeds",
            "3",
            "--duration",
            "15",
            "-q",
            "--out",
        ])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8(out.stdout).unwrap();
    let claims: Vec<serde_json::Value> =
        serde_json::from_str(&std::fs::read_to_string(dir.join("claims.json")).unwrap()).unwrap();
    assert_eq!(claims.len(), 12);
    for c in &claims {
        let figures = c["figures"].as_str().unwrap();
        let words = || figures.split(|ch: char| !ch.is_alphanumeric());
        assert!(!figures.is_empty() && !words().any(|w| w == "NaN" || w == "inf"), "{c}");
        // The printed table carries every claim with its verdict.
        let verdict = if c["holds"].as_bool().unwrap() { "yes" } else { "**no**" };
        assert!(stdout.contains(&format!("| {} | {} |", figures, verdict)), "{c}");
    }
    for id in ["1", "2", "3", "4", "6", "7", "8", "9", "10"] {
        let c = claims.iter().find(|c| c["id"] == id).unwrap();
        assert_eq!(c["holds"], true, "claim {id}: {c}");
    }
    for plot in [
        "dead_reckoning",
        "g_eigenvalues",
        "error_pair2",
        "error_tri3",
        "error_tri3_alt",
        "feasibility_norm_z",
        "feasibility_min_eig",
        "error_drift",
        "error_piecewise",
        "fusion",
    ] {
        let svg = std::fs::read_to_string(dir.join(format!("{plot}.svg"))).unwrap();
        assert!(
            svg.starts_with("<svg") && (svg.contains("<path") || svg.contains("<polyline")),
            "{plot}"
        );
    }
    assert!(std::fs::read_to_string(dir.join("claims.md"))
        .unwrap()
        .contains("| 12 |"));
}

/// Lesecq's scenario with 20 % loss on each of the accelerometer and magnetometer: the attitude error falls under 2°
/// within 3 s of each reference change and stays there, on 10 seeds; the square-root form equals the standard form
/// to 1e-9 (quaternion, and covariance relative to its largest entry).
#[test]
fn lesecq_attitude_converges_with_loss_and_the_forms_agree() {
    use simnet::reproduce::lesecq::{convergence_times, form_gap, simulate, Config, CONVERGE_S};
    for seed in 1..=10 {
        let cfg = Config {
            seed,
            ..Default::default()
        };
        let rows = simulate(&cfg).unwrap();
        let delivered = rows.iter().flat_map(|r| r.present).filter(|p| *p).count() as f64 / (2 * rows.len()) as f64;
        assert!((delivered - 0.8).abs() < 0.03, "seed {seed}: delivered {delivered}");
        for (change, t) in convergence_times(&rows, cfg.segment_s).into_iter().enumerate() {
            let t = t.unwrap_or_else(|| panic!("seed {seed}: never converged after change {change}"));
            assert!(t < CONVERGE_S, "seed {seed}: change {change} took {t} s");
        }
        let (dq, dp) = form_gap(&rows);
        assert!(
            dq <= 1e-9 && dp <= 1e-9,
            "seed {seed}: forms differ by {dq:e} (q), {dp:e} (P)"
        );
    }
}

/// The rigid pair's separation-constrained EKF beats dead reckoning by at least 25 % in each motion over 1,000 runs
/// (the paper: 26.9–31.5 % over 10,000).
#[test]
#[ignore = "long suite: Monte Carlo over 1,000 runs (.ci/run runs it)"]
fn rigid_pair_ekf_beats_dead_reckoning_by_a_quarter() {
    use simnet::reproduce::rigid_pair::{monte_carlo, Config};
    let cfg = Config {
        runs: 1000,
        ..Default::default()
    };
    let results = monte_carlo(&cfg, &|| ()).unwrap();
    for r in &results {
        eprintln!(
            "{:?}: DR {:.3} m, averaged {:.3} m, EKF {:.3} m, {:.1} ± {:.1} %",
            r.motion, r.dead_reckoning, r.averaged, r.ekf, r.improvement, r.improvement_se
        );
        assert_eq!(r.runs, 1000);
        assert!(r.improvement >= 25.0, "{:?}: {:.1} %", r.motion, r.improvement);
    }
}

/// Boundary-value reconstruction on the rate table: FEM with Dirichlet conditions beats the trapezoid rule at the end
/// of the long run (largest error over the record and at ¾ of it); the error model, given the velocities at every
/// stop of the table, recovers an injected 0.5 m/s² bias and 20 % scale error within 5 % of each error.
#[test]
fn nieminen_fem_beats_trapezoid_and_the_error_model_recovers_bias_and_scale() {
    use simnet::estimate::bvp::{fit_error_model, Constraint, End};
    use simnet::reproduce::nieminen::{record, run_test, tests, Sensor};
    let s = Sensor::default();
    let (long, _) = run_test(&tests()[1], &s).unwrap();
    let (i, ii) = (&long.methods[0], &long.methods[1]);
    assert!(
        ii.max_position < i.max_position,
        "{} vs {}",
        ii.max_position,
        i.max_position
    );
    assert!(
        ii.position[2].abs() < i.position[2].abs(),
        "{:?} vs {:?}",
        ii.position,
        i.position
    );

    let s = Sensor {
        bias: 0.5,
        scale: 1.2,
        ..Default::default()
    };
    for test in tests() {
        let r = record(&test, &s);
        let n = r.t.len();
        let stops: Vec<Constraint> = (0..=test.spins)
            .map(|k| Constraint::Velocity {
                t: s.rest_s + k as f64 * test.spin_s,
                value: 0.0,
            })
            .collect();
        let (theta, _) = fit_error_model(
            &r.t,
            &vec![0.0; n],
            &[r.measured.clone(), vec![1.0; n]],
            End::Position(r.x[0]),
            End::Position(r.x[n - 1]),
            &stops,
        )
        .unwrap();
        let (scale, bias) = (1.0 / theta[0], -theta[1] / theta[0]);
        eprintln!("{}: scale {scale:.5} (1.2), bias {bias:.5} (0.5)", test.name);
        assert!((scale - 1.2).abs() < 0.05 * 0.2, "{}: scale {scale}", test.name);
        assert!((bias - 0.5).abs() < 0.05 * 0.5, "{}: bias {bias}", test.name);
    }
}

/// `simnet run --out` writes each sensing node's IMU samples; `simnet reconstruct` reads them back: with the true
/// positions at both ends, FEM's largest error over a 30 s spiral is below the trapezoid rule's (which starts from
/// the true position and velocity), and a malformed file exits 2 naming its line.
#[test]
fn run_writes_imu_files_and_reconstruct_beats_the_trapezoid_rule() {
    use simnet::reconstruct::{reconstruct, reference_velocity, Known, Options};
    let dir = std::env::temp_dir().join(format!("simnet-test-{}-reconstruct", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let bin = env!("CARGO_BIN_EXE_simnet");
    let run = Command::new(bin)
        .args(["-t", "pair2-paper", "-q", "--out"])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let file = dir.join("imu-0.csv");
    let rec = simnet::imu_csv::parse(&std::fs::read_to_string(&file).unwrap(), "imu-0.csv").unwrap();
    assert_eq!(rec.t.len(), 3000);
    let p = rec.position.clone().unwrap();
    let v = reference_velocity(&rec.t, &p);
    let n = p.len();
    let o = Options {
        start: Some(Known::Position(p[0])),
        end: Some(Known::Position(p[n - 1])),
        start_velocity: Some(v[0]),
        ..Default::default()
    };
    let r = reconstruct(&rec, &o).unwrap();
    let max_err = |x: &[nalgebra::Vector3<f64>]| x.iter().zip(&p).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
    let (fem, trap) = (max_err(&r.fem), max_err(r.trapezoid.as_ref().unwrap()));
    eprintln!("largest position error over 30 s: FEM {fem:.4} m, trapezoid {trap:.4} m");
    assert!(fem < trap, "FEM {fem} vs trapezoid {trap}");

    // A broken copy: the CLI names the file and line and exits 2.
    let text = std::fs::read_to_string(&file).unwrap();
    let mut lines: Vec<&str> = text.lines().collect();
    lines[5] = "0.05,1,2";
    let bad = dir.join("bad.csv");
    std::fs::write(&bad, lines.join("\n")).unwrap();
    let out = Command::new(bin)
        .arg("reconstruct")
        .arg(&bad)
        .arg("--from-reference")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("bad.csv:6:") && err.contains("3 fields"), "{err}");
}
