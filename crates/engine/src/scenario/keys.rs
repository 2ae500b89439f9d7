//! Any key of a scenario by its path in the file — `sim.rate_hz`, `link.loss.p`, `node[2].sensor.gyro_noise`,
//! `generate.nodes` — set on the file as written and validated again as a whole; the file a scenario would be read
//! from ([`Scenario::to_toml`]) and its digest, which names a run in a campaign.

use sha2::{Digest, Sha256};

use super::toml::RawTopology;
use super::{Problem, Scenario, ScenarioError};

/// A value as written after `KEY=` on a command line: TOML (`0.2`, `3`, `true`, `[1, 2]`, `"x"`), else the text
/// itself as a string (`gilbert-elliott`).
pub fn parse_value(text: &str) -> toml::Value {
    let text = text.trim();
    match toml::from_str::<toml::Table>(&format!("v = {text}")) {
        Ok(mut t) => t.remove("v").unwrap_or_else(|| toml::Value::String(text.into())),
        Err(_) => toml::Value::String(text.into()),
    }
}

/// One step of a key path: a table key, and an index when it names an entry of a list (`node[2]`).
fn segments(key: &str) -> Result<Vec<(&str, Option<usize>)>, String> {
    if key.trim().is_empty() {
        return Err("the key is empty".into());
    }
    key.split('.')
        .map(|part| {
            let (name, index) = match part.split_once('[') {
                None => (part, None),
                Some((name, rest)) => {
                    let i = rest
                        .strip_suffix(']')
                        .and_then(|i| i.parse::<usize>().ok())
                        .ok_or_else(|| format!("`{part}`: an index is written name[0]"))?;
                    (name, Some(i))
                }
            };
            if name.is_empty() {
                return Err(format!("`{key}` has an empty part"));
            }
            Ok((name, index))
        })
        .collect()
}

/// `value` at `key` in `doc`: tables on the way are made as needed; a list entry must exist.
pub(super) fn put(doc: &mut toml::Value, key: &str, value: toml::Value) -> Result<(), String> {
    let path = segments(key)?;
    let mut cur = doc;
    for (i, (name, index)) in path.iter().enumerate() {
        let last = i + 1 == path.len();
        let seen = path[..i].iter().map(|(n, _)| *n).collect::<Vec<_>>().join(".");
        let table = cur
            .as_table_mut()
            .ok_or_else(|| format!("`{seen}` is a value, not a table"))?;
        if last && index.is_none() {
            table.insert(name.to_string(), value);
            return Ok(());
        }
        let entry = table.entry(name.to_string()).or_insert_with(|| match index {
            Some(_) => toml::Value::Array(Vec::new()),
            None => toml::Value::Table(Default::default()),
        });
        cur = match index {
            None => entry,
            Some(j) => {
                let list = entry.as_array_mut().ok_or_else(|| format!("`{name}` is not a list"))?;
                let len = list.len();
                let item = list
                    .get_mut(*j)
                    .ok_or_else(|| format!("`{name}` has {len} entries, so there is no {name}[{j}]"))?;
                if last {
                    *item = value;
                    return Ok(());
                }
                item
            }
        };
    }
    Ok(())
}

/// `link.REST` also set on every `[[edge]]` that gives its own value of REST's first part (an edge that gives none
/// takes `[link]`'s).
fn on_edges(doc: &mut toml::Value, key: &str, value: &toml::Value) -> Result<(), String> {
    let Some(rest) = key.strip_prefix("link.") else {
        return Ok(());
    };
    let field = rest.split(['.', '[']).next().unwrap_or(rest);
    let count = doc
        .get("edge")
        .and_then(|e| e.as_array())
        .map_or(0, |edges| edges.len());
    for i in 0..count {
        let has = doc["edge"][i].as_table().is_some_and(|t| t.contains_key(field));
        if has {
            put(doc, &format!("edge[{i}].{rest}"), value.clone())?;
        }
    }
    Ok(())
}

/// An option's problem as a problem of the key it was given as.
fn flag_problem(key: &str, e: super::FlagError, invalid: &dyn Fn(&str, String) -> ScenarioError) -> ScenarioError {
    match e {
        super::FlagError::Option { message, .. } => invalid(key, message),
        super::FlagError::Scenario(e) => e,
    }
}

