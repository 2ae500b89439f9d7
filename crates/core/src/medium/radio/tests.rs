//! The shared channel's tests: frames in turn, hidden terminals, seeds, distance.
use super::*;
use crate::link::Stream;
use crate::medium::air;
use crate::world::Place;
use nalgebra::Vector3;

fn world(at: &[(f64, f64)]) -> World {
    let mut w = World::new();
    for &(x, y) in at {
        w.place(Place::Fixed(Vector3::new(x, y, 0.0)));
    }
    w
}

/// The standard's radio with unacknowledged unicasts (as ns-3's star sends them).
fn unacked() -> Radio {
    Radio {
        max_frame_retries: None,
        ..Radio::default()
    }
}

fn send(m: &mut RadioMedium, from: usize, to: Dest, at: Time, len: usize) {
    let tx = Transmission {
        to,
        at,
        group: vec![Bytes::from(vec![from as u8; len])],
        stream: Stream::Measurement,
    };
    m.transmit(from, tx, &FaultSchedule::default());
}

fn all(m: &mut RadioMedium, until: Time) -> Vec<Delivery> {
    let mut out = Vec::new();
    for i in 0..m.macs.len() {
        out.extend(std::iter::from_fn(|| m.poll_delivery(i, until)));
    }
    out
}

/// One sender's datagrams leave one after another: the second frame starts after the first has left the air,
/// its interframe spacing, a backoff and an assessment; a 300-octet datagram takes three frames and arrives
/// once, whole, when its last frame ends.
#[test]
fn a_sender_sends_its_frames_in_turn() {
    let mut m = RadioMedium::new(unacked(), world(&[(0.0, 0.0), (5.0, 0.0)]), 3);
    send(&mut m, 0, Dest::Node(1), Time::ZERO, 40);
    send(&mut m, 0, Dest::Node(1), Time::ZERO, 300);
    let got = all(&mut m, Time::from_secs(1.0));
    assert_eq!(got.iter().map(|d| d.bytes.len()).collect::<Vec<_>>(), vec![40, 300]);
    let c = m.node_counters(0);
    assert_eq!(c.frames, 4);
    let want: u64 = [frame::airtime(40, Security::None), frame::airtime(300, Security::None)]
        .iter()
        .map(|d| d.as_nanos() as u64)
        .sum();
    assert_eq!(c.airtime_ns, want);
    // Each frame: at least an assessment and a turnaround after the previous one (and its 640 µs spacing).
    let first_end = got[0].at;
    let min_gap = csma::SYMBOL * 40 + csma::CCA + csma::TURNAROUND + frame::airtime(300, Security::None);
    assert!(
        got[1].at.since(first_end) >= min_gap,
        "{:?} then {:?}",
        got[0].at,
        got[1].at
    );
    assert_eq!(
        m.counters(0),
        vec![(
            1,
            LinkCounters {
                sent: 2,
                bytes: 340,
                ..Default::default()
            }
        )]
    );
}

/// Two senders 35 m from a sink (−93 dBm there, 2.4 dB above a CC2420's noise), each sending a 50-octet
/// datagram at the same instant, 200 times: 35 m apart they sense each other's frames and mostly defer; 70 m
/// apart, on either side of the sink, they cannot (hidden terminals) and their frames collide at the sink.
#[test]
fn hidden_senders_collide_where_senders_in_range_defer() {
    let run = |angle: f64| {
        let d = 35.0;
        let at = [(0.0, 0.0), (d, 0.0), (d * angle.cos(), d * angle.sin())];
        let mut m = RadioMedium::new(unacked(), world(&at), 11);
        let mut delivered = 0;
        for k in 0..200u64 {
            let t = Time::from_nanos(k * 50_000_000);
            for i in 1..=2 {
                send(&mut m, i, Dest::Node(0), t, 50);
            }
            delivered += all(&mut m, Time::from_nanos((k + 1) * 50_000_000)).len();
        }
        (delivered, m.nodes.iter().map(|c| c.busy).sum::<u64>())
    };
    let (near, near_busy) = run(std::f64::consts::PI / 3.0);
    let (hidden, hidden_busy) = run(std::f64::consts::PI);
    eprintln!("in range: {near} of 400 arrived, {near_busy} busy; hidden: {hidden} arrived, {hidden_busy} busy");
    assert_eq!(hidden_busy, 0, "hidden senders never sense each other");
    assert!(near_busy > 100, "senders in range defer: {near_busy} busy assessments");
    assert!(near > 300, "in range: {near} of 400");
    assert!(hidden < near / 2, "hidden: {hidden}, in range: {near}");
}

