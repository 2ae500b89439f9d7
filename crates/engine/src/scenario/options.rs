//! The one table of `simnet run`'s options that make a scenario: each option's name, the scenario key it stands
//! for, and how its value is read and checked. The command line's value parsers, `--set NAME=…` and a sweep's axis
//! by option name ([`crate::Scenario::set_all`]) and the Python package's keyword arguments all read through it, so
//! an option takes the same values and refuses the same ones with the same words everywhere.

use super::flags::{Flags, LossKind};

/// One option of `simnet run`.
#[derive(Clone, Copy)]
pub struct RunOption {
    /// As on the command line (`loss-model`); Python and `--set` may write `_` for `-`.
    pub name: &'static str,
    /// The key of the file it stands for, when `--set NAME=…` and a sweep axis take it by its name (`loss` is
    /// `link.loss.p` on every link); none for an option that says how the run is made, not what the file holds.
    pub key: Option<&'static str>,
    /// What it takes, as its error says.
    pub takes: &'static str,
    read: fn(&mut Flags, &toml::Value) -> Result<(), String>,
}

impl std::fmt::Debug for RunOption {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RunOption")
            .field("name", &self.name)
            .field("key", &self.key)
            .finish()
    }
}

impl RunOption {
    /// The option called `name` (`loss-model` or `loss_model`).
    pub fn named(name: &str) -> Option<&'static RunOption> {
        let name = name.trim();
        RUN_OPTIONS
            .iter()
            .find(|o| o.name == name || o.name.replace('-', "_") == name)
    }

    /// `value` read into `flags`, or what is wrong with it (without the option's name).
    pub fn read(&self, flags: &mut Flags, value: &toml::Value) -> Result<(), String> {
        (self.read)(flags, value)
    }
}

/// Range checks of option values, shared with the command line's value parsers.
pub mod check {
    /// In [0, 1].
    pub fn probability(v: f64) -> Result<f64, String> {
        if (0.0..=1.0).contains(&v) {
            Ok(v)
        } else {
            Err(format!("must be a probability in [0, 1], got {v}"))
        }
    }

    /// Finite and above 0.
    pub fn positive(v: f64) -> Result<f64, String> {
        if v > 0.0 && v.is_finite() {
            Ok(v)
        } else {
            Err(format!("must be a positive number, got {v}"))
        }
    }

    /// Finite and at least 0.
    pub fn non_negative(v: f64) -> Result<f64, String> {
        if v >= 0.0 && v.is_finite() {
            Ok(v)
        } else {
            Err(format!("must be a non-negative number, got {v}"))
        }
    }

    /// A mean loss run: finite and at least one packet.
    pub fn at_least_one(v: f64) -> Result<f64, String> {
        if v >= 1.0 && v.is_finite() {
            Ok(v)
        } else {
            Err(format!("a mean loss run is at least 1 packet, got {v}"))
        }
    }

    /// Consensus rounds per step: 1 to [`crate::scenario::MAX_ROUNDS`].
    pub fn rounds(r: u64) -> Result<u64, String> {
        if (1..=crate::scenario::MAX_ROUNDS as u64).contains(&r) {
            Ok(r)
        } else {
            Err(format!("must be 1 to {}, got {r}", crate::scenario::MAX_ROUNDS))
        }
    }
}

/// A value as its error shows it: text quoted, anything clipped.
fn shown(v: &toml::Value) -> String {
    match v {
        toml::Value::String(s) => crate::text::quoted(s),
        v => crate::text::clip(&v.to_string()),
    }
}

fn put<T>(slot: &mut Option<T>, v: T) -> Result<(), String> {
    *slot = Some(v);
    Ok(())
}

fn number(v: &toml::Value) -> Result<f64, String> {
    v.as_float()
        .or(v.as_integer().map(|i| i as f64))
        .ok_or_else(|| format!("expected a number, got {}", shown(v)))
}

fn whole(v: &toml::Value) -> Result<u64, String> {
    match v {
        toml::Value::Integer(i) if *i >= 0 => Ok(*i as u64),
        // TOML's integers stop at 2^63 − 1: a larger seed is written as its digits.
        toml::Value::String(s) if s.trim().parse::<u64>().is_ok() => Ok(s.trim().parse().unwrap_or_default()),
        v => Err(format!("expected a whole number from 0 to 2^64 − 1, got {}", shown(v))),
    }
}

fn text(v: &toml::Value) -> Result<String, String> {
    v.as_str()
        .map(str::to_string)
        .ok_or_else(|| format!("expected text, got {}", shown(v)))
}

