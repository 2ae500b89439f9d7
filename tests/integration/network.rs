//! Whole runs over real UDP sockets: delivered fraction (h), determinism (i), robustness (j), faults.

use simnet::net::RunOptions;
use simnet::scenario::Overrides;

use crate::common;

/// (h) End to end over real sockets, ring3 at --loss 0.2 delivers a fraction within 3σ of 0.8.
#[test]
fn ring3_delivers_80_percent_end_to_end() {
    let s = common::run(common::topology("ring3", common::bernoulli(0.2, 3)));
    let sent: u64 = s.links.iter().map(|l| l.sent).sum();
    let delivered: u64 = s.links.iter().map(|l| l.delivered).sum();
    let frac = delivered as f64 / sent as f64;
    let sigma = (0.8 * 0.2 / sent as f64).sqrt();
    println!(
        "ring3: delivered {delivered}/{sent} = {frac:.4} (3σ = {:.4})",
        3.0 * sigma
    );
    assert!((frac - 0.8).abs() < 3.0 * sigma);
    assert_eq!(s.socket_losses, 0);
    for l in &s.links {
        assert_eq!(
            l.sent,
            l.delivered + l.lost,
            "{} → {}: every datagram is delivered or lost",
            l.from,
            l.to
        );
    }
}

/// The summary as two runs of one scenario and seed must agree on it (`Summary::reproducible`).
fn reproducible(s: simnet::report::summary::Summary) -> String {
    s.reproducible().to_json()
}

/// (i) Two virtual runs with the same seed write byte-identical summary.json apart from `transport`, with every fault
/// of the link layer active.
#[test]
fn virtual_runs_are_deterministic() {
    let o = || Overrides {
        delay_ms: Some(3.0),
        jitter_ms: Some(4.0),
        duplicate: Some(0.05),
        corrupt: Some(0.02),
        duration_s: Some(10.0),
        ..common::bernoulli(0.2, 42)
    };
    let a = reproducible(common::run(common::topology("ring3", o())));
    let b = reproducible(common::run(common::topology("ring3", o())));
    assert_eq!(a, b);
    let c = reproducible(common::run(common::topology(
        "ring3",
        Overrides { seed: Some(43), ..o() },
    )));
    assert_ne!(a, c, "a different seed must give different results");
}

