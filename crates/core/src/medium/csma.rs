//! Unslotted CSMA/CA of IEEE 802.15.4 (2020 §6.2.5.1, Fig. 6-2) and its timing: before each frame a sender waits a
//! random number of unit backoff periods in {0, …, 2^BE − 1}, then assesses the channel for 8 symbols; a clear
//! channel lets it send after the RX-to-TX turnaround, a busy one raises BE (to macMaxBE) and counts a backoff, and
//! more than macMaxCSMABackoffs busy assessments abandon the frame (a channel-access failure).
//!
//! ```
//! use rand::SeedableRng;
//! use simnet_core::medium::csma::{Attempt, Csma, CsmaParams};
//!
//! let mut rng = simnet_core::rng::Rng::seed_from_u64(7);
//! let mut csma = Csma::new(CsmaParams::STANDARD);
//! // Three busy assessments, then a clear one: the frame goes.
//! for _ in 0..3 {
//!     assert!(csma.backoff(&mut rng) <= simnet_core::medium::csma::UNIT_BACKOFF * 31);
//!     assert_eq!(csma.busy(), Attempt::BackOff);
//! }
//! assert_eq!(csma.backoffs(), 3);
//! // Two more busy ones exceed macMaxCSMABackoffs = 4.
//! assert_eq!(csma.busy(), Attempt::BackOff);
//! assert_eq!(csma.busy(), Attempt::Fail);
//! ```

use std::time::Duration;

use rand::Rng as _;

use super::phy;

/// One symbol of 2.4 GHz O-QPSK (62.5 ksymbol/s).
pub const SYMBOL: Duration = Duration::from_micros(16);

/// aUnitBackoffPeriod: 20 symbols.
pub const UNIT_BACKOFF: Duration = Duration::from_micros(20 * 16);

/// The clear-channel assessment: 8 symbols.
pub const CCA: Duration = Duration::from_micros(8 * 16);

/// aTurnaroundTime, RX to TX: 12 symbols.
pub const TURNAROUND: Duration = Duration::from_micros(12 * 16);

/// The MAC's parameters of unslotted CSMA/CA.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct CsmaParams {
    /// macMinBE: the backoff exponent of a frame's first attempt.
    pub min_be: u8,
    /// macMaxBE: the largest backoff exponent.
    pub max_be: u8,
    /// macMaxCSMABackoffs: busy assessments a frame may meet before it is abandoned.
    pub max_backoffs: u8,
}

impl CsmaParams {
    /// The standard's defaults (and ns-3's): macMinBE 3, macMaxBE 5, macMaxCSMABackoffs 4.
    pub const STANDARD: CsmaParams = CsmaParams {
        min_be: 3,
        max_be: 5,
        max_backoffs: 4,
    };
}

/// What a sender does after a busy assessment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Attempt {
    /// Back off again (with the raised exponent) and assess again.
    BackOff,
    /// Abandon the frame: a channel-access failure.
    Fail,
}

/// One frame's channel access: NB (busy assessments so far) and BE.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Csma {
    params: CsmaParams,
    nb: u8,
    be: u8,
}

impl Csma {
    /// A frame's first attempt: NB = 0, BE = macMinBE.
    pub fn new(params: CsmaParams) -> Csma {
        Csma {
            params,
            nb: 0,
            be: params.min_be.min(params.max_be),
        }
    }

    /// The random delay before the next assessment: a uniform whole number of unit backoff periods in
    /// {0, …, 2^BE − 1}.
    pub fn backoff(&self, rng: &mut crate::rng::Rng) -> Duration {
        let periods = rng.gen_range(0..1u32 << self.be);
        UNIT_BACKOFF * periods
    }

    /// The assessment found the channel busy: NB + 1, BE + 1 up to macMaxBE; abandon past macMaxCSMABackoffs.
    pub fn busy(&mut self) -> Attempt {
        self.nb += 1;
        self.be = (self.be + 1).min(self.params.max_be);
        if self.nb > self.params.max_backoffs {
            Attempt::Fail
        } else {
            Attempt::BackOff
        }
    }

