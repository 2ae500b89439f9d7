//! Scenarios in code: [`ScenarioBuilder`] writes the same tables a topology file holds and [`ScenarioBuilder::build`]
//! runs the file's validator on them, so a scenario built in code has the same checks and the same error keys.

use super::toml::{RawEdge, RawFault, RawLink, RawLoss, RawNode, RawTopology};
use super::{Role, Scenario, ScenarioError, Validator};
use crate::link::{Jitter, LossModel};
use crate::model::ModelConfig;
use crate::motion::Trajectory;

/// Link settings; unset ones keep the default (`[link]`) or, on the default itself, simnet's (no loss, no delay).
#[derive(Debug, Clone, Default)]
pub struct LinkSpec {
    raw: RawLink,
}

impl LinkSpec {
    pub fn loss(mut self, l: LossModel) -> LinkSpec {
        self.raw.loss = Some(RawLoss::from(l));
        self
    }
    pub fn delay_ms(mut self, d: f64) -> LinkSpec {
        self.raw.delay_ms = Some(d);
        self
    }
    pub fn jitter_ms(mut self, j: f64, shape: Jitter) -> LinkSpec {
        self.raw.jitter_ms = Some(j);
        self.raw.jitter = Some(
            match shape {
                Jitter::Uniform => "uniform",
                Jitter::Normal => "normal",
            }
            .into(),
        );
        self
    }
    pub fn duplicate(mut self, p: f64) -> LinkSpec {
        self.raw.duplicate = Some(p);
        self
    }
    pub fn corrupt(mut self, p: f64) -> LinkSpec {
        self.raw.corrupt = Some(p);
        self
    }
}

/// Builds a [`Scenario`] without a file: `Scenario::builder().peer(0).peer(1).edge(0, 1, LinkSpec::default())
/// .build()`.
#[derive(Debug, Clone, Default)]
pub struct ScenarioBuilder {
    raw: RawTopology,
    name: Option<String>,
}

impl Scenario {
    pub fn builder() -> ScenarioBuilder {
        ScenarioBuilder::default()
    }
}

impl ScenarioBuilder {
    pub fn name(mut self, name: &str) -> ScenarioBuilder {
        self.raw.name = Some(name.into());
        self.name = Some(name.into());
        self
    }
    pub fn description(mut self, d: &str) -> ScenarioBuilder {
        self.raw.description = Some(d.into());
        self
    }
    pub fn rate_hz(mut self, r: f64) -> ScenarioBuilder {
        self.raw.sim.get_or_insert_with(Default::default).rate_hz = Some(r);
        self
    }
    pub fn duration_s(mut self, d: f64) -> ScenarioBuilder {
        self.raw.sim.get_or_insert_with(Default::default).duration_s = Some(d);
        self
    }
    pub fn burn_in_s(mut self, b: f64) -> ScenarioBuilder {
        self.raw.sim.get_or_insert_with(Default::default).burn_in_s = Some(b);
        self
    }
    pub fn seed(mut self, s: u64) -> ScenarioBuilder {
        self.raw.sim.get_or_insert_with(Default::default).seed = Some(s);
        self
    }
    pub fn trajectory(mut self, t: Trajectory) -> ScenarioBuilder {
        self.raw.sim.get_or_insert_with(Default::default).trajectory = Some(t.to_string());
        self
    }
    pub fn deadline_ms(mut self, d: f64) -> ScenarioBuilder {
        self.raw.sim.get_or_insert_with(Default::default).deadline_ms = Some(d);
        self
    }
    /// The channels of a measurement travel in separate datagrams (pose, attitude).
    pub fn split_channels(mut self, on: bool) -> ScenarioBuilder {
        self.raw.sim.get_or_insert_with(Default::default).split_channels = Some(on);
        self
    }
    pub fn model(mut self, m: impl Into<ModelConfig>) -> ScenarioBuilder {
        self.raw.model = Some(crate::model::to_raw(&m.into()));
        self
    }

