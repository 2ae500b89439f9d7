//! Multi-host results: each `simnet node` writes its part (a `summary.json` of one node plus the raw counters of its
//! links), its trace and its estimates; `simnet collect` merges the parts into one summary, joins each link's sender
//! and receiver counters, and fuses the estimates step by step.

use std::collections::BTreeMap;
use std::io::{self, BufRead, Write};

use nalgebra::{DMatrix, DVector};

pub use super::summary::PartInfo;
use super::summary::{EstimatorSummary, LinkSummary, Summary, Transport};
use crate::estimate::Gaussian;
use crate::node::{StepEstimate, TraceRow};
use crate::observe::fusion::Observer;
use crate::observe::schemes::SchemeObserver;
use crate::observe::SchemeEstimate;

#[derive(Debug, thiserror::Error)]
pub enum PartError {
    #[error("{file}: {message}")]
    Bad { file: String, message: String },
    #[error("no node-*.json part found in {0}")]
    Empty(String),
    #[error("parts disagree: {0}")]
    Mismatch(String),
    #[error("{file}: cannot read: {source}")]
    Io { file: String, source: io::Error },
}

/// The first line of `estimates-<id>.csv`: each estimator's group holds its covariance (a file whose first line
/// is another holds x alone, as an earlier build wrote it).
const ESTIMATES_HEADER: &str = "# step,frame,n,truth[n],x[n],P[n*n][,estimator,x[n],P[n*n]]...";

/// `estimates-<id>.csv`: step, frame, truth, x and P (column-major) of the networked filter (`nan` throughout where
/// the node has none), then the name, x and P of each distributed estimator the node ran (P `nan` where it is not
/// known).
pub fn write_estimates(w: &mut impl Write, estimates: &[StepEstimate]) -> io::Result<()> {
    writeln!(w, "{ESTIMATES_HEADER}")?;
    for e in estimates {
        let n = e.truth.len();
        write!(w, "{},{},{}", e.step, e.frame, n)?;
        for v in e.truth.iter() {
            write!(w, ",{v:e}")?;
        }
        match &e.networked {
            Some(g) => g.x.iter().chain(g.P.iter()).try_for_each(|v| write!(w, ",{v:e}"))?,
            None => (0..n + n * n).try_for_each(|_| write!(w, ",nan"))?,
        }
        for s in &e.schemes {
            write!(w, ",{}", s.kind.name())?;
            for v in s.x.iter() {
                write!(w, ",{v:e}")?;
            }
            match &s.P {
                Some(cov) => cov.iter().try_for_each(|v| write!(w, ",{v:e}"))?,
                None => (0..n * n).try_for_each(|_| write!(w, ",nan"))?,
            }
        }
        writeln!(w)?;
    }
    Ok(())
}