/// The same seed gives the same deliveries, at the same times; another seed other backoffs.
#[test]
fn a_seed_decides_everything() {
    let run = |seed: u64| {
        let mut m = RadioMedium::new(Radio::default(), world(&[(0.0, 0.0), (3.0, 0.0), (0.0, 3.0)]), seed);
        for k in 0..20u64 {
            for i in 0..3 {
                send(&mut m, i, Dest::Broadcast, Time::from_nanos(k * 10_000_000), 60);
            }
        }
        all(&mut m, Time::from_secs(1.0))
            .into_iter()
            .map(|d| (d.from, d.to, d.at))
            .collect::<Vec<_>>()
    };
    assert_eq!(run(5), run(5));
    assert_ne!(run(5), run(6));
}

/// A broadcast reaches the node 2 m away and is lost, and counted lost, at the one 500 m away.
#[test]
fn a_frame_too_weak_is_lost() {
    let mut m = RadioMedium::new(Radio::default(), world(&[(0.0, 0.0), (2.0, 0.0), (500.0, 0.0)]), 1);
    let faults = FaultSchedule::default();
    assert!(faults.link_up(0, 1, Time::ZERO));
    send(&mut m, 0, Dest::Broadcast, Time::ZERO, 30);
    let got = all(&mut m, Time::from_secs(1.0));
    assert_eq!(got.iter().map(|d| d.to).collect::<Vec<_>>(), vec![1]);
    let c = m.counters(0);
    assert_eq!(
        c[1],
        (
            2,
            LinkCounters {
                sent: 1,
                bytes: 30,
                lost_random: 1,
                ..Default::default()
            }
        )
    );
}

/// A broadcast reaches its sender's listeners alone and is counted on their links alone; a node that is not a
/// listener still hears the frame on the air (its own frame, sent at the same instant, collides there).
#[test]
fn a_broadcast_reaches_its_listeners_alone() {
    let at = [(0.0, 0.0), (5.0, 0.0), (0.0, 5.0)];
    let mut m = RadioMedium::new(Radio::default(), world(&at), 4).with_listeners(vec![vec![1], vec![0], vec![0]]);
    send(&mut m, 0, Dest::Broadcast, Time::ZERO, 40);
    let got = all(&mut m, Time::from_secs(1.0));
    assert_eq!(got.iter().map(|d| (d.from, d.to)).collect::<Vec<_>>(), vec![(0, 1)]);
    assert_eq!(
        m.counters(0).iter().map(|(j, c)| (*j, c.sent)).collect::<Vec<_>>(),
        vec![(1, 1)]
    );
}

/// An acknowledged unicast in range: one frame, one ACK back (5 octets, 352 µs, counted in the receiver's airtime),
/// delivered once as the frame ends; the sender's next frame waits for the ACK and the interframe spacing.
#[test]
fn a_unicast_in_range_is_acknowledged() {
    let mut m = RadioMedium::new(Radio::default(), world(&[(0.0, 0.0), (5.0, 0.0)]), 3);
    send(&mut m, 0, Dest::Node(1), Time::ZERO, 40);
    send(&mut m, 0, Dest::Node(1), Time::ZERO, 40);
    let got = all(&mut m, Time::from_secs(1.0));
    assert_eq!(got.len(), 2);
    let (s, r) = (m.node_counters(0), m.node_counters(1));
    assert_eq!((s.frames, s.retries, s.no_ack, r.acks), (2, 0, 0, 2));
    assert_eq!(r.airtime_ns, 2 * phy::airtime(ACK_PSDU).as_nanos() as u64);
    assert_eq!(phy::airtime(ACK_PSDU), std::time::Duration::from_micros(352));
    // The second frame: after the first, its ACK (turnaround and 352 µs), the long spacing, a CCA and a turnaround.
    let min_gap = csma::TURNAROUND
        + phy::airtime(ACK_PSDU)
        + csma::SYMBOL * 40
        + csma::CCA
        + csma::TURNAROUND
        + frame::airtime(40, Security::None);
    assert!(
        got[1].at.since(got[0].at) >= min_gap,
        "{:?} then {:?}",
        got[0].at,
        got[1].at
    );
    assert_eq!(m.counters(0)[0].1.lost_random, 0);
}

/// A unicast to a node out of range is sent 1 + macMaxFrameRetries times, each after macAckWaitDuration and a new
/// CSMA/CA, then given up and counted lost once; unacknowledged, it is sent once.
#[test]
fn a_unicast_out_of_range_is_retried_then_given_up() {
    for (radio, frames) in [(Radio::default(), 4), (unacked(), 1)] {
        let mut m = RadioMedium::new(radio, world(&[(0.0, 0.0), (900.0, 0.0)]), 5);
        send(&mut m, 0, Dest::Node(1), Time::ZERO, 40);
        assert!(all(&mut m, Time::from_secs(1.0)).is_empty());
        let s = m.node_counters(0);
        assert_eq!(s.frames, frames, "{radio:?}");
        assert_eq!((s.retries, s.no_ack), if frames == 4 { (3, 1) } else { (0, 0) });
        assert_eq!(m.node_counters(1).acks, 0);
        let c = m.counters(0)[0].1;
        assert_eq!((c.sent, c.lost_random), (1, 1));
    }
}