impl Scenario {
    /// The TOML this scenario would be read from: the file as written with every change since (overrides, keys
    /// set), a `[generate]` table kept as one.
    pub fn to_toml(&self) -> String {
        // Every field of the raw file is a TOML type: writing it cannot fail.
        toml::to_string(&self.raw).unwrap_or_else(|e| format!("# simnet could not write this scenario: {e}\n"))
    }

    /// This scenario with `key` (its path in the file, e.g. `link.loss.p` or `node[2].sensor.gyro_noise`) set to
    /// `value`, validated again as a whole: a key the file format does not have, or a value out of its range, is
    /// an error naming it.
    pub fn set(&self, key: &str, value: toml::Value) -> Result<Scenario, ScenarioError> {
        self.set_all(&[(key, value)])
    }

    /// This scenario with every `(key, value)` set, validated once as a whole: keys that only make sense together
    /// (`link.loss.model` and `link.loss.burst`) change together.
    pub fn set_all(&self, keys: &[(&str, toml::Value)]) -> Result<Scenario, ScenarioError> {
        let invalid = |key: &str, message: String| ScenarioError::Invalid {
            file: self.source.clone(),
            problems: vec![Problem {
                key: key.to_string(),
                message,
            }],
        };
        // Options given by name first, as the command line applies them before `--set`: only those that stand for
        // a key of the file (`loss`, not `seed`).
        let by_name = |key: &str| super::RunOption::named(key).filter(|o| o.key.is_some());
        let (options, rest): (Vec<_>, Vec<_>) = keys.iter().cloned().partition(|(k, _)| by_name(k).is_some());
        if !options.is_empty() {
            let mut flags = super::Flags::default();
            for (key, value) in &options {
                if let Some(Err(e)) = flags.set_option(key, value) {
                    return Err(flag_problem(key, e, &invalid));
                }
            }
            let o = flags.overrides().map_err(|e| flag_problem(options[0].0, e, &invalid))?;
            let t = self.with(&o)?;
            return if rest.is_empty() { Ok(t) } else { t.set_all(&rest) };
        }
        let mut doc = toml::Value::try_from(&self.raw).map_err(|e| invalid("", e.to_string()))?;
        for (key, value) in keys {
            if *key == "sim.seed" {
                return Err(invalid(
                    key,
                    "the seed is chosen per run (--seeds), not as a key".into(),
                ));
            }
            put(&mut doc, key, value.clone()).map_err(|m| invalid(key, m))?;
            on_edges(&mut doc, key, value).map_err(|m| invalid(key, m))?;
        }
        let raw: RawTopology = doc.try_into().map_err(|e: toml::de::Error| {
            // The message names the field the file format does not take; the keys set say where.
            let keys: Vec<&str> = keys.iter().map(|(k, _)| *k).collect();
            invalid(&keys.join(", "), e.message().trim_end().to_string())
        })?;
        self.revalidate(raw, self.checks())
    }

