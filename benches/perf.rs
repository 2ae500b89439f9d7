//! simnet's benchmarks: `cargo bench --bench perf` prints a Markdown table (the README's Performance section).
//!
//! Each micro-benchmark runs for about half a second after a warm-up and reports the median of five batches. The end
//! to end figures run whole virtual-clock simulations over real UDP sockets and are set beside a raw loopback UDP
//! send/receive pair measured in the same process, as a ratio.
#![allow(non_snake_case)]

use std::hint::black_box;
use std::sync::Arc;
use std::time::{Duration, Instant};

use nalgebra::{DMatrix, DVector, SMatrix, SVector, Vector3};
use simnet::estimate::attitude::{from_euler, measurement};
use simnet::estimate::bvp::End;
use simnet::estimate::{consensus_update, kalman_update, Gaussian, MissingChannels, Observation, Source};
use simnet::link::{FaultSchedule, Link, LinkConfig, LossModel};
use simnet::model::{Attitude, Dynamics, Linear, Pose, Sensing};
use simnet::net::{self, RunOptions};
use simnet::scenario::{LinkSpec, Overrides, Scenario};
use simnet::sensor::{ImuInterval, ImuSample};
use simnet::wire::{Datagram, Header, Payload};

/// Median time per call, in nanoseconds.
fn time_per_call(mut f: impl FnMut()) -> f64 {
    let start = Instant::now();
    let mut calls = 0u64;
    while start.elapsed() < Duration::from_millis(100) {
        f();
        calls += 1;
    }
    let batch = (calls / 2).max(1);
    let mut samples: Vec<f64> = (0..5)
        .map(|_| {
            let t = Instant::now();
            for _ in 0..batch {
                f();
            }
            t.elapsed().as_nanos() as f64 / batch as f64
        })
        .collect();
    samples.sort_by(f64::total_cmp);
    samples[2]
}

/// One pose node's step as the kernels see it: the filter, an IMU interval, a measurement with every row.
struct PoseStep {
    pose: Pose,
    Q: DMatrix<f64>,
    obs: Observation,
    g: Gaussian,
    interval: ImuInterval,
    z: DVector<f64>,
    present: Vec<bool>,
}

impl PoseStep {
    fn new() -> PoseStep {
        let pose = Pose::default();
        let imu = ImuSample {
            accel: Vector3::new(0.1, -0.2, 9.8),
            gyro: Vector3::new(0.01, 0.02, 0.6),
        };
        PoseStep {
            Q: Pose::noise(0.01, 3.92e-3, 8.73e-5, 0.0, 0.0, 0.0),
            obs: pose.observation(),
            pose,
            g: Gaussian {
                x: DVector::from_element(9, 0.1),
                P: DMatrix::identity(9, 9) * 0.01,
            },
            interval: ImuInterval { start: imu, end: imu },
            z: DVector::from_vec(vec![0.11, 0.09, 0.1, 0.1, 0.1, 0.12]),
            present: vec![true; 6],
        }
    }

    /// Nanoseconds of one consensus update over the own measurement (β 0.6) and `neighbours` others sharing 0.4.
    fn consensus_ns(&self, neighbours: usize) -> f64 {
        let zs: Vec<DVector<f64>> = (0..=neighbours).map(|j| &self.z * (1.0 + 0.01 * j as f64)).collect();
        let srcs: Vec<Source<'_>> = zs
            .iter()
            .enumerate()
            .map(|(j, z)| Source {
                beta: if j == 0 { 0.6 } else { 0.4 / neighbours as f64 },
                z,
                present: &self.present,
            })
            .collect();
        time_per_call(|| {
            black_box(
                consensus_update(
                    black_box(&self.g),
                    &self.obs,
                    0.01,
                    &srcs,
                    MissingChannels::Drop,
                    10,
                    1e3,
                    1e-5,
                )
                .unwrap(),
            );
        })
    }
}

fn raw_udp_pair(n: usize) -> f64 {
    let rx = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    rx.set_read_timeout(Some(Duration::from_millis(200))).unwrap();
    let addr = rx.local_addr().unwrap();
    let receiver = std::thread::spawn(move || {
        let mut buf = [0u8; 2048];
        let mut got = 0usize;
        let t = Instant::now();
        while got < n {
            match rx.recv_from(&mut buf) {
                Ok(_) => got += 1,
                Err(_) => break,
            }
        }
        (got, t.elapsed())
    });
    let tx = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let payload = [7u8; 64];
    for _ in 0..n {
        let _ = tx.send_to(&payload, addr);
    }
    let (got, elapsed) = receiver.join().unwrap();
    got as f64 / elapsed.as_secs_f64()
}

/// (node-steps/s, datagrams/s) of a virtual-clock run.
fn end_to_end(name: &str, duration: f64) -> (f64, f64, f64) {
    let t = Scenario::resolve(name).unwrap();
    let topo = Arc::new(
        t.with(&Overrides {
            duration_s: Some(duration),
            ..Default::default()
        })
        .unwrap(),
    );
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .unwrap();
    let out = rt
        .block_on(net::run(topo.clone(), RunOptions::default(), std::future::pending()))
        .unwrap();
    let datagrams: u64 = out.reports.iter().map(|r| r.counters.datagrams_in).sum();
    let node_steps = out.steps_done as f64 * topo.nodes().len() as f64;
    (node_steps / out.wall_s, datagrams as f64 / out.wall_s, out.wall_s)
}

