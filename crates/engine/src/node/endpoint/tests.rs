//! The node driven in memory: datagrams flow, probes see what the trace records, the attitude filter is
//! `estimate::attitude`'s EKF.

use super::*;
use crate::node::Node;
use crate::observe::Probe;
use crate::wire::Datagram;

/// One lockstep step with the scenario's deadline, the scenario's links carrying the datagrams.
fn step_in_memory(nodes: &mut [Node], medium: &mut crate::medium::PairwiseMedium, k: u64) {
    let window_end = nodes[0].endpoint.topo.deadline(k);
    crate::sim::lockstep(nodes, medium, k, window_end);
}

/// Two nodes driven in memory, no sockets: datagrams flow and both filters track the truth.
#[test]
fn pair_in_memory() {
    let topo = Arc::new(Scenario::resolve("pair2-paper").unwrap());
    let mut nodes: Vec<Node> = (0..2).map(|i| Node::new(topo.clone(), i, false)).collect();
    let mut medium = topo.pairwise_medium(0..2);
    for k in 0..500 {
        step_in_memory(&mut nodes, &mut medium, k);
    }
    for n in &mut nodes {
        let r = n.report(&medium);
        assert_eq!(r.rx.get(1 - r.index).delivered, 500);
        let s = r.networked.unwrap().summary(true);
        assert!(s.mean_error.unwrap() < 0.2, "{s:?}");
        assert!(!s.diverged);
    }
}

/// A probe added to a node sees every update with the score the built-in recorders see, in the same order.
#[test]
fn an_added_probe_sees_what_the_trace_records() {
    use crate::observe::{Score, Update};
    use std::sync::Mutex;
    type Seen = Arc<Mutex<Vec<(u64, bool, f64, f64)>>>;
    struct Tap(Seen);
    impl Probe for Tap {
        fn on_update(&mut self, u: &Update<'_>, s: &Score) {
            let e = s.error.unwrap_or(f64::NAN);
            self.0
                .lock()
                .unwrap()
                .push((u.step, u.filter == Filter::Networked, e, s.trace_p_post));
        }
    }
    let topo = Arc::new(Scenario::resolve("pair2-paper").unwrap());
    let mut nodes: Vec<Node> = (0..2).map(|i| Node::new(topo.clone(), i, true)).collect();
    let seen: Seen = Arc::default();
    nodes[1].add_probe(Box::new(Tap(seen.clone())));
    let mut medium = topo.pairwise_medium(0..2);
    for k in 0..200 {
        step_in_memory(&mut nodes, &mut medium, k);
    }
    let rows: Vec<_> = nodes[1]
        .take_trace()
        .iter()
        .map(|r| (r.step, r.filter == Filter::Networked, r.error, r.trace_p_post))
        .collect();
    assert_eq!(rows.len(), 400);
    assert_eq!(*seen.lock().unwrap(), rows);
}

/// A lone attitude node's filter is the quaternion EKF of `estimate::attitude` (standard form) fed with the same
/// samples: the linearised update inside the node changes nothing.
#[test]
fn attitude_node_is_the_quaternion_ekf() {
    use crate::estimate::attitude::{AttitudeEkf, AttitudeModel, Form};
    use crate::model::ModelConfig;
    use nalgebra::{Matrix3, Vector3};
    let text = "[sim]\nrate_hz = 100.0\nduration_s = 5.0\ntrajectory = \"tumble\"\n[model]\nkind = \"attitude\"\n\
                [[node]]\nid = 0\n";
    let topo = Arc::new(Scenario::from_toml(text, "t.toml").unwrap());
    let ModelConfig::Attitude(cfg) = topo.model() else {
        unreachable!()
    };
    let dt = topo.sim().dt();
    let sg = topo.nodes()[0].sensor.gyro_noise;
    let model = AttitudeModel {
        g: Vector3::new(0.0, 0.0, -crate::geom::GRAVITY),
        h: Vector3::from(cfg.mag_field),
        Rg: Matrix3::identity() * (sg * sg / dt),
        R: DMatrix::from_diagonal(&DVector::from_vec(vec![
            cfg.r_acc, cfg.r_acc, cfg.r_acc, cfg.r_mag, cfg.r_mag, cfg.r_mag,
        ])),
        lambda: topo.consensus().inflation,
    };
    let mut node = Node::new(topo.clone(), 0, true);
    let x0 = &node.endpoint.initial.x;
    let q0 = nalgebra::Vector4::new(x0[0], x0[1], x0[2], x0[3]);
    let mut ekf = AttitudeEkf::new(q0, &node.endpoint.initial.P, Form::Standard).unwrap();
    let mut worst: f64 = 0.0;
    let mut log = Vec::new();
    let mut medium = topo.pairwise_medium([0]);
    for k in 0..500 {
        step_in_memory(std::slice::from_mut(&mut node), &mut medium, k);
        log.extend(node.take_imu());
        let now = log[k as usize];
        if k > 0 {
            let before = log[k as usize - 1];
            ekf.predict(&((before.sample.gyro + now.sample.gyro) * 0.5), dt, &model)
                .unwrap();
        }
        let y = DVector::from_iterator(6, now.sample.accel.iter().chain(now.mag.unwrap().iter()).copied());
        ekf.update(&y, [true, true], &model).unwrap();
        let f = crate::estimators::Estimator::state(&node.endpoint.filters.as_ref().unwrap().independent).unwrap();
        worst = worst.max((&f.x - DVector::from_column_slice(ekf.q.as_slice())).amax());
        worst = worst.max((&f.P - ekf.P()).amax() / ekf.P().amax());
    }
    assert!(worst < 1e-10, "largest gap {worst:e}");
}

