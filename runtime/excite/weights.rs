//! `--from DIAGNOSIS.json`: the parameters a diagnosis found ambiguous or
//! poorly determined, as the regressor names them.
//!
//! Read from the JSON report (`sdnn diagnose --format json`): every named
//! effect that lists others it is `ambiguous_with` (both sides), the pairs
//! its `identifiability` calls confounded, and the effects a note calls
//! poorly determined or not identifiable. An effect of joint j maps to its
//! column (`viscous{j}`, `offset{j}`, ...); a payload or a link's inertial
//! error of link k to the link's mass and first moments (`m{k}`, `mx{k}`,
//! `my{k}`, `mz{k}`).

use anyhow::{Context, Result};
use serde_json::Value;

/// The weighted parameter names (sorted, without repeats).
pub fn from_diagnosis(text: &str, source: &str, links: &[String]) -> Result<Vec<String>> {
    let json: Value = serde_json::from_str(text).with_context(|| {
        format!("{source}: not a diagnosis JSON report (`sdnn diagnose --format json`)")
    })?;
    let effects = json
        .get("effects")
        .and_then(Value::as_array)
        .with_context(|| format!("{source}: no `effects` list: not a diagnosis JSON report (`sdnn diagnose --format json`)"))?;
    let mut names = Vec::new();
    for effect in effects {
        let label = effect_label(effect);
        let ambiguous = effect
            .get("ambiguous_with")
            .and_then(Value::as_array)
            .cloned()
            .unwrap_or_default();
        if !ambiguous.is_empty() {
            names.extend(columns(&label, links));
        }
        for other in ambiguous.iter().filter_map(Value::as_str) {
            names.extend(columns(other, links));
        }
    }
    let confounded = json
        .pointer("/identifiability/confounded")
        .and_then(Value::as_array);
    for pair in confounded.into_iter().flatten() {
        for side in ["first", "second"] {
            if let Some(label) = pair.get(side).and_then(Value::as_str) {
                names.extend(columns(label, links));
            }
        }
    }
    for note in json
        .get("notes")
        .and_then(Value::as_array)
        .into_iter()
        .flatten()
        .filter_map(Value::as_str)
    {
        let lower = note.to_lowercase();
        if [
            "poorly determined",
            "not identifiable",
            "barely",
            "tell them apart",
        ]
        .iter()
        .any(|w| lower.contains(w))
        {
            names.extend(columns(note, links));
        }
    }
    names.sort();
    names.dedup();
    Ok(names)
}

/// Whether any of the weighted parameters needs samples at rest: a torque
/// offset or direction-dependent friction, which only rests tell apart.
pub fn needs_rests(names: &[String]) -> bool {
    names
        .iter()
        .any(|n| n.starts_with("offset") || n.starts_with("coulomb_asymmetry"))
}

/// "kind on joint N" or "kind of link N" from an effect object.
fn effect_label(effect: &Value) -> String {
    let kind = effect
        .get("kind")
        .and_then(Value::as_str)
        .unwrap_or_default();
    match (
        effect.get("joint").and_then(Value::as_u64),
        effect.get("link").and_then(Value::as_str),
    ) {
        (Some(j), _) => format!("{kind} on joint {j}"),
        (None, Some(link)) => format!("{kind} of link `{link}`"),
        _ => kind.to_string(),
    }
}

/// The regressor columns a text about an effect names.
fn columns(text: &str, links: &[String]) -> Vec<String> {
    let lower = text.to_lowercase();
    let mut out = Vec::new();
    if let Some(j) = number_after(&lower, "joint ") {
        let kinds = [
            ("viscous", "viscous"),
            ("coulomb_asymmetry", "coulomb_asymmetry"),
            ("direction", "coulomb_asymmetry"),
            ("coulomb", "coulomb"),
            ("armature", "armature"),
            ("offset", "offset"),
        ];
        for (word, column) in kinds {
            if lower.contains(word) {
                out.push(format!("{column}{j}"));
                if word == "coulomb_asymmetry" || word == "direction" {
                    break;
                }
            }
        }
    }
    if lower.contains("payload") || lower.contains("inertial") || lower.contains("mass") {
        let k = links
            .iter()
            .position(|l| text.contains(&format!("`{l}`")))
            .map(|k| k + 1)
            .or_else(|| number_after(&lower, "link "))
            .or_else(|| lower.contains("payload").then_some(links.len()));
        if let Some(k) = k {
            out.extend(["m", "mx", "my", "mz"].iter().map(|p| format!("{p}{k}")));
        }
    }
    out
}

/// The number right after `word` in `text`.
fn number_after(text: &str, word: &str) -> Option<usize> {
    let at = text.find(word)? + word.len();
    let digits: String = text[at..]
        .chars()
        .take_while(char::is_ascii_digit)
        .collect();
    digits.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn links() -> Vec<String> {
        ["link1", "link2", "link3"]
            .iter()
            .map(|s| s.to_string())
            .collect()
    }

    #[test]
    fn an_ambiguous_offset_weights_both_sides() {
        let json = r#"{"effects": [{"kind": "torque_offset", "joint": 2, "link": null,
            "ambiguous_with": ["coulomb_asymmetry on joint 2"]}], "notes": []}"#;
        let names = from_diagnosis(json, "d.json", &links()).unwrap();
        assert_eq!(names, vec!["coulomb_asymmetry2", "offset2"]);
    }

    #[test]
    fn a_poorly_determined_link_mass_weights_its_mass_and_first_moments() {
        let json = r#"{"effects": [], "notes": ["inertial_error of link `link3`: the mass is poorly determined by these data"]}"#;
        let names = from_diagnosis(json, "d.json", &links()).unwrap();
        assert_eq!(names, vec!["m3", "mx3", "my3", "mz3"]);
    }

    #[test]
    fn only_an_offset_or_direction_dependent_friction_needs_rests() {
        let names = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        assert!(needs_rests(&names(&["m3", "offset2"])));
        assert!(needs_rests(&names(&["coulomb_asymmetry1"])));
        assert!(!needs_rests(&names(&["m3", "mx3", "coulomb2", "viscous1"])));
    }

    #[test]
    fn a_file_that_is_no_diagnosis_is_named() {
        let e = from_diagnosis("[1, 2]", "run.csv", &links()).unwrap_err();
        assert!(
            format!("{e:#}").contains("run.csv: no `effects` list"),
            "{e:#}"
        );
        let e = from_diagnosis("t,q1\n", "run.csv", &links()).unwrap_err();
        assert!(
            format!("{e:#}").contains("run.csv: not a diagnosis JSON"),
            "{e:#}"
        );
    }
}
