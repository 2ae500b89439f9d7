//! The node driven in memory: datagrams flow, probes see what the trace records, the attitude filter is
//! `estimate::attitude`'s EKF.

use super::*;
use crate::wire::Datagram;

/// One lockstep step with the scenario's deadline.
fn step_in_memory(nodes: &mut [Node], k: u64) {
    let sim = &nodes[0].topo.sim();
    let window_end = k as f64 * sim.dt() + sim.deadline_s;
    crate::sim::lockstep(nodes, k, window_end);
}

/// Two nodes driven in memory, no sockets: datagrams flow and both filters track the truth.
#[test]
fn pair_in_memory() {
    let topo = Arc::new(Scenario::resolve("pair2-paper").unwrap());
    let mut nodes: Vec<Node> = (0..2).map(|i| Node::new(topo.clone(), i, false)).collect();
    for k in 0..500 {
        step_in_memory(&mut nodes, k);
    }
    for n in &mut nodes {
        let r = n.report();
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
    for k in 0..200 {
        step_in_memory(&mut nodes, k);
    }
    let rows: Vec<_> = nodes[1]
        .take_trace()
        .iter()
        .map(|r| (r.step, r.networked, r.error, r.trace_p_post))
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
    let x0 = &node.initial.x;
    let q0 = nalgebra::Vector4::new(x0[0], x0[1], x0[2], x0[3]);
    let mut ekf = AttitudeEkf::new(q0, &node.initial.P, Form::Standard).unwrap();
    let mut worst: f64 = 0.0;
    let mut log = Vec::new();
    for k in 0..500 {
        step_in_memory(std::slice::from_mut(&mut node), k);
        log.extend(node.take_imu());
        let now = log[k as usize];
        if k > 0 {
            let before = log[k as usize - 1];
            ekf.predict(&((before.sample.gyro + now.sample.gyro) * 0.5), dt, &model)
                .unwrap();
        }
        let y = DVector::from_iterator(6, now.sample.accel.iter().chain(now.mag.unwrap().iter()).copied());
        ekf.update(&y, [true, true], &model).unwrap();
        let f = &node.filters.as_ref().unwrap().independent;
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
    node.handle_step(0);
    let info = |n: u8| Body::Information {
        n,
        sym: vec![1.0; (n as usize) * (n as usize + 1) / 2],
        vec: vec![0.0; n as usize],
    };
    let dg = |src: u32, round: u8, scheme: Kind, body: Body| {
        Datagram {
            header: Header::round(src, 0, 0),
            payload: Payload::Round {
                round,
                scheme: scheme as u8,
                body,
            },
        }
        .encode()
        .unwrap()
    };
    let forged = [
        dg(1, 0, Kind::Kcf, info(9)),
        dg(1, 2, Kind::Icf, info(9)),
        dg(1, 0, Kind::Icf, info(3)),
    ];
    for (i, bytes) in forged.iter().enumerate() {
        assert!(node.handle_datagram(Some(1), bytes).is_none(), "forgery {i} was taken");
        assert_eq!(node.counters.malformed, i as u64 + 1);
    }
    // From a socket that is not the header's source.
    assert!(node.handle_datagram(Some(2), &dg(1, 0, Kind::Icf, info(9))).is_none());
    assert_eq!(node.counters.malformed, 4);
    assert!(node.handle_datagram(Some(1), &dg(1, 0, Kind::Icf, info(9))).is_some());
    assert_eq!(node.counters.malformed, 4);
}