/// The fate of a frame worked out as it was before each node kept its receiver's state: [`air::receive`] over
/// every frame the receiver heard back to the last silence before it. In test builds the medium checks every fate
/// and every assessment against it, where that silence is still among the frames the medium keeps (none when
/// the air was busy longer than it keeps frames: then the kept state is the one to trust).
impl RadioMedium {
    /// What receiver `j` heard around `[lo, hi]`: every frame overlapping it or, one after another, the frames
    /// before it (whose start decides what `j` was locked onto), with their indices in `air`, and `j`'s own frames.
    #[allow(clippy::type_complexity)]
    fn heard_by(
        &self,
        j: usize,
        (mut lo, hi): (Time, Time),
    ) -> Option<(Vec<air::OnAir>, Vec<usize>, Vec<(Time, Time)>)> {
        let heard = |g: &AirFrame| g.from != j && g.hearers.power(j).is_some();
        let members = loop {
            let members: Vec<usize> = (0..self.air.len())
                .filter(|&m| self.air[m].start <= hi && self.air[m].end > lo && heard(&self.air[m]))
                .collect();
            let first = members.iter().map(|&m| self.air[m].start).min().unwrap_or(lo);
            if first >= lo {
                break members;
            }
            if first <= self.dropped_until {
                return None;
            }
            lo = first;
        };
        let sending = (self.air.iter())
            .filter(|g| g.from == j && g.start <= hi && g.end > lo)
            .map(|g| (g.start, g.end))
            .collect();
        let frames = (members.iter())
            .map(|&m| air::OnAir {
                start: self.air[m].start,
                end: self.air[m].end,
                power_w: self.air[m].hearers.power(j).expect("heard"),
            })
            .collect();
        Some((frames, members, sending))
    }

    pub(super) fn reception_by_chain(&self, k: usize, j: usize) -> Option<Reception> {
        let f = &self.air[k];
        let (frames, ids, sending) = self.heard_by(j, (f.start, f.end))?;
        CHECKED.with(|c| c.set(c.get() + 1));
        Some(match ids.iter().position(|&m| m == k) {
            Some(index) => air::receive(&frames, &sending, self.radio.receiver.noise_w())[index],
            None => Reception::Weak { sinr: 0.0 },
        })
    }

    pub(super) fn receiving_by_chain(&self, i: usize, t: Time) -> Option<bool> {
        let (frames, ids, sending) = self.heard_by(i, (t, t))?;
        let got = air::receive(&frames, &sending, self.radio.receiver.noise_w());
        Some((ids.iter().zip(got)).any(|(&m, r)| self.air[m].end > t && matches!(r, Reception::Locked { .. })))
    }
}