/// (j) Garbage sent to a running node's socket is counted as malformed, changes no result, and the run finishes;
/// datagrams corrupted by the link layer are all caught by the checksum.
#[test]
fn garbage_and_corruption_are_caught() {
    let o = || Overrides {
        duration_s: Some(10.0),
        ..common::bernoulli(0.1, 5)
    };
    let clean = common::run(common::topology("ring3", o()));

    // The garbage goes out in 25 bursts, each while the run waits between two steps (its progress callback blocks
    // until the burst is in node 0's socket buffer), so every datagram is read in the next step whatever the load:
    // the count is exact by construction, not by timing.
    let (tx, rx) = tokio::sync::oneshot::channel();
    let (go_tx, go_rx) = std::sync::mpsc::channel::<()>();
    let (ack_tx, ack_rx) = std::sync::mpsc::channel::<()>();
    let sender = std::thread::spawn(move || {
        let addrs: Vec<std::net::SocketAddr> = tokio::runtime::Builder::new_current_thread()
            .build()
            .unwrap()
            .block_on(rx)
            .unwrap();
        let target = addrs[0];
        let sock = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let mut sent = 0;
        let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
        for burst in 0..25 {
            go_rx.recv().unwrap();
            for i in 0..20 {
                let len = [0usize, 1, 7, 40, 300, 1199, 1200, 1400][(burst + i) % 8];
                let bytes: Vec<u8> = (0..len)
                    .map(|_| {
                        x ^= x << 13;
                        x ^= x >> 7;
                        x ^= x << 17;
                        x as u8
                    })
                    .collect();
                sock.send_to(&bytes, target).unwrap();
                sent += 1;
            }
            ack_tx.send(()).unwrap();
        }
        sent
    });
    let ack_rx = std::sync::Mutex::new(ack_rx);
    let progress: simnet::net::Progress = std::sync::Arc::new(move |done, _| {
        if done % 10 == 0 && done / 10 <= 25 {
            go_tx.send(()).unwrap();
            ack_rx.lock().unwrap().recv().unwrap();
        }
    });
    let opts = RunOptions {
        on_bound: Some(tx),
        progress: Some(progress),
        ..Default::default()
    };
    let (noisy, _) = common::run_with(common::topology("ring3", o()), opts);
    let sent = sender.join().unwrap();
    assert!(!noisy.interrupted);
    assert_eq!(
        noisy.nodes[0].malformed, sent,
        "every garbage datagram is counted as malformed"
    );
    let mut a = noisy.clone();
    a.nodes[0].malformed = 0;
    assert_eq!(reproducible(a), reproducible(clean), "garbage changed a result");

    // Corruption: 5 % of datagrams get one bit flipped; each one is caught, none is decoded as data.
    let o = Overrides {
        corrupt: Some(0.05),
        duration_s: Some(10.0),
        ..common::bernoulli(0.0, 6)
    };
    let (s, out) = common::run_with(common::topology("ring3", o), RunOptions::default());
    for l in &s.links {
        let tx = out.reports.iter().find(|r| r.id == l.from).unwrap();
        let flipped = tx
            .links_out
            .iter()
            .find(|(to, _)| out.reports[*to].id == l.to)
            .unwrap()
            .1
            .corrupted;
        assert!(flipped > 0);
        assert_eq!(
            l.corrupted, flipped,
            "{} → {}: every corrupted datagram is caught",
            l.from, l.to
        );
        assert_eq!(
            l.delivered + l.corrupted,
            l.sent,
            "{} → {}: nothing else lost",
            l.from,
            l.to
        );
    }
}

/// Scheduled faults: a crash with restart re-initialises the node, a partition and a link-down window cost exactly
/// the datagrams sent during them, and the survivors keep stepping.
#[test]
fn scheduled_faults() {
    let toml = simnet::scenario::builtin::get("ring3").unwrap().to_string()
        + r#"
[[fault]]
kind = "crash"
node = 2
at_s = 5.0
restart_s = 8.0
[[fault]]
kind = "link-down"
link = [0, 1]
start_s = 12.0
end_s = 13.0
[[fault]]
kind = "partition"
nodes = [1]
start_s = 20.0
end_s = 21.5
"#;
    let s = common::run(common::topology(
        &toml,
        Overrides {
            duration_s: Some(25.0),
            ..common::seed(9)
        },
    ));
    let rate = 100.0;
    let node2 = s.nodes.iter().find(|n| n.id == 2).unwrap();
    assert_eq!(node2.restarts, 1);
    assert_eq!(node2.steps_down, (3.0 * rate) as u64);
    for n in &s.nodes {
        assert!(!n.networked.as_ref().unwrap().diverged, "node {} diverged", n.id);
    }
    let link = |a: u32, b: u32| s.links.iter().find(|l| l.from == a && l.to == b).unwrap();
    // 0 → 2: down while node 2 is crashed (3 s).
    assert_eq!(link(0, 2).lost_down, (3.0 * rate) as u64);
    // 0 ↔ 1: the link-down second plus the 1.5 s partition of node 1.
    assert_eq!(link(0, 1).lost_down, (2.5 * rate) as u64);
    assert_eq!(link(1, 0).lost_down, (2.5 * rate) as u64);
    // 2 → 1: crash (node 2 sends nothing while down, so its link counts no sends) and partition.
    assert_eq!(link(2, 1).lost_down, (1.5 * rate) as u64);
}