    /// SHA-256 (hex) of [`Scenario::to_toml`] and of every recorded IMU file a node reads: one run of a campaign
    /// is this and its seed.
    pub fn digest(&self) -> String {
        let mut h = Sha256::new();
        h.update(self.to_toml().as_bytes());
        for r in self.nodes.iter().filter_map(|n| n.recording.as_ref()) {
            h.update(r.path.as_bytes());
            match std::fs::read(&r.path) {
                Ok(bytes) => h.update(&bytes),
                Err(e) => h.update(e.to_string().as_bytes()),
            }
        }
        h.finalize().iter().map(|b| format!("{b:02x}")).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_read_as_toml_or_text() {
        assert_eq!(parse_value("0.2"), toml::Value::Float(0.2));
        assert_eq!(parse_value("3"), toml::Value::Integer(3));
        assert_eq!(parse_value("true"), toml::Value::Boolean(true));
        assert_eq!(
            parse_value("gilbert-elliott"),
            toml::Value::String("gilbert-elliott".into())
        );
        assert_eq!(
            parse_value("[1, 2]"),
            toml::Value::Array(vec![toml::Value::Integer(1), toml::Value::Integer(2)])
        );
    }

    /// Every built-in is the scenario its own TOML reads back as, with the same digest.
    #[test]
    fn every_builtin_round_trips_through_its_toml() {
        for (name, _) in super::super::builtin::ALL {
            let s = Scenario::resolve(name).unwrap();
            let again = Scenario::from_toml(&s.to_toml(), name).unwrap();
            assert_eq!(again.to_toml(), s.to_toml(), "{name}");
            assert_eq!(again.digest(), s.digest(), "{name}");
            assert_eq!(again.links().len(), s.links().len(), "{name}");
        }
    }

    #[test]
    fn keys_set_what_they_name() {
        let s = Scenario::resolve("ring3").unwrap();
        let t = s.set("link.loss.p", parse_value("0.25")).unwrap();
        assert!(t
            .links()
            .iter()
            .all(|l| l.config.loss == crate::link::LossModel::Bernoulli { p: 0.25 }));
        assert_ne!(t.digest(), s.digest());
        let t = s.set("sim.rate_hz", parse_value("50")).unwrap();
        assert_eq!(t.sim().rate_hz, 50.0);
        let t = s.set("node[1].sensor.gyro_noise", parse_value("0.01")).unwrap();
        assert_eq!(t.nodes()[1].sensor.gyro_noise, 0.01);
        let t = s.set("estimators.rounds", parse_value("4")).unwrap();
        assert_eq!(t.estimators().rounds, 4);
        for (key, value, named) in [
            ("sim.rat_hz", "5", "rat_hz"),
            ("link.loss.p", "1.5", "link.loss.p"),
            ("node[7].sensor.gyro_noise", "0.1", "no node[7]"),
            ("sim.rate_hz.x", "1", "not a table"),
            ("sim.seed", "3", "--seeds"),
            ("estimators.rounds", "2.5", "expected u64"),
        ] {
            let e = s.set(key, parse_value(value)).unwrap_err().to_string();
            assert!(e.contains(named), "{key} = {value}: {e}");
        }
    }

    /// A value with long runs of quotes (the writer of toml 0.8 counted them in a byte: a panic at 256, a wrong
    /// file after) is an error naming the key where it is wrong, and round-trips where any text is allowed.
    #[test]
    fn values_with_long_runs_of_quotes_are_errors_or_round_trip() {
        let text = format!("(.,s={}x{}", "'".repeat(300), "\"".repeat(300));
        let s = Scenario::resolve("line4").unwrap();
        let e = s
            .set("loss", toml::Value::String(text.clone()))
            .unwrap_err()
            .to_string();
        assert!(e.contains("loss") && e.contains("expected a number"), "{e}");
        let t = s.set("description", toml::Value::String(text.clone())).unwrap();
        let again = Scenario::from_toml(&t.to_toml(), "line4").unwrap();
        assert_eq!(again.to_toml(), t.to_toml());
        assert!(t.to_toml().contains(&"'".repeat(300)) || t.to_toml().contains(&"\\'".repeat(300)));
        assert_eq!(again.digest(), t.digest());
    }

    /// line4 with the middle edge's own loss and delay: what a `[link]`-only setting used to leave alone.
    fn edges_override() -> Scenario {
        let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../topologies/line4.toml"))
            .unwrap()
            .replace(
                "nodes = [1, 2]",
                "nodes = [1, 2]\nloss = { p = 0.05 }\ndelay_ms = 2.0\nduplicate = 0.01\ncorrupt = 0.02\njitter_ms = 1.0",
            );
        Scenario::from_toml(&text, "line4-edges.toml").unwrap()
    }

    /// Every option of `simnet run` that sets a scenario value sets it the same way given as the option (the
    /// command line's path), by its name as a key, and by its key in the file: on every link, edges with their own
    /// value included.
    #[test]
    fn an_option_by_name_or_by_key_sets_every_link() {
        let base = edges_override();
        let edge = crate::link::LossModel::Bernoulli { p: 0.05 };
        assert_eq!(base.links().iter().filter(|l| l.config.loss == edge).count(), 2);
        let values = [
            ("loss", "0.3"),
            ("delay", "7.5"),
            ("jitter", "3"),
            ("duplicate", "0.2"),
            ("corrupt", "0.1"),
            ("rounds", "3"),
            ("estimators", "[\"icf\", \"kcf\"]"),
        ];
        for (name, _) in values {
            assert!(
                crate::scenario::RunOption::named(name).and_then(|o| o.key).is_some(),
                "{name}"
            );
        }
        for (name, text) in values {
            let key = crate::scenario::RunOption::named(name).and_then(|o| o.key).unwrap();
            let v = parse_value(text);
            let flags = crate::scenario::Flags {
                loss: (name == "loss").then(|| v.as_float().unwrap()),
                delay: (name == "delay").then(|| v.as_float().unwrap()),
                jitter: (name == "jitter").then(|| v.as_integer().unwrap() as f64),
                duplicate: (name == "duplicate").then(|| v.as_float().unwrap()),
                corrupt: (name == "corrupt").then(|| v.as_float().unwrap()),
                rounds: (name == "rounds").then(|| v.as_integer().unwrap() as u64),
                estimators: (name == "estimators")
                    .then(|| vec![crate::estimators::Kind::Icf, crate::estimators::Kind::Kcf]),
                ..Default::default()
            };
            let by_option = flags.apply(&base).unwrap();
            let by_name = base.set(name, v.clone()).unwrap();
            let by_key = base.set(key, v.clone()).unwrap();
            let configs = |s: &Scenario| s.links().iter().map(|l| format!("{:?}", l.config)).collect::<Vec<_>>();
            assert_eq!(configs(&by_name), configs(&by_option), "{name}");
            assert_eq!(configs(&by_key), configs(&by_option), "{key}");
            assert_eq!(by_key.estimators().rounds, by_option.estimators().rounds, "{key}");
            assert_eq!(by_key.estimators().run, by_option.estimators().run, "{key}");
        }
        // The measured case: a sweep over link.loss.p moves the edge with its own loss too.
        let t = base.set("link.loss.p", parse_value("0.5")).unwrap();
        assert!(t
            .links()
            .iter()
            .all(|l| l.config.loss == crate::link::LossModel::Bernoulli { p: 0.5 }));
        // Duration and rate by name are the options (the burn-in of the file kept); by key, the file's keys.
        let d = base.set("duration", parse_value("4")).unwrap();
        let o = base
            .with(&crate::Overrides {
                duration_s: Some(4.0),
                ..Default::default()
            })
            .unwrap();
        assert_eq!(d.to_toml(), o.to_toml());
        assert_eq!(d.sim().burn_in_s, o.sim().burn_in_s);
        let r = base.set("rate", parse_value("50")).unwrap();
        let o = base
            .with(&crate::Overrides {
                rate_hz: Some(50.0),
                ..Default::default()
            })
            .unwrap();
        assert_eq!((r.to_toml(), r.sim().deadline_s), (o.to_toml(), o.sim().deadline_s));
        for (name, text, says) in [
            ("loss", "x", "expected a number"),
            ("rounds", "0", "1 to 100"),
            ("estimators", "nope", "nope"),
        ] {
            let e = base.set(name, parse_value(text)).unwrap_err().to_string();
            assert!(e.contains(name) && e.contains(says), "{name} = {text}: {e}");
        }
    }

    /// A generated graph's node count is a key: `[generate]` gives the nodes and edges.
    #[test]
    fn a_generated_graph_follows_its_node_count() {
        let text = "[generate]\ngraph = \"ring\"\nnodes = 5\nnaive_every = 3\n";
        let s = Scenario::from_toml(text, "gen.toml").unwrap();
        assert_eq!((s.nodes().len(), s.links().len()), (5, 10));
        assert_eq!(s.nodes()[2].role, crate::scenario::Role::Estimator);
        let t = s.set("generate.nodes", parse_value("12")).unwrap();
        assert_eq!((t.nodes().len(), t.links().len()), (12, 24));
        assert!(t.to_toml().contains("[generate]") && !t.to_toml().contains("[[node]]"));
        for (text, key) in [
            ("[generate]\ngraph = \"ring\"\nnodes = 0\n", "generate.nodes"),
            ("[generate]\ngraph = \"torus\"\nnodes = 4\n", "generate.graph"),
            (
                "[generate]\ngraph = \"ring\"\nnodes = 4\ncolumns = 2\n",
                "generate.columns",
            ),
            (
                "[generate]\ngraph = \"ring\"\nnodes = 4\n[[node]]\nid = 0\n",
                "generate",
            ),
        ] {
            let e = Scenario::from_toml(text, "gen.toml").unwrap_err().to_string();
            assert!(e.contains(key), "{text}: {e}");
        }
    }
}
