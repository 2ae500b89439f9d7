//! Whole runs over one shared IEEE 802.15.4 channel ([`simnet::medium::radio::RadioMedium`]) in memory: what the
//! channel delivered is what the nodes received, and a built-in's traffic meets the channel's capacity.

use simnet::medium::radio::{Radio, RadioMedium};
use simnet::sim::SimOptions;
use simnet::{Overrides, Scenario, Sim};

/// Built-in `name`, `secs` long.
fn short(name: &str, secs: f64) -> Scenario {
    let o = Overrides {
        duration_s: Some(secs),
        ..Default::default()
    };
    Scenario::resolve(name).unwrap().with(&o).unwrap()
}

/// ring3 (three nodes a few decimetres apart on one package, 100 Hz, each broadcasting its measurement every step)
/// over one channel for 3 s: every datagram the channel delivered reached its receiver — in time, late or as a
/// duplicate — and none more; with the frames' airtime near the whole 10 ms step (3 × 94 octets, 9 ms), contention
/// delays and loses measurements, so fewer arrive in time than over the default lossless links.
#[test]
fn ring3_over_one_channel() {
    let s = short("ring3", 3.0);
    let medium = RadioMedium::new(Radio::default(), s.world(), s.sim().seed);
    let opts = SimOptions {
        medium: Some(Box::new(medium)),
        ..Default::default()
    };
    let radio = Sim::with_options(&s, opts).unwrap().run().unwrap();
    let links = Sim::new(&s).unwrap().run().unwrap();
    let steps = s.sim().steps();
    let (mut in_time_radio, mut in_time_links) = (0, 0);
    for (r, l) in radio.reports.iter().zip(&links.reports) {
        for &(to, c) in &r.links_out {
            let rx = radio.reports[to].rx.get(r.index);
            let came = c.sent - c.lost_random - c.lost_down;
            assert_eq!(
                rx.delivered + rx.late + rx.duplicates,
                came,
                "{} → {to}: {c:?} against {rx:?}",
                r.index
            );
            assert!(c.sent >= steps, "{} → {to} sent {}", r.index, c.sent);
        }
        for j in 0..radio.reports.len() {
            in_time_radio += radio.reports[j].rx.get(r.index).delivered;
            in_time_links += links.reports[j].rx.get(l.index).delivered;
        }
    }
    eprintln!("ring3, 3 s: measurements in time over the channel {in_time_radio}, over the links {in_time_links}");
    assert!(in_time_radio < in_time_links, "{in_time_radio} against {in_time_links}");
    assert!(in_time_radio > 0);
    let summary = radio.summary();
    assert!(summary.nodes.iter().all(|n| n
        .networked
        .as_ref()
        .and_then(|m| m.mean_error)
        .is_some_and(f64::is_finite)));
}

/// `ring3-radio`, the built-in, in memory: each node's energy is its airtime at the CC2420's 17.4 mA and the rest
/// of the radios' time on (the run, and the queues' drain after it) listening at 18.8 mA, from 3 V (the datasheet's
/// figures, computed here apart from simnet's table); the channel load is the senders' airtime over that time; the airtime is whole octets of 32 µs, at least a
/// measurement's frame (6 + 11 + 75 octets) per frame and at most the largest frame (6 + 127); a message not sent
/// was abandoned by CSMA/CA or is still queued at the end.
#[test]
fn ring3_radio_pays_its_airtime_in_energy() {
    let s = short("ring3-radio", 2.0);
    let summary = Sim::new(&s).unwrap().run().unwrap().summary();
    let radio = summary.radio.as_ref().expect("a radio run has its radio figures");
    let run_s = radio.span_s;
    assert!(run_s >= 2.0, "{run_s}");
    for n in &radio.nodes {
        let want = 3.0 * (17.4e-3 * n.airtime_s + 18.8e-3 * (run_s - n.airtime_s));
        assert!(
            (n.energy_j - want).abs() < 1e-12,
            "node {}: {} against {want}",
            n.id,
            n.energy_j
        );
        let octets = n.airtime_s / 32e-6;
        assert!((octets - octets.round()).abs() < 1e-6, "{n:?}");
        assert!(
            octets >= n.frames as f64 * 92.0 && octets <= n.frames as f64 * 133.0,
            "{n:?}"
        );
        assert!(n.frames + n.csma_failures <= 200 && n.frames > 100, "{n:?}");
    }
    let load: f64 = radio.nodes.iter().map(|n| n.airtime_s).sum::<f64>() / run_s;
    assert!((radio.channel_load - load).abs() < 1e-12);
    // Over the pairwise medium there is no radio to report.
    let plain = Sim::new(&short("ring3", 1.0)).unwrap().run().unwrap().summary();
    assert!(plain.radio.is_none());
}

