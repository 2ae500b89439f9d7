//! Every shell block of README and the book runs, as a user would paste it, in a scratch directory that holds the
//! repository's `topologies/` and `tests/data/`, with the `simnet` under test first on the PATH. A block right
//! followed by a `text` block must print it (wall times masked; a `…` line stands for any lines); one right followed
//! by a Markdown table must print that table among its lines. A block that
//! cannot run here says why in the comment above it: `<!-- book-test: skip REASON -->` (Docker, sudo, a package
//! install, a synopsis with placeholders), or `<!-- book-test: long MINUTES -->` for a block longer than the CI budget,
//! run only with `SIMNET_BOOK_LONG=1`. With `SIMNET_BLESS=1` (`cargo xtask docs --outputs`) a `text` block
//! without `…` lines that differs is written again with what the command printed. `$BOOK` is the book's source directory, for a block that cuts a file shown on
//! its page out of it.

use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A shell block of a page: where it is, its script, what it must print, and why it is not run.
struct Block {
    page: String,
    line: usize,
    script: String,
    expect: Option<String>,
    /// The lines of the page (0-based, end exclusive) of the `text` block it must print: what `SIMNET_BLESS=1`
    /// rewrites.
    text_at: Option<(usize, usize)>,
    skip: Option<String>,
    long: bool,
}

fn blocks(page: &Path) -> Vec<Block> {
    let text = std::fs::read_to_string(page).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let name = page.strip_prefix(root()).unwrap().display().to_string();
    let mut out = Vec::new();
    let mut i = 0;
    // Fenced blocks: (info, first line of the body, body).
    let fence_at = |i: usize| -> Option<(String, usize, String)> {
        let info = lines[i].strip_prefix("```")?;
        let end = (i + 1..lines.len()).find(|&j| lines[j].starts_with("```"))?;
        Some((info.trim().to_string(), end, lines[i + 1..end].join("\n")))
    };
    while i < lines.len() {
        let Some((info, end, body)) = fence_at(i) else {
            i += 1;
            continue;
        };
        if info == "sh" {
            let marker = (0..i)
                .rev()
                .map(|j| lines[j].trim())
                .find(|l| !l.is_empty())
                .and_then(|l| l.strip_prefix("<!-- book-test:"))
                .map(|l| l.trim_end_matches("-->").trim().to_string());
            let next = (end + 1..lines.len()).find(|&j| !lines[j].trim().is_empty());
            let table = |j: usize| {
                let rows: Vec<&str> = lines[j..].iter().take_while(|l| l.starts_with('|')).copied().collect();
                (!rows.is_empty()).then(|| format!("…\n{}\n…", rows.join("\n")))
            };
            let text_at = next.and_then(|j| match fence_at(j) {
                Some((info, e, _)) if info == "text" => Some((j + 1, e)),
                _ => None,
            });
            let expect = next.and_then(|j| match fence_at(j) {
                Some((info, _, b)) if info == "text" => Some(b),
                Some(_) => None,
                None => table(j),
            });
            out.push(Block {
                page: name.clone(),
                line: i + 1,
                script: body,
                expect,
                text_at,
                skip: marker
                    .as_deref()
                    .and_then(|m| m.strip_prefix("skip"))
                    .map(|r| r.trim().to_string()),
                long: marker.as_deref().is_some_and(|m| m.starts_with("long")),
            });
        }
        i = end + 1;
    }
    out
}

/// README's table of tasks: each `simnet …` command of its command column (one with a placeholder — `…`, a file of
/// the user's — is left out), and whether its row says it takes minutes.
fn readme_tasks() -> Vec<(String, bool)> {
    let text = std::fs::read_to_string(root().join("README.md")).unwrap();
    let at = text.find("| task | command |").expect("README's table of tasks");
    let mut out = Vec::new();
    for row in text[at..].lines().skip(2).take_while(|l| l.starts_with('|')) {
        let cells: Vec<&str> = row.split('|').collect();
        let long = cells.get(3).is_some_and(|c| c.contains("minutes"));
        for (k, code) in cells[2].split('`').enumerate() {
            if k % 2 == 1 && code.starts_with("simnet ") && !code.contains('…') && !code.contains("my.toml") {
                out.push((code.to_string(), long));
            }
        }
    }
    out
}

