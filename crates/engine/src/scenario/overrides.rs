//! Command-line overrides on top of a file.

use super::toml::{RawLoss, RawTopology};
use super::{Problem, Scenario, ScenarioError, Validator};
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
    /// The distributed estimators run beside the two filters (`--estimators`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub estimators: Option<Vec<crate::estimators::Kind>>,
    /// Consensus rounds per step (`--rounds`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rounds: Option<u64>,
    /// The network key file (`--key-file`): every datagram authenticated with it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub key_file: Option<String>,
    /// Authenticate with the run's own key where no key file is given (`--auth`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub auth: Option<bool>,
}

impl Overrides {
    /// Each value in its range, keyed by its field.
    fn check(&self, c: &mut Validator) {
        let key = |k: &str| format!("overrides.{k}");
        if let Some(l) = self.loss {
            c.loss(&key("loss"), &RawLoss::from(l));
        }
        for (k, v) in [("delay_ms", self.delay_ms), ("jitter_ms", self.jitter_ms)] {
            let x = c.non_negative(&key(k), v, 0.0);
            c.at_most(&key(k), x, crate::link::MAX_DELAY_MS, " ms");
        }
        c.prob(&key("duplicate"), self.duplicate, 0.0);
        c.prob(&key("corrupt"), self.corrupt, 0.0);
        c.positive(&key("duration_s"), self.duration_s, 1.0);
        let r = c.positive(&key("rate_hz"), self.rate_hz, 1.0);
        c.at_most(&key("rate_hz"), r, super::MAX_RATE_HZ, " Hz");
    }

    /// The link options replace one link's (the `[link]` defaults or an `[[edge]]`'s own).
    fn on_link(
        &self,
        loss: &mut Option<RawLoss>,
        delay: &mut Option<f64>,
        jitter: &mut Option<f64>,
        duplicate: &mut Option<f64>,
        corrupt: &mut Option<f64>,
    ) {
        if let Some(l) = self.loss {
            *loss = Some(RawLoss::from(l));
        }
        *delay = self.delay_ms.or(*delay);
        *jitter = self.jitter_ms.or(*jitter);
        *duplicate = self.duplicate.or(*duplicate);
        *corrupt = self.corrupt.or(*corrupt);
    }

    /// `b` on top of `self`: the last value of each wins.
    fn then(&self, b: &Overrides) -> Overrides {
        Overrides {
            loss: b.loss.or(self.loss),
            delay_ms: b.delay_ms.or(self.delay_ms),
            jitter_ms: b.jitter_ms.or(self.jitter_ms),
            duplicate: b.duplicate.or(self.duplicate),
            corrupt: b.corrupt.or(self.corrupt),
            duration_s: b.duration_s.or(self.duration_s),
            rate_hz: b.rate_hz.or(self.rate_hz),
            seed: b.seed.or(self.seed),
            estimators: b.estimators.clone().or(self.estimators.clone()),
            rounds: b.rounds.or(self.rounds),
            key_file: b.key_file.clone().or(self.key_file.clone()),
            auth: b.auth.or(self.auth),
        }
    }
}