/// A radio run refuses what it cannot honour, exit 2, naming it: a link rule (the channel decides loss), a radio key
/// on the pairwise medium, an unknown medium, a wall-clock run (the medium is split by sender there).
#[test]
fn a_radio_run_refuses_what_it_cannot_honour() {
    let cases: [(&[&str], &str); 5] = [
        (&["-t", "ring3-radio", "--loss", "0.2"], "link.loss"),
        (&["-t", "ring3-radio", "--delay", "3"], "link.delay_ms"),
        (&["-t", "ring3", "--set", "medium.tx_dbm=3"], "medium.tx_dbm"),
        (&["-t", "ring3-radio", "--set", "medium.kind=ether"], "medium.kind"),
        (&["-t", "ring3-radio", "--realtime"], "not yet on wall clocks"),
    ];
    for (args, names) in cases {
        refused(&[&["-q", "--duration", "1"][..], args].concat(), names);
    }
}

/// `simnet ARGS`, run to its end.
fn simnet<S: AsRef<std::ffi::OsStr>>(args: &[S]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_simnet"))
        .args(args)
        .output()
        .unwrap()
}

/// `simnet ARGS` exits 2 with an error that contains `names`.
fn refused(args: &[&str], names: &str) {
    let out = simnet(args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
    assert!(err.contains(names), "{args:?}: {err}");
}

/// `simnet compare` on a radio runs each estimator alone on the channel: each row's figures are the mean over the
/// seeds of a plain run holding that estimator and the reference (its error ratio, the channel's load, the radios'
/// power), and what a run cannot honour on a radio exits 2 naming the flag.
#[test]
fn compare_on_a_radio_runs_each_estimator_alone() {
    let dir = std::env::temp_dir().join(format!("simnet-test-{}-radio-compare", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let plot = dir.join("budget.svg");
    let compare =
        "-q compare -t rgg50-radio --seeds 2 --rounds 1,2 --duration 2 --estimators sequeira,icf --json --plot";
    let out = simnet(
        &[
            compare.split(' ').map(Into::into).collect(),
            vec![plot.clone().into_os_string()],
        ]
        .concat(),
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let rows = v["rows"].as_array().unwrap();
    let names: Vec<(u64, &str)> = rows
        .iter()
        .map(|r| (r["rounds"].as_u64().unwrap(), r["estimator"].as_str().unwrap()))
        .collect();
    assert_eq!(names, [(1, "sequeira"), (1, "icf"), (2, "sequeira"), (2, "icf")]);
    for r in rows {
        let (rounds, est) = (r["rounds"].as_u64().unwrap(), r["estimator"].as_str().unwrap());
        let runs: Vec<serde_json::Value> = (1..=2u64)
            .map(|seed| {
                let o = Overrides {
                    duration_s: Some(2.0),
                    seed: Some(seed),
                    rounds: Some(rounds),
                    estimators: Some(vec![
                        simnet::estimators::Kind::from_name(est).unwrap(),
                        simnet::estimators::Kind::Centralized,
                    ]),
                    ..Default::default()
                };
                let s = Scenario::resolve("rgg50-radio").unwrap().with(&o).unwrap();
                serde_json::to_value(Sim::new(&s).unwrap().run().unwrap().summary()).unwrap()
            })
            .collect();
        let mean = |f: &dyn Fn(&serde_json::Value) -> f64| runs.iter().map(f).sum::<f64>() / 2.0;
        let close = |a: f64, b: f64, what: &str| {
            assert!(
                (a - b).abs() <= 1e-12 * b.abs().max(1.0),
                "{est} L={rounds} {what}: {a} vs {b}"
            )
        };
        close(
            r["ratio_to_centralized"]["mean"].as_f64().unwrap(),
            mean(&|s| s["estimators"][est]["ratio_to_centralized"].as_f64().unwrap()),
            "ratio",
        );
        close(
            r["channel_load"]["mean"].as_f64().unwrap(),
            mean(&|s| s["radio"]["channel_load"].as_f64().unwrap()),
            "channel load",
        );
        let power = |s: &serde_json::Value| {
            let n = s["radio"]["nodes"].as_array().unwrap();
            n.iter().map(|n| n["mean_power_mw"].as_f64().unwrap()).sum::<f64>() / n.len() as f64
        };
        close(r["mean_power_mw"]["mean"].as_f64().unwrap(), mean(&power), "power");
    }
    // icf's estimates take air beside the measurements: more load than sequeira's measurements alone.
    assert!(rows[1]["channel_load"]["mean"].as_f64() > rows[0]["channel_load"]["mean"].as_f64());
    let svg = std::fs::read_to_string(&plot).unwrap();
    assert!(
        svg.contains("\nicf\n</text>") && svg.contains("\nsequeira\n</text>"),
        "the plot's legend"
    );
    // A plot that cannot be written (its path a directory) fails after the table is out: no figure is lost.
    let compare = "-q compare -t rgg50-radio --seeds 1 --rounds 1 --duration 1 --estimators sequeira --plot";
    let out = simnet(
        &[
            compare.split(' ').map(Into::into).collect(),
            vec![dir.clone().into_os_string()],
        ]
        .concat(),
    );
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stdout).contains("| 1 | sequeira |"));
    std::fs::remove_dir_all(&dir).unwrap();
    for (args, names) in [
        (&["compare", "-t", "rgg50-radio", "--loss", "0.1"][..], "--loss"),
        (
            &["compare", "-t", "rgg50-radio", "--estimators", "centralized"][..],
            "--estimators",
        ),
        (&["compare", "-t", "ring3", "--plot", "b.svg"][..], "--plot"),
        (
            &["compare", "-t", "rgg50-radio", "--plot", "/nonexistent/b.svg"][..],
            "--plot: /nonexistent is not a directory",
        ),
    ] {
        refused(args, names);
    }
}

/// Log-normal shadowing (`medium.shadowing_db`) on rgg50-radio's static nodes: each link's RSSI is 0 dBm less ns-3's
/// log-distance loss at its distance (computed here) less the pair's shadowing, the same both ways; over the pairs of
/// five seeds the shadowing's mean is within 3 standard errors of 0 and its variance within 3 of σ² = 36 dB².
#[test]
fn shadowing_is_reciprocal_and_normal_around_the_path_loss() {
    let mut shadow = Vec::new();
    for seed in 2..=6u64 {
        let o = Overrides {
            duration_s: Some(1.0),
            seed: Some(seed),
            ..Default::default()
        };
        let s = Scenario::resolve("rgg50-radio")
            .unwrap()
            .with(&o)
            .unwrap()
            .set("medium.shadowing_db", toml::Value::Float(6.0))
            .unwrap();
        let sum = Sim::new(&s).unwrap().run().unwrap().summary();
        let rssi: std::collections::BTreeMap<(u32, u32), (f64, f64)> = sum
            .links
            .iter()
            .filter_map(|l| {
                let r = l.radio.as_ref()?;
                Some(((l.from, l.to), (r.rssi_dbm?, r.distance_m?)))
            })
            .collect();
        for (&(from, to), &(dbm, d)) in &rssi {
            if let Some(&(back, _)) = rssi.get(&(to, from)) {
                assert!(
                    (dbm - back).abs() < 1e-9,
                    "seed {seed}: {from} → {to} {dbm} dBm, back {back} dBm"
                );
            }
            if from < to || !rssi.contains_key(&(to, from)) {
                shadow.push(-(dbm + 46.6777 + 30.0 * d.log10()));
            }
        }
    }
    let n = shadow.len() as f64;
    assert!(n > 500.0, "{n} pairs");
    let mean = shadow.iter().sum::<f64>() / n;
    let var = shadow.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    assert!(mean.abs() < 3.0 * 6.0 / n.sqrt(), "mean {mean} dB over {n} pairs");
    assert!(
        (var - 36.0).abs() < 3.0 * 36.0 * (2.0 / n).sqrt(),
        "variance {var} dB² over {n} pairs"
    );
}
