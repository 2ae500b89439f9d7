//! Generated graphs: the undirected edges of a ring, a grid, a complete graph and a seeded random geometric graph
//! over nodes 0 … n−1. [`super::ScenarioBuilder`] joins its nodes with them, and a file's `[generate]` table names
//! one, so that a node count is one key a sweep can vary.

use rand::Rng;

use super::toml::{RawNode, RawTopology};
use crate::scenario::Validator;

/// The most nodes `[generate]` makes, the most edges, and the most nodes of the graphs whose construction looks at
/// every pair (complete, random geometric).
pub const MAX_GENERATED: i64 = 10_000;
pub const MAX_GENERATED_EDGES: usize = 200_000;
pub const MAX_PAIRWISE: usize = 2_000;

/// Edges (a, b), a < b unless the ring closes, joining 0 … n−1 in a ring (one edge for two nodes).
pub fn ring(n: usize) -> Vec<(usize, usize)> {
    match n {
        0 | 1 => Vec::new(),
        2 => vec![(0, 1)],
        _ => (0..n).map(|i| (i, (i + 1) % n)).collect(),
    }
}

/// A grid `columns` wide, row by row: each node joined to the next in its row and the one below it.
pub fn grid(n: usize, columns: usize) -> Vec<(usize, usize)> {
    let columns = columns.max(1);
    let mut edges = Vec::new();
    for i in 0..n {
        if (i + 1) % columns != 0 && i + 1 < n {
            edges.push((i, i + 1));
        }
        if i + columns < n {
            edges.push((i, i + columns));
        }
    }
    edges
}

/// Every pair.
pub fn complete(n: usize) -> Vec<(usize, usize)> {
    (0..n).flat_map(|a| ((a + 1)..n).map(move |b| (a, b))).collect()
}

/// The side of the square a random geometric graph's nodes are drawn in, m. Its connectivity radius at 50 nodes is
/// then 28 m: at 0 dBm under ns-3's default log-distance loss (46.68 dB at 1 m, exponent 3) a frame arrives at
/// −90 dBm there, near a CC2420's −95 dBm sensitivity, so the graph's links are about a radio's.
pub const RGG_SIDE_M: f64 = 100.0;

/// Positions uniform in the unit square from `seed`, an edge between two nodes closer than r = c √(ln n / n) — the
/// connectivity threshold (Penrose 2003) — with c = 1 grown by 10 % until the graph is connected.
pub fn random_geometric(n: usize, seed: u64) -> Vec<(usize, usize)> {
    random_geometric_placed(n, seed).1
}

/// [`random_geometric`] with the positions its graph was drawn from, scaled to a square of [`RGG_SIDE_M`] (m).
pub fn random_geometric_placed(n: usize, seed: u64) -> (Vec<[f64; 2]>, Vec<(usize, usize)>) {
    let mut rng = crate::rng::stream(seed, "random-geometric", n as u64, 0);
    let at: Vec<(f64, f64)> = (0..n).map(|_| (rng.gen::<f64>(), rng.gen::<f64>())).collect();
    let placed = at.iter().map(|(x, y)| [x * RGG_SIDE_M, y * RGG_SIDE_M]).collect();
    if n < 2 {
        return (placed, Vec::new());
    }
    let d = |a: usize, b: usize| ((at[a].0 - at[b].0).powi(2) + (at[a].1 - at[b].1).powi(2)).sqrt();
    let mut r = ((n as f64).ln() / n as f64).sqrt();
    loop {
        let edges: Vec<(usize, usize)> = complete(n).into_iter().filter(|&(a, b)| d(a, b) < r).collect();
        if connected(n, &edges) {
            return (placed, edges);
        }
        r *= 1.1;
    }
}

pub(super) fn connected(n: usize, edges: &[(usize, usize)]) -> bool {
    let mut around = vec![Vec::new(); n];
    for &(a, b) in edges {
        around[a].push(b);
        around[b].push(a);
    }
    let mut seen = vec![false; n];
    let mut stack = vec![0];
    seen[0] = true;
    while let Some(a) = stack.pop() {
        for &b in &around[a] {
            if !std::mem::replace(&mut seen[b], true) {
                stack.push(b);
            }
        }
    }
    seen.into_iter().all(|s| s)
}