/// Every option of `simnet run` that makes the scenario, in the order of `simnet run --help`.
pub const RUN_OPTIONS: &[RunOption] = &[
    RunOption {
        name: "loss",
        key: Some("link.loss.p"),
        takes: "a probability in [0, 1]",
        read: |f, v| put(&mut f.loss, check::probability(number(v)?)?),
    },
    RunOption {
        name: "loss-model",
        key: None,
        takes: "bernoulli or gilbert-elliott",
        read: |f, v| put(&mut f.loss_model, LossKind::parse(&text(v)?)?),
    },
    RunOption {
        name: "burst",
        key: None,
        takes: "a mean loss run of at least 1 packet",
        read: |f, v| put(&mut f.burst, check::at_least_one(number(v)?)?),
    },
    RunOption {
        name: "delay",
        key: Some("link.delay_ms"),
        takes: "milliseconds, 0 or more",
        read: |f, v| put(&mut f.delay, check::non_negative(number(v)?)?),
    },
    RunOption {
        name: "jitter",
        key: Some("link.jitter_ms"),
        takes: "milliseconds, 0 or more",
        read: |f, v| put(&mut f.jitter, check::non_negative(number(v)?)?),
    },
    RunOption {
        name: "duplicate",
        key: Some("link.duplicate"),
        takes: "a probability in [0, 1]",
        read: |f, v| put(&mut f.duplicate, check::probability(number(v)?)?),
    },
    RunOption {
        name: "corrupt",
        key: Some("link.corrupt"),
        takes: "a probability in [0, 1]",
        read: |f, v| put(&mut f.corrupt, check::probability(number(v)?)?),
    },
    RunOption {
        name: "duration",
        key: Some("sim.duration_s"),
        takes: "seconds, above 0",
        read: |f, v| put(&mut f.duration, check::positive(number(v)?)?),
    },
    RunOption {
        name: "rate",
        key: Some("sim.rate_hz"),
        takes: "steps per second, above 0",
        read: |f, v| put(&mut f.rate, check::positive(number(v)?)?),
    },
    RunOption {
        name: "seed",
        key: None,
        takes: "a whole number from 0 to 2^64 − 1",
        read: |f, v| put(&mut f.seed, whole(v)?),
    },
    RunOption {
        name: "estimators",
        key: Some("estimators.run"),
        takes: "scheme names, comma-separated or a list, or all",
        read: |f, v| {
            let names: Vec<String> = match v {
                toml::Value::Array(a) => a.iter().map(text).collect::<Result<_, _>>()?,
                toml::Value::String(s) => s.split(',').map(|x| x.trim().to_string()).collect(),
                v => return Err(format!("expected estimator names, got {}", shown(v))),
            };
            put(&mut f.estimators, crate::estimators::Kind::parse_list(&names)?)
        },
    },
    RunOption {
        name: "rounds",
        key: Some("estimators.rounds"),
        takes: "a whole number of rounds, 1 to 100",
        read: |f, v| {
            let r = v
                .as_integer()
                .filter(|r| *r >= 0)
                .ok_or_else(|| format!("expected a whole number of rounds, got {}", shown(v)))?;
            put(&mut f.rounds, check::rounds(r as u64)?)
        },
    },
    RunOption {
        name: "key-file",
        key: None,
        takes: "the path of a key file (`simnet keygen`)",
        read: |f, v| put(&mut f.key_file, text(v)?),
    },
    RunOption {
        name: "auth",
        key: None,
        takes: "true or false",
        read: |f, v| {
            f.auth = v
                .as_bool()
                .ok_or_else(|| format!("expected true or false, got {}", shown(v)))?;
            Ok(())
        },
    },
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn options_are_found_by_either_spelling_and_read_what_they_name() {
        assert_eq!(RunOption::named("loss_model").unwrap().name, "loss-model");
        assert_eq!(RunOption::named("key-file").unwrap().name, "key-file");
        assert!(RunOption::named("link.loss.p").is_none());
        let mut f = Flags::default();
        for (name, value) in [
            ("loss", "0.25"),
            ("loss_model", "\"gilbert-elliott\""),
            ("burst", "3"),
            ("delay", "2"),
            ("jitter", "0.5"),
            ("duplicate", "0.01"),
            ("corrupt", "0"),
            ("duration", "4"),
            ("rate", "50"),
            ("seed", "\"18446744073709551615\""),
            ("estimators", "\"kcf, icf\""),
            ("rounds", "3"),
            ("key_file", "\"net.key\""),
            ("auth", "true"),
        ] {
            let o = RunOption::named(name).unwrap();
            o.read(&mut f, &super::super::parse_value(value)).unwrap();
        }
        use crate::estimators::Kind;
        let want = Flags {
            loss: Some(0.25),
            loss_model: Some(LossKind::GilbertElliott),
            burst: Some(3.0),
            delay: Some(2.0),
            jitter: Some(0.5),
            duplicate: Some(0.01),
            corrupt: Some(0.0),
            duration: Some(4.0),
            rate: Some(50.0),
            seed: Some(u64::MAX),
            estimators: Some(vec![Kind::Kcf, Kind::Icf]),
            rounds: Some(3),
            key_file: Some("net.key".into()),
            auth: true,
            set: Vec::new(),
        };
        assert_eq!(f, want);
        assert_eq!(RUN_OPTIONS.len(), 14, "every option is read above");
    }

    #[test]
    fn bad_values_say_what_the_option_takes() {
        for (name, value, says) in [
            ("loss", "1.5", "probability in [0, 1], got 1.5"),
            ("loss", "\"lots\"", "expected a number, got `lots`"),
            ("burst", "0.5", "at least 1 packet"),
            ("delay", "-1", "non-negative number, got -1"),
            ("duration", "0", "positive number, got 0"),
            ("rate", "nan", "positive number, got NaN"),
            ("seed", "-3", "0 to 2^64 − 1, got -3"),
            ("rounds", "0", "must be 1 to 100, got 0"),
            ("rounds", "2.5", "whole number of rounds, got 2.5"),
            ("estimators", "\"kcf,nope\"", "unknown estimator `nope`"),
            ("estimators", "[1]", "expected text, got 1"),
            ("loss-model", "\"markov\"", "unknown loss model `markov`"),
            ("auth", "1", "expected true or false, got 1"),
        ] {
            let e = RunOption::named(name)
                .unwrap()
                .read(&mut Flags::default(), &super::super::parse_value(value))
                .unwrap_err();
            assert!(e.contains(says), "{name} = {value}: {e}");
        }
    }
}