pub fn read_estimates(r: impl BufRead, node: usize, file: &str) -> Result<Vec<StepEstimate>, PartError> {
    let bad = |line: usize, m: &str| PartError::Bad {
        file: file.to_string(),
        message: format!("line {line}: {m}"),
    };
    let mut out = Vec::new();
    // Whether each estimator's group carries its covariance: so from this build on (its first line says).
    let mut with_p = false;
    for (i, line) in r.lines().enumerate() {
        let line = line.map_err(|e| bad(i + 1, &e.to_string()))?;
        if i == 0 && line == ESTIMATES_HEADER {
            with_p = true;
        }
        if line.starts_with('#') || line.is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').collect();
        let num = |s: &str| {
            s.parse::<f64>()
                .map_err(|_| bad(i + 1, &format!("{} is not a number", crate::input::quoted(s))))
        };
        let int = |s: &str| {
            s.parse::<u64>()
                .map_err(|_| bad(i + 1, &format!("{} is not an integer", crate::input::quoted(s))))
        };
        if f.len() < 3 {
            return Err(bad(i + 1, "too few fields"));
        }
        let given = int(f[2])?;
        // Bounded by the line before it is squared: a damaged file gets an error, not an overflow. The estimators
        // follow in groups of a name, n values and, with `with_p`, n² more.
        let group = |n: usize| 1 + n + if with_p { n * n } else { 0 };
        let fits = |n: usize| {
            let filter = 3 + 2 * n + n * n;
            f.len() >= filter && (f.len() - filter).is_multiple_of(group(n))
        };
        let n = match usize::try_from(given) {
            Ok(n) if n <= f.len() && fits(n) => n,
            Ok(n) if n <= f.len() => {
                return Err(bad(
                    i + 1,
                    &format!(
                        "expected {} fields for n = {n}, and {} more per estimator",
                        3 + 2 * n + n * n,
                        group(n)
                    ),
                ));
            }
            _ => return Err(bad(i + 1, &format!("n = {given} is more than the line has fields"))),
        };
        let filter_end = 3 + 2 * n + n * n;
        let v: Vec<f64> = f[3..filter_end].iter().map(|s| num(s)).collect::<Result<_, _>>()?;
        let mut schemes = Vec::new();
        for g in f[filter_end..].chunks(group(n)) {
            let kind = crate::estimators::Kind::from_name(g[0])
                .ok_or_else(|| bad(i + 1, &format!("`{}` is not an estimator", g[0])))?;
            let v: Vec<f64> = g[1..].iter().map(|s| num(s)).collect::<Result<_, _>>()?;
            // A covariance written as `nan` throughout was not known.
            let cov =
                (v.len() > n && v[n..].iter().any(|p| !p.is_nan())).then(|| DMatrix::from_column_slice(n, n, &v[n..]));
            schemes.push(SchemeEstimate {
                kind,
                x: DVector::from_column_slice(&v[..n]),
                P: cov,
            });
        }
        out.push(StepEstimate {
            node,
            step: int(f[0])?,
            frame: int(f[1])?,
            truth: DVector::from_column_slice(&v[..n]),
            // A networked filter written as `nan` throughout was not there.
            networked: v[n..].iter().any(|x| !x.is_nan()).then(|| Gaussian {
                x: DVector::from_column_slice(&v[n..2 * n]),
                P: DMatrix::from_column_slice(n, n, &v[2 * n..]),
            }),
            diverged: false,
            schemes,
        });
    }
    Ok(out)
}

/// Parse a `trace.csv` back (for the plots of `simnet collect`).
/// The column names (as after `true_`) and the rows of the nodes' filters.
pub fn read_trace(r: impl BufRead, file: &str) -> Result<(Vec<String>, Vec<TraceRow>), PartError> {
    let bad = |line: usize, m: String| PartError::Bad {
        file: file.to_string(),
        message: format!("line {line}: {m}"),
    };
    let mut lines = r.lines();
    let header = match lines.next() {
        Some(h) => h.map_err(|e| bad(1, e.to_string()))?,
        None => return Ok(Default::default()),
    };
    let names: Vec<String> = header
        .split(',')
        .filter_map(|c| c.strip_prefix("true_"))
        .map(String::from)
        .collect();
    let cols = names.len();
    let fields = 4 + 3 * cols + 7;
    let mut out = Vec::new();
    for (i, line) in lines.enumerate() {
        let line = line.map_err(|e| bad(i + 2, e.to_string()))?;
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != fields {
            return Err(bad(i + 2, format!("expected {fields} fields, got {}", f.len())));
        }
        // Fused rows are recomputed from the estimates.
        let Some(filter) = crate::observe::Filter::from_name(f[3]) else {
            continue;
        };
        let num = |s: &str| -> Result<f64, PartError> {
            if s.is_empty() {
                Ok(f64::NAN)
            } else {
                s.parse()
                    .map_err(|_| bad(i + 2, format!("{} is not a number", crate::input::quoted(s))))
            }
        };
        let vals = |a: usize, b: usize| -> Result<Vec<f64>, PartError> { f[a..b].iter().map(|s| num(s)).collect() };
        let tail = 4 + 3 * cols;
        out.push(TraceRow {
            step: f[0].parse().map_err(|_| bad(i + 2, "bad step".into()))?,
            t: num(f[1])?,
            node: f[2].parse().map_err(|_| bad(i + 2, "bad node".into()))?,
            filter,
            truth: vals(4, 4 + cols)?,
            est: vals(4 + cols, 4 + 2 * cols)?,
            var: vals(4 + 2 * cols, tail)?,
            error: num(f[tail])?,
            trace_p_prior: num(f[tail + 1])?,
            trace_p_post: num(f[tail + 2])?,
            received: f[tail + 3]
                .split(';')
                .filter(|s| !s.is_empty())
                .filter_map(|s| s.parse().ok())
                .collect(),
            feasible: f[tail + 4] == "true",
            nees: num(f[tail + 5])?,
            diverged: f[tail + 6] == "true",
        });
    }
    Ok((names, out))
}

