//! Command-line overrides on top of a file.

use super::Scenario;
use crate::link::LossModel;

/// Command-line overrides applied on top of a file (as `summary.json` records them: unset ones left out).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct Overrides {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub loss: Option<LossModel>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub delay_ms: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub jitter_ms: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub duplicate: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub corrupt: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub duration_s: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rate_hz: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
}

impl Scenario {
    /// CLI link options replace the value on every link (file defaults and per-edge overrides alike).
    pub fn apply(&mut self, o: &Overrides) {
        let a = &mut self.applied;
        macro_rules! keep {
            ($($f:ident),*) => { $( if o.$f.is_some() { a.$f = o.$f; } )* };
        }
        keep!(loss, delay_ms, jitter_ms, duplicate, corrupt, duration_s, rate_hz, seed);
        for l in &mut self.links {
            if let Some(loss) = o.loss {
                l.config.loss = loss;
            }
            if let Some(d) = o.delay_ms {
                l.config.delay_ms = d;
            }
            if let Some(j) = o.jitter_ms {
                l.config.jitter_ms = j;
            }
            if let Some(d) = o.duplicate {
                l.config.duplicate = d;
            }
            if let Some(c) = o.corrupt {
                l.config.corrupt = c;
            }
        }
        if let Some(d) = o.duration_s {
            self.sim.duration_s = d;
            if self.sim.burn_in_s > d / 2.0 {
                let asked = self.sim.burn_in_shortened_from.unwrap_or(self.sim.burn_in_s);
                self.sim.burn_in_shortened_from = Some(asked);
                self.sim.burn_in_s = d / 2.0;
            }
        }
        if let Some(r) = o.rate_hz {
            let old_dt = self.sim.dt();
            self.sim.rate_hz = r;
            if (self.sim.deadline_s - old_dt).abs() < 1e-12 || self.sim.deadline_s > self.sim.dt() {
                self.sim.deadline_s = self.sim.dt();
            }
        }
        if let Some(s) = o.seed {
            self.sim.seed = s;
        }
    }
}