/// A ring of `n` peers on a scalar linear model (estimation nearly free): what simnet's lockstep itself costs.
fn scalar_ring(n: usize, steps: u64) -> Scenario {
    let one = |v: f64| DMatrix::from_element(1, 1, v);
    let model = Linear::new(one(0.9), one(1.0), one(0.1), one(0.5), DVector::zeros(1), one(1.0));
    let mut b = Scenario::builder()
        .name(&format!("scalar-ring{n}"))
        .rate_hz(100.0)
        .duration_s(steps as f64 / 100.0)
        .burn_in_s(0.0)
        .model(model);
    for i in 0..n {
        b = b.peer(i as u32);
    }
    b.ring().build().unwrap()
}

/// Seconds per step of a virtual-clock run over UDP.
fn simnet_step(s: &Scenario) -> f64 {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .unwrap();
    let out = rt
        .block_on(net::run(
            Arc::new(s.clone()),
            RunOptions::default(),
            std::future::pending(),
        ))
        .unwrap();
    assert!(!out.interrupted && out.socket_losses == 0);
    out.wall_s / out.steps_done as f64
}

/// The anchor of the lockstep: simnet's traffic shape with nothing else — one socket per node, one 64 B datagram to
/// each ring neighbour per step, a node moving on once both neighbours' datagrams of the step are in, one worker per
/// core owning a block of nodes (as simnet's lockstep). Seconds per step.
fn free_running_ring(n: usize, steps: u64) -> f64 {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async move {
        let mut sockets = Vec::with_capacity(n);
        for _ in 0..n {
            sockets.push(tokio::net::UdpSocket::bind("127.0.0.1:0").await.unwrap());
        }
        let addrs: Arc<Vec<std::net::SocketAddr>> = Arc::new(sockets.iter().map(|s| s.local_addr().unwrap()).collect());
        let workers = std::thread::available_parallelism().map_or(1, |p| p.get()).min(n);
        let per = n.div_ceil(workers);
        let start = Instant::now();
        let mut handles = Vec::new();
        let mut sockets = sockets.into_iter();
        for w in 0..workers {
            let mine: Vec<(usize, tokio::net::UdpSocket)> = (w * per..((w + 1) * per).min(n))
                .map(|i| (i, sockets.next().unwrap()))
                .collect();
            let addrs = addrs.clone();
            handles.push(tokio::spawn(async move {
                // Datagrams received per node, by step modulo 64 (a ring keeps neighbours within a step).
                let mut got = vec![[0u8; 64]; mine.len()];
                let mut buf = [0u8; 2048];
                for k in 0..steps {
                    let mut payload = [0u8; 64];
                    payload[..8].copy_from_slice(&k.to_le_bytes());
                    for (i, s) in &mine {
                        s.send_to(&payload, addrs[(i + 1) % n]).await.unwrap();
                        s.send_to(&payload, addrs[(i + n - 1) % n]).await.unwrap();
                    }
                    let slot = (k % 64) as usize;
                    loop {
                        for (j, (_, s)) in mine.iter().enumerate() {
                            while got[j][slot] < 2 {
                                let Ok((len, _)) = s.try_recv_from(&mut buf) else { break };
                                if len >= 8 {
                                    let step = u64::from_le_bytes(buf[..8].try_into().unwrap());
                                    got[j][(step % 64) as usize] += 1;
                                }
                            }
                        }
                        match got.iter().position(|g| g[slot] < 2) {
                            Some(j) => mine[j].1.readable().await.unwrap(),
                            None => break,
                        }
                    }
                    got.iter_mut().for_each(|g| g[slot] = 0);
                }
            }));
        }
        for h in handles {
            h.await.unwrap();
        }
        start.elapsed().as_secs_f64() / steps as f64
    })
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Lockstep target: simnet's scalar ring step ≤ 1.25 × the free-running anchor of the same size, measured in
/// alternation, medians of three.
fn lockstep_ratios(only: Option<usize>) {
    for (n, steps) in [(3usize, 3000u64), (100, 1000), (1000, 200)] {
        if only.is_some_and(|o| o != n) {
            continue;
        }
        let s = scalar_ring(n, steps);
        let (mut ours, mut anchor) = (Vec::new(), Vec::new());
        for _ in 0..3 {
            anchor.push(free_running_ring(n, steps));
            ours.push(simnet_step(&s));
        }
        let (o, a) = (median(ours), median(anchor));
        println!(
            "ratio lockstep_scalar_ring{n} = {:.2} (target ≤ 1.25)   simnet {:.1} µs/step, free-running anchor {:.1} µs/step",
            o / a,
            o * 1e6,
            a * 1e6
        );
    }
}