/// A forged round message — a scheme the run does not hold, a round past L, a state of the wrong size, a source
/// that is not a peer — is counted as malformed and changes nothing; a valid one is taken.
#[test]
fn forged_round_messages_are_counted_not_used() {
    use crate::estimators::Kind;
    use crate::wire::Body;
    let topo = Scenario::resolve("ring3")
        .unwrap()
        .with(&crate::scenario::Overrides {
            estimators: Some(vec![Kind::Icf]),
            rounds: Some(2),
            ..Default::default()
        })
        .unwrap();
    let mut node = Node::new(Arc::new(topo), 0, false);
    node.open_step(0);
    let info = |n: u8| Body::Information {
        n,
        sym: vec![1.0; (n as usize) * (n as usize + 1) / 2],
        vec: vec![0.0; n as usize],
    };
    let to = |dst: u32, src: u32, round: u8, scheme: Kind, body: Body| {
        Datagram {
            header: Header::round(src, dst, 0, scheme.id(), Time::ZERO, Time::ZERO),
            payload: Payload::Round { round, body },
        }
        .encode()
        .unwrap()
    };
    let dg = |src: u32, round: u8, scheme: Kind, body: Body| to(0, src, round, scheme, body);
    let forged = [
        dg(1, 0, Kind::Kcf, info(9)),
        dg(1, 2, Kind::Icf, info(9)),
        dg(1, 0, Kind::Icf, info(3)),
        // Addressed to node 2.
        to(2, 1, 0, Kind::Icf, info(9)),
    ];
    for (i, bytes) in forged.iter().enumerate() {
        assert!(node.handle_datagram(Some(1), bytes).is_none(), "forgery {i} was taken");
        assert_eq!(node.endpoint.counters.malformed, i as u64 + 1);
    }
    // From a socket that is not the header's source.
    assert!(node.handle_datagram(Some(2), &dg(1, 0, Kind::Icf, info(9))).is_none());
    assert_eq!(node.endpoint.counters.malformed, 5);
    assert!(node.handle_datagram(Some(1), &dg(1, 0, Kind::Icf, info(9))).is_some());
    // A broadcast is for every node that hears it.
    assert!(node
        .handle_datagram(Some(1), &to(BROADCAST, 1, 0, Kind::Icf, info(9)))
        .is_some());
    assert_eq!(node.endpoint.counters.malformed, 5);
}

/// A step is believed only inside the run and no further ahead of the node's own than two seconds of steps: a
/// neighbour's measurement at the run's last step, a hello running at 2⁶⁴ − 2, or one step past the window is counted
/// and dropped; the next step's measurement and a hello a few steps ahead are taken.
#[test]
fn implausible_steps_are_counted_not_used() {
    let topo = Arc::new(Scenario::resolve("ring3").unwrap());
    let (steps, rate) = (topo.sim().steps(), topo.sim().rate_hz);
    let window = (2.0 * rate).ceil() as u64;
    let mut node = Node::new(topo, 0, false);
    let measurement = |step: u64| {
        Datagram {
            header: Header::new(1, 0, 0, Time::at_step(step, 1.0 / rate)),
            payload: Payload::measurement(0b111, vec![0.0; 3]),
        }
        .encode()
        .unwrap()
    };
    let hello = |running: u64| {
        Datagram {
            header: Header::hello(1, 0, 0, Time::ZERO),
            payload: Payload::Hello {
                running: Some(running),
                run: 1,
                boot: 3,
                echo: 0,
                probe: 0,
                answer: 0,
            },
        }
        .encode()
        .unwrap()
    };
    // Before the first step: nothing outside the run moves the node's start.
    assert!(node.handle_datagram(Some(1), &hello(u64::MAX - 1)).is_none());
    assert!(node.handle_datagram(Some(1), &hello(steps)).is_none());
    assert_eq!(node.endpoint.counters.implausible_step, 2);
    let k = 10;
    node.open_step(k);
    for (bytes, what) in [
        (measurement(steps - 1), "the run's last step"),
        (measurement(steps + 2990), "a step past the run"),
        (measurement(k + window + 1), "one step past the window"),
        (hello(u64::MAX - 1), "a hello at 2^64 - 2"),
    ] {
        assert!(node.handle_datagram(Some(1), &bytes).is_none(), "{what} was taken");
    }
    assert_eq!(node.endpoint.counters.implausible_step, 6);
    assert!(node.handle_datagram(Some(1), &measurement(k + 1)).is_some());
    assert!(node.handle_datagram(Some(1), &measurement(k + window)).is_some());
    assert!(node.handle_datagram(Some(1), &hello(k + 3)).is_some());
    assert_eq!(node.endpoint.counters.implausible_step, 6);
    assert_eq!(node.endpoint.counters.malformed, 0);
}

