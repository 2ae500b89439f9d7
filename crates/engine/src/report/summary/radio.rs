//! The radio channel's figures in a summary: per node, the frames it sent, its time on the air and its energy, and
//! the channel's load; absent from runs over the pairwise medium.

use serde::{Deserialize, Serialize};

use crate::medium::energy::Energy;
use crate::node::NodeReport;
use crate::scenario::{MediumConfig, Scenario};

/// A radio run's channel, whole and per node.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct RadioSummary {
    /// The radios' transmit power, dBm.
    pub tx_dbm: f64,
    /// Their sensitivity, dBm.
    pub sensitivity_dbm: f64,
    /// The time the radios were on: the run, and after its last step until the last frame queued left the air
    /// (a saturated channel drains its queues after the run), s.
    pub span_s: f64,
    /// The senders' airtime summed over the span (more than 1 only where frames overlap, or where senders out of
    /// each other's range share the time).
    pub channel_load: f64,
    /// Every node's energy, J.
    pub energy_j: f64,
    /// The supply and currents the energy is costed at.
    pub energy_model: String,
    pub nodes: Vec<NodeRadio>,
}

/// One directed pair on the radio channel: the sender's frames at the receiver.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct LinkRadio {
    /// Frames the sender put on the air for the receiver.
    pub frames: u64,
    /// Their mean distance as each began, m.
    pub distance_m: Option<f64>,
    /// The mean power at the receiver of those it heard, dBm.
    pub rssi_dbm: Option<f64>,
    /// The mean of the lowest SINR over each frame it locked onto, dB.
    pub sinr_db: Option<f64>,
    /// The mean link quality indication (0–255) of the frames it locked onto: each frame's chance to arrive intact
    /// scaled to 0–255, as ns-3 gives it.
    #[serde(default)]
    pub lqi: Option<f64>,
    /// Frames that arrived intact over frames sent (by frame; `loss_rate` counts messages).
    pub prr: Option<f64>,
}

impl LinkRadio {
    /// The figures of `q`.
    pub fn of(q: &crate::medium::radio::LinkQuality) -> LinkRadio {
        LinkRadio {
            frames: q.frames,
            distance_m: q.mean_distance_m(),
            rssi_dbm: q.mean_rssi_dbm(),
            sinr_db: q.mean_sinr_db(),
            lqi: q.mean_lqi(),
            prr: q.prr(),
        }
    }
}

/// One node's radio over the run.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct NodeRadio {
    pub id: u32,
    /// Frames it put on the air.
    pub frames: u64,
    /// Its time transmitting, s.
    pub airtime_s: f64,
    /// Its time transmitting over the span.
    pub duty: f64,
    /// Frames abandoned after macMaxCSMABackoffs busy assessments.
    pub csma_failures: u64,
    /// Clear-channel assessments that found the channel busy.
    pub busy_assessments: u64,
    /// ACK frames it sent (in its airtime).
    pub acks: u64,
    /// Frames it sent again for want of an ACK.
    pub retries: u64,
    /// Unicast messages it gave up without an ACK after its retries.
    pub no_ack: u64,
    /// Its radio's energy: transmitting, and listening the rest of the span, J.
    pub energy_j: f64,
    /// Its mean power, mW.
    pub mean_power_mw: f64,
}