/// Delay and jitter in simulated time: with 8 ms ± 4 ms (uniform) and a 10 ms deadline, a quarter of the datagrams
/// arrive after their step closed and are counted late, not used.
#[test]
fn jitter_past_the_deadline_makes_datagrams_late() {
    let o = Overrides {
        delay_ms: Some(8.0),
        jitter_ms: Some(4.0),
        duration_s: Some(20.0),
        ..common::bernoulli(0.0, 8)
    };
    let s = common::run(common::topology("ring3", o));
    let sent: u64 = s.links.iter().map(|l| l.sent).sum();
    let late: u64 = s.links.iter().map(|l| l.late).sum();
    let delivered: u64 = s.links.iter().map(|l| l.delivered).sum();
    assert_eq!(
        late + delivered,
        sent,
        "no loss configured: every datagram is delivered or late"
    );
    let frac = late as f64 / sent as f64;
    let sigma = (0.25 * 0.75 / sent as f64).sqrt();
    println!("late fraction {frac:.4} (expected 0.25 ± {:.4})", 3.0 * sigma);
    assert!((frac - 0.25).abs() < 3.0 * sigma);
    for n in &s.nodes {
        assert!(n.error_ratio.unwrap() < 1.0, "node {}", n.id);
    }
}

/// A receiver counts from the sequence numbers alone what its sender lost on their link: over UDP and in memory,
/// broadcast and sealed per link, with bursty loss, duplicates, reordering and a crash, its gaps are the sender's
/// losses but for the run of losses after the last datagram that came (which no receiver can see).
#[test]
fn a_receiver_counts_the_senders_losses_from_sequence_gaps() {
    let faults = "[[fault]]\nkind = \"crash\"\nnode = 2\nat_s = 1.0\nrestart_s = 1.5\n";
    let toml = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/topologies/ring3.toml")).unwrap() + faults;
    for auth in [false, true] {
        let o = Overrides {
            loss: Some(simnet::link::LossModel::gilbert_elliott_from(0.2, 3.0).unwrap()),
            duplicate: Some(0.2),
            delay_ms: Some(5.0),
            jitter_ms: Some(4.0),
            duration_s: Some(4.0),
            auth: auth.then_some(true),
            ..common::seed(6)
        };
        let topo = common::topology(&toml, o);
        let memory = simnet::Sim::new(&topo).unwrap().run().unwrap();
        let (_, udp) = common::run_with(topo, RunOptions::default());
        for (how, results) in [("memory", &memory), ("udp", &udp)] {
            if results.socket_losses > 0 {
                // Frames the kernel dropped and no resend recovered (a loaded machine): gaps no link made.
                println!(
                    "{how}: {} frames lost in the socket layer, gaps not compared",
                    results.socket_losses
                );
                continue;
            }
            let mut lost = 0;
            for from in &results.reports {
                for (to, tx) in &from.links_out {
                    let rx = results.reports[*to].rx.get(from.index);
                    let gone = tx.lost_random + tx.lost_down;
                    assert!(gone > 0, "{how}: {} → {to} lost nothing", from.index);
                    assert_eq!(
                        rx.seq_gaps,
                        gone - tx.current_run,
                        "{how}, auth {auth}: {} → {to}: {tx:?} {rx:?}",
                        from.index
                    );
                    lost += gone;
                }
            }
            assert!(lost > 200, "{how}: {lost}");
        }
    }
}

