//! The options of `simnet run` as plain values: the command line and the Python package make a scenario from them
//! the same way, with the same errors.

use super::{Overrides, Scenario, ScenarioError};
use crate::link::LossModel;

/// The loss process `loss` sets.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum LossKind {
    #[default]
    Bernoulli,
    GilbertElliott,
}

impl LossKind {
    /// `bernoulli` or `gilbert-elliott` (as the command line spells them).
    pub fn parse(s: &str) -> Result<LossKind, String> {
        match s {
            "bernoulli" => Ok(LossKind::Bernoulli),
            "gilbert-elliott" | "gilbert_elliott" => Ok(LossKind::GilbertElliott),
            _ => Err(format!("unknown loss model `{s}` (known: bernoulli, gilbert-elliott)")),
        }
    }
}

/// The longest run accepted (the validator's bound on `sim.duration_s` × `sim.rate_hz`).
pub const MAX_STEPS: f64 = 1e8;

/// `simnet run`'s options, each named as on the command line; unset ones leave the file's value.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Flags {
    /// Loss probability on every link (stationary loss for Gilbert–Elliott).
    pub loss: Option<f64>,
    pub loss_model: Option<LossKind>,
    /// Mean loss run in packets (Gilbert–Elliott).
    pub burst: Option<f64>,
    /// One-way delay, ms.
    pub delay: Option<f64>,
    /// Jitter, ms.
    pub jitter: Option<f64>,
    pub duplicate: Option<f64>,
    pub corrupt: Option<f64>,
    /// Simulated duration, s.
    pub duration: Option<f64>,
    /// Step rate, Hz.
    pub rate: Option<f64>,
    pub seed: Option<u64>,
    pub estimators: Option<Vec<crate::estimators::Kind>>,
    pub rounds: Option<u64>,
    pub key_file: Option<String>,
    pub auth: bool,
    /// Scenario keys as in the file (`consensus.gate`), set after the options above, in order.
    pub set: Vec<(String, toml::Value)>,
}

/// Why the options make no scenario: an option named as on the command line, or a key of the scenario.
#[derive(Debug, thiserror::Error)]
pub enum FlagError {
    #[error("--{option} {message}")]
    Option { option: &'static str, message: String },
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
}

impl Flags {
    /// The loss, link and run overrides these options make.
    pub fn overrides(&self) -> Result<Overrides, FlagError> {
        let bad = |option, message: &str| FlagError::Option {
            option,
            message: message.to_string(),
        };
        let loss = match (self.loss, self.loss_model.unwrap_or_default(), self.burst) {
            (None, _, Some(_)) => return Err(bad("burst", "needs --loss (and --loss-model gilbert-elliott)")),
            (None, LossKind::GilbertElliott, None) if self.loss_model.is_some() => {
                return Err(bad("loss-model", "needs --loss"))
            }
            (None, _, None) => None,
            (Some(p), LossKind::Bernoulli, None) => Some(LossModel::Bernoulli { p }),
            (Some(_), LossKind::Bernoulli, Some(_)) => {
                return Err(bad("burst", "applies to --loss-model gilbert-elliott only"))
            }
            (Some(l), LossKind::GilbertElliott, burst) => {
                let b = burst.ok_or_else(|| bad("loss-model", "gilbert-elliott needs --burst B (mean loss run)"))?;
                Some(LossModel::gilbert_elliott_from(l, b).map_err(|e| bad("loss", &format!("and --burst: {e}")))?)
            }
        };
        if let Some(r) = self.rounds {
            if !(1..=super::MAX_ROUNDS as u64).contains(&r) {
                return Err(bad("rounds", &format!("must be 1 to {}, got {r}", super::MAX_ROUNDS)));
            }
        }
        Ok(Overrides {
            loss,
            delay_ms: self.delay,
            jitter_ms: self.jitter,
            duplicate: self.duplicate,
            corrupt: self.corrupt,
            duration_s: self.duration,
            rate_hz: self.rate,
            seed: self.seed,
            estimators: self.estimators.clone(),
            rounds: self.rounds,
            key_file: self.key_file.clone(),
            auth: self.auth.then_some(true),
        })
    }