/// Loading and stepping linear in the network: a 100,000-node scalar ring (`SCALE_N` nodes) built (the file's
/// validator) and run for 100 steps in memory.
fn scale() {
    let t = Instant::now();
    let n: usize = std::env::var("SCALE_N")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(100_000);
    let s = scalar_ring(n, 100);
    let built = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let out = simnet::Sim::new(&s).unwrap().run().unwrap();
    let ran = t.elapsed().as_secs_f64();
    assert_eq!(out.steps_done, 100);
    println!(
        "scale: a {n}-node scalar ring builds and validates in {built:.2} s and runs 100 steps in memory in {ran:.2} s \
         ({:.2} µs per node-step)",
        ran / (n as f64 * 100.0) * 1e6
    );
}

/// CPU seconds this process has used, user and system (/proc/self/stat, in clock ticks of 1/100 s on Linux).
fn cpu_s() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let after = stat.rsplit_once(')').map_or("", |(_, r)| r);
    let f: Vec<f64> = after.split_whitespace().map(|v| v.parse().unwrap_or(0.0)).collect();
    // Fields 14 and 15 of the file (utime, stime) are the 12th and 13th after the command name.
    (f.get(11).unwrap_or(&0.0) + f.get(12).unwrap_or(&0.0)) / 100.0
}

type M9 = SMatrix<f64, 9, 9>;
type M6 = SMatrix<f64, 6, 6>;
type M69 = SMatrix<f64, 6, 9>;
type V9 = SVector<f64, 9>;
type V6 = SVector<f64, 6>;

/// The anchors of the kernel ratios: the pose step on static nalgebra types from end to end — no dynamic matrix,
/// no conversion, every row present, nothing checked but the Cholesky factorisations.
struct BareStatic {
    x: DVector<f64>,
    P: M9,
    Q: M9,
    H: M69,
    R: M6,
    z: V6,
}

impl BareStatic {
    fn new(p: &PoseStep) -> BareStatic {
        BareStatic {
            x: p.g.x.clone(),
            P: M9::from_column_slice(p.g.P.as_slice()),
            Q: M9::from_column_slice(p.Q.as_slice()),
            H: M69::from_column_slice(p.obs.H.as_slice()),
            R: M6::from_column_slice(p.obs.R.as_slice()),
            z: V6::from_column_slice(p.z.as_slice()),
        }
    }

    /// Prediction (the model's own f and F) and the Joseph update.
    fn kf_step(&self, imu: &ImuInterval) -> (V9, M9) {
        let (x, F) = simnet::model::pose::step(&self.x, Some(imu), 0.01);
        let x = V9::from_column_slice(x.as_slice());
        let P = F * self.P * F.transpose() + self.Q;
        let S = self.H * P * self.H.transpose() + self.R;
        let K = nalgebra::Cholesky::new(S).unwrap().solve(&(self.H * P)).transpose();
        let nu = self.z - self.H * x;
        let IKH = M9::identity() - K * self.H;
        (x + K * nu, IKH * P * IKH.transpose() + K * self.R * K.transpose())
    }

    /// Eqs. (5)–(10) over `zs` with weights `beta`, and the three Cholesky tests of (17), (19).
    fn consensus(&self, zs: &[V6], beta: &[f64]) -> (V9, M9, bool) {
        let x = V9::from_column_slice(self.x.as_slice());
        let S = self.H * self.P * self.H.transpose() + self.R;
        let K = nalgebra::Cholesky::new(S)
            .unwrap()
            .solve(&(self.H * self.P))
            .transpose();
        let mut c = V9::zeros();
        let mut Pn = self.P - K * S * K.transpose() * (1.0 - 0.01);
        for (z, b) in zs.iter().zip(beta) {
            let kz = K * (z - self.H * x);
            c += kz * *b;
            Pn += kz * kz.transpose() * *b;
        }
        Pn -= c * c.transpose();
        let Z = (Pn - self.P) * 1e-3;
        let spd = |m: M9| nalgebra::Cholesky::new(m).is_some();
        (x + c, Pn, spd(Pn) && spd(M9::identity() - Z) && spd(M9::identity() + Z))
    }
}

/// The kernel targets: simnet's pose KF step and consensus against the same on bare static types, same run.
fn kernel_ratios() {
    let p = PoseStep::new();
    let bare = BareStatic::new(&p);
    let (mut ours, mut anchor) = (Vec::new(), Vec::new());
    for _ in 0..3 {
        anchor.push(time_per_call(|| {
            black_box(bare.kf_step(black_box(&p.interval)));
        }));
        ours.push(time_per_call(|| {
            let g = p.pose.predict(black_box(&p.g), Some(&p.interval), &p.Q, 0.01);
            black_box(kalman_update(&g, &p.obs, &p.z, &p.present, MissingChannels::Drop).unwrap());
        }));
    }
    let (o, a) = (median(ours), median(anchor));
    println!(
        "ratio pose_kf_step = {:.2} (target ≤ 1.3)   simnet {:.2} µs, bare static {:.2} µs",
        o / a,
        o / 1e3,
        a / 1e3
    );
    let zs: Vec<V6> = (0..=2).map(|j| bare.z * (1.0 + 0.01 * j as f64)).collect();
    let beta = [0.6, 0.2, 0.2];
    let (mut ours, mut anchor) = (Vec::new(), Vec::new());
    for _ in 0..3 {
        anchor.push(time_per_call(|| {
            black_box(bare.consensus(black_box(&zs), &beta));
        }));
        ours.push(p.consensus_ns(2));
    }
    let (o, a) = (median(ours), median(anchor));
    println!(
        "ratio consensus_2_neighbours = {:.2} (target ≤ 1.3)   simnet {:.2} µs, bare static {:.2} µs",
        o / a,
        o / 1e3,
        a / 1e3
    );
}

