//! What a campaign runs: the swept keys and their values ([`Axis`]), their cartesian product ([`Point`]s, the first
//! key varying slowest), each point's scenario validated before anything runs, and the runs — every point × seeds
//! 1 … N — each named by the digest of its resolved scenario and seed ([`RunSpec::key`]). Pure: no file, no clock.

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use simnet_engine::scenario::{parse_value, Overrides, Problem, Scenario, ScenarioError};

/// The most values one key takes, and the most runs a campaign holds.
pub const MAX_VALUES: usize = 10_000;
pub const MAX_RUNS: usize = 1_000_000;

/// One swept key and the values it takes, in order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Axis {
    pub key: String,
    pub values: Vec<toml::Value>,
}

impl Axis {
    /// `KEY=V1,V2,...` or `KEY=START:END:STEP` (END included; integers when all three are).
    pub fn parse(spec: &str) -> Result<Axis, String> {
        let (key, values) = spec
            .split_once('=')
            .ok_or_else(|| format!("`{spec}`: expected KEY=V1,V2,... or KEY=START:END:STEP"))?;
        let key = key.trim().to_string();
        if key.is_empty() {
            return Err(format!("`{spec}`: the key is empty"));
        }
        let values = values.trim();
        let parts: Vec<&str> = values.split(':').collect();
        let values = if parts.len() == 3 && !values.contains(',') {
            range(parts[0], parts[1], parts[2]).map_err(|e| format!("{key}: {e}"))?
        } else {
            split_top(values)
                .into_iter()
                .map(|v| {
                    if v.trim().is_empty() {
                        Err(format!("{key}: an empty value in `{values}`"))
                    } else {
                        Ok(parse_value(v))
                    }
                })
                .collect::<Result<Vec<_>, _>>()?
        };
        if values.is_empty() {
            return Err(format!("{key}: no value given"));
        }
        // A value given twice would run its point twice and count its runs twice.
        let number = |v: &toml::Value| v.as_float().or(v.as_integer().map(|i| i as f64));
        for (i, v) in values.iter().enumerate() {
            let same = |w: &toml::Value| w == v || number(w).is_some_and(|x| Some(x) == number(v));
            if values[..i].iter().any(same) {
                return Err(format!("{key}: the value {} is given twice", cell(v)));
            }
        }
        if values.len() > MAX_VALUES {
            return Err(format!("{key}: {} values, at most {MAX_VALUES}", values.len()));
        }
        Ok(Axis { key, values })
    }
}

