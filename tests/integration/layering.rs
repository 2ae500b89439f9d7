//! No module imports a module that imports it back: in every crate of the workspace (`src/`, `crates/*/src/`), at
//! every level (the crate's top modules, each module's children), the graph of which module names which
//! (`crate::a::…`, `super::b::…`, outside test code) has no cycle. A cycle fails with the modules in it and the lines
//! that close it. Between crates the compiler holds it: a crate cannot name a crate that depends on it.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The source folder of every crate in the workspace that is Rust library code.
fn roots() -> Vec<PathBuf> {
    let top = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let mut out = vec![top.join("src")];
    for e in std::fs::read_dir(top.join("crates")).unwrap() {
        let src = e.unwrap().path().join("src");
        if src.is_dir() {
            out.push(src);
        }
    }
    out
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// A file's module path: `src/node/wire.rs` is `node::wire`, `src/node/mod.rs` is `node`.
fn module_of(root: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(root).unwrap().with_extension("");
    let mut m: Vec<String> = rel.iter().map(|c| c.to_string_lossy().into_owned()).collect();
    if matches!(m.last().map(String::as_str), Some("mod" | "lib" | "main")) {
        m.pop();
    }
    m
}

/// The code of a file outside its test module and comments.
fn code(text: &str) -> String {
    let text = text.split("#[cfg(test)]").next().unwrap_or_default();
    text.lines()
        .map(|l| l.split("//").next().unwrap_or_default())
        .collect::<Vec<_>>()
        .join("\n")
}

/// Every path `prefix::a::b` names in `code`, as its segments.
fn paths_after(code: &str, prefix: &str) -> Vec<(Vec<String>, usize)> {
    let mut out = Vec::new();
    let mut from = 0;
    while let Some(i) = code[from..].find(prefix) {
        let at = from + i;
        from = at + prefix.len();
        let before = code[..at].chars().next_back();
        // A word that only ends in the prefix, or a later `super` of `super::super`.
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_') || code[..at].ends_with("::") {
            continue;
        }
        let mut segs = Vec::new();
        let mut rest = &code[from..];
        while let Some(r) = rest.strip_prefix("::") {
            let name: String = r
                .chars()
                .take_while(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || *c == '_')
                .collect();
            if name.is_empty() {
                break;
            }
            rest = &r[name.len()..];
            segs.push(name);
        }
        let line = code[..at].matches('\n').count() + 1;
        out.push((segs, line));
    }
    out
}

/// The strongly connected components of more than one module (Tarjan).
fn cycles(edges: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    struct T<'a> {
        edges: &'a BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<String, usize>,
        low: BTreeMap<String, usize>,
        stack: Vec<String>,
        on: BTreeSet<String>,
        out: Vec<Vec<String>>,
    }
    fn visit(t: &mut T, v: &str) {
        let i = t.index.len();
        t.index.insert(v.into(), i);
        t.low.insert(v.into(), i);
        t.stack.push(v.into());
        t.on.insert(v.into());
        for w in t.edges.get(v).into_iter().flatten() {
            if !t.index.contains_key(w) {
                visit(t, w);
                let l = t.low[v].min(t.low[w]);
                t.low.insert(v.into(), l);
            } else if t.on.contains(w) {
                let l = t.low[v].min(t.index[w]);
                t.low.insert(v.into(), l);
            }
        }
        if t.low[v] == t.index[v] {
            let mut comp = Vec::new();
            while let Some(w) = t.stack.pop() {
                t.on.remove(&w);
                let done = w == v;
                comp.push(w);
                if done {
                    break;
                }
            }
            if comp.len() > 1 {
                comp.sort();
                t.out.push(comp);
            }
        }
    }
    let mut t = T {
        edges,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        out: Vec::new(),
    };
    for v in edges.keys() {
        if !t.index.contains_key(v) {
            visit(&mut t, v);
        }
    }
    t.out
}

#[test]
fn no_module_imports_a_module_that_imports_it_back() {
    let roots = roots();
    assert!(roots.len() >= 2, "the core crate's sources are missing: {roots:?}");
    let found: Vec<String> = roots.iter().flat_map(|r| cycles_in(r)).collect();
    assert!(found.is_empty(), "import cycles:\n{}", found.join("\n"));
}

/// The cycles of one crate, each with its modules and the lines that close it.
fn cycles_in(root: &Path) -> Vec<String> {
    let mut files = Vec::new();
    rust_files(root, &mut files);
    // (from module, to module, where): every reference between modules outside test code.
    let mut refs: Vec<(Vec<String>, Vec<String>, String)> = Vec::new();
    for f in &files {
        let m = module_of(root, f);
        if m.last().is_some_and(|x| x == "tests") || m.first().is_some_and(|x| x == "main") {
            continue;
        }
        let text = code(&std::fs::read_to_string(f).unwrap());
        let at = |line: usize| format!("{}:{line}", f.strip_prefix(root.parent().unwrap()).unwrap().display());
        for (segs, line) in paths_after(&text, "crate") {
            refs.push((m.clone(), segs, at(line)));
        }
        for (segs, line) in paths_after(&text, "super") {
            // `super::super::x`: each `super` one level up.
            let ups = 1 + segs.iter().take_while(|s| *s == "super").count();
            let names: Vec<String> = segs.into_iter().skip_while(|s| s == "super").collect();
            let base = m[..m.len().saturating_sub(ups)].to_vec();
            refs.push((m.clone(), [base, names].concat(), at(line)));
        }
    }
    let parents: BTreeSet<Vec<String>> = files
        .iter()
        .map(|f| {
            let m = module_of(root, f);
            m[..m.len().saturating_sub(1)].to_vec()
        })
        .chain([Vec::new()])
        .collect();
    let mut found = Vec::new();
    for parent in &parents {
        let n = parent.len();
        let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
        let mut why: BTreeMap<(String, String), String> = BTreeMap::new();
        for (from, to, at) in &refs {
            if from.len() > n && to.len() > n && from[..n] == parent[..] && to[..n] == parent[..] && from[n] != to[n] {
                edges.entry(from[n].clone()).or_default().insert(to[n].clone());
                why.entry((from[n].clone(), to[n].clone()))
                    .or_insert_with(|| at.clone());
            }
        }
        for comp in cycles(&edges) {
            let lines: Vec<String> = why
                .iter()
                .filter(|((a, b), _)| comp.contains(a) && comp.contains(b))
                .map(|((a, b), at)| format!("    {a} → {b} ({at})"))
                .collect();
            let level = if parent.is_empty() {
                let dir = root.parent().unwrap();
                let rel = dir.strip_prefix(env!("CARGO_MANIFEST_DIR")).unwrap_or(dir);
                format!("the crate at ./{}", rel.display())
            } else {
                parent.join("::")
            };
            found.push(format!("in {level}: {}\n{}", comp.join(", "), lines.join("\n")));
        }
    }
    found
}