/// The estimation targets: a pose ring's node-step against the sum of its kernels (two predictions, the consensus
/// over the own and two neighbours' measurements, the independent Kalman update), in memory (throughput, `Sim`) and
/// over UDP (CPU per node-step, both cores).
fn estimation_ratios() {
    let p = PoseStep::new();
    let predict = time_per_call(|| {
        black_box(p.pose.predict(black_box(&p.g), Some(&p.interval), &p.Q, 0.01));
    });
    let update = time_per_call(|| {
        black_box(kalman_update(black_box(&p.g), &p.obs, &p.z, &p.present, MissingChannels::Drop).unwrap());
    });
    let consensus = p.consensus_ns(2);
    let kernels = 2.0 * predict + update + consensus;
    // Scoring each of the two updates against the truth (error, NEES, trace P): work every node-step of a run does.
    let mut scorer = simnet::observe::Scorer::new(Arc::new(p.pose.clone()), 0, f64::INFINITY);
    let truth = &p.g.x * 1.01;
    let post = Gaussian {
        x: &p.g.x * 0.99,
        P: &p.g.P * 0.5,
    };
    let score = time_per_call(|| {
        black_box(scorer.score(&simnet::observe::Update {
            node: 0,
            step: 1,
            t: 0.01,
            filter: simnet::observe::Filter::Networked,
            truth: black_box(&truth),
            prior: &p.g,
            post: &post,
            failed: false,
            feasible: true,
            received: &[],
        }));
    });
    let scored = kernels + 2.0 * score;
    // The observer's fused estimate: one covariance-intersection stage (ω = 0.5) per node and step over the
    // networked filters' estimates, the headline figure every run reports; per node, from a cascade of 100.
    let layout = simnet::model::Report::fusion(&p.pose);
    let estimates: Vec<Gaussian> = (0..100)
        .map(|i| Gaussian {
            x: &p.g.x * (1.0 + 1e-3 * i as f64),
            P: &p.g.P * (1.0 + 1e-2 * i as f64),
        })
        .collect();
    let fuse = time_per_call(|| {
        black_box(
            simnet::estimate::fusion::cascade(
                black_box(&estimates),
                simnet::estimate::fusion::Omega::Fixed(0.5),
                &layout.angle_states,
            )
            .unwrap(),
        );
    }) / estimates.len() as f64;
    let reported = scored + fuse;
    let s = Scenario::resolve("ring100")
        .unwrap()
        .with(&Overrides {
            duration_s: Some(3.0),
            ..Default::default()
        })
        .unwrap();
    let node_steps = (s.sim().steps() * s.nodes().len() as u64) as f64;
    // The median of three runs: one run on a shared machine is too noisy a figure.
    let sim = median(
        (0..3)
            .map(|_| {
                let t = Instant::now();
                simnet::Sim::new(&s).unwrap().run().unwrap();
                t.elapsed().as_secs_f64() * 1e9 / node_steps
            })
            .collect(),
    );
    println!(
        "ratio sim_pose_ring100_throughput = {:.2} (target ≥ 0.8)   kernels {:.2} µs per node-step, Sim {:.2} µs",
        kernels / sim,
        kernels / 1e3,
        sim / 1e3
    );
    println!(
        "ratio sim_pose_ring100_throughput_scored = {:.2} (target ≥ 0.8)   kernels and scoring {:.2} µs per node-step, Sim {:.2} µs",
        scored / sim,
        scored / 1e3,
        sim / 1e3
    );
    println!(
        "ratio sim_pose_ring100_throughput_reported = {:.2}   kernels, scoring and the observer's fusion {:.2} µs per node-step, Sim {:.2} µs",
        reported / sim,
        reported / 1e3,
        sim / 1e3
    );
    let c0 = cpu_s();
    simnet_step(&s);
    let cpu = (cpu_s() - c0) * 1e9 / node_steps;
    println!(
        "ratio lockstep_pose_ring100_cpu = {:.2} (target ≤ 1.5)   CPU {:.2} µs per node-step over UDP",
        cpu / kernels,
        cpu / 1e3
    );
}

/// Peak resident memory of this process, KiB.
fn peak_rss_kib() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse().ok())
        })
        .unwrap_or(0)
}

/// Steps each size of the scaling curve runs (about a second or two each).
fn scaling_steps(n: usize) -> u64 {
    (200_000 / n as u64).clamp(50, 3000)
}

/// One point of the scaling curve, in a process of its own (peak RSS is per process): prints "µs-per-step KiB".
fn scaling_one(n: usize, mode: &str) {
    let steps = scaling_steps(n);
    let per_step = match mode {
        "udp" => simnet_step(&scalar_ring(n, steps)),
        "sim" => {
            let s = scalar_ring(n, steps);
            let t = Instant::now();
            let out = simnet::Sim::new(&s).unwrap().run().unwrap();
            t.elapsed().as_secs_f64() / out.steps_done as f64
        }
        _ => free_running_ring(n, steps),
    };
    println!("{} {}", per_step * 1e6, peak_rss_kib());
}