/// The datagrams a part's node refused with a bad tag, when it took none from any neighbour (a key not shared).
pub fn unheard(part: &Summary) -> Option<u64> {
    let info = part.part.as_ref()?;
    let refused: u64 = part.nodes.iter().map(|n| n.rejected.bad_tag).sum();
    let delivered: u64 = info.rx.iter().map(|(_, c)| c.delivered).sum();
    (refused > 0 && delivered == 0).then_some(refused)
}

/// Merge node parts into one summary; `estimates` (by node id) are fused step by step when given.
pub fn merge(
    parts: &[Summary],
    estimates: &BTreeMap<u32, Vec<StepEstimate>>,
) -> Result<(Summary, Observer), PartError> {
    let first = parts
        .first()
        .ok_or_else(|| PartError::Empty("the given directories".into()))?;
    let info = |s: &Summary| -> Result<PartInfo, PartError> {
        s.part
            .clone()
            .ok_or_else(|| PartError::Mismatch(format!("{} is a whole-run summary, not a node part", s.topology)))
    };
    for p in parts {
        // A part is a file anyone could have written: its figures are checked before they size or pace anything.
        if !(p.rate_hz > 0.0 && p.rate_hz <= crate::scenario::MAX_RATE_HZ) {
            return Err(PartError::Mismatch(format!(
                "a step rate of {} Hz is not one a run can have",
                crate::checks::num(p.rate_hz)
            )));
        }
        if p.topology != first.topology || p.seed != first.seed || p.rate_hz != first.rate_hz {
            return Err(PartError::Mismatch(format!(
                "`{}` seed {} at {} Hz vs `{}` seed {} at {} Hz",
                p.topology, p.seed, p.rate_hz, first.topology, first.seed, first.rate_hz
            )));
        }
    }
    let infos: Vec<PartInfo> = parts.iter().map(info).collect::<Result<_, _>>()?;
    let fusion = &infos[0].fusion;
    let n = fusion.angle_states.len();
    if n == 0 || fusion.error_rows.iter().any(|&r| r >= n) || (fusion.quaternion && fusion.error_rows.len() != 4) {
        return Err(PartError::Mismatch(format!(
            "node {}'s part describes no state its errors can be taken over",
            infos[0].node
        )));
    }
    if let Some(i) = infos.iter().find(|i| i.fusion != *fusion) {
        return Err(PartError::Mismatch(format!(
            "nodes {} and {} estimate different states",
            infos[0].node, i.node
        )));
    }
    for (id, es) in estimates {
        if let Some(e) = es
            .iter()
            .find(|e| e.truth.len() != n || e.schemes.iter().any(|s| s.x.len() != n))
        {
            return Err(PartError::Mismatch(format!(
                "node {id}'s estimates of step {} have {} states, the run's have {n}",
                e.step,
                e.truth.len()
            )));
        }
    }
    // One run's parts: the nodes agreed on its id in their hellos.
    if let Some(i) = infos.iter().find(|i| i.run != infos[0].run) {
        // No node took a datagram from any other, and every one refused some whose tag failed: they never agreed
        // on anything because they hold different keys.
        let refused: Option<Vec<u64>> = parts.iter().map(unheard).collect();
        if let Some(r) = refused {
            return Err(PartError::Mismatch(format!(
                "no node took a datagram from a neighbour ({} refused with a bad tag in all): do the nodes share a key?",
                r.iter().sum::<u64>()
            )));
        }
        let show = |r: Option<u64>| r.map_or("none".to_string(), |r| format!("{r:016x}"));
        return Err(PartError::Mismatch(format!(
            "the parts come from different runs: node {}'s is run {}, node {}'s is run {} (an earlier run's part?)",
            infos[0].node,
            show(infos[0].run),
            i.node,
            show(i.run)
        )));
    }
    let mut seen = std::collections::BTreeSet::new();
    if let Some(twice) = infos.iter().find(|i| !seen.insert(i.node)) {
        return Err(PartError::Mismatch(format!(
            "node {} has two parts (an earlier run's beside this one's?)",
            twice.node
        )));
    }
    missing_parts(first, &infos)?;
    let mut nodes: Vec<_> = parts.iter().flat_map(|p| p.nodes.clone()).collect();
    nodes.sort_by_key(|n| n.id);
    let mut links = Vec::new();
    for i in &infos {
        for (to, tx) in &i.links_out {
            let rx = infos
                .iter()
                .find(|q| q.node == *to)
                .and_then(|q| q.rx.iter().find(|(from, _)| *from == i.node).map(|(_, c)| *c))
                .unwrap_or_default();
            links.push(LinkSummary::join(i.node, *to, tx, &rx));
        }
    }
    links.sort_by_key(|l| (l.from, l.to));
    let fi = &infos[0];
    let mut observer = Observer::new(first.burn_in_steps, fi.fusion.clone(), true);
    if parts.iter().any(|p| !p.estimators.is_empty()) {
        observer = observer.with_schemes(SchemeObserver::of_parts(fi.fusion.clone(), first.burn_in_steps));
    }
    let mut by_step: BTreeMap<u64, Vec<StepEstimate>> = BTreeMap::new();
    for es in estimates.values() {
        for e in es {
            by_step.entry(e.step).or_default().push(e.clone());
        }
    }
    for (_, es) in by_step {
        observer.push(es);
    }
    observer.finish();
    let merged = Summary {
        simnet_version: first.simnet_version.clone(),
        topology: first.topology.clone(),
        source: first.source.clone(),
        model: first.model,
        seed: first.seed,
        clock: crate::report::summary::Clock::MultiHost,
        rate_hz: first.rate_hz,
        steps: infos.iter().map(|i| i.steps_done).max().unwrap_or(0),
        burn_in_steps: first.burn_in_steps,
        interrupted: parts.iter().any(|p| p.interrupted),
        transport: Transport {
            wall_s: parts.iter().map(|p| p.transport.wall_s).fold(0.0, f64::max),
            frames_resent: 0,
            kernel_drops: parts.iter().flat_map(|p| p.transport.kernel_drops.clone()).collect(),
            schedule: parts.iter().filter_map(|p| p.transport.schedule).reduce(|mut a, b| {
                a.merge(&b);
                a
            }),
        },
        socket_losses: 0,
        nodes,
        links,
        fused: observer.summary(),
        estimators: merge_estimators(parts, observer.schemes()),
        settings: first.settings.clone(),
        part: None,
        security: parts.iter().filter_map(|p| p.security.clone()).reduce(|mut a, b| {
            a.rejected.add(&b.rejected);
            a
        }),
        attacks: Vec::new(),
        attack_effect: Vec::new(),
        // One node per process splits the medium by sender: never a radio's.
        radio: None,
    };
    let mut merged = merged;
    merged.attacks = crate::report::summary::AttackSummary::merge(parts, &merged.links);
    Ok((merged, observer))
}

