//! Where a node is: on its package at a lever arm, or still at a position ([`crate::world::Place`]).

use crate::scenario::Validator;

/// The farthest a node may be placed from the origin, or its antenna from its package's origin, m.
pub const MAX_DISTANCE_M: f64 = 1e6;

impl Validator {
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