/// Time per step and peak RSS of scalar rings of 10 to 10,000 nodes: simnet over UDP (virtual clock), in memory
/// (`Sim`), and the free-running anchor; the table, and `target/perf/scaling.svg`.
fn scaling() {
    let exe = std::env::current_exe().unwrap();
    let mut series: Vec<(String, Vec<(f64, f64)>)> = [
        "simnet over UDP (virtual clock)",
        "simnet in memory (Sim)",
        "free-running UDP anchor",
    ]
    .iter()
    .map(|s| (s.to_string(), Vec::new()))
    .collect();
    println!("| nodes | over UDP µs/step | peak RSS | in memory µs/step | peak RSS | anchor µs/step | peak RSS |");
    println!("|---|---|---|---|---|---|---|");
    for n in [10usize, 100, 1000, 10_000] {
        let mut row = format!("| {n} |");
        for (k, mode) in ["udp", "sim", "anchor"].iter().enumerate() {
            let out = std::process::Command::new(&exe)
                .args(["scaling-one", &n.to_string(), mode])
                .output()
                .unwrap();
            let text = String::from_utf8_lossy(&out.stdout);
            let mut f = text.split_whitespace().map(|v| v.parse::<f64>().unwrap_or(f64::NAN));
            let (us, kib) = (f.next().unwrap_or(f64::NAN), f.next().unwrap_or(f64::NAN));
            row += &format!(" {us:.1} | {:.1} MB |", kib / 1024.0);
            series[k].1.push(((n as f64).log10(), us / n as f64));
        }
        println!("{row}");
    }
    let svg = simnet::report::plot::lines(
        &series,
        "log₁₀ nodes in the ring",
        "µs per node-step",
        false,
        "scalar rings: time per node-step against size (2 cores)",
    )
    .unwrap();
    std::fs::create_dir_all("target/perf").unwrap();
    std::fs::write("target/perf/scaling.svg", svg).unwrap();
    println!("wrote target/perf/scaling.svg");
}

/// A ring of `n` peers of the pose model (the builder's default) at 100 Hz.
fn pose_ring(n: usize, steps: u64) -> Scenario {
    let mut b = Scenario::builder()
        .name(&format!("pose-ring{n}"))
        .rate_hz(100.0)
        .duration_s(steps as f64 / 100.0)
        .burn_in_s(0.0);
    for i in 0..n {
        b = b.peer(i as u32);
    }
    b.ring().build().unwrap()
}

/// One run in a process of its own (peak RSS is per process): a `model` ring ("scalar" or "pose") of `n` nodes for
/// `secs` at 100 Hz on `clock` ("realtime" or "virtual"). Prints "largest-lag-ms late-node-steps node-steps KiB".
fn clock_one(n: usize, model: &str, secs: f64, clock: &str) {
    let steps = (secs * 100.0) as u64;
    let s = if model == "pose" {
        pose_ring(n, steps)
    } else {
        scalar_ring(n, steps)
    };
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .unwrap();
    let opts = RunOptions {
        clock: if clock == "realtime" {
            simnet::net::Clock::Realtime
        } else {
            simnet::net::Clock::Virtual
        },
        ..Default::default()
    };
    let out = rt
        .block_on(net::run(Arc::new(s), opts, std::future::pending()))
        .unwrap();
    assert!(!out.interrupted);
    let sch = out.schedule.unwrap_or_default();
    println!("{} {} {} {}", sch.max_lag_ms, sch.late_steps, sch.steps, peak_rss_kib());
}

/// Realtime keeping up, and the memory of a 1000-node ring over 30 s on both clocks, each run in its own process.
fn realtime() {
    let exe = std::env::current_exe().unwrap();
    let one = |n: usize, model: &str, secs: f64, clock: &str| -> Vec<f64> {
        let out = std::process::Command::new(&exe)
            .args(["clock-one", &n.to_string(), model, &secs.to_string(), clock])
            .output()
            .unwrap();
        String::from_utf8_lossy(&out.stdout)
            .split_whitespace()
            .map(|v| v.parse().unwrap_or(f64::NAN))
            .collect()
    };
    let f = one(1000, "scalar", 10.0, "realtime");
    println!(
        "target realtime_scalar_ring1000_late = {:.4} (target ≤ 0)   100 Hz for 10 s: largest lag {:.1} ms, {} of {} \
         node-steps more than a period late",
        f[1] / f[2],
        f[0],
        f[1],
        f[2]
    );
    for clock in ["virtual", "realtime"] {
        let f = one(1000, "scalar", 30.0, clock);
        println!(
            "target ring1000_30s_{clock}_rss_mb = {:.1} (target ≤ 40)",
            f[3] / 1024.0
        );
    }
    println!("| pose ring, 100 Hz, 5 s | largest lag | node-steps late | peak RSS |");
    println!("|---|---|---|---|");
    for n in [100usize, 200, 300, 400, 600] {
        let f = one(n, "pose", 5.0, "realtime");
        println!(
            "| {n} | {:.1} ms | {:.1} % | {:.1} MB |",
            f[0],
            100.0 * f[1] / f[2],
            f[3] / 1024.0
        );
    }
}

