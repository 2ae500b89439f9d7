//! Raw → typed: the file as written ([`super::toml`]) becomes a [`Scenario`], every problem recorded in
//! [`Checks`] with its key.

mod attack;
mod consensus;
mod link;
mod medium;
mod place;

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use super::toml::*;
use super::{
    Beta, ConsensusConfig, DirectedLink, EstimatorsConfig, LmiConfig, NodeConfig, Overrides, Role, Scenario,
    ScenarioError, SimConfig, Validator, MAX_ROUNDS,
};
use crate::link::LinkConfig;
use crate::motion::Trajectory;
use crate::sensor::SensorProfile;

impl Scenario {
    /// Parse and validate TOML text; `file` names the source in errors.
    pub fn from_toml(text: &str, file: &str) -> Result<Scenario, ScenarioError> {
        let raw: RawTopology = ::toml::from_str(text).map_err(|e| ScenarioError::Parse {
            file: file.to_string(),
            message: parse_error(text, &e),
        })?;
        Validator::default().validate(raw, file)
    }
}

/// Where the TOML went wrong and why, without the line itself: a file that is not a topology (a password file given
/// by mistake) is not printed back.
fn parse_error(text: &str, e: &::toml::de::Error) -> String {
    let why = e.message().trim_end();
    match e.span() {
        Some(span) => {
            let before = &text[..span.start.min(text.len())];
            let line = before.matches('\n').count() + 1;
            let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
            format!("TOML parse error at line {line}, column {column}: {why}")
        }
        None => format!("TOML parse error: {why}"),
    }
}

impl Validator {
    /// Raw → typed, or every problem found.
    pub(crate) fn validate(mut self, raw: RawTopology, file: &str) -> Result<Scenario, ScenarioError> {
        let topo = self.topology(raw, file);
        if self.problems.is_empty() {
            Ok(topo.expect("no problems implies a topology"))
        } else {
            Err(ScenarioError::Invalid {
                file: file.to_string(),
                problems: self.0.problems,
            })
        }
    }
}

