//! What the frames of one sender were like at one receiver: how strong, how clean, how many arrived.

use super::phy;

/// One directed pair's frames over a run: every frame the sender meant for the receiver, how many the receiver
/// heard above the cut-off and locked onto, their mean power, SINR and distance, and how many arrived intact.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LinkQuality {
    /// Frames the sender put on the air for the receiver (its unicasts to it, its broadcasts it listens to).
    pub frames: u64,
    /// Of them, those that reached the receiver above a hundredth of its noise floor.
    pub heard: u64,
    /// Those it locked onto (SINR above −5 dB as the frame began, not busy, not transmitting).
    pub locked: u64,
    /// Those that arrived intact.
    pub received: u64,
    /// The sum of the heard frames' power at the receiver, dBm.
    pub rssi_dbm_sum: f64,
    /// The sum of the locked frames' lowest SINR, dB.
    pub sinr_db_sum: f64,
    /// The sum of the locked frames' link quality indication ([`lqi`]).
    #[serde(default)]
    pub lqi_sum: f64,
    /// The sum of the distance between the two as each frame began, m.
    pub distance_m_sum: f64,
}

impl LinkQuality {
    /// One frame: its power and distance at the receiver, its lowest SINR and chance to arrive intact when locked
    /// onto (linear), and whether it arrived.
    pub(super) fn count(
        &mut self,
        power_w: f64,
        heard: bool,
        locked: Option<(f64, f64)>,
        received: bool,
        distance_m: f64,
    ) {
        self.frames += 1;
        self.distance_m_sum += distance_m;
        if heard {
            self.heard += 1;
            self.rssi_dbm_sum += phy::w_to_dbm(power_w);
        }
        if let Some((s, success)) = locked {
            self.locked += 1;
            self.sinr_db_sum += 10.0 * s.log10();
            self.lqi_sum += f64::from(lqi(success));
        }
        self.received += u64::from(received);
    }

    /// The mean power of the heard frames, dBm.
    pub fn mean_rssi_dbm(&self) -> Option<f64> {
        (self.heard > 0).then(|| self.rssi_dbm_sum / self.heard as f64)
    }

    /// The mean of the locked frames' lowest SINR, dB.
    pub fn mean_sinr_db(&self) -> Option<f64> {
        (self.locked > 0).then(|| self.sinr_db_sum / self.locked as f64)
    }

    /// The mean link quality indication of the locked frames (0–255).
    pub fn mean_lqi(&self) -> Option<f64> {
        (self.locked > 0).then(|| self.lqi_sum / self.locked as f64)
    }

    /// The frames that arrived intact over those sent for the receiver (the packet reception ratio, by frame).
    pub fn prr(&self) -> Option<f64> {
        (self.frames > 0).then(|| self.received as f64 / self.frames as f64)
    }

    /// The mean distance, m.
    pub fn mean_distance_m(&self) -> Option<f64> {
        (self.frames > 0).then(|| self.distance_m_sum / self.frames as f64)
    }
}

/// A frame's link quality indication: its chance to arrive intact scaled to 0–255, as ns-3's `LrWpanPhy` gives it
/// (there the scaling is truncated after each stretch of constant interference; here once, over the frame).
pub fn lqi(success: f64) -> u8 {
    (255.0 * success.clamp(0.0, 1.0)).floor() as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    /// LQI is the chance scaled to 0–255 and truncated; a pair's mean is over the frames locked onto: a frame alone
    /// at 1 dB under the noise (208 bits) has LQI ⌊255 (1 − BER)^208⌋.
    #[test]
    fn lqi_is_the_chance_scaled_to_255() {
        assert_eq!((lqi(1.0), lqi(0.5), lqi(0.0), lqi(1.5)), (255, 127, 0, 255));
        let s = phy::frame_success_rate(10f64.powf(-0.1), 208);
        assert!(s > 0.01 && s < 0.99, "{s}");
        let mut q = LinkQuality::default();
        q.count(1e-12, true, Some((10f64.powf(-0.1), s)), true, 40.0);
        q.count(1e-12, true, Some((100.0, 1.0)), true, 40.0);
        q.count(1e-15, false, None, false, 40.0);
        let want = ((255.0 * s).floor() + 255.0) / 2.0;
        assert_eq!(q.mean_lqi(), Some(want));
        assert_eq!((q.frames, q.locked), (3, 2));
    }
}
