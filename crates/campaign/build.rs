//! The git commit simnet is built from, when the source is a git checkout: `SIMNET_GIT_COMMIT` for the provenance
//! a campaign's manifest records.

use std::path::Path;
use std::process::Command;

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    // This crate is crates/engine of the workspace.
    let git = Path::new("../../.git");
    if !git.is_dir() {
        return;
    }
    // Rebuilt when HEAD moves: a commit rewrites the ref HEAD names.
    println!("cargo:rerun-if-changed=../../.git/HEAD");
    if let Ok(head) = std::fs::read_to_string(git.join("HEAD")) {
        if let Some(r) = head.strip_prefix("ref: ") {
            if git.join(r.trim()).exists() {
                println!("cargo:rerun-if-changed=../../.git/{}", r.trim());
            }
        }
    }
    if git.join("packed-refs").exists() {
        println!("cargo:rerun-if-changed=../../.git/packed-refs");
    }
    let Ok(out) = Command::new("git").args(["rev-parse", "HEAD"]).output() else {
        return;
    };
    let commit = String::from_utf8_lossy(&out.stdout).trim().to_string();
    if out.status.success() && commit.len() == 40 && commit.chars().all(|c| c.is_ascii_hexdigit()) {
        println!("cargo:rustc-env=SIMNET_GIT_COMMIT={commit}");
    }
}
