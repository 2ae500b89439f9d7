//! What a radio's time costs: the current it draws in each state, from its supply, as energy. An unslotted CSMA/CA
//! node keeps its receiver on whenever it is not transmitting (it listens for frames and assesses the channel), so
//! its time splits into transmitting and listening.
//!
//! ```
//! use simnet_core::medium::energy::Energy;
//!
//! // One second of a CC2420 at 0 dBm: 10 ms transmitting, the rest listening, from 3 V.
//! let e = Energy::CC2420.joules(0.0, 0.010, 0.990);
//! assert!((e - 3.0 * (0.0174 * 0.010 + 0.0188 * 0.990)).abs() < 1e-12);
//! ```

/// A radio chip's currents and supply.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Energy {
    /// The supply voltage, V.
    pub supply_v: f64,
    /// The current while receiving or listening, A.
    pub rx_a: f64,
    /// The current while transmitting at each output power: (dBm, A), by power.
    pub tx_a: &'static [(f64, f64)],
}

/// The TI CC2420's transmit currents by output power (datasheet SWRS041c, Table 9, typical, at 1.8 V core).
const CC2420_TX: &[(f64, f64)] = &[
    (-25.0, 8.5e-3),
    (-15.0, 9.9e-3),
    (-10.0, 11.2e-3),
    (-7.0, 12.5e-3),
    (-5.0, 13.9e-3),
    (-3.0, 15.2e-3),
    (-1.0, 16.5e-3),
    (0.0, 17.4e-3),
];

impl Energy {
    /// The TI CC2420 (datasheet SWRS041c: RX 18.8 mA; TX 17.4 mA at 0 dBm down to 8.5 mA at −25 dBm), from a 3 V
    /// supply (two AA cells).
    pub const CC2420: Energy = Energy {
        supply_v: 3.0,
        rx_a: 18.8e-3,
        tx_a: CC2420_TX,
    };

    /// The transmit current at `tx_dbm`, A: the datasheet's figure, linear between its powers, its first or last
    /// beyond them (a power the chip does not have is costed at the nearest it has).
    pub fn tx_current(&self, tx_dbm: f64) -> f64 {
        let t = self.tx_a;
        match t.iter().position(|&(p, _)| p >= tx_dbm) {
            None => t.last().map_or(0.0, |l| l.1),
            Some(0) => t[0].1,
            Some(i) => {
                let ((p0, a0), (p1, a1)) = (t[i - 1], t[i]);
                a0 + (a1 - a0) * (tx_dbm - p0) / (p1 - p0)
            }
        }
    }

    /// The energy of `tx_s` seconds transmitting at `tx_dbm` and `listen_s` seconds listening, J.
    pub fn joules(&self, tx_dbm: f64, tx_s: f64, listen_s: f64) -> f64 {
        self.supply_v * (self.tx_current(tx_dbm) * tx_s + self.rx_a * listen_s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The datasheet's powers give its currents; between two, the line between them; beyond, the nearest.
    #[test]
    fn the_transmit_current_is_the_datasheets() {
        let e = Energy::CC2420;
        for &(p, a) in CC2420_TX {
            assert_eq!(e.tx_current(p), a);
        }
        assert!((e.tx_current(-2.0) - (15.2e-3 + 16.5e-3) / 2.0).abs() < 1e-15);
        assert_eq!(e.tx_current(5.0), 17.4e-3);
        assert_eq!(e.tx_current(-40.0), 8.5e-3);
    }
}