impl Scenario {
    /// This scenario with `o` applied, validated again as a whole (the same checks and keys as the file). Link
    /// options replace the value on every link (file defaults and per-edge overrides alike); a duration shorter
    /// than twice the burn-in halves the burn-in; a new rate keeps a deadline of one period.
    pub fn with(&self, o: &Overrides) -> Result<Scenario, ScenarioError> {
        let mut c = self.checks();
        o.check(&mut c);
        if !c.problems.is_empty() {
            return Err(ScenarioError::Invalid {
                file: self.source.clone(),
                problems: c.0.problems,
            });
        }
        let mut raw = self.raw.clone();
        let l = raw.link.get_or_insert_with(Default::default);
        o.on_link(
            &mut l.loss,
            &mut l.delay_ms,
            &mut l.jitter_ms,
            &mut l.duplicate,
            &mut l.corrupt,
        );
        for e in &mut raw.edge {
            o.on_link(
                &mut e.loss,
                &mut e.delay_ms,
                &mut e.jitter_ms,
                &mut e.duplicate,
                &mut e.corrupt,
            );
        }
        let sim = raw.sim.get_or_insert_with(Default::default);
        let mut shortened = self.sim.burn_in_shortened_from;
        if let Some(d) = o.duration_s {
            sim.duration_s = Some(d);
            // The burn-in stays what it was (not the default of the new duration) unless it would cover half the run.
            let mut burn_in = self.sim.burn_in_s;
            if burn_in > d / 2.0 {
                shortened = Some(shortened.unwrap_or(burn_in));
                burn_in = d / 2.0;
            }
            sim.burn_in_s = Some(burn_in);
        }
        if let Some(r) = o.rate_hz {
            let old_dt = self.sim.dt();
            sim.rate_hz = Some(r);
            // A deadline of one period stays one period; a longer one than the new period is cut to it.
            if (self.sim.deadline_s - old_dt).abs() < 1e-12 || self.sim.deadline_s > 1.0 / r {
                sim.deadline_ms = None;
            }
        }
        if let Some(s) = o.seed {
            sim.seed = Some(s);
        }
        if o.estimators.is_some() || o.rounds.is_some() {
            let e = raw.estimators.get_or_insert_with(Default::default);
            if let Some(run) = &o.estimators {
                e.run = Some(run.iter().map(|k| k.name().to_string()).collect());
            }
            e.rounds = o.rounds.or(e.rounds);
        }
        if o.key_file.is_some() || o.auth.is_some() {
            let s = raw.security.get_or_insert_with(Default::default);
            if let Some(f) = &o.key_file {
                // A path given on the command line is the caller's (the working directory's), never the topology
                // file's: made absolute whether or not it exists, so that an error names the file looked for.
                s.key_file = Some(
                    std::path::Path::new(f)
                        .canonicalize()
                        .or_else(|_| std::path::absolute(f))
                        .map_or(f.clone(), |p| p.display().to_string()),
                );
            }
            s.auth = o.auth.or(s.auth);
        }
        let mut t = self.revalidate(raw, c)?;
        t.sim.burn_in_shortened_from = shortened;
        t.applied = self.applied.then(o);
        t.check_recordings()?;
        Ok(t)
    }

    /// This scenario with another consensus weight matrix (row i = receiving node i), validated again.
    /// `guard` turns the LMI guard of (17)/(19) on or off.
    pub fn with_beta(&self, beta: &[Vec<f64>], guard: bool) -> Result<Scenario, ScenarioError> {
        let mut raw = self.raw.clone();
        let c = raw.consensus.get_or_insert_with(Default::default);
        c.matrix = Some(beta.to_vec());
        (c.self_weight, c.neighbor) = (None, None);
        c.lmi.get_or_insert_with(Default::default).enabled = Some(guard);
        self.revalidate(raw, self.checks())
    }

    /// This scenario with another β₀ (the weight of a node's own measurement, Sequeira 2023 eq. 9), validated again.
    pub fn with_beta0(&self, beta0: f64) -> Result<Scenario, ScenarioError> {
        let mut raw = self.raw.clone();
        raw.consensus.get_or_insert_with(Default::default).beta0 = Some(beta0);
        self.revalidate(raw, self.checks())
    }

    /// This scenario with the LMI guard of (17)/(19) on or off, validated again.
    pub fn with_guard(&self, enabled: bool) -> Result<Scenario, ScenarioError> {
        let mut raw = self.raw.clone();
        let c = raw.consensus.get_or_insert_with(Default::default);
        c.lmi.get_or_insert_with(Default::default).enabled = Some(enabled);
        self.revalidate(raw, self.checks())
    }

    /// This scenario with node `i`'s sensor replaced, validated again.
    pub fn with_sensor(&self, i: usize, sensor: &crate::sensor::SensorProfile) -> Result<Scenario, ScenarioError> {
        let mut raw = self.raw.clone();
        let Some(n) = raw.node.get_mut(i) else {
            return Err(ScenarioError::Invalid {
                file: self.source.clone(),
                problems: vec![Problem {
                    key: format!("node[{i}]"),
                    message: format!(
                        "there is no node {i}: the scenario has {}",
                        super::count(self.nodes.len(), "node")
                    ),
                }],
            });
        };
        n.sensor = Some(super::toml::RawSensor::from(sensor));
        self.revalidate(raw, self.checks())
    }

    /// This scenario with another trajectory, validated again.
    pub fn with_trajectory(&self, t: crate::motion::Trajectory) -> Result<Scenario, ScenarioError> {
        let mut raw = self.raw.clone();
        raw.sim.get_or_insert_with(Default::default).trajectory = Some(t.to_string());
        self.revalidate(raw, self.checks())
    }