/// Every node of the run (its resolved scenario, which parts record) has a part: a missing one would read as a node
/// that never sent nor received, 100 % loss on its links.
fn missing_parts(first: &Summary, infos: &[PartInfo]) -> Result<(), PartError> {
    let Some(text) = first
        .settings
        .as_ref()
        .map(|s| s.scenario.as_str())
        .filter(|t| !t.is_empty())
    else {
        // A part from before parts recorded their scenario.
        return Ok(());
    };
    let Ok(raw) = toml::from_str::<crate::scenario::toml::RawTopology>(text) else {
        return Err(PartError::Mismatch("the parts' scenario does not read back".into()));
    };
    let ids: Vec<u32> = match &raw.generate {
        Some(g) => (0..g.nodes.unwrap_or(0).clamp(0, crate::scenario::graph::MAX_GENERATED) as u32).collect(),
        None => raw
            .node
            .iter()
            .enumerate()
            .map(|(i, n)| n.id.unwrap_or(i as i64).clamp(0, u32::MAX as i64) as u32)
            .collect(),
    };
    let have: std::collections::BTreeSet<u32> = infos.iter().map(|i| i.node).collect();
    let missing: Vec<String> = ids
        .iter()
        .filter(|id| !have.contains(id))
        .map(|id| format!("node-{id}.json"))
        .collect();
    if missing.is_empty() {
        Ok(())
    } else {
        Err(PartError::Mismatch(format!(
            "{} of the run's {} nodes have no part: {} (collect every node's directory)",
            missing.len(),
            ids.len(),
            missing.join(", ")
        )))
    }
}

