//! The arithmetic of an IEEE 802.15.4 2.4 GHz O-QPSK radio: path loss over distance, the receiver's noise floor,
//! the bit and frame error rates at a signal-to-interference-plus-noise ratio, and a frame's time on air. Pure
//! functions of their arguments; the numbers follow ns-3's lr-wpan model (the reference simnet's radio is checked
//! against), and each one says where it comes from.
//!
//! ```
//! use simnet_core::medium::phy::{self, LogDistance, Receiver};
//!
//! // ns-3's defaults: 0 dBm at 95 m through the log-distance model, a receiver of maximum sensitivity.
//! let rx_dbm = 0.0 - LogDistance::NS3.loss_db(95.0);
//! let sinr = phy::dbm_to_w(rx_dbm) / Receiver::MAX_SENSITIVITY.noise_w();
//! let per = phy::frame_error_rate(sinr, phy::psdu_bits(20));
//! assert!(per > 0.0 && per < 0.01, "{per}");
//! // A full 127-byte PSDU is on the air 4.256 ms.
//! assert_eq!(phy::airtime(127).as_nanos(), 4_256_000);
//! ```

use std::time::Duration;

/// Power in watts of `dbm` dBm.
pub fn dbm_to_w(dbm: f64) -> f64 {
    10f64.powf(dbm / 10.0) / 1000.0
}

/// Power in dBm of `w` watts.
pub fn w_to_dbm(w: f64) -> f64 {
    10.0 * (w * 1000.0).log10()
}

/// Log-distance path loss: PL(d) = PL₀ + 10 n log₁₀(d / d₀) for d > d₀, PL₀ within d₀ (Rappaport, *Wireless
/// Communications*, eq. 4.68; ns-3's `LogDistancePropagationLossModel`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LogDistance {
    /// The path-loss exponent n.
    pub exponent: f64,
    /// The reference distance d₀, m.
    pub reference_m: f64,
    /// The loss at the reference distance PL₀, dB.
    pub reference_loss_db: f64,
}

impl LogDistance {
    /// ns-3's defaults: n = 3, d₀ = 1 m, PL₀ = 46.6777 dB (free space at 1 m and 5.15 GHz).
    pub const NS3: LogDistance = LogDistance {
        exponent: 3.0,
        reference_m: 1.0,
        reference_loss_db: 46.6777,
    };

    /// The loss over `distance_m` metres, dB.
    pub fn loss_db(&self, distance_m: f64) -> f64 {
        if distance_m <= self.reference_m {
            return self.reference_loss_db;
        }
        self.reference_loss_db + 10.0 * self.exponent * (distance_m / self.reference_m).log10()
    }

    /// The distance over which the loss reaches `loss_db`, m: d₀ 10^((L − PL₀) / 10n); d₀ for a loss at most PL₀,
    /// infinite for a loss that does not grow.
    pub fn distance_for(&self, loss_db: f64) -> f64 {
        if loss_db <= self.reference_loss_db {
            return self.reference_m;
        }
        if self.exponent <= 0.0 {
            return f64::INFINITY;
        }
        self.reference_m * 10f64.powf((loss_db - self.reference_loss_db) / (10.0 * self.exponent))
    }
}

/// Boltzmann's constant, J/K (CODATA 2018, exact).
pub const BOLTZMANN: f64 = 1.380_649e-23;

/// The noise temperature of the receiver's input, K (the IEEE standard reference, 290 K).
pub const T0: f64 = 290.0;

/// The bandwidth the noise is taken over, Hz: ns-3 integrates the noise density over the five 1 MHz bins of a
/// 2.4 GHz channel's mask.
pub const NOISE_BANDWIDTH_HZ: f64 = 5.0e6;

/// A receiver, by its sensitivity: the signal at which a 20-octet PSDU is lost 1 % of the time (the standard's
/// definition, IEEE 802.15.4-2020 §12.3.4). Its noise floor is kT·B raised by the noise factor F that puts the 1 %
/// point at the sensitivity, as ns-3's `LrWpanPhy::SetRxSensitivity` does: F = sensitivity / −106.58 dBm, the
/// sensitivity of a noiseless receiver (F = 1) with ns-3's noise.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Receiver {
    /// The sensitivity, dBm.
    pub sensitivity_dbm: f64,
}

impl Receiver {
    /// A noiseless receiver (noise factor 1): ns-3's default.
    pub const MAX_SENSITIVITY: Receiver = Receiver {
        sensitivity_dbm: -106.58,
    };

    /// The TI CC2420's typical sensitivity, −95 dBm (CC2420 datasheet, SWRS041c, table "RF receive section").
    pub const CC2420: Receiver = Receiver { sensitivity_dbm: -95.0 };