impl Validator {
    fn topology(&mut self, raw: RawTopology, file: &str) -> Option<Scenario> {
        // The file as written (a `[generate]` table stays one) is what a change validates again.
        let kept = raw.clone();
        let (raw, drawn) = self.generated(raw);
        let name = raw.name.clone().unwrap_or_else(|| {
            Path::new(file)
                .file_stem()
                .map(|s| s.to_string_lossy().trim_start_matches("builtin:").to_string())
                .unwrap_or_default()
        });
        let description = raw.description.clone().unwrap_or_default();
        let trajectory_given = raw.sim.as_ref().is_some_and(|s| s.trajectory.is_some());
        let sim = self.sim(raw.sim.unwrap_or_default());
        let mut model = crate::model::parse(raw.model.unwrap_or_default(), self);
        if trajectory_given && !model.get().imu_driven() {
            self.bad(
                "sim.trajectory",
                format!(
                    "a {} model moves no body: its truth comes from its own dynamics; drop sim.trajectory",
                    model.kind()
                ),
            );
        }

        // Nodes.
        if raw.node.is_empty() {
            self.bad("node", "at least one [[node]] is required");
        }
        let mut ids: HashMap<i64, usize> = HashMap::new();
        let sensor_defaults = self.sensor("sensor", raw.sensor.as_ref(), &SensorProfile::default());
        let mut nodes = Vec::new();
        for (i, n) in raw.node.iter().enumerate() {
            let key = format!("node[{i}]");
            let id = n.id.unwrap_or(i as i64);
            // 2³² − 1 is the wire's broadcast address ([`crate::wire::BROADCAST`]).
            if !(0..crate::wire::BROADCAST as i64).contains(&id) {
                self.bad(
                    format!("{key}.id"),
                    format!("must be 0 to 4294967294 (4294967295 addresses every node), got {id}"),
                );
            }
            if ids.insert(id, i).is_some() {
                self.bad(format!("{key}.id"), format!("id {id} is used by more than one node"));
            }
            let role = match n.role.as_deref().unwrap_or("peer") {
                "peer" => Role::Peer,
                "sensor" => Role::Sensor,
                "estimator" => Role::Estimator,
                other => {
                    self.bad(
                        format!("{key}.role"),
                        format!("expected peer | sensor | estimator, got `{other}`"),
                    );
                    Role::Peer
                }
            };
            let sensor = self.sensor(&format!("{key}.sensor"), n.sensor.as_ref(), &sensor_defaults);
            let recording = n
                .imu_csv
                .as_deref()
                .and_then(|f| self.recording(&format!("{key}.imu_csv"), f, file));
            if recording.is_some() {
                if role == Role::Estimator {
                    self.bad(format!("{key}.imu_csv"), "an estimator has no IMU to replace");
                }
                if !model.get().imu_driven() {
                    self.bad(
                        format!("{key}.imu_csv"),
                        format!("a {} model has no IMU: only for kind = pose or attitude", model.kind()),
                    );
                }
            }
            if let Some(a) = &n.addr {
                if let Err(m) = check_addr(a) {
                    self.bad(format!("{key}.addr"), m);
                }
            }
            let drawn_at = drawn.as_ref().and_then(|d| d.get(i)).map(|[x, y]| vec![*x, *y, 0.0]);
            let place = self.place(&key, n, drawn_at, model.get().imu_driven(), &model.kind().to_string());
            nodes.push(NodeConfig {
                id: id.clamp(0, u32::MAX as i64) as u32,
                role,
                addr: n.addr.clone(),
                sensor,
                recording,
                place,
            });
        }
        self.stand(&mut model, &nodes);
        let n = nodes.len();
        let index = |v: &mut Validator, key: &str, id: i64| -> Option<usize> {
            let r = ids.get(&id).copied();
            if r.is_none() {
                v.bad(key, format!("no [[node]] has id {id}"));
            }
            r
        };

        // Links: [link] defaults, then one or two directed links per [[edge]].
        let default_link = self.link("link", raw.link.clone().unwrap_or_default(), &LinkConfig::default());
        let mut links: Vec<DirectedLink> = Vec::new();
        // (from, to) of every link so far: the checks below stay linear in the links.
        let mut linked: std::collections::HashSet<(usize, usize)> = Default::default();
        for (e, edge) in raw.edge.iter().enumerate() {
            let key = format!("edge[{e}]");
            if edge.nodes.len() != 2 {
                self.bad(
                    format!("{key}.nodes"),
                    format!("must list exactly two node ids, got {}", edge.nodes.len()),
                );
                continue;
            }
            let a = index(self, &format!("{key}.nodes"), edge.nodes[0]);
            let b = index(self, &format!("{key}.nodes"), edge.nodes[1]);
            let (Some(a), Some(b)) = (a, b) else { continue };
            if a == b {
                self.bad(format!("{key}.nodes"), "an edge must join two different nodes");
                continue;
            }
            let over = RawLink {
                loss: edge.loss.clone(),
                delay_ms: edge.delay_ms,
                jitter_ms: edge.jitter_ms,
                jitter: edge.jitter.clone(),
                duplicate: edge.duplicate,
                corrupt: edge.corrupt,
            };
            let cfg = self.link(&key, over, &default_link);
            let mut add = |v: &mut Validator, from: usize, to: usize| {
                if !linked.insert((from, to)) {
                    v.bad(
                        format!("{key}.nodes"),
                        format!("link {} -> {} is given twice", nodes[from].id, nodes[to].id),
                    );
                } else {
                    links.push(DirectedLink { from, to, config: cfg });
                }
            };
            add(self, a, b);
            if !edge.directed.unwrap_or(false) {
                add(self, b, a);
            }
        }

        // Roles must make sense on the graph.
        let (mut ins, mut outs) = (vec![Vec::new(); n], vec![Vec::new(); n]);
        for (li, l) in links.iter().enumerate() {
            ins[l.to].push(li);
            outs[l.from].push(li);
        }
        for (i, node) in nodes.iter().enumerate() {
            let key = format!("node[{i}].role");
            if node.role == Role::Estimator && ins[i].is_empty() {
                self.bad(key, "an estimator with no incoming edge never receives a measurement");
            } else if node.role == Role::Sensor && outs[i].is_empty() {
                self.bad(key, "a sensor with no outgoing edge sends to nobody");
            }
        }

        let consensus = self.consensus(raw.consensus.unwrap_or_default(), &nodes, &linked);
        let max_degree = ins.iter().map(Vec::len).max().unwrap_or(0);
        let mut estimators = self.estimators(
            raw.estimators.unwrap_or_default(),
            &model,
            max_degree,
            (&nodes, &ids),
            default_link,
        );
        // Its nodes run no networked filter: sequeira's gain is one for every source. "all" is all it can run.
        let sequeira = crate::estimators::Kind::Sequeira;
        if !model.get().observes_alike() && estimators.run.len() == crate::estimators::Kind::all().len() {
            estimators.run.retain(|k| *k != sequeira);
        }
        if !model.get().observes_alike() && estimators.run.contains(&sequeira) {
            self.bad(
                "estimators.run",
                format!(
                    "model `{}` observes differently at each node: {}",
                    model.kind(),
                    crate::estimators::NOT_ALIKE
                ),
            );
        }
        if estimators.any_in_node() {
            // Once per scenario, on the graph of every node's in-neighbours.
            let heard: Vec<Vec<usize>> = ins
                .iter()
                .map(|ls| ls.iter().map(|&l| links[l].from).collect())
                .collect();
            estimators.weights = Arc::new(crate::estimators::metropolis(&heard));
        }
        let faults = self.faults(&raw.fault, &ids, n);
        let security = self.security(raw.security.as_ref(), file, sim.seed);
        let medium = self.medium(raw.medium.as_ref(), &links, &nodes);
        let rows = model.get().observation().dim();
        let attacks = self.attacks(&raw.attack, &ids, &linked, rows, sim.duration_s);
        if sim.split_channels && model.get().observation().channels() < 2 {
            self.bad(
                "sim.split_channels",
                "only the pose and attitude models have separate channels",
            );
        }
        let by_id = nodes.iter().enumerate().map(|(i, nd)| (nd.id, i)).collect();
        Some(Scenario {
            name,
            description,
            source: file.to_string(),
            sim,
            model,
            consensus,
            estimators,
            security,
            medium,
            applied: Overrides::default(),
            raw: kept,
            nodes,
            links,
            ins,
            outs,
            by_id,
            faults,
            attacks,
        })
    }

