//! A prismatic axis end to end, as a user runs it: the virtual robot
//! records the shipped lift-and-arm, upright and turned into a gantry (its
//! linear axis horizontal), whose axis has more viscous friction and a
//! force offset than its description says, and `sdnn diagnose` with no
//! flags names both, in N s/m and N.

use crate::util::{Dir, root, sdnn, sdnn_json};

/// The shipped lift with `effects` on its axis, turned along x for a
/// gantry.
fn lift(effects: &str, gantry: bool) -> String {
    let lift = std::fs::read_to_string(root().join("models/lift_arm.toml")).unwrap();
    let nominal = "effects = { armature = 2.0, viscous = 40.0, coulomb = 12.0 }";
    assert!(
        lift.contains(nominal) && lift.contains("axis = [0.0, 0.0, 1.0]\nlimits = { lower = 0.0")
    );
    let axis = if gantry {
        "1.0, 0.0, 0.0"
    } else {
        "0.0, 0.0, 1.0"
    };
    lift.replacen(
        "axis = [0.0, 0.0, 1.0]\nlimits = { lower = 0.0",
        &format!("axis = [{axis}]\nlimits = {{ lower = 0.0"),
        1,
    )
    .replacen(nominal, effects, 1)
}

#[test]
fn viscous_friction_and_a_force_offset_on_a_gantry_axis_are_named() {
    hidden_friction_and_offset_are_named(true);
}

/// Upright, the offset is a constant force beside the constant weight the
/// lift carries (mass on an axis no other joint feels would fit it as
/// well): the joint's own effect is named.
#[test]
fn viscous_friction_and_a_force_offset_on_a_lift_are_named() {
    hidden_friction_and_offset_are_named(false);
}

fn hidden_friction_and_offset_are_named(gantry: bool) {
    let dir = Dir::new();
    let model = dir.write(
        "axis.toml",
        &lift(
            "effects = { armature = 2.0, viscous = 40.0, coulomb = 12.0 }",
            gantry,
        ),
    );
    let plant = dir.write(
        "axis_plant.toml",
        &lift(
            "effects = { armature = 2.0, viscous = 90.0, coulomb = 12.0, offset = 8.0 }",
            gantry,
        ),
    );
    let recordings = dir.path().join("recordings");
    let path = |p: &std::path::Path| p.to_str().unwrap().to_string();
    let run = sdnn(&[
        "simulate",
        "--plant",
        &path(&plant),
        "--nominal",
        &path(&model),
        "--count",
        "3",
        "--out",
        &path(&recordings),
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let data: Vec<String> = (1..=3)
        .map(|k| path(&recordings.join(format!("trajectory_{k:02}.csv"))))
        .collect();
    let mut args = vec!["diagnose", "--model", model.to_str().unwrap()];
    args.push("--data");
    args.extend(data.iter().map(String::as_str));
    let text = sdnn(&args);
    let text = String::from_utf8_lossy(&text.stdout).to_string();
    args.extend(["--format", "json"]);
    let report = sdnn_json(&args);
    assert_eq!(report["joint_kinds"][0], "prismatic");
    let effects = report["effects"].as_array().unwrap();
    let named = |kind: &str| {
        effects
            .iter()
            .find(|e| e["kind"] == kind && e["joint"] == 1)
            .unwrap_or_else(|| panic!("{kind} on the axis not named:\n{text}"))
    };
    let viscous = named("viscous_friction")["parameters"]["coefficient"]
        .as_f64()
        .unwrap();
    let offset = named("torque_offset")["parameters"]["offset"]
        .as_f64()
        .unwrap();
    assert!(
        (viscous - 50.0).abs() < 0.15 * 50.0,
        "viscous {viscous}:\n{text}"
    );
    assert!(
        (offset - 8.0).abs() < 0.15 * 8.0,
        "offset {offset}:\n{text}"
    );
    for unit in [" N s/m (95% CI", " N (95% CI"] {
        assert!(text.contains(unit), "{unit}:\n{text}");
    }
    // --apply writes both into the axis's effects, and the gap shrinks.
    let mse = |model: &std::path::Path| -> f64 {
        let mut args = vec!["evaluate", "--model", model.to_str().unwrap(), "--data"];
        args.extend(data.iter().map(String::as_str));
        args.extend(["--format", "json"]);
        sdnn_json(&args)["mse"][0].as_f64().unwrap()
    };
    let before = mse(&model);
    let mut apply = vec!["diagnose", "--model", model.to_str().unwrap(), "--apply"];
    apply.push("--data");
    apply.extend(data.iter().map(String::as_str));
    let run = sdnn(&apply);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let applied = std::fs::read_to_string(&model).unwrap();
    assert!(applied.contains("offset = "), "{applied}");
    let after = mse(&model);
    assert!(after < 0.3 * before, "joint 1 MSE {before} -> {after}");
    assert!(!text.contains("N m s/rad"), "{text}");
}

/// `--angles deg` would read a prismatic joint's metres as degrees: refused.
#[test]
fn degrees_are_refused_for_a_model_with_a_prismatic_joint() {
    let dir = Dir::new();
    let states = dir.write(
        "states.csv",
        "q1,q2,q3,q4,qd1,qd2,qd3,qd4,qdd1,qdd2,qdd3,qdd4\n0.1,10,20,30,0,0,0,0,0,0,0,0\n",
    );
    let run = sdnn(&[
        "tau",
        "--model",
        "lift_arm",
        "--angles",
        "deg",
        "--input",
        states.to_str().unwrap(),
    ]);
    assert_eq!(run.status.code(), Some(2));
    let message = String::from_utf8_lossy(&run.stderr);
    assert!(
        message.contains("joint 1") && message.contains("prismatic"),
        "{message}"
    );
}