    /// The noise factor F (linear, ≥ 1 for a sensitivity no better than the noiseless receiver's).
    pub fn noise_factor(&self) -> f64 {
        dbm_to_w(self.sensitivity_dbm) / dbm_to_w(Receiver::MAX_SENSITIVITY.sensitivity_dbm)
    }

    /// The noise power at the demodulator, W: k T₀ B F.
    pub fn noise_w(&self) -> f64 {
        BOLTZMANN * T0 * NOISE_BANDWIDTH_HZ * self.noise_factor()
    }
}

/// C(16, k), for the sum of [`bit_error_rate`].
const C16: [f64; 17] = [
    1.0, 16.0, 120.0, 560.0, 1820.0, 4368.0, 8008.0, 11440.0, 12870.0, 11440.0, 8008.0, 4368.0, 1820.0, 560.0, 120.0,
    16.0, 1.0,
];

/// The bit error rate of 2.4 GHz O-QPSK with 16-ary orthogonal spreading at `sinr` (linear, not dB):
/// BER = (8/15)(1/16) Σ_{k=2}^{16} (−1)^k C(16, k) exp(20 · SINR · (1/k − 1)) (IEEE 802.15.4-2020 Annex E, eq. E.1;
/// ns-3's `LrWpanErrorModel`), at most 1.
pub fn bit_error_rate(sinr: f64) -> f64 {
    // Above 80 (19 dB) every term's exponent is below −800, where exp is 0 in f64: the sum is exactly 0.
    if sinr >= 80.0 {
        return 0.0;
    }
    let sum: f64 = (2..=16)
        .map(|k| {
            let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
            sign * C16[k] * (20.0 * sinr * (1.0 / k as f64 - 1.0)).exp()
        })
        .sum();
    (sum * 8.0 / 15.0 / 16.0).clamp(0.0, 1.0)
}

/// The probability that a frame of `bits` bits is lost at `sinr` (linear): 1 − (1 − BER)^bits, every bit
/// independent (Annex E).
pub fn frame_error_rate(sinr: f64, bits: u32) -> f64 {
    // bits·ln(1 − BER) through ln_1p and exp_m1: exact where BER is far below the rounding of 1 − BER.
    -(f64::from(bits) * (-bit_error_rate(sinr)).ln_1p()).exp_m1()
}

/// The probability that a frame of `bits` bits arrives intact at `sinr` (linear): (1 − BER)^bits, exact where it
/// is far below the rounding of 1 − [`frame_error_rate`].
pub fn frame_success_rate(sinr: f64, bits: u32) -> f64 {
    (f64::from(bits) * (-bit_error_rate(sinr)).ln_1p()).exp()
}

/// The bits of a PSDU of `octets` octets (the part of a frame the error rate is taken over).
pub fn psdu_bits(octets: u32) -> u32 {
    8 * octets
}

/// The PHY's synchronisation header and PHY header: preamble 4 octets, start-of-frame delimiter 1, length 1.
pub const SHR_PHR_OCTETS: u32 = 6;

/// The largest PSDU, octets (aMaxPhyPacketSize).
pub const MAX_PSDU_OCTETS: u32 = 127;

/// Time to send one octet at 250 kbit/s.
pub const OCTET: Duration = Duration::from_micros(32);

