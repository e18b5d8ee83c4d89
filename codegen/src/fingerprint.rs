//! Fingerprints that tie a generated file to its description and generator.
//!
//! A generated file is fresh when the fingerprint in its header equals the
//! fingerprint of the current TOML text and generator. Checking that needs
//! no Symbolica, so builds of an up-to-date checkout never start it.

use sha2::{Digest, Sha256};

/// The generator's sources: any change to them changes every fingerprint,
/// so output produced by an older generator is never taken as fresh.
const GENERATOR_SOURCES: [&str; 8] = [
    include_str!("description.rs"),
    include_str!("reduce.rs"),
    include_str!("fingerprint.rs"),
    include_str!("lagrangian.rs"),
    include_str!("program.rs"),
    include_str!("recursive.rs"),
    include_str!("emit.rs"),
    include_str!("generate.rs"),
];

/// Marker of the header line that carries the fingerprint.
pub const FINGERPRINT_PREFIX: &str = "// fingerprint: ";

/// The generator's version: crate version plus a hash of its sources.
pub fn generator_version() -> String {
    let mut hasher = Sha256::new();
    for source in GENERATOR_SOURCES {
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
    fn recorded_fingerprint_is_read_from_the_header() {
        let f = fingerprint("x");
        let file =
            format!("// header\n{FINGERPRINT_PREFIX}{f} (toml sha256 + generator)\nfn x() {{}}\n");
        assert!(is_fresh("x", &file));
        assert!(!is_fresh("y", &file));
        assert_eq!(recorded_fingerprint("fn x() {}"), None);
    }
}
