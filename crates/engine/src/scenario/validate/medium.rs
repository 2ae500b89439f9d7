//! `[medium]`: the pairwise links of `[link]` and `[[edge]]`, or one shared IEEE 802.15.4 channel
//! ([`crate::medium::radio`]) whose radios are set here.

use crate::medium::phy::{LogDistance, Receiver};
use crate::medium::radio::Radio;
use crate::medium::shadow::Shadowing;
use crate::scenario::toml::RawMedium;
use crate::scenario::{DirectedLink, MediumConfig, NodeConfig, Validator};

/// The transmit powers accepted, dBm: from a radio turned far down to one with an amplifier.
pub const TX_DBM: (f64, f64) = (-50.0, 30.0);

impl Validator {
    /// The medium of `raw`; a radio's keys need `kind = "radio"`, and a radio decides every frame's fate itself,
    /// so the links it replaces must carry no rule of their own.
    pub(super) fn medium(
        &mut self,
        raw: Option<&RawMedium>,
        links: &[DirectedLink],
        nodes: &[NodeConfig],
    ) -> MediumConfig {
        let Some(m) = raw else {
            return MediumConfig::Pairwise;
        };
        let radio_keys = [
            ("tx_dbm", m.tx_dbm.is_some()),
            ("path_loss_exponent", m.path_loss_exponent.is_some()),
            ("reference_loss_db", m.reference_loss_db.is_some()),
            ("reference_m", m.reference_m.is_some()),
            ("sensitivity_dbm", m.sensitivity_dbm.is_some()),
            ("ack", m.ack.is_some()),
            ("max_frame_retries", m.max_frame_retries.is_some()),
            ("shadowing_db", m.shadowing_db.is_some()),
            ("shadowing_decorrelation_m", m.shadowing_decorrelation_m.is_some()),
        ];
        match m.kind.as_deref().unwrap_or("pairwise") {
            "pairwise" => {
                for (key, _) in radio_keys.iter().filter(|(_, given)| *given) {
                    self.bad(
                        format!("medium.{key}"),
                        "only a radio medium has this setting: give medium.kind = \"radio\"",
                    );
                }
                MediumConfig::Pairwise
            }
            "radio" => {
                if let Some(l) = links.iter().find(|l| l.config != crate::link::LinkConfig::default()) {
                    let (c, d) = (l.config, crate::link::LinkConfig::default());
                    let rule = if c.loss != d.loss {
                        "loss"
                    } else if c.delay_ms != d.delay_ms {
                        "delay_ms"
                    } else if c.jitter_ms != d.jitter_ms || c.jitter != d.jitter {
                        "jitter_ms"
                    } else if c.duplicate != d.duplicate {
                        "duplicate"
                    } else {
                        "corrupt"
                    };
                    self.bad(
                        format!("link.{rule}"),
                        format!(
                            "a radio medium (medium.kind = \"radio\") decides every frame's fate from distance, noise \
                             and contention: the rules of [link] and [[edge]] are for the pairwise medium, and link {} \
                             → {} has one",
                            nodes[l.from].id, nodes[l.to].id
                        ),
                    );
                }
                let d = Radio::default();
                let within = |v: &mut Validator, key: &str, x: Option<f64>, (lo, hi): (f64, f64), default: f64| match x
                {
                    Some(x) if !(lo..=hi).contains(&x) => {
                        v.bad(format!("medium.{key}"), format!("must be in [{lo}, {hi}], got {x}"));
                        default
                    }
                    Some(x) => x,
                    None => default,
                };
                let tx_dbm = within(self, "tx_dbm", m.tx_dbm, TX_DBM, d.tx_dbm);
                let ns3 = LogDistance::NS3;
                let path_loss = LogDistance {
                    exponent: within(
                        self,
                        "path_loss_exponent",
                        m.path_loss_exponent,
                        (0.5, 10.0),
                        ns3.exponent,
                    ),
                    reference_m: within(self, "reference_m", m.reference_m, (1e-3, 1e3), ns3.reference_m),
                    reference_loss_db: within(
                        self,
                        "reference_loss_db",
                        m.reference_loss_db,
                        (0.0, 200.0),
                        ns3.reference_loss_db,
                    ),
                };
                let noiseless = Receiver::MAX_SENSITIVITY.sensitivity_dbm;
                let sensitivity_dbm = within(
                    self,
                    "sensitivity_dbm",
                    m.sensitivity_dbm,
                    (noiseless, 0.0),
                    d.receiver.sensitivity_dbm,
                );
                let retries = match m.max_frame_retries {
                    None => 3,
                    Some(r @ 0..=7) => r as u8,
                    Some(r) => {
                        self.bad("medium.max_frame_retries", format!("must be 0 to 7, got {r}"));
                        3
                    }
                };
                let sigma_db = within(self, "shadowing_db", m.shadowing_db, (0.0, 20.0), 0.0);
                let decorrelation_m = within(
                    self,
                    "shadowing_decorrelation_m",
                    m.shadowing_decorrelation_m,
                    (0.01, 1e4),
                    Shadowing::DECORRELATION_M,
                );
                MediumConfig::Radio(Radio {
                    max_frame_retries: m.ack.unwrap_or(true).then_some(retries),
                    shadowing: (sigma_db > 0.0).then_some(Shadowing {
                        sigma_db,
                        decorrelation_m,
                    }),
                    tx_dbm,
                    path_loss,
                    receiver: Receiver { sensitivity_dbm },
                    ..d
                })
            }
            other => {
                self.bad("medium.kind", format!("must be pairwise or radio, got `{other}`"));
                MediumConfig::Pairwise
            }
        }
    }
}