/// Every part's estimators, node by node, with the traffic summed; the median over the nodes and the disagreement
/// from every node's estimates of each step (`schemes`, fed the parts' estimates files).
fn merge_estimators(parts: &[Summary], schemes: Option<&SchemeObserver>) -> BTreeMap<String, EstimatorSummary> {
    let mut out: BTreeMap<String, EstimatorSummary> = BTreeMap::new();
    for (name, e) in parts.iter().flat_map(|p| &p.estimators) {
        let m = out.entry(name.clone()).or_insert_with(|| EstimatorSummary {
            mean_error: None,
            median_error: None,
            ratio_to_centralized: None,
            disagreement: None,
            fused_error: None,
            diverged: 0,
            messages: 0,
            bytes: 0,
            delivered: None,
            nodes: Vec::new(),
        });
        m.nodes.extend(e.nodes.iter().cloned());
        m.messages += e.messages;
        m.bytes += e.bytes;
        m.diverged += e.diverged;
    }
    for (name, e) in out.iter_mut() {
        if let (Some(o), Some(kind)) = (schemes, crate::estimators::Kind::from_name(name)) {
            let a = o.agreement(kind);
            (e.median_error, e.disagreement, e.fused_error) = (a.median_error, a.disagreement, a.fused_error);
        }
        e.nodes.sort_by_key(|n| n.id);
        let errors: Vec<f64> = e.nodes.iter().filter_map(|n| n.figures.mean_error).collect();
        e.mean_error = (!errors.is_empty() && errors.len() == e.nodes.len())
            .then(|| errors.iter().sum::<f64>() / errors.len() as f64);
    }
    out
}

/// The parts found in some folders: each node's summary, its estimates and its trace rows.
#[derive(Debug, Default)]
pub struct Parts {
    pub summaries: Vec<Summary>,
    /// Networked estimates by node id.
    pub estimates: BTreeMap<u32, Vec<StepEstimate>>,
    pub rows: Vec<TraceRow>,
    /// The reported columns of the trace files.
    pub columns: Vec<String>,
}