thread_local! {
    /// Fates checked against the whole timeline, in this thread.
    pub(super) static CHECKED: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

/// A saturated channel — 24 nodes within 60 m, hidden terminals among them, each broadcasting and sending
/// acknowledged unicasts of up to three frames every 4 ms — where every fate and every assessment the receivers'
/// kept state gives equals the one worked out over the whole timeline (checked as the medium runs, in test builds).
#[test]
fn each_receivers_state_gives_the_fates_the_whole_timeline_gives() {
    let at: Vec<(f64, f64)> = (0..24)
        .map(|i| ((i % 6) as f64 * 12.0, (i / 6) as f64 * 15.0))
        .collect();
    let mut m = RadioMedium::new(Radio::default(), world(&at), 7);
    let mut rng = crate::rng::stream(7, "test", 0, 0);
    let mut got = 0;
    for step in 0..250u64 {
        let now = Time::from_nanos(step * 4_000_000);
        for i in 0..24 {
            let len = rand::Rng::gen_range(&mut rng, 10..300);
            let to = match rand::Rng::gen_range(&mut rng, 0..3) {
                0 => Dest::Node(rand::Rng::gen_range(&mut rng, 0..24)),
                _ => Dest::Broadcast,
            };
            send(&mut m, i, to, now, len);
        }
        got += all(&mut m, now + std::time::Duration::from_millis(4)).len();
    }
    let busy: u64 = (0..24).map(|i| m.node_counters(i).busy).sum();
    let checked = CHECKED.with(|c| c.get());
    assert!(
        got > 300 && busy > 1000 && checked > 1000,
        "delivered {got}, busy {busy} times, {checked} checked"
    );
}

/// The grid finds every node that hears a sender and no other: in a still world of 400 nodes over 1.2 km, each
/// sender's hearers equal those of a pass over every node at the same floor.
#[test]
fn the_grid_finds_exactly_the_nodes_that_hear() {
    let mut rng = crate::rng::stream(3, "test", 0, 0);
    let at: Vec<(f64, f64)> = (0..400)
        .map(|_| {
            (
                rand::Rng::gen_range(&mut rng, 0.0..1200.0),
                rand::Rng::gen_range(&mut rng, 0.0..1200.0),
            )
        })
        .collect();
    let (radio, w) = (Radio::default(), world(&at));
    let noise_w = radio.receiver.noise_w();
    let mut reach = Reach::new(&radio, &w, noise_w);
    let mut total = 0;
    for from in 0..at.len() {
        let got: Vec<(usize, f64)> = reach.hearers(&radio, &w, &mut None, from, Time::ZERO).iter().collect();
        let want: Vec<(usize, f64)> = (0..at.len())
            .filter(|&j| j != from)
            .map(|j| {
                (
                    j,
                    phy::dbm_to_w(radio.tx_dbm - radio.path_loss.loss_db(w.distance(from, j, Time::ZERO))),
                )
            })
            .filter(|&(_, p)| p >= reach::NEGLIGIBLE * noise_w)
            .collect();
        assert_eq!(got, want, "sender {from}");
        total += got.len();
    }
    // About π·195² / (1200²) of the others, less at the edges.
    assert!(total > 400 * 20 && total < 400 * 80, "{total}");
    // The distance where the loss reaches a value is its inverse.
    let pl = radio.path_loss;
    for loss in [50.0, 80.0, 115.4] {
        assert!((pl.loss_db(pl.distance_for(loss)) - loss).abs() < 1e-9);
    }
    assert_eq!(pl.distance_for(10.0), pl.reference_m);
}

/// A moving pair: node 1 rides a body along x at about 1 m/s away from node 0, which broadcasts 20 octets every
/// 10 ms while the distance grows from 30 to 56 m, across the edge of the range. In every 2 s window the frames
/// node 1 got are within 3 σ of the sum of each frame's closed-form chance at the distance as it was sent,
/// (1 − BER(S/N))^bits over its 8 × (6 + PSDU) bits — the distance is taken at each transmission — and the ratio
/// falls from all to almost none.
#[test]
fn delivery_over_time_follows_a_moving_pairs_distance() {
    let mut w = World::new();
    w.place(Place::Fixed(Vector3::zeros()));
    let body = w.add_body(crate::motion::Trajectory::Line);
    w.place(Place::Mounted {
        body,
        lever: Vector3::zeros(),
    });
    let radio = Radio::default();
    let noise_w = radio.receiver.noise_w();
    let psdu = frame::psdus(20, Security::None)[0];
    let mut m = RadioMedium::new(radio, w.clone(), 11);
    let (first, steps) = (3000u64, 2600u64);
    let mut expected = vec![(0.0, 0.0); (steps / 200) as usize];
    let mut got = vec![0u64; expected.len()];
    for k in 0..steps {
        let at = Time::from_nanos((first + k) * 10_000_000);
        let d = w.distance(0, 1, at);
        let snr = phy::dbm_to_w(radio.tx_dbm - radio.path_loss.loss_db(d)) / noise_w;
        let p = phy::frame_success_rate(snr, 8 * (phy::SHR_PHR_OCTETS + psdu));
        let e = &mut expected[(k / 200) as usize];
        *e = (e.0 + p, e.1 + p * (1.0 - p));
        send(&mut m, 0, Dest::Broadcast, at, 20);
        let arrived = all(&mut m, at + std::time::Duration::from_millis(10)).len() as u64;
        got[(k / 200) as usize] += arrived;
    }
    for (n, ((mean, var), got)) in expected.iter().zip(&got).enumerate() {
        let z = (*got as f64 - mean) / var.sqrt().max(0.5);
        assert!(
            z.abs() <= 3.0,
            "window {n} ({} s on): {got} of 200 arrived, {mean:.1} expected, z = {z:.2}",
            30 + 2 * n
        );
    }
    assert!(got[0] >= 198 && got[got.len() - 1] <= 5, "{got:?}");
}

/// A node nobody asks about (it never sends, and no broadcast is for it) still hears: its inbox stays bounded.
#[test]
fn an_ear_nobody_asks_stays_bounded() {
    let mut m = RadioMedium::new(unacked(), world(&[(0.0, 0.0), (10.0, 0.0)]), 1).with_listeners(vec![vec![], vec![]]);
    for k in 0..3000u64 {
        let at = Time::from_nanos(k * 5_000_000);
        send(&mut m, 0, Dest::Broadcast, at, 20);
        assert!(all(&mut m, at + std::time::Duration::from_millis(5)).is_empty());
    }
    assert_eq!(m.node_counters(0).frames, 3000);
    assert!(m.ears[1].queued() <= 1024, "{}", m.ears[1].queued());
}