    /// A node that senses and estimates.
    pub fn peer(self, id: u32) -> ScenarioBuilder {
        self.node(id, Role::Peer)
    }
    pub fn node(mut self, id: u32, role: Role) -> ScenarioBuilder {
        self.raw.node.push(RawNode {
            id: Some(id as i64),
            role: Some(role.as_str().into()),
            addr: None,
            sensor: None,
            imu_csv: None,
            position_m: None,
            lever_arm_m: None,
        });
        self
    }

    /// The default of every link (`[link]`).
    pub fn link(mut self, spec: LinkSpec) -> ScenarioBuilder {
        self.raw.link = Some(spec.raw);
        self
    }
    /// An undirected edge; `spec` overrides the default link on it.
    pub fn edge(self, a: u32, b: u32, spec: LinkSpec) -> ScenarioBuilder {
        self.push_edge(a, b, false, spec)
    }
    /// One direction only: `from`'s measurements reach `to`.
    pub fn directed(self, from: u32, to: u32, spec: LinkSpec) -> ScenarioBuilder {
        self.push_edge(from, to, true, spec)
    }
    fn push_edge(mut self, a: u32, b: u32, directed: bool, spec: LinkSpec) -> ScenarioBuilder {
        let l = spec.raw;
        self.raw.edge.push(RawEdge {
            nodes: vec![a as i64, b as i64],
            directed: Some(directed),
            loss: l.loss,
            delay_ms: l.delay_ms,
            jitter_ms: l.jitter_ms,
            jitter: l.jitter,
            duplicate: l.duplicate,
            corrupt: l.corrupt,
        });
        self
    }
    /// Undirected edges joining the nodes given so far in a ring, in the order given.
    pub fn ring(self) -> ScenarioBuilder {
        self.joined(super::graph::ring)
    }

    /// Undirected edges of a random geometric graph over the nodes given so far
    /// ([`super::graph::random_geometric`]: the connectivity threshold from `seed`, grown until connected).
    /// A linear system's nodes stand where the graph was drawn (`position_m`); an IMU network's ride its package.
    pub fn random_geometric(mut self, seed: u64) -> ScenarioBuilder {
        let (at, _) = super::graph::random_geometric_placed(self.raw.node.len(), seed);
        let linear = self.raw.model.as_ref().and_then(|m| m.kind.as_deref()) == Some("linear");
        if linear {
            for (n, [x, y]) in self.raw.node.iter_mut().zip(at) {
                n.position_m = Some(vec![x, y, 0.0]);
            }
        }
        self.joined(|n| super::graph::random_geometric(n, seed))
    }

    /// Node `id` stands still at `position` (m): for a linear system (an IMU network's nodes ride its package).
    pub fn position(mut self, id: u32, position: [f64; 3]) -> ScenarioBuilder {
        if let Some(n) = self.raw.node.iter_mut().find(|n| n.id == Some(id as i64)) {
            n.position_m = Some(position.to_vec());
        }
        self
    }

    /// Node `id` rides the package at `lever` (m, body frame) from its origin: for an IMU network.
    pub fn lever_arm(mut self, id: u32, lever: [f64; 3]) -> ScenarioBuilder {
        if let Some(n) = self.raw.node.iter_mut().find(|n| n.id == Some(id as i64)) {
            n.lever_arm_m = Some(lever.to_vec());
        }
        self
    }

    /// The edges `graph` gives over the nodes given so far, by position.
    fn joined(mut self, graph: impl Fn(usize) -> Vec<(usize, usize)>) -> ScenarioBuilder {
        let ids: Vec<u32> = self.raw.node.iter().filter_map(|n| n.id).map(|i| i as u32).collect();
        for (a, b) in graph(ids.len()) {
            self = self.edge(ids[a], ids[b], LinkSpec::default());
        }
        self
    }

    /// β from the graph: Metropolis–Hastings weights (the file's `weights = "metropolis"`).
    pub fn metropolis(mut self) -> ScenarioBuilder {
        self.raw.consensus.get_or_insert_with(Default::default).weights = Some("metropolis".into());
        self
    }

