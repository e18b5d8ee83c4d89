//! Fingerprints that tie a generated file to its description and generator.
//!
//! A generated file is fresh when the fingerprint in its header equals the
//! fingerprint of the current TOML text and generator. Checking that needs
//! no Symbolica, so builds of an up-to-date checkout never start it.

use sha2::{Digest, Sha256};

/// The generator's sources (every file under `src/`, found by the build
/// script, and `Cargo.toml`, which pins Symbolica's version), by path: any
/// change to them changes every fingerprint, so output produced by an
/// older generator is never taken as fresh.
const GENERATOR_SOURCES: &[(&str, &str)] =
    include!(concat!(env!("OUT_DIR"), "/generator_sources.rs"));

/// Marker of the header line that carries the fingerprint.
pub const FINGERPRINT_PREFIX: &str = "// fingerprint: ";

/// The generator's version: crate version plus a hash of its sources.
pub fn generator_version() -> String {
    let mut hasher = Sha256::new();
    for (path, source) in GENERATOR_SOURCES {
        hasher.update(path.as_bytes());
        hasher.update([0]);
        hasher.update(normalize_newlines(source).as_bytes());
        hasher.update([0]);
    }
    format!(
        "{} ({})",
        env!("CARGO_PKG_VERSION"),
        &hex(&hasher.finalize())[..12]
    )
}

/// Fingerprint of a description's text under the current generator.
pub fn fingerprint(toml_source: &str) -> String {
    let mut hasher = Sha256::new();
    hasher.update(normalize_newlines(toml_source).as_bytes());
    hasher.update([0]);
    hasher.update(generator_version().as_bytes());
    hex(&hasher.finalize())[..32].to_string()
}

/// The fingerprint recorded in a generated file's header, if any.
pub fn recorded_fingerprint(generated: &str) -> Option<&str> {
    generated
        .lines()
        .take(12)
        .find_map(|line| line.strip_prefix(FINGERPRINT_PREFIX))
        .map(|rest| rest.split_whitespace().next().unwrap_or(""))
}

/// Whether `generated` was produced from `toml_source` by this generator.
pub fn is_fresh(toml_source: &str, generated: &str) -> bool {
    recorded_fingerprint(generated) == Some(fingerprint(toml_source).as_str())
}

fn normalize_newlines(text: &str) -> String {
    text.replace("\r\n", "\n")
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fingerprint_ignores_line_endings_but_not_content() {
        assert_eq!(fingerprint("a = 1\n"), fingerprint("a = 1\r\n"));
        assert_ne!(fingerprint("a = 1\n"), fingerprint("a = 2\n"));
    }

    #[test]
    fn every_generator_source_is_covered() {
        let paths: Vec<&str> = GENERATOR_SOURCES.iter().map(|(p, _)| *p).collect();
        for required in [
            "Cargo.toml",
            "src/support.rs",
            "src/emit.rs",
            "src/recursive/mod.rs",
        ] {
            assert!(
                paths.contains(&required),
                "{required} missing from {paths:?}"
            );
        }
        let on_disk = std::fs::read_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/src"))
            .unwrap()
            .filter(|e| {
                e.as_ref()
                    .unwrap()
                    .path()
                    .extension()
                    .is_some_and(|x| x == "rs")
            })
            .count();
        let top_level = paths.iter().filter(|p| p.matches('/').count() == 1).count();
        assert_eq!(top_level, on_disk);
    }

    #[test]
    fn recorded_fingerprint_is_read_from_the_header() {
        let f = fingerprint("x");
        let file =
            format!("// header\n{FINGERPRINT_PREFIX}{f} (toml sha256 + generator)\nfn x() {{}}\n");
        assert!(is_fresh("x", &file));
        assert!(!is_fresh("y", &file));
        assert_eq!(recorded_fingerprint("fn x() {}"), None);
    }
}