    /// `base` with these options applied, then the keys set, validated as a whole.
    pub fn apply(&self, base: &Scenario) -> Result<Scenario, FlagError> {
        let mut t = base.with(&self.overrides()?)?;
        if !self.set.is_empty() {
            let keys: Vec<(&str, toml::Value)> = self.set.iter().map(|(k, v)| (k.as_str(), v.clone())).collect();
            t = t.set_all(&keys)?;
        }
        Ok(t)
    }

    /// Option `name` (`loss-model` or `loss_model`, [`super::RUN_OPTIONS`]) set from `value`; `None` when no option
    /// has that name (it is a scenario key).
    pub fn set_option(&mut self, name: &str, value: &toml::Value) -> Option<Result<(), FlagError>> {
        let o = super::RunOption::named(name)?;
        Some(o.read(self, value).map_err(|message| FlagError::Option {
            option: o.name,
            message,
        }))
    }
}

/// `KEY=VALUE` of `--set`, the value read as TOML (a bare word as a string).
pub fn parse_set(kv: &str) -> Result<(String, toml::Value), FlagError> {
    let (k, v) = kv.split_once('=').ok_or_else(|| FlagError::Option {
        option: "set",
        message: format!("`{kv}`: write KEY=VALUE, e.g. consensus.gate=0.999"),
    })?;
    Ok((k.trim().to_string(), super::parse_value(v)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ring3() -> Scenario {
        Scenario::resolve("ring3").unwrap()
    }

    #[test]
    fn options_become_the_overrides_and_keys_the_file_would_hold() {
        let f = Flags {
            loss: Some(0.2),
            duration: Some(3.0),
            set: vec![parse_set("consensus.gate=0.999").unwrap()],
            ..Default::default()
        };
        let t = f.apply(&ring3()).unwrap();
        assert_eq!(t.sim().duration_s, 3.0);
        assert!(t
            .links()
            .iter()
            .all(|l| l.config.loss == LossModel::Bernoulli { p: 0.2 }));
        let by_hand = ring3()
            .with(&Overrides {
                loss: Some(LossModel::Bernoulli { p: 0.2 }),
                duration_s: Some(3.0),
                ..Default::default()
            })
            .unwrap()
            .set("consensus.gate", toml::Value::Float(0.999))
            .unwrap();
        assert_eq!(t.digest(), by_hand.digest());
    }

    #[test]
    fn each_bad_option_is_named() {
        let cases: [(Flags, &str); 4] = [
            (
                Flags {
                    burst: Some(3.0),
                    ..Default::default()
                },
                "burst",
            ),
            (
                Flags {
                    loss: Some(0.2),
                    loss_model: Some(LossKind::GilbertElliott),
                    ..Default::default()
                },
                "loss-model",
            ),
            (
                Flags {
                    loss: Some(0.2),
                    burst: Some(3.0),
                    ..Default::default()
                },
                "burst",
            ),
            (
                Flags {
                    rounds: Some(0),
                    ..Default::default()
                },
                "rounds",
            ),
        ];
        for (f, name) in cases {
            match f.apply(&ring3()) {
                Err(FlagError::Option { option, .. }) => assert_eq!(option, name, "{f:?}"),
                other => panic!("{f:?}: {other:?}"),
            }
        }
        let e = Flags {
            set: vec![parse_set("consensus.nope=1").unwrap()],
            ..Default::default()
        }
        .apply(&ring3())
        .unwrap_err();
        assert!(
            matches!(e, FlagError::Scenario(ScenarioError::Invalid { ref problems, .. })
            if problems[0].key == "consensus.nope"),
            "{e}"
        );
        assert!(parse_set("novalue").is_err());
    }
}
