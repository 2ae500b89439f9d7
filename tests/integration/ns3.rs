//! simnet's radio beside ns-3's lr-wpan, the reference implementation of the IEEE 802.15.4 PHY: the numbers ns-3
//! computes (written by `tests/ns3/phy_reference.py` from the `ns3` wheel) against simnet's own. `.ci/run` runs
//! these; by hand: `bash tests/ns3/ns3.sh` then `cargo test --test integration -- --ignored ns3::`.

use simnet::medium::phy::{self, LogDistance, Receiver};

/// ns-3's numbers; none (the test says it skips) where they were not written and `SIMNET_REQUIRE_NS3` is unset.
fn reference() -> Option<serde_json::Value> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/ns3/phy.json");
    let text = match std::fs::read_to_string(&path) {
        Ok(text) => text,
        Err(e) if std::env::var_os("SIMNET_REQUIRE_NS3").is_some() => {
            panic!("{}: {e} — `bash tests/ns3/ns3.sh` writes it", path.display())
        }
        Err(e) => {
            eprintln!(
                "SKIPPED: {}: {e} — `bash tests/ns3/ns3.sh` writes it (pip installs ns3==3.44.post0)",
                path.display()
            );
            return None;
        }
    };
    Some(serde_json::from_str(&text).unwrap())
}

/// The chunk success rate, the log-distance path loss and the noise floor equal ns-3's: the success rate
/// (1 − BER)^bits at 69 SNRs from −10 to +7 dB and 4 lengths to 1e-9 relative, the loss at 8 distances to 1e-9 dB, and the
/// noise to the ratio of the two Boltzmann constants (simnet takes CODATA's 1.380649e-23 J/K, ns-3 1.3803e-23: the
/// floors differ by 0.0011 dB, and by nothing else).
#[test]
#[ignore = "needs ns-3's numbers (target/ns3/phy.json); .ci/run writes them and runs this"]
fn the_radio_arithmetic_is_ns3s() {
    let Some(r) = reference() else { return };
    let rows = r["success"].as_array().unwrap();
    assert!(rows.len() > 200, "{} rows", rows.len());
    let mut worst = 0f64;
    for row in rows {
        let (snr_db, bits, ns3) = (
            row[0].as_f64().unwrap(),
            row[1].as_u64().unwrap() as u32,
            row[2].as_f64().unwrap(),
        );
        let ours = phy::frame_success_rate(10f64.powf(snr_db / 10.0), bits);
        let rel = (ours - ns3).abs() / ns3.max(f64::MIN_POSITIVE);
        worst = worst.max(rel);
        assert!(
            rel < 1e-9,
            "SNR {snr_db} dB, {bits} bits: simnet {ours:e}, ns-3 {ns3:e}"
        );
    }
    eprintln!(
        "success rates: {} points, worst relative difference {worst:.1e}",
        rows.len()
    );
    for row in r["log_distance_loss_db"].as_array().unwrap() {
        let (d, ns3) = (row[0].as_f64().unwrap(), row[1].as_f64().unwrap());
        let ours = LogDistance::NS3.loss_db(d);
        assert!((ours - ns3).abs() < 1e-9, "{d} m: simnet {ours} dB, ns-3 {ns3} dB");
    }
    let ns3 = r["noise_w"].as_f64().unwrap();
    let ours = Receiver::MAX_SENSITIVITY.noise_w();
    let ratio = phy::BOLTZMANN / 1.3803e-23;
    assert!(
        (ours / ns3 / ratio - 1.0).abs() < 1e-9,
        "noise: simnet {ours:e} W, ns-3 {ns3:e} W"
    );
    eprintln!(
        "noise: simnet {:.4} dBm, ns-3 {:.4} dBm",
        phy::w_to_dbm(ours),
        phy::w_to_dbm(ns3)
    );
}
