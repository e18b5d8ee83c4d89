//! Effects the model already has with the wrong value (issue 26): the
//! diagnosis names the missing part as a correction of the model's value,
//! reports the total, and `--apply` writes that total.

use std::path::Path;

use crate::util::{Dir, root, sdnn, sdnn_json};

/// The shipped nominal model with `effects` (TOML inline tables) on its
/// joints 1-3.
fn with_effects(effects: [&str; 3]) -> String {
    let source = std::fs::read_to_string(root().join("models/kinova_gen3_lite_3dof.toml")).unwrap();
    let mut parts: Vec<String> = source.split("[[joints]]").map(str::to_string).collect();
    assert_eq!(parts.len(), 4, "three joints");
    for (part, effect) in parts[1..].iter_mut().zip(effects) {
        *part = format!("{}\neffects = {{ {effect} }}\n\n", part.trim_end());
    }
    parts.join("[[joints]]")
}

/// Each joint's effects in a description file.
fn joint_effects(path: &Path) -> Vec<codegen::JointEffects> {
    let text = std::fs::read_to_string(path).unwrap();
    let description = codegen::Description::parse(&text, "m", path).unwrap();
    description
        .chain()
        .free_bodies()
        .map(|b| b.effects)
        .collect()
}

fn near(value: f64, truth: f64, tolerance: f64, what: &str) {
    assert!(
        (value - truth).abs() <= tolerance,
        "{what}: {value}, expected {truth}"
    );
}

/// The model has a quarter of the plant's ripple (6 cycles per revolution:
/// it was "none significant"), of its spring, Coulomb and viscous friction,
/// and a third of its offset: each is named as the missing part, with the
/// model's value and the total, and `--apply` writes the plant's values.
#[test]
fn effects_in_the_model_with_wrong_values_are_refit() {
    let dir = Dir::new();
    let plant = dir.write(
        "plant.toml",
        &with_effects([
            "spring = 2.0, spring_rest = 0.3",
            "ripple_sin = 0.4, ripple_cycles = 6, coulomb = 0.4",
            "viscous = 0.4, offset = 0.3",
        ]),
    );
    let model = dir.write(
        "model.toml",
        &with_effects([
            "spring = 0.5, spring_rest = 0.3",
            "ripple_sin = 0.1, ripple_cycles = 6, coulomb = 0.1",
            "viscous = 0.1, offset = 0.1",
        ]),
    );
    let out = dir.path().join("rec");
    let (plant, model, out) = (
        plant.to_str().unwrap(),
        model.to_str().unwrap(),
        out.to_str().unwrap(),
    );
    let run = sdnn(&["simulate", "--plant", plant, "--count", "3", "--out", out]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let data: Vec<String> = (1..=3)
        .map(|k| format!("{out}/trajectory_0{k}.csv"))
        .collect();
    let mut args = vec!["diagnose", "--model", model, "--data"];
    args.extend(data.iter().map(String::as_str));
    let d = sdnn_json(&[&args[..], &["--format", "json"]].concat());
    let effect = |kind: &str, joint: u64| {
        d["effects"]
            .as_array()
            .unwrap()
            .iter()
            .find(|e| e["kind"] == kind && e["joint"] == joint)
            .unwrap_or_else(|| panic!("{kind} on joint {joint} not named: {d}"))
            .clone()
    };
    let ripple = effect("torque_ripple", 2);
    near(
        ripple["parameters"]["sin"].as_f64().unwrap(),
        0.3,
        0.03,
        "missing ripple",
    );
    assert_eq!(ripple["parameters"]["cycles"], 6.0);
    assert_eq!(ripple["modelled"]["sin"], 0.1);
    near(
        ripple["total"]["sin"].as_f64().unwrap(),
        0.4,
        0.03,
        "ripple in all",
    );
    let cases = [
        ("joint_spring", 1, "stiffness", 2.0),
        ("coulomb_friction", 2, "level", 0.4),
        ("viscous_friction", 3, "coefficient", 0.4),
        ("torque_offset", 3, "offset", 0.3),
    ];
    for (kind, joint, parameter, truth) in cases {
        let total = effect(kind, joint)["total"][parameter].as_f64();
        near(total.unwrap_or(f64::NAN), truth, 0.05 * truth, kind);
    }
    let text = sdnn(&args);
    let report = String::from_utf8_lossy(&text.stdout);
    assert!(
        report.contains("sin 0.100 N m: cos"),
        "the model's value and the total are reported: {report}"
    );
    let applied = sdnn(&[&args[..], &["--apply"]].concat());
    assert!(
        applied.status.success(),
        "{}",
        String::from_utf8_lossy(&applied.stderr)
    );
    let effects = joint_effects(Path::new(model));
    near(effects[0].spring, 2.0, 0.1, "applied spring");
    near(effects[0].spring_rest, 0.3, 0.01, "applied spring rest");
    near(effects[1].ripple_sin, 0.4, 0.03, "applied ripple");
    assert_eq!(effects[1].ripple_cycles, 6.0);
    near(effects[1].coulomb, 0.4, 0.02, "applied Coulomb friction");
    near(effects[2].viscous, 0.4, 0.02, "applied viscous friction");
    near(effects[2].offset, 0.3, 0.015, "applied offset");
}
