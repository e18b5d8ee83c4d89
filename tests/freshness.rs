//! Committed generated code cannot go stale: every description's generated
//! file records the fingerprint of the TOML text and the generator. This
//! recomputes it (no Symbolica) and fails with the refresh command.

use codegen::fingerprint::{fingerprint, recorded_fingerprint};

use crate::util::root;

#[test]
fn generated_models_are_fresh() {
    let models = root().join("models");
    let mut stale = Vec::new();
    let mut count = 0;
    for entry in std::fs::read_dir(&models).unwrap() {
        let toml = entry.unwrap().path();
        if toml.extension().is_none_or(|x| x != "toml") {
            continue;
        }
        count += 1;
        let name = toml.file_stem().unwrap().to_string_lossy().to_string();
        let generated = models.join(codegen::generated_file_name(&name));
        let source = std::fs::read_to_string(&toml).unwrap();
        let code = std::fs::read_to_string(&generated).unwrap_or_default();
        if recorded_fingerprint(&code) != Some(fingerprint(&source).as_str()) {
            stale.push(format!(
                "models/generated/{name}.rs is stale or missing: run `cargo build` (or \
                 `cargo run --release -p sdnn-codegen -- models/{name}.toml`) and commit \
                 models/generated/{name}.rs with models/{name}.toml"
            ));
        }
    }
    assert!(
        count >= 2,
        "expected the shipped models in {}",
        models.display()
    );
    assert!(stale.is_empty(), "{}", stale.join("\n"));
}

#[test]
fn every_generated_file_has_a_description() {
    let generated = root().join("models/generated");
    for entry in std::fs::read_dir(&generated).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_stem().unwrap().to_string_lossy().to_string();
        assert!(
            root().join("models").join(format!("{name}.toml")).exists(),
            "models/generated/{name}.rs has no models/{name}.toml: delete it"
        );
    }
}