/// What authentication costs: sealing and opening one measurement datagram against encoding and decoding it, and
/// whole runs with `--auth` against the same runs without, in memory and over UDP (each the median of three).
fn auth_ratios() {
    use simnet::wire::secure::{Key, Opener, Sealer};
    let d = Datagram {
        header: Header::new(3, 4, 17, simnet::time::Time::at_step(12345, 0.01)),
        payload: Payload::measurement(0b111111, vec![0.11, 0.09, 0.1, 0.1, 0.1, 0.12]),
    };
    let key = Key::from_bytes([7; 16]);
    let mut sealer = Sealer::new(&key, 3, 1);
    let plain = d.encode().unwrap();
    let enc = time_per_call(|| {
        black_box(black_box(&d).encode().unwrap());
    });
    let seal = time_per_call(|| {
        black_box(sealer.seal(black_box(&d), 4, 9).unwrap());
    });
    let dec = time_per_call(|| {
        black_box(Datagram::decode(black_box(&plain)).unwrap());
    });
    // A fresh opener each call: every sealed datagram opens once.
    let mut fresh = Sealer::new(&key, 3, 2);
    let sealed: Vec<_> = (0..64).map(|_| fresh.seal(&d, 4, 9).unwrap()).collect();
    let mut i = 0;
    let mut opener = Opener::new(&key, 4, 9);
    let open = time_per_call(|| {
        if i % 64 == 0 {
            opener = Opener::new(&key, 4, 9);
        }
        black_box(opener.open(black_box(&sealed[i % 64]), |_| true).unwrap());
        i += 1;
    });
    println!(
        "| seal / open a {} B measurement datagram (AES-128-CCM, {} B sealed) | {seal:.0} ns / {open:.0} ns ({:.1}× encode, {:.1}× decode) |",
        plain.len(),
        sealed[0].len(),
        seal / enc,
        open / dec
    );
    for (name, udp) in [("ring3", false), ("rgg50", false), ("ring3", true)] {
        let wall = |auth: bool| {
            let topo = Scenario::resolve(name)
                .unwrap()
                .with(&Overrides {
                    duration_s: Some(if name == "rgg50" { 10.0 } else { 30.0 }),
                    auth: auth.then_some(true),
                    ..Default::default()
                })
                .unwrap();
            median(
                (0..3)
                    .map(|_| {
                        let t = Instant::now();
                        // Whole runs: the kernels, the link layer and (over UDP) the sockets, sealed or not.
                        if udp {
                            let rt = tokio::runtime::Builder::new_multi_thread()
                                .enable_all()
                                .build()
                                .unwrap();
                            black_box(
                                rt.block_on(net::run(
                                    Arc::new(topo.clone()),
                                    RunOptions::default(),
                                    std::future::pending(),
                                ))
                                .unwrap(),
                            );
                        } else {
                            black_box(simnet::Sim::new(&topo).unwrap().run().unwrap());
                        }
                        t.elapsed().as_secs_f64()
                    })
                    .collect(),
            )
        };
        let (plain, sealed) = (wall(false), wall(true));
        println!(
            "| `{name}` {} with `--auth` against without | {sealed:.2} s / {plain:.2} s = {:.3}× |",
            if udp {
                "over UDP (virtual clock)"
            } else {
                "in memory (Sim)"
            },
            sealed / plain
        );
    }
}

/// rgg50 in memory over the radio channel against the same run over the pairwise links, wall time, in alternated
/// rounds (the best of each): at 10 Hz (the channel a quarter busy) and at its 100 Hz (saturated).
fn radio_ratios() {
    for (rate, secs) in [(10.0, 40.0), (100.0, 4.0)] {
        let pairwise = Scenario::resolve("rgg50")
            .unwrap()
            .with(&Overrides {
                duration_s: Some(secs),
                ..Default::default()
            })
            .unwrap()
            .set("sim.rate_hz", toml::Value::Float(rate))
            .unwrap();
        let radio = pairwise
            .set("medium.kind", toml::Value::String("radio".into()))
            .unwrap();
        let time = |s: &Scenario| {
            let t = Instant::now();
            black_box(simnet::Sim::new(s).unwrap().run().unwrap());
            t.elapsed().as_secs_f64()
        };
        let (mut a, mut b) = (f64::MAX, f64::MAX);
        for _ in 0..3 {
            a = a.min(time(&pairwise));
            b = b.min(time(&radio));
        }
        println!(
            "| rgg50 in memory at {rate} Hz ({secs} s simulated): radio channel / pairwise links, wall | {:.2} ({b:.3} s / {a:.3} s) |",
            b / a
        );
    }
}

