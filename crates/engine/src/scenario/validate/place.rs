//! Where a node is: on its package at a lever arm, or still at a position ([`crate::world::Place`]).

use crate::scenario::Validator;

/// The farthest a node may be placed from the origin, or its antenna from its package's origin, m.
pub const MAX_DISTANCE_M: f64 = 1e6;

impl Validator {
    /// A ranged model's nodes measure from where they stand: from one place, ranges leave the bearing unknown.
    pub(super) fn stand(&mut self, model: &mut crate::model::ModelConfig, nodes: &[crate::scenario::NodeConfig]) {
        let sites: Vec<[f64; 2]> = nodes
            .iter()
            .map(|n| match n.place {
                crate::world::Place::Fixed(p) => [p.x, p.y],
                crate::world::Place::Mounted { .. } => [f64::NAN; 2],
            })
            .collect();
        if matches!(model, crate::model::ModelConfig::Ranged { .. }) && sites.windows(2).all(|w| w[0] == w[1]) {
            self.bad(
                "node[].position_m",
                "observe = \"ranges\" needs nodes standing in at least two places (ranges from one place leave the \
                 body's bearing unknown): give each node's position_m",
            );
        }
        model.stand_at(sites);
    }

    /// Where node `key` is: on the package at its lever arm (an IMU network), or still at its position (a linear
    /// system; where its generated graph was drawn when the file gives none; the origin else).
    pub(super) fn place(
        &mut self,
        key: &str,
        n: &crate::scenario::toml::RawNode,
        drawn: Option<Vec<f64>>,
        on_package: bool,
        kind: &str,
    ) -> crate::world::Place {
        let vector = |v: &mut Validator, name: &str, given: &Vec<f64>| -> nalgebra::Vector3<f64> {
            let k = format!("{key}.{name}");
            match given[..] {
                [x, y] | [x, y, _] if given.iter().all(|c| c.is_finite() && c.abs() <= MAX_DISTANCE_M) => {
                    nalgebra::Vector3::new(x, y, given.get(2).copied().unwrap_or(0.0))
                }
                [_, _] | [_, _, _] => {
                    v.bad(
                        k,
                        format!("each coordinate must be finite and within ±{MAX_DISTANCE_M} m"),
                    );
                    nalgebra::Vector3::zeros()
                }
                _ => {
                    v.bad(
                        k,
                        format!("must be [x, y] or [x, y, z] in metres, got {} numbers", given.len()),
                    );
                    nalgebra::Vector3::zeros()
                }
            }
        };
        if on_package {
            if n.position_m.is_some() {
                self.bad(
                    format!("{key}.position_m"),
                    format!(
                        "a {kind} model's nodes ride its package (sim.trajectory): place this one with lever_arm_m"
                    ),
                );
            }
            let lever = n
                .lever_arm_m
                .as_ref()
                .map_or_else(nalgebra::Vector3::zeros, |l| vector(self, "lever_arm_m", l));
            crate::world::Place::Mounted { body: 0, lever }
        } else {
            if n.lever_arm_m.is_some() {
                self.bad(
                    format!("{key}.lever_arm_m"),
                    format!("a {kind} model moves no body: give the node's position_m"),
                );
            }
            let at = n.position_m.clone().or(drawn);
            crate::world::Place::Fixed(at.map_or_else(nalgebra::Vector3::zeros, |p| vector(self, "position_m", &p)))
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::model::ModelConfig;
    use crate::scenario::Scenario;

    const MODEL: &str = "[sim]\nduration_s = 1.0\n[model]\nkind = \"linear\"\nobserve = \"ranges\"\n\
                         a = [[1.0, 0.0], [0.0, 1.0]]\nq = [[1e-4, 0.0], [0.0, 1e-4]]\nr = [[0.01]]\n";

    fn sites(s: &Scenario) -> Vec<[f64; 2]> {
        match s.model() {
            ModelConfig::Ranged { model, .. } => model.sensing.sites().to_vec(),
            other => panic!("not ranged: {other:?}"),
        }
    }

    /// A ranged model's sites are where its nodes stand: given, or where a random geometric graph drew them.
    #[test]
    fn ranged_nodes_measure_from_where_they_stand() {
        let given = format!(
            "{MODEL}[[node]]\nposition_m = [1.0, 2.0]\n[[node]]\nposition_m = [-3.0, 4.0, 5.0]\n[[edge]]\nnodes = [0, 1]\n"
        );
        let s = Scenario::from_toml(&given, "r.toml").unwrap();
        assert_eq!(sites(&s), vec![[1.0, 2.0], [-3.0, 4.0]]);
        let drawn = format!("{MODEL}[generate]\ngraph = \"random-geometric\"\nnodes = 6\n");
        let s = Scenario::from_toml(&drawn, "r.toml").unwrap();
        let at: Vec<[f64; 2]> = s
            .nodes()
            .iter()
            .map(|n| match n.place {
                crate::world::Place::Fixed(p) => [p.x, p.y],
                _ => unreachable!("a linear model's nodes stand still"),
            })
            .collect();
        assert_eq!(sites(&s), at);
        assert!(at.windows(2).any(|w| w[0] != w[1]), "{at:?}");
        // Written back and read again, it is the same model.
        let again = Scenario::from_toml(&s.to_toml(), "r.toml").unwrap();
        assert_eq!(sites(&again), at);
    }

    /// Each way a ranged model can be wrong is refused by its key.
    #[test]
    fn a_ranged_model_that_cannot_be_is_refused_by_key() {
        let two = "[[node]]\nposition_m = [0.0, 0.0]\n[[node]]\nposition_m = [10.0, 0.0]\n";
        for (file, key, words) in [
            (
                format!("{MODEL}c = [[1.0, 0.0]]\n{two}"),
                "model.c",
                "linearised where the node stands",
            ),
            (
                MODEL.replace("ranges", "bearing") + two,
                "model.observe",
                "state | ranges",
            ),
            (
                MODEL.replace("r = [[0.01]]", "r = [[0.01, 0.0], [0.0, 0.01]]") + two,
                "model.r",
                "",
            ),
            (
                MODEL
                    .replace("[[1.0, 0.0], [0.0, 1.0]]", "[[1.0]]")
                    .replace("[[1e-4, 0.0], [0.0, 1e-4]]", "[[1.0]]")
                    + two,
                "model.a",
                "at least 2 states",
            ),
            (
                format!("{MODEL}[[node]]\n[[node]]\n"),
                "node[].position_m",
                "two places",
            ),
            (
                "[model]\nkind = \"pose\"\nobserve = \"ranges\"\n[[node]]\n".to_string(),
                "model.observe",
                "kind = \"linear\"",
            ),
        ] {
            let e = Scenario::from_toml(&file, "r.toml").unwrap_err().to_string();
            assert!(e.contains(key) && e.contains(words), "{key}: {e}");
        }
    }
}