/// A scratch directory with the repository's inputs, and a PATH whose `simnet` (and `cargo run --release --`,
/// README's first command) is the binary under test.
fn scratch(tag: &str) -> (PathBuf, String) {
    let d = std::env::temp_dir().join(format!("simnet-book-{}-{tag}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(d.join("bin")).unwrap();
    std::fs::create_dir_all(d.join("tests")).unwrap();
    std::os::unix::fs::symlink(root().join("topologies"), d.join("topologies")).unwrap();
    std::os::unix::fs::symlink(root().join("tests/data"), d.join("tests/data")).unwrap();
    std::os::unix::fs::symlink(env!("CARGO_BIN_EXE_simnet"), d.join("bin/simnet")).unwrap();
    let path = format!(
        "{}:{}",
        d.join("bin").display(),
        std::env::var("PATH").unwrap_or_default()
    );
    (d, path)
}

/// Output with what differs between runs masked: the number before ` s wall` becomes `…`.
fn masked(s: &str) -> Vec<String> {
    s.lines()
        .map(|l| {
            let l = l.trim_end();
            let Some(at) = l.find(" s wall") else {
                return l.to_string();
            };
            let start = l[..at]
                .rfind(|c: char| !(c.is_ascii_digit() || c == '.'))
                .map_or(0, |i| i + 1);
            format!("{}…{}", &l[..start], &l[at..])
        })
        .collect()
}

/// `want`'s lines in `got`, in order, a `…` line standing for any run of lines.
fn matches(want: &[String], got: &[String]) -> bool {
    match want.split_first() {
        None => got.iter().all(|l| l.trim().is_empty()),
        Some((w, rest)) if w.trim() == "…" => (0..=got.len()).any(|k| matches(rest, &got[k..])),
        Some((w, rest)) => got.first().is_some_and(|g| g == w) && matches(rest, &got[1..]),
    }
}

#[test]
#[ignore = "long suite: every shell block of README and the book (.ci/run runs it)"]
fn every_shell_block_of_readme_and_the_book_runs_and_prints_what_it_shows() {
    let long = std::env::var_os("SIMNET_BOOK_LONG").is_some();
    let bless = std::env::var_os("SIMNET_BLESS").is_some();
    // (page, text block's lines, what the command printed): the blocks `SIMNET_BLESS=1` writes again.
    let mut blessed: Vec<(String, (usize, usize), String)> = Vec::new();
    let mut failed = Vec::new();
    let mut not_run = Vec::new();
    for (k, b) in super::docs::pages().iter().flat_map(|p| blocks(p)).enumerate() {
        let at = format!("{}:{}", b.page, b.line);
        if let Some(why) = &b.skip {
            not_run.push(format!("{at}: {why}"));
            continue;
        }
        if b.long && !long {
            not_run.push(format!("{at}: longer than the CI budget (SIMNET_BOOK_LONG=1 runs it)"));
            continue;
        }
        let (dir, path) = scratch(&k.to_string());
        // README's first command builds and runs the binary: here, the binary under test; its second is the test
        // suite this test belongs to.
        let script: Vec<String> = b
            .script
            .lines()
            .filter(|l| l.trim() != "cargo test --locked")
            .map(|l| l.replace("cargo run --release --", "simnet"))
            .collect();
        let out = run(&dir, &path, &script.join("\n"));
        let before = failed.len();
        let printed = String::from_utf8_lossy(&out.stdout).into_owned();
        let ok = out.status.success();
        check(&at, b.expect.as_deref(), out, &mut failed);
        // A text block without `…` lines is the whole output: blessed, it becomes what was printed (wall times
        // masked as the check masks them).
        let whole = b.expect.as_deref().is_some_and(|e| !e.lines().any(|l| l.trim() == "…"));
        if bless && ok && failed.len() > before && whole {
            if let Some(at_lines) = b.text_at {
                failed.pop();
                blessed.push((b.page.clone(), at_lines, masked(&printed).join("\n")));
            }
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
    // Each page's blocks from its last up, so that earlier line numbers hold.
    blessed.sort_by(|a, b| (&a.0, b.1).cmp(&(&b.0, a.1)));
    for (page, (from, to), text) in &blessed {
        let file = root().join(page);
        let old = std::fs::read_to_string(&file).unwrap();
        let mut lines: Vec<String> = old.lines().map(String::from).collect();
        lines.splice(from..to, text.lines().map(String::from));
        std::fs::write(&file, lines.join("\n") + "\n").unwrap();
        eprintln!("blessed {page}:{}", from + 1);
    }
    for (k, (command, minutes)) in readme_tasks().into_iter().enumerate() {
        let at = format!("README.md, table of tasks: {command}");
        if minutes && !long {
            not_run.push(format!("{at}: takes minutes (SIMNET_BOOK_LONG=1 runs it)"));
            continue;
        }
        let (dir, path) = scratch(&format!("task-{k}"));
        let out = run(&dir, &path, &command);
        check(&at, None, out, &mut failed);
        let _ = std::fs::remove_dir_all(&dir);
    }
    eprintln!("not run ({}):\n{}", not_run.len(), not_run.join("\n"));
    assert!(
        failed.is_empty(),
        "{} blocks failed:\n{}",
        failed.len(),
        failed.join("\n\n")
    );
}

fn run(dir: &Path, path: &str, script: &str) -> std::process::Output {
    Command::new("bash")
        .args(["-euo", "pipefail", "-c", script])
        .current_dir(dir)
        .env("PATH", path)
        // The book's own pages, for a block that takes a file the page shows (`sed -n … "$BOOK/page.md"`).
        .env("BOOK", root().join("docs/src"))
        .env_remove("RUST_LOG")
        .output()
        .unwrap()
}

fn check(at: &str, expect: Option<&str>, out: std::process::Output, failed: &mut Vec<String>) {
    let stdout = String::from_utf8_lossy(&out.stdout);
    if !out.status.success() {
        failed.push(format!(
            "{at}: exit {:?}\n{}",
            out.status.code(),
            String::from_utf8_lossy(&out.stderr)
        ));
    } else if let Some(want) = expect {
        if !matches(&masked(want), &masked(&stdout)) {
            failed.push(format!("{at}: printed\n{stdout}\ninstead of\n{want}"));
        }
    }
}