/// A static radio network of `RADIO_N` nodes (10,000 by default) in memory: a square lattice at rgg50's density
/// (one node per 200 m², 14.1 m apart), each node's consensus neighbours the lattice's four, 10 Hz, 2 s; the radio
/// against the same network over the pairwise links, and the cost of a node-step.
fn radio_scale() {
    let n: usize = std::env::var("RADIO_N")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10_000);
    let side = (n as f64).sqrt().ceil() as usize;
    let spacing = 200f64.sqrt();
    let one = |v: f64| DMatrix::from_element(1, 1, v);
    let model = Linear::new(one(0.9), one(1.0), one(0.1), one(0.5), DVector::zeros(1), one(1.0));
    let mut b = Scenario::builder()
        .name(&format!("radio-lattice{n}"))
        .rate_hz(10.0)
        .duration_s(2.0)
        .burn_in_s(0.0)
        .model(model);
    for i in 0..n {
        let (x, y) = ((i % side) as f64 * spacing, (i / side) as f64 * spacing);
        b = b.peer(i as u32).position(i as u32, [x, y, 0.0]);
    }
    for i in 0..n {
        for j in [i + 1, i + side] {
            let neighbour = if j == i + 1 { (i + 1) % side != 0 } else { j < n };
            if neighbour && j < n {
                b = b.edge(i as u32, j as u32, LinkSpec::default());
            }
        }
    }
    let pairwise = b.build().unwrap();
    let radio = pairwise
        .set("medium.kind", toml::Value::String("radio".into()))
        .unwrap();
    let time = |s: &Scenario| {
        let t = Instant::now();
        let out = black_box(simnet::Sim::new(s).unwrap().run().unwrap());
        (t.elapsed().as_secs_f64(), out.steps_done)
    };
    let (a, steps) = time(&pairwise);
    let (r, _) = time(&radio);
    println!(
        "| a {n}-node static lattice in memory at 10 Hz (2 s simulated): radio channel / pairwise links, wall | {:.2} ({r:.2} s / {a:.2} s; {:.1} µs per node-step on the radio) |",
        r / a,
        r / (n as f64 * steps as f64) * 1e6
    );
}

