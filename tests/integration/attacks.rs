//! The adversary model (`[[attack]]`): with a key, forged, tampered and replayed datagrams change nothing and are
//! counted by cause; without one, forgery moves the estimate; the innovation gate against a compromised node.

use simnet::attack::AttackKind;
use simnet::link::LossModel;
use simnet::{Overrides, Scenario, Summary};

use super::common;

/// ring3 over faulty links for 6 s, with one attack and, when `auth`, every datagram sealed.
fn attacked(attack: &str, auth: bool, lossless: bool) -> Scenario {
    let base = Scenario::resolve("ring3").unwrap();
    let text = format!("{}\n[[attack]]\n{attack}\n", base.to_toml());
    let faults = Overrides {
        loss: Some(LossModel::Bernoulli {
            p: if lossless { 0.0 } else { 0.1 },
        }),
        jitter_ms: (!lossless).then_some(3.0),
        duplicate: (!lossless).then_some(0.1),
        corrupt: (!lossless).then_some(0.02),
        duration_s: Some(6.0),
        auth: auth.then_some(true),
        ..Default::default()
    };
    common::topology(&text, faults)
}

/// Every figure of a run, without the counters an attack adds to (what the nodes refused and took in).
fn figures(s: &Summary) -> Vec<serde_json::Value> {
    let mut v = serde_json::to_value(s).unwrap();
    for n in v["nodes"].as_array_mut().unwrap() {
        let n = n.as_object_mut().unwrap();
        for k in [
            "rejected",
            "malformed",
            "corrupted",
            "implausible_step",
            "unknown_address",
        ] {
            n.remove(k);
        }
    }
    ["nodes", "links", "fused", "socket_losses"]
        .map(|k| v[k].clone())
        .to_vec()
}

fn error(s: &Summary, id: u32) -> f64 {
    s.nodes[id as usize].networked.as_ref().unwrap().mean_error.unwrap()
}

const FORGE: &str = "kind = \"forge\"\ntarget = 0\nclaim = 1\nstart_s = 2.0\nbias = [20.0]";
const TAMPER: &str = "kind = \"tamper\"\ntarget = 0\nclaim = 1\nstart_s = 2.0\nbias = [20.0]";
const REPLAY: &str = "kind = \"replay\"\ntarget = 0\nclaim = 1\nstart_s = 2.0\ndelay_s = 0.5";

#[test]
fn with_a_key_forged_tampered_and_replayed_datagrams_change_nothing() {
    for (attack, kind) in [
        (FORGE, AttackKind::Forge),
        (TAMPER, AttackKind::Tamper),
        (REPLAY, AttackKind::Replay),
    ] {
        let topo = attacked(attack, true, false);
        let clean = common::simulate(topo.without_attacks());
        let udp = common::run(topo.clone());
        let memory = common::simulate(topo);
        for (s, how) in [(&udp, "over UDP"), (&memory, "in memory")] {
            assert_eq!(figures(s), figures(&clean), "{kind:?} {how}");
            let a = &s.attacks[0];
            let d = a.datagrams;
            assert!(d.sent > 300, "{kind:?}: {d:?}");
            assert_eq!((d.used, d.ignored), (0, 0), "{kind:?} {how}: {d:?}");
            assert_eq!(d.rejected.total(), d.sent, "{kind:?} {how}: {d:?}");
            let r = d.rejected;
            match kind {
                AttackKind::Replay => assert_eq!(r.too_old + r.replay, d.sent, "{d:?}"),
                // Unsealed: no tag at all.
                AttackKind::Forge => assert_eq!(r.bad_tag, d.sent, "{d:?}"),
                // A copy of a link's duplicate is a replay of a counter already accepted, refused before its tag
                // is checked.
                _ => {
                    assert_eq!(r.bad_tag + r.replay, d.sent, "{d:?}");
                    assert!(r.bad_tag as f64 > 0.8 * d.sent as f64, "{d:?}");
                }
            }
            // The node counts the same refusals by cause as the attack's tally, on top of the clean run's.
            let (r, c) = (&s.nodes[0].rejected, &clean.nodes[0].rejected);
            assert_eq!(r.bad_tag - c.bad_tag, d.rejected.bad_tag, "{kind:?}");
            assert_eq!(
                r.too_old + r.replay - c.too_old - c.replay,
                d.rejected.too_old + d.rejected.replay
            );
        }
    }
}

