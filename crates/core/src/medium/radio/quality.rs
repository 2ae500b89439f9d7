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
    /// The sum of the distance between the two as each frame began, m.
    pub distance_m_sum: f64,
}

impl LinkQuality {
    /// One frame: its power and distance at the receiver, its lowest SINR when locked onto (linear), and whether it
    /// arrived.
    pub(super) fn count(&mut self, power_w: f64, heard: bool, sinr: Option<f64>, received: bool, distance_m: f64) {
        self.frames += 1;
        self.distance_m_sum += distance_m;
        if heard {
            self.heard += 1;
            self.rssi_dbm_sum += phy::w_to_dbm(power_w);
        }
        if let Some(s) = sinr {
            self.locked += 1;
            self.sinr_db_sum += 10.0 * s.log10();
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

    /// The frames that arrived intact over those sent for the receiver (the packet reception ratio, by frame).
    pub fn prr(&self) -> Option<f64> {
        (self.frames > 0).then(|| self.received as f64 / self.frames as f64)
    }

    /// The mean distance, m.
    pub fn mean_distance_m(&self) -> Option<f64> {
        (self.frames > 0).then(|| self.distance_m_sum / self.frames as f64)
    }
}