/// The realtime clock: steps paced by the wall clock, delay and jitter as real waits. Timing is not asserted (shared
/// machines); accounting and estimation are.
#[test]
fn realtime_run_accounts_for_every_datagram() {
    let o = Overrides {
        delay_ms: Some(2.0),
        jitter_ms: Some(1.0),
        duration_s: Some(2.0),
        ..common::bernoulli(0.2, 4)
    };
    let opts = RunOptions {
        clock: simnet::net::Clock::Realtime,
        ..Default::default()
    };
    let (s, _) = common::run_with(common::topology("ring3", o.clone()), opts);
    assert!(!s.interrupted);
    assert_eq!(s.steps, 200);
    // Every node-step's start is measured against the schedule; how late is the machine's, not asserted.
    let sch = s.transport.schedule.expect("a realtime summary reports its schedule");
    assert_eq!(sch.steps, 3 * 200);
    assert!(sch.late_steps <= sch.steps && sch.max_lag_ms >= 0.0 && sch.max_lag_ms.is_finite());
    let (virt, _) = common::run_with(common::topology("ring3", o), RunOptions::default());
    assert_eq!(
        virt.transport.schedule, None,
        "the virtual clock has no schedule to fall behind"
    );
    for l in &s.links {
        assert_eq!(l.sent, 200);
        assert_eq!(l.delivered + l.late + l.lost, l.sent, "{} → {}", l.from, l.to);
        assert!(l.delivered > 100, "{} → {}: {} delivered", l.from, l.to, l.delivered);
    }
    for n in &s.nodes {
        let net = n.networked.as_ref().unwrap();
        assert!(!net.diverged && net.mean_error.unwrap() < 0.1, "node {}: {net:?}", n.id);
    }
}

/// A realtime run stopped part-way ends every worker after the same step: each link sent exactly the steps the run
/// reports, and the fused trace holds each of them. The stop is triggered by a count of fused steps, not a time.
#[test]
fn a_stopped_realtime_run_ends_every_node_after_the_same_step() {
    let o = Overrides {
        duration_s: Some(100_000.0),
        ..common::bernoulli(0.0, 5)
    };
    let (tx, rx) = tokio::sync::oneshot::channel::<()>();
    let tx = std::sync::Mutex::new(Some(tx));
    let opts = RunOptions {
        clock: simnet::net::Clock::Realtime,
        progress: Some(std::sync::Arc::new(move |done, _| {
            if done >= 40 {
                if let Some(tx) = tx.lock().unwrap().take() {
                    let _ = tx.send(());
                }
            }
        })),
        ..Default::default()
    };
    let topo = std::sync::Arc::new(common::topology("ring3", o));
    let out = common::runtime()
        .block_on(simnet::net::run(topo, opts, async {
            let _ = rx.await;
        }))
        .unwrap();
    let s = out.summary();
    assert!(s.interrupted);
    assert!(s.steps >= 40, "{} steps", s.steps);
    for l in &s.links {
        assert_eq!(l.sent, s.steps, "{} → {}", l.from, l.to);
        assert_eq!(l.delivered + l.late + l.lost, l.sent);
    }
    let sch = s.transport.schedule.unwrap();
    assert_eq!(
        sch.steps,
        3 * s.steps,
        "every node-step run was measured against the schedule"
    );
}

/// Receive buffers so small that the kernel drops frames: each is asked for again (a NACK) and resent, so the run
/// loses no frame to the socket layer and its figures are those of the same run in memory.
#[test]
fn a_frame_the_kernel_drops_is_asked_for_again_and_changes_nothing() {
    use simnet::net::RunOptions;
    let topo = common::topology("rgg50", common::bernoulli(0.1, 3)).with(&simnet::Overrides {
        duration_s: Some(3.0),
        ..Default::default()
    });
    let topo = topo.unwrap();
    let memory = common::simulate(topo.clone());
    let (udp, _) = common::run_with(
        topo,
        RunOptions {
            recv_buffer: 6144,
            ..Default::default()
        },
    );
    let drops = udp.transport.kernel_drops_total();
    println!(
        "kernel drops {drops}, frames resent {}, socket losses {}",
        udp.transport.frames_resent, udp.socket_losses
    );
    assert!(drops > 0, "no frame was dropped: the test shows nothing");
    assert!(udp.transport.frames_resent > 0);
    assert_eq!(udp.socket_losses, 0);
    let figures = |s: &simnet::Summary| {
        let v = serde_json::to_value(s.reproducible()).unwrap();
        ["nodes", "links", "fused"].map(|k| v[k].clone())
    };
    assert_eq!(figures(&udp), figures(&memory));
}