fn main() {
    // `cargo bench --bench perf -- MODE` runs one part: `lockstep [N]` (the lockstep ratios, of the ring of N),
    // `estimation` (the kernel and node-step ratios), `radio`, `radio-scale`, `realtime`, `scale`, `scaling`; `kf-loop`,
    // `sim-loop` and `radio-loop [rate]` are loops for a profiler. No mode: everything.
    let args: Vec<String> = std::env::args().collect();
    if let Some(i) = args.iter().position(|a| a == "scaling-one") {
        scaling_one(args[i + 1].parse().unwrap(), &args[i + 2]);
        return;
    }
    if let Some(i) = args.iter().position(|a| a == "clock-one") {
        clock_one(
            args[i + 1].parse().unwrap(),
            &args[i + 2],
            args[i + 3].parse().unwrap(),
            &args[i + 4],
        );
        return;
    }
    if args.iter().any(|a| a == "auth") {
        println!("| benchmark | figure |");
        println!("|---|---|");
        auth_ratios();
        return;
    }
    if args.iter().any(|a| a == "realtime") {
        realtime();
        return;
    }
    if args.iter().any(|a| a == "radio-scale") {
        radio_scale();
        return;
    }
    if args.iter().any(|a| a == "radio") {
        radio_ratios();
        return;
    }
    if args.iter().any(|a| a == "scaling") {
        scaling();
        return;
    }
    if args.iter().any(|a| a == "sim-loop") {
        // For a profiler: ring100 in memory.
        let s = Scenario::resolve("ring100")
            .unwrap()
            .with(&Overrides {
                duration_s: Some(10.0),
                ..Default::default()
            })
            .unwrap();
        simnet::Sim::new(&s).unwrap().run().unwrap();
        return;
    }
    if let Some(i) = args.iter().position(|a| a == "radio-loop") {
        // For a profiler: rgg50 over the radio at the rate given (10 or 100 Hz), 10 s.
        let rate: f64 = args.get(i + 1).and_then(|r| r.parse().ok()).unwrap_or(100.0);
        let s = Scenario::resolve("rgg50-radio")
            .unwrap()
            .with(&Overrides {
                duration_s: Some(10.0),
                ..Default::default()
            })
            .unwrap()
            .set("sim.rate_hz", toml::Value::Float(rate))
            .unwrap();
        simnet::Sim::new(&s).unwrap().run().unwrap();
        return;
    }
    if args.iter().any(|a| a == "kf-loop") {
        // For a profiler: the pose KF step and the consensus, nothing else.
        let p = PoseStep::new();
        let t = Instant::now();
        while t.elapsed() < Duration::from_secs(3) {
            let g = p.pose.predict(black_box(&p.g), Some(&p.interval), &p.Q, 0.01);
            black_box(kalman_update(&g, &p.obs, &p.z, &p.present, MissingChannels::Drop).unwrap());
            let srcs = [Source {
                beta: 1.0,
                z: &p.z,
                present: &p.present,
            }];
            black_box(consensus_update(&g, &p.obs, 0.01, &srcs, MissingChannels::Drop, 10, 1e3, 1e-5).unwrap());
        }
        return;
    }
    if args.iter().any(|a| a == "estimation") {
        kernel_ratios();
        estimation_ratios();
        return;
    }
    if args.iter().any(|a| a == "scale") {
        scale();
        return;
    }
    if let Some(i) = args.iter().position(|a| a == "lockstep") {
        lockstep_ratios(args.get(i + 1).and_then(|n| n.parse().ok()));
        return;
    }
    let step = PoseStep::new();

    println!("| benchmark | figure |");
    println!("|---|---|");
    let kf = time_per_call(|| {
        let p = step
            .pose
            .predict(black_box(&step.g), Some(&step.interval), &step.Q, 0.01);
        black_box(kalman_update(&p, &step.obs, &step.z, &step.present, MissingChannels::Drop).unwrap());
    });
    println!(
        "| KF step, pose model (9 states, 6 measurements): predict + Joseph update | {:.2} µs |",
        kf / 1e3
    );
    // The attitude node's step: quaternion prediction (A_t, Q_t from Ξ(q̂)), the measurement linearised about the
    // prior, the Joseph update.
    let att = Attitude::default();
    let Rg = DMatrix::identity(3, 3) * 2.8e-4;
    let q0 = from_euler(&Vector3::new(0.2, -0.1, 0.7));
    let ga = Gaussian {
        x: DVector::from_column_slice(q0.as_slice()),
        P: DMatrix::identity(4, 4) * 1e-4,
    };
    let (g_nav, h_nav) = (Vector3::new(0.0, 0.0, -9.81), Vector3::new(0.25, 0.0, -0.433));
    let (y, _) = measurement(&q0, &g_nav, &h_nav);
    let att_obs = att.observation();
    let ekf = time_per_call(|| {
        let p = att.predict(black_box(&ga), Some(&step.interval), &Rg, 0.01);
        let (obs, z) = att.linearize_at(&att_obs, &p, simnet::model::Site { node: 0 }, &[&y]);
        let (obs, z) = (obs.into_owned(), z[0].clone().into_owned());
        black_box(kalman_update(&p, &obs, &z, &step.present, MissingChannels::Inflate(1e3)).unwrap());
    });
    println!(
        "| EKF step, attitude model (quaternion, accelerometer + magnetometer): predict + linearised Joseph update | {:.2} µs |",
        ekf / 1e3
    );
    for neighbours in [2usize, 4] {
        let t = step.consensus_ns(neighbours);
        println!(
            "| consensus update + LMI checks (17), (19), {neighbours} neighbours | {:.2} µs |",
            t / 1e3
        );
    }
    let cfg = LinkConfig {
        loss: LossModel::gilbert_elliott_from(0.2, 3.0).unwrap(),
        jitter_ms: 2.0,
        duplicate: 0.01,
        corrupt: 0.01,
        ..Default::default()
    };
    let mut link = Link::new(0, 1, cfg, simnet::rng::stream(1, "link", 0, 1));
    let sched = FaultSchedule::default();
    let mut now = simnet::time::Time::ZERO;
    let t = time_per_call(|| {
        now = now + std::time::Duration::from_millis(10);
        black_box(link.verdict(now, 80, &sched));
    });
    println!(
        "| link verdict (Gilbert–Elliott, jitter, duplication, corruption) | {:.0} ns |",
        t
    );
    let d = Datagram {
        header: Header::new(3, 9, 17, simnet::time::Time::at_step(12345, 0.01)),
        payload: Payload::measurement(0b111111, step.z.iter().copied().collect()),
    };
    let bytes = d.encode().unwrap();
    let enc = time_per_call(|| {
        black_box(black_box(&d).encode().unwrap());
    });
    let dec = time_per_call(|| {
        black_box(Datagram::decode(black_box(&bytes)).unwrap());
    });
    println!(
        "| wire encode / decode ({} B measurement datagram) | {enc:.0} ns / {dec:.0} ns |",
        bytes.len()
    );

    // Boundary-value reconstruction: the tridiagonal FEM solve should cost the same per sample at every length.
    for n in [10_000usize, 100_000, 1_000_000] {
        let t: Vec<f64> = (0..n).map(|i| i as f64 * 0.01).collect();
        let a: Vec<f64> = t.iter().map(|s| (0.7 * s).sin()).collect();
        let ns = time_per_call(|| {
            std::hint::black_box(simnet::estimate::bvp::solve(&t, &a, End::Position(0.0), End::Position(1.0)).unwrap());
        });
        println!(
            "| FEM solve, Dirichlet at both ends, {n} samples | {:.2} ms, {:.1} ns/sample |",
            ns / 1e6,
            ns / n as f64
        );
    }

    let raw = raw_udp_pair(200_000);
    println!(
        "| raw loopback UDP, one blocking sender → one receiver thread (64 B) | {:.0} datagrams/s |",
        raw
    );
    for (name, duration) in [("ring3", 30.0), ("attitude3", 30.0), ("ring100", 3.0)] {
        let (ns, dg, wall) = end_to_end(name, duration);
        println!(
            "| end to end, virtual clock, `{name}` ({duration} s simulated, {wall:.2} s wall) | {ns:.0} node-steps/s, {dg:.0} datagrams/s = {:.1} % of raw UDP |",
            100.0 * dg / raw
        );
    }
    auth_ratios();
    lockstep_ratios(None);
    kernel_ratios();
    estimation_ratios();
    radio_ratios();
    radio_scale();
    realtime();
    scale();
    scaling();
}