/// A frame's time on the air: (SHR + PHR + PSDU) octets at 32 µs each.
pub fn airtime(psdu_octets: u32) -> Duration {
    OCTET * (SHR_PHR_OCTETS + psdu_octets)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shortcut above 80 changes nothing: the sum itself is exactly 0 there, and the rate is continuous at it.
    #[test]
    fn the_rate_is_exactly_zero_where_the_sum_underflows() {
        let sum = |sinr: f64| {
            (2..=16)
                .map(|k| {
                    let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
                    sign * C16[k] * (20.0 * sinr * (1.0 / k as f64 - 1.0)).exp()
                })
                .sum::<f64>()
        };
        for sinr in [80.0, 80.5, 1e3, 1e9] {
            assert_eq!(sum(sinr), 0.0, "{sinr}");
            assert_eq!(bit_error_rate(sinr), 0.0);
        }
        // Just below it the sum is subnormal, not yet 0: its rate rounds to nothing a frame could show.
        assert!(bit_error_rate(74.0) > 0.0 && bit_error_rate(79.99) < 1e-320);
    }

    /// ns-3's own test values of its error model (`lr-wpan-error-model-test.cc`), within the tolerances that test
    /// gives them (the values are printed to three figures).
    #[test]
    fn the_bit_error_rate_is_ns3s_at_its_test_points() {
        for (snr_db, ber, tol) in [
            (5.0, 7.38e-14, 0.01e-14),
            (2.0, 5.13e-7, 0.01e-7),
            (-1.0, 0.00114, 0.00001),
            (-4.0, 0.0391, 0.0001),
            (-7.0, 0.175, 0.001),
        ] {
            let got = bit_error_rate(10f64.powf(snr_db / 10.0));
            assert!(
                (got - ber).abs() <= tol,
                "SNR {snr_db} dB: BER {got:e}, ns-3 {ber:e} ± {tol:e}"
            );
        }
    }

    /// The sum written out term by term with binomial coefficients computed here, and the limits: BER → 1/2 as the
    /// SINR → 0 (a coin toss per bit), decreasing in the SINR.
    #[test]
    fn the_bit_error_rate_is_the_annex_sum_and_falls_with_the_sinr() {
        let choose = |k: u64| (1..=k).fold(1.0, |c, i| c * (16 - i + 1) as f64 / i as f64);
        for sinr in [0.05, 0.3, 1.0, 2.5] {
            let sum: f64 = (2..=16u64)
                .map(|k| (-1f64).powi(k as i32) * choose(k) * (20.0 * sinr * (1.0 / k as f64 - 1.0)).exp())
                .sum();
            let want = sum * 8.0 / 15.0 / 16.0;
            assert!(
                (bit_error_rate(sinr) - want).abs() <= 1e-12 * want.max(1e-300),
                "{sinr}"
            );
        }
        // At zero SINR every exponential is 1: (8/15)(1/16)(Σ (−1)^k C(16,k) over k ≥ 2) = (8/15)(1/16)(0 − 1 + 16).
        assert!((bit_error_rate(0.0) - 0.5).abs() < 1e-12);
        let rates: Vec<f64> = (0..60).map(|i| bit_error_rate(i as f64 * 0.1)).collect();
        assert!(rates.windows(2).all(|w| w[1] <= w[0]), "{rates:?}");
    }

    /// A noiseless receiver's 1 % point is −106.58 dBm for a 20-octet PSDU, by the definition its noise factor
    /// rests on; and a CC2420's is 11.58 dB higher, at −95 dBm.
    #[test]
    fn a_receivers_sensitivity_is_its_one_percent_point() {
        for rx in [Receiver::MAX_SENSITIVITY, Receiver::CC2420] {
            let per = |dbm: f64| frame_error_rate(dbm_to_w(dbm) / rx.noise_w(), psdu_bits(20));
            let at = per(rx.sensitivity_dbm);
            assert!((at - 0.01).abs() < 0.0006, "{rx:?}: PER {at} at its sensitivity");
            assert!(per(rx.sensitivity_dbm - 0.5) > 0.01 && per(rx.sensitivity_dbm + 0.5) < 0.01);
        }
        // kT₀B at 5 MHz is −106.99 dBm.
        assert!((w_to_dbm(Receiver::MAX_SENSITIVITY.noise_w()) + 106.99).abs() < 0.005);
        assert!((Receiver::CC2420.noise_factor() - dbm_to_w(-95.0) / dbm_to_w(-106.58)).abs() < 1e-12);
    }

    /// ns-3's distance test: 0 dBm over 95 m (log-distance, its defaults) to a noiseless receiver delivers at
    /// least 990 of 1000 20-octet packets; the PSDU there is 20 octets of payload with an 11-octet MAC header and FCS.
    #[test]
    fn at_95_m_ns3s_distance_test_delivers_99_percent() {
        let sinr = dbm_to_w(-LogDistance::NS3.loss_db(95.0)) / Receiver::MAX_SENSITIVITY.noise_w();
        let per = frame_error_rate(sinr, psdu_bits(20 + 11));
        assert!(per < 0.01, "PER {per}");
        assert!((LogDistance::NS3.loss_db(95.0) - (46.6777 + 30.0 * 95f64.log10())).abs() < 1e-12);
        assert_eq!(LogDistance::NS3.loss_db(0.5), 46.6777);
    }

    /// A frame's time on air is (6 + PSDU) × 32 µs exactly; the error rate of no bits is 0, of a frame is
    /// 1 − (1 − BER)^bits.
    #[test]
    fn airtime_and_frame_error_rate() {
        assert_eq!(airtime(0), Duration::from_micros(192));
        assert_eq!(airtime(MAX_PSDU_OCTETS), Duration::from_micros(4256));
        for sinr in [0.2, 0.8, 1.5] {
            let ber = bit_error_rate(sinr);
            let want = 1.0 - (1.0 - ber).powi(800);
            assert!((frame_error_rate(sinr, 800) - want).abs() < 1e-12, "{sinr}");
            assert_eq!(frame_error_rate(sinr, 0), 0.0);
            assert!((frame_success_rate(sinr, 800) + frame_error_rate(sinr, 800) - 1.0).abs() < 1e-15);
        }
    }
}
