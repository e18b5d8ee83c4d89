//! The generated files as artifacts: they compile in a `#![no_std]` crate
//! with no dependency (with and without FMA), the controller example builds,
//! and names from a description never become code.

use std::path::Path;
use std::process::Command;

use crate::util::root;

/// Builds the crate at `dir` with `rustflags` in its own target directory.
fn cargo_build(dir: &Path, target: &Path, rustflags: &str) {
    let output = Command::new(env!("CARGO"))
        .args(["build", "--offline", "--quiet"])
        .current_dir(dir)
        .env("CARGO_TARGET_DIR", target)
        .env("RUSTFLAGS", rustflags)
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .env_remove("CARGO_BUILD_RUSTFLAGS")
        .output()
        .expect("cargo runs");
    assert!(
        output.status.success(),
        "building {} with RUSTFLAGS={rustflags:?} failed:\n{}",
        dir.display(),
        String::from_utf8_lossy(&output.stderr)
    );
}

#[test]
fn every_generated_file_compiles_in_a_no_std_crate_without_dependencies() {
    let temp = tempfile::tempdir().unwrap();
    let krate = temp.path().join("bare");
    std::fs::create_dir_all(krate.join("src")).unwrap();
    std::fs::write(
        krate.join("Cargo.toml"),
        "[package]\nname = \"bare\"\nversion = \"0.1.0\"\nedition = \"2024\"\n\n[workspace]\n",
    )
    .unwrap();
    let mut lib = String::from("#![no_std]\n#![deny(warnings)]\n");
    let generated = root().join("models/generated");
    let mut files: Vec<_> = std::fs::read_dir(&generated)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    for (k, file) in files.iter().enumerate() {
        lib.push_str(&format!(
            "#[allow(clippy::all)]\npub mod model{k} {{ include!({:?}); }}\n",
            file.display().to_string()
        ));
    }
    std::fs::write(krate.join("src/lib.rs"), lib).unwrap();
    let target = temp.path().join("target");
    cargo_build(&krate, &target, "");
    if cfg!(target_arch = "x86_64") {
        cargo_build(&krate, &target, "-C target-feature=+fma");
    }
}

#[test]
fn the_controller_example_builds_without_symbolica() {
    let example = root().join("examples/controller");
    let temp = tempfile::tempdir().unwrap();
    cargo_build(&example, temp.path(), "");
    let manifest = std::fs::read_to_string(example.join("Cargo.toml")).unwrap();
    assert!(
        !manifest.contains("[dependencies]"),
        "the example must stand alone"
    );
}

#[test]
fn a_name_with_a_newline_is_refused_with_its_location() {
    let toml = "name = \"Arm\\npub fn injected() -> u32 { 42 }\\n//\"\n\
                [[links]]\nname = \"base\"\n";
    let error = codegen::Description::parse(toml, "arm", Path::new("arm.toml"))
        .expect_err("a control character in a name is refused");
    let text = error.to_string();
    assert!(text.contains("arm.toml") && text.contains("name"), "{text}");
    assert!(text.contains("U+000A"), "{text}");
}

#[test]
fn names_with_quotes_and_comment_ends_stay_inert_text() {
    let generated = root().join("models/generated");
    // Every name in a generated file sits in a string literal or an
    // escaped comment: no line outside the header starts with a name.
    for entry in std::fs::read_dir(&generated).unwrap() {
        let code = std::fs::read_to_string(entry.unwrap().path()).unwrap();
        let robot_line = code.lines().find(|l| l.starts_with("// Robot: ")).unwrap();
        assert!(robot_line.starts_with("// Robot: \""), "{robot_line}");
    }
    let toml = "name = \"Arm \\\"quoted\\\" */ end\"\n[[links]]\nname = \"base\"\n\
                [[links]]\nname = \"l1\"\nmass = 1.0\ninertia = { ixx = 1.0, iyy = 1.0, izz = 1.0 }\n\
                [[joints]]\nname = \"j1\"\ntype = \"revolute\"\nparent = \"base\"\nchild = \"l1\"\n";
    let description = codegen::Description::parse(toml, "arm", Path::new("arm.toml")).unwrap();
    assert_eq!(description.robot, "Arm \"quoted\" */ end");
}

#[test]
fn a_model_file_named_like_a_keyword_is_refused() {
    let error = codegen::description::check_model_name("type", Path::new("models/type.toml"))
        .expect_err("a keyword cannot name a module");
    assert!(
        error.contains("models/type.toml") && error.contains("keyword"),
        "{error}"
    );
    assert!(codegen::description::check_model_name("panda", Path::new("panda.toml")).is_ok());
}