/// A node crashed and restarted twice never seals two different datagrams under one key and nonce: every datagram
/// it sends to a neighbour (measurements and consensus rounds) carries a (source, epoch, counter) of its own on that
/// link, each restart a later epoch from counter 0, and the neighbour it was sealed for opens them all.
#[test]
fn restarts_never_reuse_a_nonce() {
    use crate::estimators::Kind;
    use crate::wire::secure::{claimed_nonce, Opener};
    let topo = Scenario::resolve("ring3")
        .unwrap()
        .with(&crate::scenario::Overrides {
            auth: Some(true),
            estimators: Some(vec![Kind::Icf]),
            rounds: Some(2),
            duplicate: Some(0.3),
            ..Default::default()
        })
        .unwrap();
    let key = topo.security().key.clone().unwrap();
    let topo = Arc::new(topo);
    let mut node = Node::new(topo.clone(), 0, false);
    let mut medium = topo.pairwise_medium([0]);
    node.endpoint.boot(7);
    let mut seen: std::collections::HashMap<(usize, (u32, u64, u64)), bytes::Bytes> = Default::default();
    let mut epochs = Vec::new();
    // Each neighbour's end, in the run's boot (7) that node 0 seals for.
    let mut openers: Vec<Opener> = (0..3).map(|j| Opener::new(&key, topo.nodes()[j].id, 7)).collect();
    let (mut sent, mut opened) = (0, 0);
    let dt = topo.sim().dt();
    for k in 0..400u64 {
        match k {
            100 | 250 => node.endpoint.handle_crash(),
            150 | 300 => node.endpoint.handle_restart(),
            _ => {}
        }
        // Crashes given by hand, outside the scenario's timeline: the step's parts are called one by one.
        node.open_step(k);
        for r in 0..2 {
            node.endpoint.handle_round(k, r);
        }
        let _ = node.endpoint.handle_deadline(k);
        node.send_to(&mut medium);
        while let Some(t) = medium.poll_delivery(0, Time::at_step(k + 1, dt) + std::time::Duration::from_secs(1)) {
            let n = claimed_nonce(&t.bytes).expect("every datagram is sealed");
            if let Some(before) = seen.insert((t.to, n), t.bytes.clone()) {
                // The link layer's duplicate: the same bytes again, never another datagram under the nonce.
                assert_eq!(before, t.bytes, "nonce {n:?} sealed two datagrams");
            } else {
                sent += 1;
                opened += usize::from(openers[t.to].open(&t.bytes, |_| true).is_ok());
            }
            if epochs.last() != Some(&n.1) {
                epochs.push(n.1);
            }
        }
    }
    assert_eq!(epochs, vec![7, 8, 9], "each boot one later epoch");
    for e in [8, 9] {
        for j in [1, 2] {
            assert!(
                seen.contains_key(&(j, (0, e, 0))),
                "epoch {e} does not start at counter 0 on the link to {j}"
            );
        }
    }
    assert!(sent > 600, "{sent} datagrams");
    assert_eq!(opened, sent, "a neighbour opens every datagram");
}

/// The call order on the node's timeline: a step's start, each round's close but the last, the deadline; one step
/// closed per call however late the call; nothing after the last step.
#[test]
fn the_timeline_is_start_rounds_deadline() {
    let topo = Scenario::resolve("ring3")
        .unwrap()
        .with(&crate::scenario::Overrides {
            duration_s: Some(0.03),
            estimators: Some(vec![crate::estimators::Kind::Kcf]),
            rounds: Some(3),
            ..Default::default()
        })
        .unwrap();
    let topo = Arc::new(topo);
    let mut node = Node::new(topo.clone(), 1, false);
    let mut seen = Vec::new();
    while let Some(t) = node.poll_timeout() {
        seen.push(t);
        let closed = node.handle_timeout(t);
        assert_eq!(
            closed.is_some(),
            t == topo.deadline(closed.as_ref().map_or(u64::MAX, |c| c.step))
        );
    }
    let mut want = Vec::new();
    for k in 0..3 {
        want.extend([
            topo.step_time(k),
            topo.round_end(k, 0),
            topo.round_end(k, 1),
            topo.deadline(k),
        ]);
    }
    assert_eq!(seen, want);
    // Called once far past the end: each call closes one step, in order.
    let mut late = Node::new(topo.clone(), 1, false);
    late.start_at(1);
    let steps: Vec<u64> = std::iter::from_fn(|| late.handle_timeout(Time::MAX).map(|c| c.step)).collect();
    assert_eq!(steps, vec![1, 2]);
    assert_eq!(late.poll_timeout(), None);
}