    /// β weights: own measurement and each neighbour's (the file's `self` and `neighbor`).
    pub fn weights(mut self, own: f64, neighbour: f64) -> ScenarioBuilder {
        let c = self.raw.consensus.get_or_insert_with(Default::default);
        (c.self_weight, c.neighbor) = (Some(own), Some(neighbour));
        self
    }
    /// β₀, the weight of the prior in the consensus update (eq. (5) of Sequeira (2023)).
    pub fn beta0(mut self, b: f64) -> ScenarioBuilder {
        self.raw.consensus.get_or_insert_with(Default::default).beta0 = Some(b);
        self
    }
    /// The LMI guard of (17)/(19): α, γ, and whether it is on.
    pub fn lmi(mut self, alpha: f64, gamma: f64, enabled: bool) -> ScenarioBuilder {
        self.raw.consensus.get_or_insert_with(Default::default).lmi = Some(super::toml::RawLmi {
            alpha: Some(alpha),
            gamma: Some(gamma),
            enabled: Some(enabled),
        });
        self
    }
    /// The full β matrix, row i = receiving node i (in the order the nodes were given).
    pub fn beta(mut self, m: Vec<Vec<f64>>) -> ScenarioBuilder {
        self.raw.consensus.get_or_insert_with(Default::default).matrix = Some(m);
        self
    }

    /// Node `id` stops at `at_s`; with `restart_s` it comes back with fresh filters.
    pub fn crash(mut self, id: u32, at_s: f64, restart_s: Option<f64>) -> ScenarioBuilder {
        self.raw.fault.push(RawFault {
            kind: "crash".into(),
            node: Some(id as i64),
            at_s: Some(at_s),
            restart_s,
            ..RawFault::default()
        });
        self
    }
    /// The link a–b carries nothing (both ways) from `start_s` to `end_s`.
    pub fn link_down(mut self, a: u32, b: u32, start_s: f64, end_s: f64) -> ScenarioBuilder {
        self.raw.fault.push(RawFault {
            kind: "link-down".into(),
            link: Some(vec![a as i64, b as i64]),
            start_s: Some(start_s),
            end_s: Some(end_s),
            ..RawFault::default()
        });
        self
    }
    /// `ids` cannot talk to the other nodes from `start_s` to `end_s`.
    pub fn partition(mut self, ids: &[u32], start_s: f64, end_s: f64) -> ScenarioBuilder {
        self.raw.fault.push(RawFault {
            kind: "partition".into(),
            nodes: Some(ids.iter().map(|&i| i as i64).collect()),
            start_s: Some(start_s),
            end_s: Some(end_s),
            ..RawFault::default()
        });
        self
    }

    /// The validated scenario, or every problem with its key (as for a file).
    pub fn build(self) -> Result<Scenario, ScenarioError> {
        let file = format!("builder:{}", self.name.as_deref().unwrap_or("scenario"));
        let t = Validator::default().validate(self.raw, &file)?;
        t.check_recordings()?;
        Ok(t)
    }
}

/// Every node reachable from the first along `edges`.
#[cfg(test)]
mod tests {
    use super::*;

    /// The rotating target of Kamal, Farrell & Roy-Chowdhury (2013): A a rotation by π/400, process noise 2I,
    /// position observed with unit noise.
    fn rotating_target() -> crate::model::Linear {
        use nalgebra::{DMatrix, DVector};
        let th = std::f64::consts::PI / 400.0;
        crate::model::Linear::new(
            DMatrix::from_row_slice(2, 2, &[th.cos(), -th.sin(), th.sin(), th.cos()]),
            DMatrix::identity(2, 2),
            DMatrix::identity(2, 2) * 2.0,
            DMatrix::identity(2, 2),
            DVector::zeros(2),
            DMatrix::identity(2, 2),
        )
    }