    /// `max_degree`: the most in-neighbours of a node (KCF's default gain is the consensus step bound 1/(1 + Δ));
    /// `star_link`: the `[link]` defaults, for centralized-net's links to the sink where the scenario has none.
    fn estimators(
        &mut self,
        e: RawEstimators,
        model: &crate::model::ModelConfig,
        max_degree: usize,
        (nodes, ids): (&[NodeConfig], &HashMap<i64, usize>),
        star_link: LinkConfig,
    ) -> EstimatorsConfig {
        use crate::estimators::{Kind, Params};
        let run = match Kind::parse_list(e.run.as_deref().unwrap_or_default()) {
            Ok(run) => run,
            Err(msg) => {
                self.bad("estimators.run", msg);
                Vec::new()
            }
        };
        let rounds = match e.rounds {
            None => 1,
            Some(r) if (1..=MAX_ROUNDS as u64).contains(&r) => r as usize,
            Some(r) => {
                self.bad("estimators.rounds", format!("must be 1 to {MAX_ROUNDS}, got {r}"));
                1
            }
        };
        let kcf_gamma = self.non_negative("estimators.kcf_gamma", e.kcf_gamma, 1.0 / (1.0 + max_degree as f64));
        let hcmci_omega = e
            .hcmci_omega
            .map(|w| self.positive("estimators.hcmci_omega", Some(w), 1.0));
        let m = model.get();
        let states = m.angle_states().len();
        if states > crate::wire::MAX_STATES && run.iter().any(|k| k.in_node()) {
            self.bad(
                "estimators.run",
                format!(
                    "the model has {states} states; a round's message carries at most {}",
                    crate::wire::MAX_STATES
                ),
            );
        }
        let configured = self.configured(&run, &e.schemes);
        EstimatorsConfig {
            run,
            rounds,
            params: Params { kcf_gamma, hcmci_omega },
            configured,
            sink: self.sink(e.sink, nodes, ids),
            star_link,
            weights: Arc::default(),
        }
    }