/// Every `node-ID.json` in `dirs` (in name order) with the `estimates-ID.csv` and `trace-ID.csv` beside it.
pub fn read_parts(dirs: &[std::path::PathBuf]) -> Result<Parts, PartError> {
    let io_err = |p: &std::path::Path| {
        let file = p.display().to_string();
        move |source| PartError::Io { file, source }
    };
    let mut out = Parts::default();
    for dir in dirs {
        let mut names: Vec<std::path::PathBuf> = std::fs::read_dir(dir)
            .map_err(io_err(dir))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .collect();
        names.sort();
        for p in names {
            let name = p.file_name().and_then(|n| n.to_str()).unwrap_or_default().to_string();
            let Some(id) = name.strip_prefix("node-").and_then(|n| n.strip_suffix(".json")) else {
                continue;
            };
            let bad = |message: String| PartError::Bad {
                file: p.display().to_string(),
                message,
            };
            let id: u32 = id
                .parse()
                .map_err(|_| bad(format!("{} is not a node id", crate::input::quoted(id))))?;
            let text = crate::input::read_text(&p, crate::input::MAX_JSON).map_err(io_err(&p))?;
            let s: Summary = serde_json::from_str(&text).map_err(|e| bad(format!("not a node part: {e}")))?;
            let node_index = out.summaries.len();
            out.summaries.push(s);
            let est = dir.join(format!("estimates-{id}.csv"));
            if est.exists() {
                let f = crate::input::open_lines(&est, crate::input::MAX_TABLE).map_err(io_err(&est))?;
                let es = read_estimates(f, node_index, &est.display().to_string())?;
                out.estimates.insert(id, es);
            }
            let tr = dir.join(format!("trace-{id}.csv"));
            if tr.exists() {
                let f = crate::input::open_lines(&tr, crate::input::MAX_TABLE).map_err(io_err(&tr))?;
                let (names, r) = read_trace(f, &tr.display().to_string())?;
                if out.columns.is_empty() {
                    out.columns = names;
                }
                out.rows.extend(r);
            }
        }
    }
    if out.summaries.is_empty() {
        let dirs: Vec<String> = dirs.iter().map(|d| d.display().to_string()).collect();
        return Err(PartError::Empty(dirs.join(", ")));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A damaged estimates file is an error naming the line, never an overflow or a panic.
    #[test]
    fn damaged_estimates_are_errors() {
        for (text, says) in [
            ("0,0,18446744073709551615,1,2\n", "more than the line has fields"),
            ("0,0,1,1,2\n", "expected 6 fields for n = 1"),
            ("0,0,1,1,2,x\n", "`x` is not a number"),
            ("0,0\n", "too few fields"),
            ("0,0,1,1.5,2,0.25,icf\n", "and 2 more per estimator"),
            ("0,0,1,1.5,2,0.25,kalman,3\n", "`kalman` is not an estimator"),
            ("0,0,1,1.5,2,0.25,icf,y\n", "`y` is not a number"),
        ] {
            let e = read_estimates(text.as_bytes(), 0, "estimates-0.csv")
                .unwrap_err()
                .to_string();
            assert!(e.contains("line 1") && e.contains(says), "{text:?}: {e}");
        }
        // Under this build's first line, each estimator's group holds its covariance as well.
        let e = read_estimates(
            format!("{ESTIMATES_HEADER}\n0,0,1,1.5,2,0.25,icf,3\n").as_bytes(),
            0,
            "estimates-0.csv",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("line 2") && e.contains("and 3 more per estimator"), "{e}");
        let ok = read_estimates("0,0,1,1.5,2,0.25\n".as_bytes(), 0, "e.csv").unwrap();
        let g = ok[0].networked.as_ref().unwrap();
        assert_eq!((ok[0].truth[0], g.x[0], g.P[(0, 0)]), (1.5, 2.0, 0.25));
    }

    /// The estimators' estimates and covariances travel through the file unchanged (a covariance not known stays
    /// unknown, and so does a networked filter a node did not have); a file of an earlier build, with x alone, is
    /// read with none.
    #[test]
    fn estimates_round_trip_with_the_estimators() {
        use crate::estimators::Kind;
        let e = StepEstimate {
            node: 0,
            step: 7,
            frame: 1,
            truth: DVector::from_vec(vec![1.0, -2.5]),
            networked: Some(Gaussian {
                x: DVector::from_vec(vec![0.9, -2.4]),
                P: DMatrix::from_row_slice(2, 2, &[0.5, 0.1, 0.1, 0.25]),
            }),
            diverged: false,
            schemes: vec![
                SchemeEstimate {
                    kind: Kind::Icf,
                    x: DVector::from_vec(vec![1.0 / 3.0, 1e-300]),
                    P: Some(DMatrix::from_row_slice(2, 2, &[2.0, -0.5, -0.5, 1.0 / 7.0])),
                },
                SchemeEstimate {
                    kind: Kind::Ci,
                    x: DVector::from_vec(vec![-7.0, 2.0]),
                    P: None,
                },
            ],
        };
        let mut buf = Vec::new();
        write_estimates(&mut buf, std::slice::from_ref(&e)).unwrap();
        let back = read_estimates(buf.as_slice(), 0, "e.csv").unwrap();
        let b = &back[0];
        assert_eq!(back.len(), 1);
        assert_eq!(
            (b.step, b.frame, &b.truth, &b.networked),
            (e.step, e.frame, &e.truth, &e.networked)
        );
        assert_eq!(b.schemes, e.schemes);
        let none = StepEstimate {
            networked: None,
            ..e.clone()
        };
        let mut buf = Vec::new();
        write_estimates(&mut buf, std::slice::from_ref(&none)).unwrap();
        let back = read_estimates(buf.as_slice(), 0, "e.csv").unwrap();
        assert_eq!((&back[0].networked, &back[0].schemes), (&None, &e.schemes));
        let earlier = "# step,frame,n,truth[n],x[n],P[n*n][,estimator,x[n]]...\n7,1,1,1,0.9,0.5,icf,0.25\n";
        let back = read_estimates(earlier.as_bytes(), 0, "e.csv").unwrap();
        assert_eq!((back[0].schemes[0].x[0], &back[0].schemes[0].P), (0.25, &None));
    }
}
