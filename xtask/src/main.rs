//! `cargo xtask docs`: the book's generated pages made again from the code — the topology file's keys
//! (`simnet::scenario::schema`) and the output files (`simnet::report::outputs`); with `--outputs`, every output the
//! book shows in full after a command made again by running the command (the long suite's book test, blessing);
//! with `--images`, its run plots rendered again (`docs/images.sh`, which needs Chromium). The fast suite fails while
//! a generated page differs from what this writes; the long suite while a command prints other than the book shows.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Each generated page and what writes it.
fn pages() -> [(&'static str, String); 2] {
    simnet::report::outputs::book_pages()
}

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("xtask/ is in the repository")
        .to_path_buf()
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let images = args.iter().any(|a| a == "--images");
    let outputs = args.iter().any(|a| a == "--outputs");
    match args.first().map(String::as_str) {
        Some("docs") if args[1..].iter().all(|a| a == "--images" || a == "--outputs") => {}
        _ => {
            eprintln!("usage: cargo xtask docs [--outputs] [--images]");
            return ExitCode::from(2);
        }
    }
    let root = root();
    for (path, text) in pages() {
        let file = root.join(path);
        let old = std::fs::read_to_string(&file).unwrap_or_default();
        if old == text {
            println!("{path}: unchanged");
            continue;
        }
        if let Err(e) = std::fs::write(&file, &text) {
            eprintln!("error: cannot write {}: {e}", file.display());
            return ExitCode::FAILURE;
        }
        println!("{path}: written");
    }
    let mut steps: Vec<(&str, std::process::Command)> = Vec::new();
    if outputs {
        let mut c = std::process::Command::new(env!("CARGO"));
        c.args([
            "test",
            "--locked",
            "--test",
            "integration",
            "every_shell_block",
            "--",
            "--ignored",
        ])
        .env("SIMNET_BLESS", "1");
        steps.push(("the book's command outputs", c));
    }
    if images {
        let mut c = std::process::Command::new("bash");
        c.arg(root.join("docs/images.sh"));
        steps.push(("docs/images.sh", c));
    }
    for (what, mut c) in steps {
        match c.current_dir(&root).status() {
            Ok(s) if s.success() => {}
            Ok(s) => {
                eprintln!("error: {what} failed ({s})");
                return ExitCode::FAILURE;
            }
            Err(e) => {
                eprintln!("error: cannot run {what}: {e}");
                return ExitCode::FAILURE;
            }
        }
    }
    ExitCode::SUCCESS
}
