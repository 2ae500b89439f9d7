//! Who hears a sender's frame, and how loud. A frame reaches every node at the power the path loss (and the
//! pair's shadowing) leaves; a node where that is below a hundredth of the noise floor does not hear it at all —
//! not as a frame, not as interference, not in an assessment. Beyond the distance where even a frame shadowed 5 σ
//! above its median falls under that floor, nodes are not looked at: in a world of nodes that stand still they are
//! found through a grid of cells that wide, and each sender's hearers are worked out once. A frame then costs the
//! nodes around its sender, not every node.

use std::collections::HashMap;
use std::sync::Arc;

use nalgebra::Vector3;

use super::Radio;
use crate::medium::phy;
use crate::medium::shadow::ShadowField;
use crate::time::Time;
use crate::world::World;

/// Below this share of the noise floor a frame is not heard.
pub(super) const NEGLIGIBLE: f64 = 0.01;

/// The nodes that hear one sender's frame, in index order, and its power at each, W.
#[derive(Debug, Clone, Default, PartialEq)]
pub(super) struct Hearers {
    nodes: Vec<usize>,
    power_w: Vec<f64>,
}

impl Hearers {
    /// The frame's power at node `j`, if `j` hears it.
    pub(super) fn power(&self, j: usize) -> Option<f64> {
        self.nodes.binary_search(&j).ok().map(|k| self.power_w[k])
    }

    /// Every node that hears it, with the power there.
    pub(super) fn iter(&self) -> impl Iterator<Item = (usize, f64)> + '_ {
        self.nodes.iter().copied().zip(self.power_w.iter().copied())
    }
}

/// Who hears whom in one world.
#[derive(Debug)]
pub(super) struct Reach {
    /// No node farther than this hears a frame, m.
    cutoff_m: f64,
    floor_w: f64,
    /// In a world of nodes that stand still: where they are, and who hears each.
    still: Option<Still>,
}

/// The nodes by grid cell, and each sender's hearers once worked out.
#[derive(Debug)]
struct Still {
    cells: HashMap<[i64; 3], Vec<usize>>,
    known: Vec<Option<Arc<Hearers>>>,
}

impl Reach {
    pub(super) fn new(radio: &Radio, world: &World, noise_w: f64) -> Reach {
        let floor_w = NEGLIGIBLE * noise_w;
        let margin_db = 5.0 * radio.shadowing.map_or(0.0, |s| s.sigma_db);
        // The distance where the path loss alone leaves the floor plus the margin, and 1 % more so that the power,
        // not the distance, decides at the edge.
        let budget_db = radio.tx_dbm + margin_db - phy::w_to_dbm(floor_w);
        let cutoff_m = 1.01 * radio.path_loss.distance_for(budget_db);
        let still = (0..world.len()).all(|i| world.is_still(i)).then(|| {
            let mut cells: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
            for i in 0..world.len() {
                cells
                    .entry(cell(world.position(i, Time::ZERO), cutoff_m))
                    .or_default()
                    .push(i);
            }
            Still {
                cells,
                known: vec![None; world.len()],
            }
        });
        Reach {
            cutoff_m,
            floor_w,
            still,
        }
    }

    /// The nodes that hear a frame `from` begins at `t`, and how loud.
    pub(super) fn hearers(
        &mut self,
        radio: &Radio,
        world: &World,
        shadow: &mut Option<ShadowField>,
        from: usize,
        t: Time,
    ) -> Arc<Hearers> {
        let at = world.position(from, t);
        let mut near: Vec<usize> = match &self.still {
            Some(still) => {
                if let Some(h) = &still.known[from] {
                    return h.clone();
                }
                let c = cell(at, self.cutoff_m);
                let mut near = Vec::new();
                for dx in -1..=1 {
                    for dy in -1..=1 {
                        for dz in -1..=1 {
                            if let Some(v) = still.cells.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) {
                                near.extend_from_slice(v);
                            }
                        }
                    }
                }
                near.sort_unstable();
                near
            }
            None => (0..world.len()).collect(),
        };
        near.retain(|&j| j != from);
        let mut heard = Hearers::default();
        for j in near {
            let p = world.position(j, t);
            let distance_m = (p - at).norm();
            if distance_m > self.cutoff_m {
                continue;
            }
            let shadow_db = shadow.as_mut().map_or(0.0, |s| s.db(from, j, at, p));
            let loss = radio.path_loss.loss_db(distance_m) + shadow_db;
            let power_w = phy::dbm_to_w(radio.tx_dbm - loss);
            if power_w >= self.floor_w {
                heard.nodes.push(j);
                heard.power_w.push(power_w);
            }
        }
        let heard = Arc::new(heard);
        if let Some(still) = &mut self.still {
            still.known[from] = Some(heard.clone());
        }
        heard
    }
}

/// The grid cell, `size` wide, of a position.
fn cell(p: Vector3<f64>, size: f64) -> [i64; 3] {
    let c = |v: f64| (v / size).floor() as i64;
    [c(p.x), c(p.y), c(p.z)]
}