impl RadioSummary {
    /// The channel's figures of a run of `steps` steps over `topo`'s radio; none over the pairwise medium.
    pub fn of(topo: &Scenario, reports: &[NodeReport], steps: u64) -> Option<RadioSummary> {
        let MediumConfig::Radio(radio) = *topo.medium() else {
            return None;
        };
        let last_end = reports
            .iter()
            .filter_map(|r| r.radio.map(|c| c.last_end_ns as f64 * 1e-9))
            .fold(0.0, f64::max);
        let run_s = (steps as f64 * topo.sim().dt()).max(last_end);
        let chip = Energy::CC2420;
        let nodes: Vec<NodeRadio> = reports
            .iter()
            .map(|r| {
                let c = r.radio.unwrap_or_default();
                let airtime_s = c.airtime_ns as f64 * 1e-9;
                let energy_j = chip.joules(radio.tx_dbm, airtime_s, (run_s - airtime_s).max(0.0));
                NodeRadio {
                    id: r.id,
                    frames: c.frames,
                    airtime_s,
                    duty: if run_s > 0.0 { airtime_s / run_s } else { 0.0 },
                    csma_failures: c.csma_failures,
                    busy_assessments: c.busy,
                    acks: c.acks,
                    retries: c.retries,
                    no_ack: c.no_ack,
                    energy_j,
                    mean_power_mw: if run_s > 0.0 { energy_j / run_s * 1e3 } else { 0.0 },
                }
            })
            .collect();
        Some(RadioSummary {
            span_s: run_s,
            tx_dbm: radio.tx_dbm,
            sensitivity_dbm: radio.receiver.sensitivity_dbm,
            channel_load: nodes.iter().map(|n| n.duty).sum(),
            energy_j: nodes.iter().map(|n| n.energy_j).sum(),
            energy_model: format!(
                "CC2420 (datasheet SWRS041c): TX {:.1} mA at {} dBm, RX/listen {:.1} mA, {} V",
                chip.tx_current(radio.tx_dbm) * 1e3,
                radio.tx_dbm,
                chip.rx_a * 1e3,
                chip.supply_v
            ),
            nodes,
        })
    }
}

impl super::Summary {
    /// The radio's table: per node its frames, time on the air, channel access and energy.
    pub(super) fn write_radio(&self, w: &mut impl std::io::Write) -> std::io::Result<()> {
        let Some(r) = &self.radio else {
            return Ok(());
        };
        writeln!(w)?;
        writeln!(
            w,
            "radio: one IEEE 802.15.4 channel at {} dBm, sensitivity {} dBm; radios on {:.2} s{}; channel load {:.1} % \
             (the senders' airtime over that time); energy {:.3} J, {}",
            r.tx_dbm,
            r.sensitivity_dbm,
            r.span_s,
            if r.span_s > self.steps as f64 / self.rate_hz + 1e-9 {
                " (the queues drained after the last step)"
            } else {
                ""
            },
            r.channel_load * 100.0,
            r.energy_j,
            r.energy_model
        )?;
        writeln!(
            w,
            "{:>5} │ {:>8} {:>10} {:>7} │ {:>9} {:>9} {:>7} {:>7} │ {:>9} {:>9}",
            "node", "frames", "airtime s", "duty", "CCA busy", "CSMA fail", "retries", "no ACK", "energy J", "power mW"
        )?;
        writeln!(w, "{}", "─".repeat(100))?;
        for n in &r.nodes {
            writeln!(
                w,
                "{:>5} │ {:>8} {:>10.3} {:>6.1}% │ {:>9} {:>9} {:>7} {:>7} │ {:>9.3} {:>9.2}",
                n.id,
                n.frames,
                n.airtime_s,
                n.duty * 100.0,
                n.busy_assessments,
                n.csma_failures,
                n.retries,
                n.no_ack,
                n.energy_j,
                n.mean_power_mw
            )?;
        }
        let pairs: Vec<_> = self.links.iter().filter_map(|l| Some((l, l.radio.as_ref()?))).collect();
        if pairs.is_empty() {
            return Ok(());
        }
        writeln!(
            w,
            "PRR: frames that arrived intact over frames sent; SINR: the lowest over each frame locked onto"
        )?;
        writeln!(
            w,
            "{:>9} │ {:>7} {:>10} │ {:>9} {:>8} {:>7}",
            "link", "frames", "distance m", "RSSI dBm", "SINR dB", "PRR"
        )?;
        writeln!(w, "{}", "─".repeat(60))?;
        let f = |v: Option<f64>, p: usize| v.map_or("—".to_string(), |v| format!("{v:.p$}"));
        for (l, r) in pairs {
            writeln!(
                w,
                "{:>9} │ {:>7} {:>10} │ {:>9} {:>8} {:>7}",
                format!("{} → {}", l.from, l.to),
                r.frames,
                f(r.distance_m, 2),
                f(r.rssi_dbm, 1),
                f(r.sinr_db, 1),
                f(r.prr, 3)
            )?;
        }
        Ok(())
    }
}
