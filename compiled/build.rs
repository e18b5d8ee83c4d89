//! Regenerates stale `models/*.toml` into `models/generated/*.rs` (Symbolica
//! runs only then) and writes the registry of compiled models to OUT_DIR.

use std::path::PathBuf;

use codegen::{Config, Outcome};

fn main() {
    // A directory: cargo re-runs this script when any file below it changes,
    // including added or removed descriptions.
    println!("cargo:rerun-if-changed=../models");
    // CI sets this to regenerate every model in memory and fail on any
    // difference from the committed text (nothing is written).
    println!("cargo:rerun-if-env-changed=SDNN_VERIFY_GENERATED");
    let verify = std::env::var_os("SDNN_VERIFY_GENERATED").is_some();
    let results = match Config::new("../models").check(verify).run() {
        Ok(results) => results,
        Err(e) => fail(&e),
    };
    let mut names = Vec::new();
    let mut errors = Vec::new();
    for result in results {
        match result {
            Ok(report) => {
                if let Outcome::Regenerated {
                    seconds,
                    operations,
                } = &report.outcome
                {
                    let ops: Vec<String> = operations.iter().map(ToString::to_string).collect();
                    println!(
                        "cargo:warning=regenerated {} in {seconds:.1} s (operations: {}); commit it with its TOML",
                        shown(&report.generated),
                        ops.join(", ")
                    );
                }
                if report.outcome == Outcome::Stale {
                    errors.push(format!(
                        "{} differs from what the generator now produces from {}; delete it, \
                         run `cargo build --release` (it regenerates the file) and commit the result",
                        shown(&report.generated),
                        shown(&report.toml)
                    ));
                }
                names.push(report.name);
            }
            Err(e) => errors.push(e),
        }
    }
    if !errors.is_empty() {
        fail(&errors.join("\n"));
    }
    let out = PathBuf::from(std::env::var_os("OUT_DIR").unwrap_or_default()).join("models.rs");
    if let Err(e) = std::fs::write(&out, codegen::registry(&names)) {
        fail(&format!("{}: {e}", out.display()));
    }
}

/// A path under `../models` as the repository root sees it.
fn shown(path: &std::path::Path) -> std::path::Display<'_> {
    path.strip_prefix("..").unwrap_or(path).display()
}

fn fail(message: &str) -> ! {
    eprintln!("error: {message}");
    std::process::exit(1);
}