#[test]
fn without_a_key_forgery_moves_the_estimate() {
    for (attack, kind) in [(FORGE, AttackKind::Forge), (TAMPER, AttackKind::Tamper)] {
        let topo = attacked(attack, false, false);
        let clean = common::simulate(topo.without_attacks());
        let s = common::run(topo);
        let d = s.attacks[0].datagrams;
        let (before, after) = (error(&clean, 0), error(&s, 0));
        println!(
            "{kind:?} without a key: node 0's mean error {before:.4} m → {after:.4} m ({:.0}×); {} sent, {} used",
            after / before,
            d.sent,
            d.used
        );
        assert!(after > 20.0 * before, "{kind:?}: {before} → {after}");
        assert!(d.used as f64 >= 0.85 * d.sent as f64, "{d:?}");
        assert_eq!(d.used + d.ignored, d.sent, "nothing refused: {d:?}");
        // Nodes exchange measurements, not estimates: the other nodes are not moved.
        for id in [1, 2] {
            assert_eq!(error(&s, id), error(&clean, id));
        }
    }
    // A replay without a key is still only old steps: late or a duplicate, never used.
    let topo = attacked(REPLAY, false, false);
    let clean = common::simulate(topo.without_attacks());
    let s = common::run(topo);
    let d = s.attacks[0].datagrams;
    assert!(d.sent > 300 && d.used == 0 && d.ignored == d.sent, "{d:?}");
    for id in 0..3 {
        assert_eq!(error(&s, id), error(&clean, id));
    }
    assert_eq!(s.fused, clean.fused);
    // But the receiver counts the replays as its link's late datagrams, and so underestimates the link's loss.
    let late = |s: &Summary| {
        s.links
            .iter()
            .find(|l| (l.from, l.to) == (1, 0))
            .map(|l| l.late)
            .unwrap()
    };
    assert_eq!(late(&s) - late(&clean), d.ignored);
}

#[test]
fn a_flood_is_counted_as_garbage_and_changes_nothing() {
    let topo = attacked("kind = \"flood\"\ntarget = 0\nrate_hz = 20000", true, false);
    let clean = common::simulate(topo.without_attacks());
    let s = common::run(topo);
    let d = s.attacks[0].datagrams;
    // 200 a step for 600 steps.
    assert_eq!(d.sent, 120_000);
    assert_eq!(d.rejected.malformed + d.rejected.corrupted, d.sent, "{d:?}");
    assert_eq!(figures(&s), figures(&clean));
}

/// A compromised node holds the key: only the innovation gate stands between its false data and its neighbours.
#[test]
fn the_innovation_gate_stops_a_compromised_node() {
    let fdi = "kind = \"false-data\"\nnode = 1\nstart_s = 2.0\nbias = [1.0]\nramp = [0.5]";
    let gated = |on: bool| {
        let t = attacked(fdi, true, true);
        if on {
            t.set("consensus.gate", 0.999.into()).unwrap()
        } else {
            t
        }
    };
    let open = gated(false);
    let clean = common::simulate(open.without_attacks());
    let s = common::simulate(open);
    let sent = s.attacks[0].datagrams.sent;
    // Two out-links, one measurement each per step from 2 s to 6 s.
    assert_eq!(sent, 2 * 400);
    let (c, a) = (error(&clean, 0), error(&s, 0));
    assert!(a > 20.0 * c, "the insider moves node 0: {c} → {a}");
    assert_eq!(
        s.attacks[0].datagrams.rejected.total(),
        0,
        "the key does not help against the insider"
    );

    let with_gate = gated(true);
    let clean_gated = common::simulate(with_gate.without_attacks());
    let mut g = common::simulate(with_gate);
    g.compare_clean(&clean_gated);
    let att = &g.attacks[0];
    let (cg, ag) = (error(&clean_gated, 0), error(&g, 0));
    println!(
        "false data (bias 1 m + 0.5 m/s): node 0 {c:.4} m clean, {a:.4} m attacked; gated: {cg:.4} m clean, {ag:.4} m \
         attacked, {} of {sent} left out ({} in the clean run)",
        att.gated,
        att.gated_clean.unwrap()
    );
    assert!(att.gated >= sent - 2, "{att:?}");
    assert!(ag < 1.5 * cg, "the gate keeps node 0 near its clean error: {cg} → {ag}");
    assert!(cg < 1.2 * c, "the gate costs the clean run little: {c} → {cg}");
    assert_eq!(g.attack_effect.len(), 3);
}
