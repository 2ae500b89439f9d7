//! README and the book (`docs/src`): every chapter is in `SUMMARY.md` and every entry of it exists; every relative
//! link reaches a file, and every `#anchor` a heading of its page (slugged as GitHub and mdBook do); README stays a
//! front page.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// README and every page of the book.
pub(crate) fn pages() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(root().join("docs/src"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "md"))
        .collect();
    v.sort();
    v.insert(0, root().join("README.md"));
    v
}

/// A heading's anchor: lower case, spaces to `-`, every character but letters, digits, `-` and `_` dropped.
fn slug(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
            _ => None,
        })
        .collect()
}

fn anchors(text: &str) -> BTreeSet<String> {
    let mut fence = false;
    let mut out = BTreeSet::new();
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fence = !fence;
        } else if !fence && line.starts_with('#') {
            out.insert(slug(line.trim_start_matches('#')));
        }
    }
    out
}

/// Every `](target)` outside code fences.
fn links(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut fence = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fence = !fence;
            continue;
        }
        if fence {
            continue;
        }
        let mut rest = line;
        while let Some(i) = rest.find("](") {
            let after = &rest[i + 2..];
            let Some(j) = after.find(')') else { break };
            out.push(after[..j].to_string());
            rest = &after[j..];
        }
    }
    out
}

#[test]
fn every_link_of_readme_and_the_book_reaches_its_file_and_heading() {
    let mut broken = Vec::new();
    for page in pages() {
        let text = std::fs::read_to_string(&page).unwrap();
        for link in links(&text) {
            if link.starts_with("http://") || link.starts_with("https://") || link.starts_with("mailto:") {
                continue;
            }
            let (file, anchor) = link
                .split_once('#')
                .map_or((link.as_str(), None), |(f, a)| (f, Some(a)));
            let target = if file.is_empty() {
                page.clone()
            } else {
                page.parent().unwrap().join(file)
            };
            if !target.exists() {
                broken.push(format!("{}: {link}: no such file", page.display()));
                continue;
            }
            if let Some(a) = anchor {
                let t = std::fs::read_to_string(&target).unwrap_or_default();
                if !anchors(&t).contains(a) {
                    broken.push(format!(
                        "{}: {link}: no heading #{a} in {}",
                        page.display(),
                        target.display()
                    ));
                }
            }
        }
    }
    assert!(
        broken.is_empty(),
        "{} broken links:\n{}",
        broken.len(),
        broken.join("\n")
    );
}

#[test]
fn every_chapter_is_in_the_summary_and_every_entry_exists() {
    let dir = root().join("docs/src");
    let summary = std::fs::read_to_string(dir.join("SUMMARY.md")).unwrap();
    let listed: BTreeSet<String> = links(&summary).into_iter().collect();
    for l in &listed {
        assert!(dir.join(l).exists(), "SUMMARY.md lists {l}, which does not exist");
    }
    for page in pages().iter().skip(1) {
        let name = page.file_name().unwrap().to_string_lossy().into_owned();
        if name != "SUMMARY.md" {
            assert!(listed.contains(&name), "docs/src/{name} is not in SUMMARY.md");
        }
    }
}

#[test]
fn readme_is_a_front_page_with_the_two_commands_first() {
    let text = std::fs::read_to_string(root().join("README.md")).unwrap();
    assert!(text.lines().count() <= 250, "README has {} lines", text.lines().count());
    let first = text
        .split("```sh\n")
        .nth(1)
        .and_then(|b| b.split("```").next())
        .unwrap();
    assert_eq!(
        first.lines().collect::<Vec<_>>(),
        [
            "cargo run --release -- --topology ring3 --loss 0.2",
            "cargo test --locked"
        ]
    );
}

/// A path the book names as a file of the repository (`tests/…`, `src/…`) exists.
#[test]
fn the_repository_files_the_book_names_exist() {
    let mut missing = Vec::new();
    for page in pages() {
        let text = std::fs::read_to_string(&page).unwrap();
        for word in text.split(|c: char| c.is_whitespace() || "`()[],;:\"'".contains(c)) {
            let w = word.trim_end_matches('.');
            let named = [
                "src/",
                "crates/",
                "tests/",
                "benches/",
                "python/",
                "topologies/",
                "fuzz/",
                "docs/",
            ]
            .iter()
            .any(|p| w.starts_with(p));
            let file = Path::new(w).extension().is_some_and(|x| {
                ["rs", "py", "sh", "toml", "md", "ipynb", "png", "csv", "txt", "json"].contains(&x.to_str().unwrap())
            });
            if named && file && !w.contains('*') && !w.contains('<') && !root().join(w).exists() {
                missing.push(format!("{}: {w}", page.display()));
            }
        }
    }
    missing.sort();
    missing.dedup();
    assert!(
        missing.is_empty(),
        "{} paths that do not exist:\n{}",
        missing.len(),
        missing.join("\n")
    );
}

/// The book's generated pages are what `cargo xtask docs` writes from the code today: a key, a column or a field
/// added without them fails here.
#[test]
fn the_generated_pages_are_what_the_code_generates() {
    for (path, text) in simnet::report::outputs::book_pages() {
        let committed = std::fs::read_to_string(root().join(path)).unwrap_or_default();
        assert!(
            committed == text,
            "{path} is not what the code generates: run `cargo xtask docs`"
        );
    }
}

/// Every generated page is included by a chapter.
#[test]
fn every_generated_page_is_in_a_chapter() {
    let book: String = pages().iter().map(|p| std::fs::read_to_string(p).unwrap()).collect();
    for (path, _) in simnet::report::outputs::book_pages() {
        let page = path.trim_start_matches("docs/src/");
        assert!(
            book.contains(&format!("{{{{#include {page}}}}}")),
            "no chapter includes {page}"
        );
    }
}