    /// Checks that know this scenario's recordings.
    pub(super) fn checks(&self) -> Validator {
        let mut c = Validator::default();
        for r in self.nodes.iter().filter_map(|n| n.recording.as_ref()) {
            c.loaded.insert(r.path.clone(), r.data.clone());
        }
        c
    }

    pub(super) fn revalidate(&self, raw: RawTopology, c: Validator) -> Result<Scenario, ScenarioError> {
        let mut t = c.validate(raw, &self.source)?;
        t.source = self.source.clone();
        t.name = self.name.clone();
        t.applied = self.applied.clone();
        t.sim.burn_in_shortened_from = self.sim.burn_in_shortened_from;
        Ok(t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ring3() -> Scenario {
        Scenario::resolve("ring3").unwrap()
    }

    #[test]
    fn bad_overrides_are_errors_naming_their_key() {
        let t = ring3();
        for (o, key) in [
            (
                Overrides {
                    loss: Some(LossModel::Bernoulli { p: f64::NAN }),
                    ..Default::default()
                },
                "overrides.loss.p",
            ),
            (
                Overrides {
                    delay_ms: Some(-1.0),
                    ..Default::default()
                },
                "overrides.delay_ms",
            ),
            (
                Overrides {
                    rate_hz: Some(0.0),
                    ..Default::default()
                },
                "overrides.rate_hz",
            ),
            (
                Overrides {
                    duplicate: Some(1.5),
                    ..Default::default()
                },
                "overrides.duplicate",
            ),
        ] {
            let e = t.with(&o).unwrap_err().to_string();
            assert!(e.contains(key), "{key}: {e}");
        }
        let e = t.with_beta(&[vec![1.0]], true).unwrap_err().to_string();
        assert!(e.contains("consensus.matrix"), "{e}");
    }

    #[test]
    fn overrides_reach_every_link_and_keep_the_burn_in_rules() {
        let t = ring3()
            .with(&Overrides {
                delay_ms: Some(4.0),
                duration_s: Some(4.0),
                ..Default::default()
            })
            .unwrap();
        assert!(t.links.iter().all(|l| l.config.delay_ms == 4.0));
        assert_eq!((t.sim.burn_in_s, t.sim.burn_in_shortened_from), (2.0, Some(3.0)));
        let t = t
            .with(&Overrides {
                rate_hz: Some(50.0),
                seed: Some(9),
                ..Default::default()
            })
            .unwrap();
        assert_eq!((t.sim.deadline_s, t.sim.seed, t.sim.duration_s), (0.02, 9, 4.0));
        assert_eq!(t.applied.delay_ms, Some(4.0));
        assert_eq!(t.applied.rate_hz, Some(50.0));
    }

    /// Each change keeps the ones before it, and each is checked like the file's own values.
    #[test]
    fn changes_keep_each_other_and_are_checked() {
        let twelve = Overrides {
            duration_s: Some(12.0),
            ..Default::default()
        };
        let t = ring3().with(&twelve).unwrap().with_beta0(0.0).unwrap();
        let mut s = t.nodes()[1].sensor.clone();
        s.accel_drift = [0.05; 3];
        let t = t.with_sensor(1, &s).unwrap();
        let seed = Overrides {
            seed: Some(5),
            ..Default::default()
        };
        let u = t.with(&seed).unwrap();
        assert_eq!((u.sim().duration_s, u.sim().seed, u.consensus().beta0), (12.0, 5, 0.0));
        assert_eq!(u.nodes()[1].sensor.accel_drift, [0.05; 3]);
        let v = u
            .with_beta(&t.consensus().beta.to_dense(), false)
            .unwrap()
            .with_guard(true)
            .unwrap();
        assert_eq!(
            (v.sim().duration_s, v.consensus().beta0, v.consensus().lmi.enabled),
            (12.0, 0.0, true)
        );
        let w = v.with_trajectory(crate::motion::Trajectory::Circle).unwrap();
        assert_eq!(
            (w.sim().trajectory, w.sim().duration_s),
            (crate::motion::Trajectory::Circle, 12.0)
        );
        for (e, key) in [
            (t.with_beta0(f64::NAN).unwrap_err(), "consensus.beta0"),
            (t.with_sensor(7, &s).unwrap_err(), "node[7]"),
        ] {
            assert!(e.to_string().contains(key), "{key}: {e}");
        }
        s.gyro_noise = -1.0;
        let e = t.with_sensor(0, &s).unwrap_err().to_string();
        assert!(e.contains("node[0].sensor"), "{e}");
    }
}