    /// The schemes a program registered, each set up from its own table (`[estimators.<name>]`): every one in `run`
    /// (from an empty table when the file has none) and every one the file gives a table. A table of any other
    /// name is refused, naming it.
    fn configured(
        &mut self,
        run: &[crate::estimators::Kind],
        given: &std::collections::BTreeMap<String, toml::Table>,
    ) -> std::collections::BTreeMap<crate::estimators::Kind, crate::estimators::Configured> {
        use crate::estimators::Kind;
        let mut out = std::collections::BTreeMap::new();
        for (name, table) in given {
            // A crafted file's table name is echoed clipped, as every other name it gives.
            let key = format!("estimators.{}", crate::text::clip(name));
            match Kind::from_name(name) {
                Some(kind) if kind.takes_table() => {
                    out.extend(kind.configure(table, &mut self.0).map(|c| (kind, c)));
                }
                Some(_) => self.bad(
                    key,
                    "only a scheme a program registered takes a table of its own; the built-in schemes' keys are \
                     estimators.kcf_gamma and estimators.hcmci_omega",
                ),
                None => {
                    let tables: Vec<&str> = Kind::all()
                        .into_iter()
                        .filter(|k| k.takes_table())
                        .map(Kind::name)
                        .collect();
                    let tables = match tables.is_empty() {
                        true => " (only a scheme a program registered does)".to_string(),
                        false => format!(" (those that do: {})", tables.join(", ")),
                    };
                    self.bad(key, format!("no scheme of that name takes a table{tables}"))
                }
            }
        }
        for &kind in run.iter().filter(|k| k.takes_table()) {
            if !out.contains_key(&kind) {
                out.extend(kind.configure(&toml::Table::new(), &mut self.0).map(|c| (kind, c)));
            }
        }
        out
    }

    /// The fusion center of both centralized schemes: `estimators.sink`, else the first sensing node (its IMU
    /// drives the prediction).
    fn sink(&mut self, id: Option<i64>, nodes: &[NodeConfig], ids: &HashMap<i64, usize>) -> Option<usize> {
        let Some(id) = id else {
            return nodes.iter().position(|n| n.role.senses());
        };
        match ids.get(&id) {
            Some(&i) if nodes[i].role.senses() => Some(i),
            Some(_) => {
                self.bad(
                    "estimators.sink",
                    format!("node {id} does not sense: the center predicts with its IMU"),
                );
                None
            }
            None => {
                self.bad("estimators.sink", format!("no [[node]] has id {id}"));
                None
            }
        }
    }