/// Split at commas outside brackets and quotes, so that a list value (`[1, 2]`) stays one.
fn split_top(s: &str) -> Vec<&str> {
    let (mut depth, mut quoted, mut start, mut out) = (0i32, false, 0, Vec::new());
    for (i, c) in s.char_indices() {
        match c {
            '"' => quoted = !quoted,
            '[' | '{' if !quoted => depth += 1,
            ']' | '}' if !quoted => depth -= 1,
            ',' if !quoted && depth == 0 => {
                out.push(&s[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    out.push(&s[start..]);
    out
}

/// START, START + STEP, … up to END (within a millionth of a step), rounded to 12 decimals so that 0.1 steps give
/// 0.3, not 0.30000000000000004.
fn range(start: &str, end: &str, step: &str) -> Result<Vec<toml::Value>, String> {
    let num = |s: &str| {
        s.trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("`{s}` is not a number"))
    };
    let (a, b, d) = (num(start)?, num(end)?, num(step)?);
    if d <= 0.0 {
        return Err(format!("the step must be positive, got {d}"));
    }
    if b < a {
        return Err(format!("the range ends ({b}) before it starts ({a})"));
    }
    let n = ((b - a) / d + 1e-6).floor() + 1.0;
    if n > MAX_VALUES as f64 {
        return Err(format!("{n} values, at most {MAX_VALUES}"));
    }
    let integers = [start, end, step].iter().all(|s| s.trim().parse::<i64>().is_ok());
    Ok((0..n as usize)
        .map(|i| {
            let v = a + i as f64 * d;
            if integers {
                toml::Value::Integer(v.round() as i64)
            } else {
                toml::Value::Float((v * 1e12).round() / 1e12)
            }
        })
        .collect())
}

/// A value as a cell of a table: numbers as Rust writes them, strings bare.
pub fn cell(v: &toml::Value) -> String {
    match v {
        toml::Value::String(s) => s.clone(),
        toml::Value::Float(f) => f.to_string(),
        other => other.to_string(),
    }
}

/// One combination of the swept values and its scenario.
#[derive(Debug, Clone)]
pub struct Point {
    pub index: usize,
    /// One value per axis, in axis order.
    pub values: Vec<toml::Value>,
    pub scenario: Scenario,
    /// [`Scenario::digest`] of `scenario` (without the seed).
    pub digest: String,
}

/// One run: a point and a seed.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct RunSpec {
    /// Position in the campaign's run list (point-major, seed-minor): what a shard selects on.
    pub index: usize,
    pub point: usize,
    pub seed: u64,
    /// The first 16 hex digits of SHA-256(point digest, seed): the run's name in the store.
    pub key: String,
}

/// Everything a campaign runs, validated.
#[derive(Debug, Clone)]
pub struct Plan {
    /// The scenario every point starts from (the options common to all runs applied).
    pub base: Scenario,
    pub axes: Vec<Axis>,
    /// Seeds 1 … `seeds` at every point.
    pub seeds: u64,
    pub points: Vec<Point>,
}

impl Plan {
    /// Every point of `axes` over `base`, each validated: the first bad key or value is an error naming it and the
    /// point.
    pub fn new(base: Scenario, axes: Vec<Axis>, seeds: u64) -> Result<Plan, ScenarioError> {
        let invalid = |key: &str, message: String| ScenarioError::Invalid {
            file: base.source().to_string(),
            problems: vec![Problem {
                key: key.to_string(),
                message,
            }],
        };
        if seeds == 0 {
            return Err(invalid("seeds", "at least one seed is needed".into()));
        }
        for (i, a) in axes.iter().enumerate() {
            if axes[..i].iter().any(|b| b.key == a.key) {
                return Err(invalid(&a.key, "is swept twice".into()));
            }
        }
        let points: usize = axes.iter().map(|a| a.values.len()).product();
        if points.saturating_mul(seeds as usize) > MAX_RUNS {
            return Err(invalid(
                "seeds",
                format!("{points} points × {seeds} seeds is more than {MAX_RUNS} runs"),
            ));
        }
        let mut out = Vec::with_capacity(points);
        for index in 0..points {
            let values = combination(&axes, index);
            let keys: Vec<(&str, toml::Value)> = axes
                .iter()
                .map(|a| a.key.as_str())
                .zip(values.iter().cloned())
                .collect();
            let s = base.set_all(&keys).map_err(|e| at_point(e, &axes, &values))?;
            let digest = s.digest();
            if let Some(p) = out.iter().find(|p: &&Point| p.digest == digest) {
                return Err(invalid(
                    &axes.iter().map(|a| a.key.as_str()).collect::<Vec<_>>().join(", "),
                    format!(
                        "{} and {} are the same scenario: each would be run and counted twice",
                        describe(&axes, &p.values),
                        describe(&axes, &values)
                    ),
                ));
            }
            out.push(Point {
                index,
                values,
                scenario: s,
                digest,
            });
        }
        Ok(Plan {
            base,
            axes,
            seeds,
            points: out,
        })
    }

    /// Every run, point-major and seed-minor.
    pub fn runs(&self) -> Vec<RunSpec> {
        runs_of(self.points.iter().map(|p| p.digest.as_str()), self.seeds)
    }

    /// The scenario of one run: its point's with the seed.
    pub fn scenario(&self, run: &RunSpec) -> Result<Scenario, ScenarioError> {
        self.points[run.point].scenario.with(&Overrides {
            seed: Some(run.seed),
            ..Default::default()
        })
    }

    /// Every swept key's value at `point`.
    pub fn values(&self, point: usize) -> std::collections::BTreeMap<String, toml::Value> {
        values_by_key(&self.axes, &self.points[point].values)
    }

    /// `key = value` of each axis at `point`, for messages.
    pub fn describe(&self, point: usize) -> String {
        describe(&self.axes, &self.points[point].values)
    }
}

/// Shard `i` of `n` (1-based): the runs whose index is i − 1 modulo n — a deterministic, balanced split.
pub fn shard(runs: &[RunSpec], i: usize, n: usize) -> Vec<RunSpec> {
    runs.iter().filter(|r| r.index % n == i - 1).cloned().collect()
}

/// `I/N` with 1 ≤ I ≤ N.
pub fn parse_shard(s: &str) -> Result<(usize, usize), String> {
    let bad = || format!("`{s}`: a shard is I/N with 1 ≤ I ≤ N (e.g. 2/3)");
    let (i, n) = s.trim().split_once('/').ok_or_else(bad)?;
    let (i, n) = (
        i.trim().parse::<usize>().map_err(|_| bad())?,
        n.trim().parse::<usize>().map_err(|_| bad())?,
    );
    if i == 0 || n == 0 || i > n {
        return Err(bad());
    }
    Ok((i, n))
}

/// The runs of points with these digests, seeds 1 … `seeds` each, point-major.
pub(super) fn runs_of<'a>(digests: impl Iterator<Item = &'a str>, seeds: u64) -> Vec<RunSpec> {
    digests
        .enumerate()
        .flat_map(|(point, d)| (1..=seeds).map(move |seed| (point, d, seed)))
        .enumerate()
        .map(|(index, (point, d, seed))| RunSpec {
            index,
            point,
            seed,
            key: run_key(d, seed),
        })
        .collect()
}

fn run_key(digest: &str, seed: u64) -> String {
    let mut h = Sha256::new();
    h.update(digest.as_bytes());
    h.update(b"\nseed ");
    h.update(seed.to_string().as_bytes());
    h.finalize()[..8].iter().map(|b| format!("{b:02x}")).collect()
}

/// `values` (one per axis, in axis order) by key.
pub(super) fn values_by_key(axes: &[Axis], values: &[toml::Value]) -> std::collections::BTreeMap<String, toml::Value> {
    axes.iter().map(|a| a.key.clone()).zip(values.iter().cloned()).collect()
}

/// The values of point `index`: the last axis varies fastest.
pub(super) fn combination(axes: &[Axis], mut index: usize) -> Vec<toml::Value> {
    let mut values = vec![toml::Value::Boolean(false); axes.len()];
    for (i, a) in axes.iter().enumerate().rev() {
        values[i] = a.values[index % a.values.len()].clone();
        index /= a.values.len();
    }
    values
}

fn describe(axes: &[Axis], values: &[toml::Value]) -> String {
    axes.iter()
        .zip(values)
        .map(|(a, v)| format!("{} = {}", a.key, cell(v)))
        .collect::<Vec<_>>()
        .join(", ")
}

/// A point's validation error, its problems prefixed with the point.
fn at_point(e: ScenarioError, axes: &[Axis], values: &[toml::Value]) -> ScenarioError {
    match e {
        ScenarioError::Invalid { file, problems } => ScenarioError::Invalid {
            file,
            problems: problems
                .into_iter()
                .map(|p| Problem {
                    message: format!("{} (at {})", p.message, describe(axes, values)),
                    ..p
                })
                .collect(),
        },
        e => e,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axes_parse_lists_and_ranges() {
        let a = Axis::parse("link.loss.p=0:0.5:0.1").unwrap();
        assert_eq!(a.key, "link.loss.p");
        let v: Vec<f64> = a.values.iter().map(|v| v.as_float().unwrap()).collect();
        assert_eq!(v, vec![0.0, 0.1, 0.2, 0.3, 0.4, 0.5]);
        let r = Axis::parse("estimators.rounds=1:10:3").unwrap();
        assert_eq!(r.values, [1, 4, 7, 10].map(toml::Value::Integer).to_vec());
        let l = Axis::parse("sim.trajectory=spiral,circle").unwrap();
        assert_eq!(l.values[1], toml::Value::String("circle".into()));
        let m = Axis::parse("consensus.matrix=[[1.0]],[[0.5]]").unwrap();
        assert_eq!(m.values.len(), 2);
        for bad in [
            "link.loss.p",
            "=1,2",
            "x=1,,2",
            "x=1:0:0.1",
            "x=0:1:0",
            "x=0:1e9:1e-3",
            "x=a:1:1",
            "link.loss.p=0.1,0.1,0.2",
            "estimators.rounds=1,2,1.0",
        ] {
            assert!(Axis::parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn points_are_the_product_and_runs_are_named_by_scenario_and_seed() {
        let base = Scenario::resolve("ring3").unwrap();
        let axes = vec![
            Axis::parse("link.loss.p=0,0.2").unwrap(),
            Axis::parse("consensus.self=0.5,0.6,0.7").unwrap(),
        ];
        let plan = Plan::new(base, axes, 2).unwrap();
        assert_eq!(plan.points.len(), 6);
        assert_eq!(plan.describe(4), "link.loss.p = 0.2, consensus.self = 0.6");
        let runs = plan.runs();
        assert_eq!(runs.len(), 12);
        let keys: std::collections::BTreeSet<&str> = runs.iter().map(|r| r.key.as_str()).collect();
        assert_eq!(keys.len(), 12, "every run has its own key");
        // The same plan gives the same keys; shards partition the runs.
        let again = Plan::new(plan.base.clone(), plan.axes.clone(), 2).unwrap().runs();
        assert_eq!(runs, again);
        let mut all: Vec<usize> = (1..=3).flat_map(|i| shard(&runs, i, 3)).map(|r| r.index).collect();
        all.sort();
        assert_eq!(all, (0..12).collect::<Vec<_>>());
        assert_eq!(plan.scenario(&runs[3]).unwrap().sim().seed, 2);
    }

    #[test]
    fn a_bad_point_is_named_before_anything_runs() {
        let base = Scenario::resolve("ring3").unwrap();
        let e = Plan::new(base.clone(), vec![Axis::parse("link.loss.p=0.1,1.5").unwrap()], 1)
            .unwrap_err()
            .to_string();
        assert!(e.contains("link.loss.p") && e.contains("at link.loss.p = 1.5"), "{e}");
        let e = Plan::new(base.clone(), vec![Axis::parse("sim.rate_hzz=5").unwrap()], 1)
            .unwrap_err()
            .to_string();
        assert!(e.contains("rate_hzz"), "{e}");
        // Two points that are one scenario are refused, however their values were made.
        let twice = Axis {
            key: "link.loss.p".into(),
            values: vec![toml::Value::Float(0.1), toml::Value::Float(0.1)],
        };
        let e = Plan::new(base, vec![twice], 1).unwrap_err().to_string();
        assert!(e.contains("are the same scenario"), "{e}");
        for s in ["0/3", "4/3", "x", "1/0"] {
            assert!(parse_shard(s).is_err(), "{s}");
        }
        assert_eq!(parse_shard("2/3"), Ok((2, 3)));
    }
}
