//! Whole runs over one shared IEEE 802.15.4 channel ([`simnet::medium::radio::RadioMedium`]) in memory: what the
//! channel delivered is what the nodes received, and a built-in's traffic meets the channel's capacity.

use simnet::medium::radio::{Radio, RadioMedium};
use simnet::sim::SimOptions;
use simnet::{Overrides, Scenario, Sim};

/// ring3 (three nodes a few decimetres apart on one package, 100 Hz, each broadcasting its measurement every step)
/// over one channel for 3 s: every datagram the channel delivered reached its receiver — in time, late or as a
/// duplicate — and none more; with the frames' airtime near the whole 10 ms step (3 × 94 octets, 9 ms), contention
/// delays and loses measurements, so fewer arrive in time than over the default lossless links.
#[test]
fn ring3_over_one_channel() {
    let s = Scenario::resolve("ring3")
        .unwrap()
        .with(&Overrides {
            duration_s: Some(3.0),
            ..Default::default()
        })
        .unwrap();
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