    /// Busy assessments so far (NB).
    pub fn backoffs(&self) -> u8 {
        self.nb
    }

    /// The current backoff exponent (BE).
    pub fn exponent(&self) -> u8 {
        self.be
    }
}

/// Whether an energy-detection assessment finds the channel busy (CCA mode 1): the strongest power heard during
/// the assessment at least 10 dB above the receiver's sensitivity (IEEE 802.15.4-2020 §10.2.8: the ED threshold is
/// at most 10 dB above it; ns-3's `LrWpanPhy::EndCca`).
pub fn energy_busy(peak_w: f64, sensitivity_dbm: f64) -> bool {
    peak_w >= phy::dbm_to_w(sensitivity_dbm + 10.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    /// The backoff is uniform over {0, …, 2^BE − 1} unit periods at each exponent: a χ² test of 80,000 draws per
    /// exponent against the uniform law at the 0.1 % level, and every draw a whole number of 320 µs periods.
    #[test]
    fn the_backoff_is_uniform_over_its_window() {
        let mut rng = crate::rng::Rng::seed_from_u64(41);
        let mut csma = Csma::new(CsmaParams::STANDARD);
        for be in 3..=5u8 {
            assert_eq!(csma.exponent(), be);
            let cells = 1usize << be;
            let n = 80_000;
            let mut counts = vec![0u64; cells];
            for _ in 0..n {
                let d = csma.backoff(&mut rng);
                assert_eq!(d.as_nanos() % UNIT_BACKOFF.as_nanos(), 0);
                counts[(d.as_nanos() / UNIT_BACKOFF.as_nanos()) as usize] += 1;
            }
            let expected = n as f64 / cells as f64;
            let chi2: f64 = counts.iter().map(|&c| (c as f64 - expected).powi(2) / expected).sum();
            let limit = crate::stats::chi2_quantile(0.999, (cells - 1) as f64);
            assert!(chi2 < limit, "BE {be}: χ² {chi2:.1} over {limit:.1}, counts {counts:?}");
            assert_eq!(csma.busy(), Attempt::BackOff);
        }
        // BE stays at macMaxBE.
        assert_eq!(csma.exponent(), 5);
    }

    /// NB counts busy assessments; the fifth abandons the frame; BE climbs from macMinBE by one to macMaxBE.
    #[test]
    fn busy_assessments_raise_the_exponent_and_end_in_failure() {
        let mut csma = Csma::new(CsmaParams::STANDARD);
        let mut seen = vec![csma.exponent()];
        let mut outcomes = Vec::new();
        for _ in 0..5 {
            outcomes.push(csma.busy());
            seen.push(csma.exponent());
        }
        assert_eq!(seen, vec![3, 4, 5, 5, 5, 5]);
        assert_eq!(outcomes, [[Attempt::BackOff; 4].as_slice(), &[Attempt::Fail]].concat());
        // macMinBE 0: the first attempt does not wait.
        let eager = Csma::new(CsmaParams {
            min_be: 0,
            ..CsmaParams::STANDARD
        });
        let mut rng = crate::rng::Rng::seed_from_u64(1);
        assert!((0..100).all(|_| eager.backoff(&mut rng) == Duration::ZERO));
    }

    /// The timing constants in symbols of 16 µs, and the ED threshold 10 dB above the sensitivity.
    #[test]
    fn timing_and_the_energy_threshold() {
        assert_eq!((UNIT_BACKOFF, CCA, TURNAROUND), (SYMBOL * 20, SYMBOL * 8, SYMBOL * 12));
        assert_eq!(SYMBOL * 2, phy::OCTET, "two symbols per octet");
        assert!(energy_busy(phy::dbm_to_w(-85.0), -95.0));
        assert!(!energy_busy(phy::dbm_to_w(-85.1), -95.0));
    }
}