    fn sim(&mut self, s: RawSim) -> SimConfig {
        let rate_hz = self.positive("sim.rate_hz", s.rate_hz, 100.0);
        let rate_hz = self.at_most("sim.rate_hz", rate_hz, super::MAX_RATE_HZ, " Hz");
        let duration_s = self.positive("sim.duration_s", s.duration_s, 30.0);
        if duration_s * rate_hz < 1.0 {
            self.bad(
                "sim.duration_s",
                format!(
                    "{} s at {} Hz is not one step: a run needs at least one period",
                    crate::checks::num(duration_s),
                    crate::checks::num(rate_hz)
                ),
            );
        }
        let burn_in_s = self.non_negative("sim.burn_in_s", s.burn_in_s, 3.0_f64.min(duration_s / 10.0));
        if burn_in_s >= duration_s {
            self.bad(
                "sim.burn_in_s",
                format!("must be shorter than sim.duration_s ({duration_s} s), got {burn_in_s}"),
            );
        }
        let trajectory = match s.trajectory.as_deref().unwrap_or("spiral").parse::<Trajectory>() {
            Ok(t) => t,
            Err(e) => {
                self.bad("sim.trajectory", e.to_string());
                Trajectory::Spiral
            }
        };
        let period_ms = 1000.0 / rate_hz;
        let deadline_ms = self.positive("sim.deadline_ms", s.deadline_ms, period_ms);
        if deadline_ms > period_ms + 1e-9 {
            self.bad(
                "sim.deadline_ms",
                format!("must not exceed one step period ({period_ms} ms): a measurement is used only in its own step"),
            );
        }
        let divergence_trace = self.positive("sim.divergence_trace", s.divergence_trace, 1e6);
        if duration_s * rate_hz > super::MAX_STEPS {
            self.bad("sim.duration_s", "more than 1e8 steps");
        }
        SimConfig {
            rate_hz,
            duration_s,
            burn_in_s,
            burn_in_shortened_from: None,
            seed: s.seed.unwrap_or(1),
            trajectory,
            deadline_s: deadline_ms.min(period_ms) / 1000.0,
            split_channels: s.split_channels.unwrap_or(false),
            divergence_trace,
        }
    }