    /// rgg50 as `topologies/rgg50.toml` ships it: a 50-node random geometric graph from seed 1, every third node
    /// naive (it estimates without observing), Metropolis weights, the rotating target.
    fn rgg50() -> ScenarioBuilder {
        let mut b = Scenario::builder()
            .name("rgg50")
            .rate_hz(100.0)
            .duration_s(20.0)
            .burn_in_s(1.0)
            .seed(1)
            .model(rotating_target());
        for i in 0..50 {
            b = b.node(i, if i % 3 == 2 { Role::Estimator } else { Role::Peer });
        }
        b.random_geometric(1).metropolis()
    }

    fn toml_of(name: &str, description: &str, b: &ScenarioBuilder) -> String {
        let th = std::f64::consts::PI / 400.0;
        let mut t = format!(
            "name = \"{name}\"\ndescription = \"{description}\"\n\n[sim]\nrate_hz = 100.0\nduration_s = 20.0\nburn_in_s = 1.0\nseed = 1\n\n\
             [model]\nkind = \"linear\"\na = [[{c:?}, {ms:?}], [{s:?}, {c:?}]]\nc = [[1.0, 0.0], [0.0, 1.0]]\n\
             q = [[2.0, 0.0], [0.0, 2.0]]\nr = [[1.0, 0.0], [0.0, 1.0]]\nx0 = [0.0, 0.0]\np0 = [[1.0, 0.0], [0.0, 1.0]]\n\n\
             [consensus]\nweights = \"metropolis\"\n",
            c = th.cos(),
            s = th.sin(),
            ms = -th.sin()
        );
        for n in &b.raw.node {
            t += &format!(
                "\n[[node]]\nid = {}\nrole = \"{}\"\n",
                n.id.unwrap(),
                n.role.as_deref().unwrap()
            );
            if let Some(p) = &n.position_m {
                t += &format!("position_m = {p:?}\n");
            }
        }
        for e in &b.raw.edge {
            t += &format!("\n[[edge]]\nnodes = [{}, {}]\n", e.nodes[0], e.nodes[1]);
        }
        t
    }