/// Files a reader can hold: no source file of any crate over 600 lines, and the node (`node/mod.rs`, what every
/// driver calls) and its endpoint (`node/endpoint/mod.rs`, the state machine) each within 500.
#[test]
fn no_source_file_is_over_600_lines_and_the_node_endpoint_is_within_500() {
    let mut long = Vec::new();
    for root in roots() {
        let mut files = Vec::new();
        rust_files(&root, &mut files);
        for f in files {
            let n = std::fs::read_to_string(&f).unwrap().lines().count();
            let limit = if f.ends_with("node/mod.rs") || f.ends_with("node/endpoint/mod.rs") {
                500
            } else {
                600
            };
            if n > limit {
                long.push(format!("{}: {n} lines (at most {limit})", f.display()));
            }
        }
    }
    assert!(long.is_empty(), "files too long:\n{}", long.join("\n"));
}

/// The workspace's crates, lowest first, with the crates none of their dependencies may be: each depends only on
/// the crates before it in this list, and only `simnet-net` (and the facade) on sockets and an async runtime.
const LAYERS: [(&str, &str, &[&str]); 6] = [
    ("simnet-core", "crates/core", NO_SOCKETS),
    ("simnet-engine", "crates/engine", NO_SOCKETS),
    ("simnet-net", "crates/net", &[]),
    ("simnet-campaign", "crates/campaign", NO_SOCKETS),
    ("simnet-studies", "crates/studies", NO_SOCKETS),
    ("simnet", ".", &[]),
];

/// What opens a socket or runs an event loop.
const NO_SOCKETS: &[&str] = &["tokio", "mio", "socket2", "libc"];

/// A crate's `[dependencies]`, by name (optional ones too; dev-dependencies are the tests').
fn dependencies(dir: &str) -> Vec<String> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(dir).join("Cargo.toml");
    let manifest: toml::Table = std::fs::read_to_string(&path).unwrap().parse().unwrap();
    let name = manifest["package"]["name"].as_str().unwrap().to_string();
    assert_eq!(
        name,
        LAYERS.iter().find(|l| l.1 == dir).unwrap().0,
        "{}",
        path.display()
    );
    manifest
        .get("dependencies")
        .and_then(|d| d.as_table())
        .map(|d| d.keys().cloned().collect())
        .unwrap_or_default()
}

#[test]
fn each_crate_depends_only_on_the_crates_below_it() {
    let mut wrong = Vec::new();
    for (i, (name, dir, forbidden)) in LAYERS.iter().enumerate() {
        for dep in dependencies(dir) {
            match LAYERS.iter().position(|l| l.0 == dep) {
                Some(j) if j >= i => wrong.push(format!("{name} depends on {dep}, a crate at or above it")),
                _ if forbidden.contains(&dep.as_str()) => wrong.push(format!("{name} depends on {dep}")),
                _ => {}
            }
        }
    }
    assert!(wrong.is_empty(), "layering broken:\n{}", wrong.join("\n"));
    // Every library crate of crates/ has its layer.
    for e in std::fs::read_dir(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("crates")).unwrap() {
        let dir = format!("crates/{}", e.unwrap().file_name().to_string_lossy());
        assert!(LAYERS.iter().any(|l| l.1 == dir), "{dir} is not in LAYERS");
    }
}

/// The node's endpoint never sees the truth: no file of `node/endpoint/` (its tests aside) names the truth, the
/// sensor that reads it, or the observer that scores against it; its testbed hands it samples and scores what it
/// hands out.
#[test]
fn the_node_endpoint_never_names_the_truth() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("crates/engine/src/node/endpoint");
    let mut files = Vec::new();
    rust_files(&dir, &mut files);
    assert!(files.len() > 5, "{} files in {}", files.len(), dir.display());
    let mut found = Vec::new();
    for f in files.iter().filter(|f| !f.ends_with("tests.rs")) {
        let text = std::fs::read_to_string(f).unwrap();
        for (i, line) in text.lines().enumerate() {
            let code = line.split("//").next().unwrap_or("");
            let words = code.split(|c: char| !(c.is_alphanumeric() || c == '_'));
            if let Some(w) = words
                .into_iter()
                .find(|w| ["Truth", "Scorer", "Probes", "Sensor", "Testbed"].contains(w))
            {
                found.push(format!("{}:{}: {w}", f.display(), i + 1));
            }
        }
    }
    assert!(
        found.is_empty(),
        "the endpoint names what only its testbed may:\n{}",
        found.join("\n")
    );
}