    fn sensor(&mut self, key: &str, raw: Option<&RawSensor>, base: &SensorProfile) -> SensorProfile {
        let Some(s) = raw else { return base.clone() };
        let vec3 = |v: &mut Validator, k: &str, x: Option<[f64; 3]>, d: [f64; 3]| -> [f64; 3] {
            match x {
                Some(a) if a.iter().any(|e| !e.is_finite()) => {
                    v.bad(format!("{key}.{k}"), "entries must be finite");
                    d
                }
                Some(a) => a,
                None => d,
            }
        };
        let non_neg3 = |v: &mut Validator, k: &str, x: Option<[f64; 3]>, d: [f64; 3]| -> [f64; 3] {
            let a = vec3(v, k, x, d);
            if a.iter().any(|e| *e < 0.0) {
                v.bad(format!("{key}.{k}"), "standard deviations must be non-negative");
            }
            a
        };
        SensorProfile {
            accel_noise: self.non_negative(&format!("{key}.accel_noise"), s.accel_noise, base.accel_noise),
            gyro_noise: self.non_negative(&format!("{key}.gyro_noise"), s.gyro_noise, base.gyro_noise),
            accel_bias: vec3(self, "accel_bias", s.accel_bias, base.accel_bias),
            gyro_bias: vec3(self, "gyro_bias", s.gyro_bias, base.gyro_bias),
            accel_drift: non_neg3(self, "accel_drift", s.accel_drift, base.accel_drift),
            gyro_drift: non_neg3(self, "gyro_drift", s.gyro_drift, base.gyro_drift),
            pos_noise: self.non_negative(&format!("{key}.pos_noise"), s.pos_noise, base.pos_noise),
            att_noise: self.non_negative(&format!("{key}.att_noise"), s.att_noise, base.att_noise),
            mag_noise: self.non_negative(&format!("{key}.mag_noise"), s.mag_noise, base.mag_noise),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_builtin_validates() {
        for (name, _) in crate::scenario::builtin::ALL {
            let t = Scenario::resolve(name).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(t.name, *name);
        }
    }

    #[test]
    fn problems_name_the_key() {
        let err = Scenario::from_toml("[sim]\nrate_hz = -1\n[[node]]\nid=0\nrole='boss'\n", "x.toml").unwrap_err();
        let s = err.to_string();
        assert!(s.contains("sim.rate_hz") && s.contains("node[0].role"), "{s}");
        let err = Scenario::from_toml("[sim]\nrat_hz = 1\n", "x.toml").unwrap_err();
        assert!(err.to_string().contains("rat_hz"), "{err}");
    }
}

/// `HOST:PORT` as a node's `addr`: an IPv4 address, `[IPv6]`, or a host name (letters, digits, `-` and `.`, labels
/// of at most 63, 253 in all: what DNS and Docker's service names take), and a port 1 to 65535. Nothing else reaches
/// a socket or a generated compose file.
pub fn check_addr(a: &str) -> Result<(), String> {
    let bad = |why: &str| Err(format!("`{}` is not HOST:PORT ({why})", a.escape_debug()));
    let Some((host, port)) = a.rsplit_once(':') else {
        return bad("no `:PORT`");
    };
    if !port.parse::<u16>().is_ok_and(|p| p > 0) || !port.bytes().all(|b| b.is_ascii_digit()) {
        return bad("the port must be 1 to 65535");
    }
    if let Some(v6) = host.strip_prefix('[').and_then(|h| h.strip_suffix(']')) {
        return if v6.parse::<std::net::Ipv6Addr>().is_ok() {
            Ok(())
        } else {
            bad("not an IPv6 address in brackets")
        };
    }
    if host.parse::<std::net::Ipv4Addr>().is_ok() {
        return Ok(());
    }
    let label_ok = |l: &str| {
        !l.is_empty()
            && l.len() <= 63
            && l.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-')
            && !l.starts_with('-')
            && !l.ends_with('-')
    };
    if host.is_empty() || host.len() > 253 || !host.split('.').all(label_ok) {
        return bad("a host is an IP address or a name of letters, digits, `-` and `.`");
    }
    // A name's last label is never all digits (RFC 3696 §2): `999.1.1.1` is a bad IPv4 address, not a name.
    if host
        .rsplit('.')
        .next()
        .is_some_and(|l| l.bytes().all(|b| b.is_ascii_digit()))
    {
        return bad("not an IPv4 address: each of its four numbers is 0 to 255");
    }
    Ok(())
}

#[cfg(test)]
mod ignored_keys {
    /// A key that would change nothing is refused, not ignored: a linear model has no body to move.
    #[test]
    fn a_trajectory_for_a_linear_model_is_refused() {
        let linear = "[model]\nkind = \"linear\"\na = [[1.0]]\nc = [[1.0]]\nq = [[1.0]]\nr = [[1.0]]\n\
                      [[node]]\nid = 0\n";
        assert!(crate::Scenario::from_toml(linear, "t").is_ok());
        let e = crate::Scenario::from_toml(&format!("[sim]\ntrajectory = \"circle\"\n{linear}"), "t")
            .unwrap_err()
            .to_string();
        assert!(e.contains("sim.trajectory") && e.contains("linear"), "{e}");
    }
}

#[cfg(test)]
mod addr_tests {
    #[test]
    fn addresses_follow_a_strict_grammar() {
        for ok in ["node0:7000", "127.0.0.1:9", "[::1]:7000", "a-b.c:65535", "0.0.0.0:7000"] {
            assert!(super::check_addr(ok).is_ok(), "{ok}");
        }
        for bad in [
            "node0",
            "node0:0",
            "node0:70000",
            "node0:+7",
            "x\n    privileged: true:7000",
            "x, pid: host:7000",
            "-x:1",
            "a..b:1",
            "[zz]:1",
            ":7000",
            "a b:1",
            "999.1.1.1:99",
            "1=nohost:x",
            "nohost:x",
        ] {
            assert!(super::check_addr(bad).is_err(), "{bad:?}");
        }
    }
}
