//! `sdnn-codegen`: regenerate model code explicitly, or check it is fresh.
//!
//! Usage: `sdnn-codegen [--check] [--force] [MODELS_DIR | FILE.toml ...]`
//! (default `models`). Exit code 0 when everything is fresh or written,
//! 1 when `--check` finds stale files, 2 on errors.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use codegen::{Config, Outcome};

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let check = args.iter().any(|a| a == "--check");
    let force = args.iter().any(|a| a == "--force");
    let paths: Vec<PathBuf> = args
        .iter()
        .filter(|a| !a.starts_with("--"))
        .map(PathBuf::from)
        .collect();
    if let Some(bad) = args
        .iter()
        .find(|a| a.starts_with("--") && *a != "--check" && *a != "--force")
    {
        eprintln!(
            "sdnn-codegen: unknown option `{bad}`; usage: sdnn-codegen [--check] [--force] [MODELS_DIR | FILE.toml ...]"
        );
        return ExitCode::from(2);
    }
    let results = match paths.as_slice() {
        [] => run_dir(Path::new("models"), check, force),
        [dir] if dir.is_dir() => run_dir(dir, check, force),
        files => files
            .iter()
            .map(|f| {
                let dir = f
                    .parent()
                    .filter(|p| !p.as_os_str().is_empty())
                    .unwrap_or(Path::new("."));
                Config::new(dir).check(check).force(force).run_one(f)
            })
            .collect(),
    };
    let mut status = ExitCode::SUCCESS;
    for result in results {
        match result {
            Ok(report) => match report.outcome {
                Outcome::Fresh => println!("fresh        {}", report.generated.display()),
                Outcome::Stale => {
                    println!(
                        "STALE        {} (regenerate it with `sdnn-codegen --force {}` or by deleting it and running `cargo build --release`, and commit the result)",
                        report.generated.display(),
                        report.toml.display()
                    );
                    status = ExitCode::from(1);
                }
                Outcome::Regenerated {
                    seconds,
                    operations,
                } => {
                    let ops: Vec<String> = operations.iter().map(ToString::to_string).collect();
                    println!(
                        "regenerated  {} in {seconds:.2} s (operations: {})",
                        report.generated.display(),
                        ops.join(", ")
                    );
                }
            },
            Err(e) => {
                eprintln!("sdnn-codegen: {e}");
                status = ExitCode::from(2);
            }
        }
    }
    status
}

fn run_dir(dir: &Path, check: bool, force: bool) -> Vec<Result<codegen::Report, String>> {
    match Config::new(dir).check(check).force(force).run() {
        Ok(results) => results,
        Err(e) => vec![Err(e)],
    }
}