    /// The shipped rgg50 is the builder's graph (`SIMNET_BLESS=1` writes it), connected, with Metropolis rows that
    /// sum to one and weigh exactly the measurements a node can have.
    #[test]
    fn rgg50_is_the_seeded_random_geometric_graph() {
        let b = rgg50();
        let text = toml_of(
            "rgg50",
            "a 50-node random geometric graph (seed 1, radius at the connectivity threshold) with Metropolis weights; every third node naive; the rotating target of Kamal et al. (2013)",
            &b,
        );
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../topologies/rgg50.toml");
        if std::env::var_os("SIMNET_BLESS").is_some() {
            std::fs::write(&path, &text).unwrap();
        }
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            text,
            "topologies/rgg50.toml is not the builder's graph"
        );
        let built = b.build().unwrap();
        let file = Scenario::from_toml(&text, "rgg50").unwrap();
        assert_eq!(built.links().len(), file.links().len());
        let n = file.nodes().len();
        let beta = file.consensus().beta.to_dense();
        let linked: std::collections::HashSet<(usize, usize)> = file.links().iter().map(|l| (l.from, l.to)).collect();
        for (i, row) in beta.iter().enumerate() {
            let sum: f64 = row.iter().sum();
            assert!((sum - 1.0).abs() < 1e-12, "row {i} sums to {sum}");
            for (j, b) in row.iter().enumerate() {
                let carried = (i == j || linked.contains(&(j, i))) && file.nodes()[j].role.senses();
                assert_eq!(*b > 0.0, carried, "β[{i}][{j}] = {b}");
            }
        }
        assert!(super::super::graph::connected(
            n,
            &file.links().iter().map(|l| (l.from, l.to)).collect::<Vec<_>>()
        ));
        // Its nodes stand where the graph was drawn: every edge is shorter than every pair left unjoined (the
        // graph is the pairs closer than one radius), and a [generate] table of the same seed places them alike.
        let world = file.world();
        let (mut longest_edge, mut nearest_apart) = (0.0f64, f64::INFINITY);
        for a in 0..n {
            for b in (a + 1)..n {
                let d = world.distance(a, b, crate::time::Time::ZERO);
                if linked.contains(&(a, b)) {
                    longest_edge = longest_edge.max(d);
                } else {
                    nearest_apart = nearest_apart.min(d);
                }
            }
        }
        assert!(longest_edge < nearest_apart, "{longest_edge} {nearest_apart}");
        assert!(
            longest_edge > 10.0 && longest_edge < super::super::graph::RGG_SIDE_M / 2.0,
            "{longest_edge}"
        );
        let generated = Scenario::from_toml(
            &text[..text.find("[[node]]").unwrap()].replace(
                "[consensus]",
                "[generate]\ngraph = \"random-geometric\"\nnodes = 50\nseed = 1\nnaive_every = 3\n\n[consensus]",
            ),
            "gen",
        )
        .unwrap()
        .world();
        assert_eq!(generated, world);
    }

    /// `weights` names its rule and excludes the other ways of giving β; an unknown rule is named.
    #[test]
    fn metropolis_weights_are_checked() {
        let base = "[[node]]\nid = 0\n[[node]]\nid = 1\n[[edge]]\nnodes = [0, 1]\n[consensus]\n";
        let err = |extra: &str| {
            Scenario::from_toml(&format!("{base}{extra}"), "t")
                .unwrap_err()
                .to_string()
        };
        assert!(err("weights = \"metropolis\"\nself = 0.5\n").contains("`consensus.weights`: give either `weights`"));
        assert!(err("weights = \"uniform\"\n").contains("`consensus.weights`: unknown rule `uniform`"));
        let ok = Scenario::from_toml(&format!("{base}weights = \"metropolis\"\n"), "t").unwrap();
        // Two nodes of degree one: π₀₁ = 1/2, π₀₀ = 1/2.
        assert_eq!(ok.consensus().beta.to_dense(), vec![vec![0.5, 0.5], vec![0.5, 0.5]]);
    }

    /// ring3 built in code is ring3: the same summary, run for run.
    #[test]
    fn ring3_in_code_is_the_file() {
        let built = Scenario::builder()
            .name("ring3")
            .rate_hz(100.0)
            .duration_s(3.0)
            .burn_in_s(1.0)
            .seed(1)
            .trajectory(Trajectory::Spiral)
            .model(crate::model::Pose::default())
            .peer(0)
            .peer(1)
            .peer(2)
            .ring()
            .weights(0.7, 0.15)
            .beta0(0.01)
            .lmi(1000.0, 1e-5, true)
            .link(LinkSpec::default().loss(LossModel::Bernoulli { p: 0.1 }))
            .build()
            .unwrap();
        let file = Scenario::resolve("ring3")
            .unwrap()
            .with(&crate::scenario::Overrides {
                duration_s: Some(3.0),
                loss: Some(LossModel::Bernoulli { p: 0.1 }),
                ..Default::default()
            })
            .unwrap();
        let file = {
            let mut raw = file.raw.clone();
            raw.sim.get_or_insert_with(Default::default).burn_in_s = Some(1.0);
            Validator::default().validate(raw, "ring3").unwrap()
        };
        let a = crate::sim::Sim::new(&built).unwrap().run().unwrap().summary();
        let b = crate::sim::Sim::new(&file).unwrap().run().unwrap().summary();
        assert_eq!(a.nodes, b.nodes);
        assert_eq!(a.links, b.links);
        assert_eq!(a.fused, b.fused);
    }

    #[test]
    fn a_bad_scenario_in_code_names_its_key() {
        let e = Scenario::builder()
            .rate_hz(f64::NAN)
            .peer(0)
            .peer(1)
            .edge(0, 7, LinkSpec::default().duplicate(2.0))
            .build()
            .unwrap_err()
            .to_string();
        for key in ["sim.rate_hz", "edge[0].nodes"] {
            assert!(e.contains(key), "{key}: {e}");
        }
        let e = Scenario::builder()
            .peer(0)
            .peer(1)
            .edge(0, 1, LinkSpec::default().duplicate(2.0))
            .build()
            .unwrap_err()
            .to_string();
        assert!(e.contains("edge[0].duplicate"), "{e}");
    }
}
