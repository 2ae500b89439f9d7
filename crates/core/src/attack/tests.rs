use super::*;
use crate::medium::Ingress;
use crate::wire::secure::{Key, Opener, Rejected, Sealer};

fn attack(kind: AttackKind) -> Attack {
    Attack {
        kind,
        target: Some(0),
        claim: Some(1),
        node: None,
        start_s: 1.0,
        end_s: 2.0,
        bias: vec![5.0, 0.0, -1.0],
        ramp: Vec::new(),
        delay_s: 0.25,
        rate_hz: 1000.0,
    }
}

fn air(a: Attack) -> Air {
    Air::new(&[a], 0, |j| 10 + j as u32, 7)
}

/// `s` seconds into the run.
fn secs(s: f64) -> crate::time::Time {
    crate::time::Time::from_secs(s)
}

/// Step `k`'s time at 100 Hz.
fn at(k: u64) -> crate::time::Time {
    crate::time::Time::at_step(k, 0.01)
}

/// Node 1 (id 11)'s measurement of step `step` for node 0 (id 10), unsealed.
fn genuine(step: u64) -> Bytes {
    Datagram {
        header: Header::new(11, 10, 3, at(step)),
        payload: Payload::measurement(0b111, vec![1.0, 2.0, 3.0]),
    }
    .encode()
    .unwrap()
}

#[test]
fn a_forger_claims_the_source_with_its_values_moved_inside_its_window_only() {
    let mut air = air(attack(AttackKind::Forge));
    assert!(
        air.on_arrival(secs(0.5), Some(1), &genuine(50)).is_empty(),
        "before start_s"
    );
    assert!(
        air.on_arrival(secs(1.5), Some(2), &genuine(150)).is_empty(),
        "another link"
    );
    let out = air.on_arrival(secs(1.5), Some(1), &genuine(150));
    assert_eq!(out.len(), 1);
    assert_eq!((out[0].attack, out[0].from), (0, Some(1)));
    let d = Datagram::decode(&out[0].bytes).unwrap();
    assert_eq!((d.header.src, d.header.dst, d.header.pertains), (11, 10, at(150)));
    assert_eq!(d.payload, Payload::measurement(0b111, vec![6.0, 2.0, 2.0]));
    assert!(
        air.on_arrival(secs(2.0), Some(1), &genuine(200)).is_empty(),
        "end_s is excluded"
    );
}

#[test]
fn a_tampered_sealed_datagram_keeps_its_checksum_and_fails_its_tag() {
    let key = Key::from_bytes([9; 16]);
    let d = Datagram {
        header: Header::new(11, 12, 0, at(150)),
        payload: Payload::measurement(0b111, vec![1.0, 2.0, 3.0]),
    };
    let sealed = Sealer::new(&key, 11, 1).seal(&d, 12, 3).unwrap();
    let out = air(attack(AttackKind::Tamper)).on_arrival(secs(1.5), Some(1), &sealed);
    assert_eq!(out.len(), 1);
    assert_ne!(out[0].bytes, sealed);
    assert!(crate::wire::peek_header(&out[0].bytes).is_ok(), "the checksum holds");
    let mut o = Opener::new(&key, 12, 3);
    assert_eq!(o.open(&out[0].bytes, |_| true).unwrap_err(), Rejected::BadTag);
    // The original still opens: a rejected forgery moves no replay window.
    assert_eq!(o.open(&sealed, |_| true).unwrap().0, d);
    // Unsealed, the values are moved and the datagram is well-formed.
    let out = air(attack(AttackKind::Tamper)).on_arrival(secs(1.5), Some(1), &genuine(150));
    let t = Datagram::decode(&out[0].bytes).unwrap();
    assert_eq!(t.header, Header::new(11, 10, 3, at(150)));
    assert_eq!(t.payload, Payload::measurement(0b111, vec![6.0, 2.0, 2.0]));
}

#[test]
fn a_replay_comes_back_after_its_delay_byte_for_byte() {
    let mut air = air(attack(AttackKind::Replay));
    assert!(
        air.on_arrival(secs(1.5), Some(1), &genuine(150)).is_empty(),
        "nothing ahead of the original"
    );
    assert!(air.on_step(secs(1.74), 0.01).is_empty());
    let out = air.on_step(secs(1.75), 0.01);
    assert_eq!(out.len(), 1);
    assert_eq!((out[0].from, &out[0].bytes[..]), (Some(1), &genuine(150)[..]));
    assert!(air.on_step(secs(1.76), 0.01).is_empty(), "once");
}

#[test]
fn a_flood_sends_its_rate_exactly_in_its_window() {
    let mut a = attack(AttackKind::Flood);
    a.rate_hz = 333.0;
    a.claim = None;
    let mut air = air(a);
    let dt = 0.01;
    let sent: usize = (0..300)
        .map(|k| air.on_step(crate::time::Time::at_step(k, dt), dt).len())
        .sum();
    // Steps 100 … 199 are inside [1, 2): 333 per second for one second, within one datagram of carried credit.
    assert!((332..=333).contains(&sent), "{sent}");
}

#[test]
fn false_data_adds_bias_and_ramp() {
    let mut a = attack(AttackKind::FalseData);
    a.ramp = vec![2.0];
    let mut z = DVector::from_vec(vec![1.0, 1.0, 1.0]);
    a.taint(&mut z, secs(1.5));
    assert_eq!(z.as_slice(), &[7.0, 1.0, 0.0]);
}