impl Validator {
    /// The file's `[generate]` table written out as `[[node]]` and `[[edge]]` lists, with the positions a
    /// random geometric graph was drawn from; the raw file unchanged without one. Problems are recorded under
    /// `generate.*`.
    pub(super) fn generated(&mut self, raw: RawTopology) -> (RawTopology, Option<Vec<[f64; 2]>>) {
        let mut drawn = None;
        let raw = self.generated_lists(raw, &mut drawn);
        (raw, drawn)
    }

    fn generated_lists(&mut self, mut raw: RawTopology, drawn: &mut Option<Vec<[f64; 2]>>) -> RawTopology {
        let Some(g) = raw.generate.clone() else {
            return raw;
        };
        if !raw.node.is_empty() || !raw.edge.is_empty() {
            self.bad(
                "generate",
                "a file gives either [generate] or its own [[node]] and [[edge]] lists, not both",
            );
            return raw;
        }
        let n = match g.nodes {
            Some(n) if (1..=MAX_GENERATED).contains(&n) => n as usize,
            Some(n) => {
                self.bad("generate.nodes", format!("must be 1 to {MAX_GENERATED}, got {n}"));
                return raw;
            }
            None => {
                self.bad("generate.nodes", "the number of nodes is required");
                return raw;
            }
        };
        let naive = match g.naive_every {
            None => None,
            Some(k) if k >= 2 => Some(k as usize),
            Some(k) => {
                self.bad(
                    "generate.naive_every",
                    format!("must be at least 2 (every node naive would leave nothing to sense), got {k}"),
                );
                None
            }
        };
        if matches!(g.graph.as_str(), "complete" | "random-geometric") && n > MAX_PAIRWISE {
            self.bad(
                "generate.nodes",
                format!(
                    "a {} graph is built from every pair: at most {MAX_PAIRWISE} nodes, got {n}",
                    g.graph
                ),
            );
            return raw;
        }
        let edges = match g.graph.as_str() {
            "ring" => ring(n),
            "grid" => {
                let columns = match g.columns {
                    None => ((n as f64).sqrt().round() as usize).max(1),
                    Some(c) if (1..=n as i64).contains(&c) => c as usize,
                    Some(c) => {
                        self.bad("generate.columns", format!("must be 1 to {n} (the nodes), got {c}"));
                        1
                    }
                };
                grid(n, columns)
            }
            "complete" => complete(n),
            "random-geometric" => {
                let (at, edges) = random_geometric_placed(n, g.seed.unwrap_or(1));
                *drawn = Some(at);
                edges
            }
            other => {
                self.bad(
                    "generate.graph",
                    format!("expected ring | grid | complete | random-geometric, got `{other}`"),
                );
                return raw;
            }
        };
        if edges.len() > MAX_GENERATED_EDGES {
            self.bad(
                "generate.nodes",
                format!(
                    "{} edges, more than the {MAX_GENERATED_EDGES} a generated graph may have",
                    edges.len()
                ),
            );
            return raw;
        }
        for (key, given, graphs) in [
            ("columns", g.columns.is_some(), "grid"),
            ("seed", g.seed.is_some(), "random-geometric"),
        ] {
            if given && g.graph != graphs {
                self.bad(format!("generate.{key}"), format!("only for graph = \"{graphs}\""));
            }
        }
        raw.node = (0..n)
            .map(|i| RawNode {
                id: Some(i as i64),
                role: Some(
                    if naive.is_some_and(|k| i % k == k - 1) {
                        "estimator"
                    } else {
                        "peer"
                    }
                    .into(),
                ),
                addr: None,
                sensor: None,
                imu_csv: None,
                position_m: None,
                lever_arm_m: None,
            })
            .collect();
        raw.edge = edges
            .into_iter()
            .map(|(a, b)| super::toml::RawEdge {
                nodes: vec![a as i64, b as i64],
                directed: None,
                loss: None,
                delay_ms: None,
                jitter_ms: None,
                jitter: None,
                duplicate: None,
                corrupt: None,
            })
            .collect();
        raw
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn graphs_have_their_edges() {
        assert_eq!(ring(4), vec![(0, 1), (1, 2), (2, 3), (3, 0)]);
        assert_eq!(ring(2), vec![(0, 1)]);
        // 3 wide, 7 nodes: rows 0-2, 3-5, 6.
        assert_eq!(
            grid(7, 3),
            vec![(0, 1), (0, 3), (1, 2), (1, 4), (2, 5), (3, 4), (3, 6), (4, 5)]
        );
        assert_eq!(complete(4).len(), 6);
        for n in [2, 10, 50, 200] {
            assert!(connected(n, &random_geometric(n, 3)), "{n}");
        }
    }
}
