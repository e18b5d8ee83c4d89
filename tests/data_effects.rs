//! Properties of the recording, not of the robot: a torque sensor's scale
//! and a delay between torque and state. The diagnosis names them with the
//! option that corrects the recording, `--apply` leaves the description
//! alone and prints the command that shows the gap close, and that command
//! does close it.

use sdnn::trajectory::{Trajectory, write_csv};

use crate::diagnose::raw_recordings;
use crate::util::{Dir, oracle, sdnn, sdnn_json};

const NOMINAL: &str = "kinova_gen3_lite_3dof";

/// Joint 2's torque logged 8% high and every torque 15 ms late.
fn distorted(recording: &Trajectory) -> Trajectory {
    let mut tau = recording.tau().clone();
    tau.column_mut(1).scale_mut(1.08);
    let shift = 15; // samples at 1 kHz
    let late = nalgebra::DMatrix::from_fn(tau.nrows(), tau.ncols(), |s, j| {
        tau[(s.saturating_sub(shift), j)]
    });
    recording.with_tau(late).unwrap()
}

#[test]
fn a_scaled_and_late_torque_is_named_corrected_and_closes_the_gap() {
    let dir = Dir::new();
    let recordings = raw_recordings(&oracle(NOMINAL), 3);
    let files = dir.recordings("r", recordings.iter().map(distorted));
    let mut args = vec!["diagnose", "--model", NOMINAL, "--format", "json", "--data"];
    args.extend(files.iter().map(String::as_str));
    let report = sdnn_json(&args);
    let effects = report["effects"].as_array().unwrap();
    let named: Vec<String> = effects
        .iter()
        .map(|e| format!("{} {}", e["kind"], e["joint"]))
        .collect();
    assert_eq!(effects.len(), 2, "{named:?}");
    let scale = effects
        .iter()
        .find(|e| e["kind"] == "torque_scale")
        .unwrap_or_else(|| panic!("{named:?}"));
    assert_eq!(scale["joint"], 2);
    let s = scale["parameters"]["scale"].as_f64().unwrap();
    assert!((s - 1.08).abs() < 0.01, "scale {s}");
    let delay = effects
        .iter()
        .find(|e| e["kind"] == "torque_delay")
        .unwrap_or_else(|| panic!("{named:?}"));
    let d = delay["parameters"]["delay"].as_f64().unwrap();
    // 15 ms late, read half a sample early by the simulator's zero-order hold.
    assert!((d - 0.0145).abs() < 0.0015, "delay {d}");

    // --apply: the description stays, the printed command corrects the data.
    let toml = dir.path().join("arm.toml");
    std::fs::copy(
        crate::util::root()
            .join("models")
            .join(format!("{NOMINAL}.toml")),
        &toml,
    )
    .unwrap();
    let before = std::fs::read_to_string(&toml).unwrap();
    let mut args = vec!["diagnose", "--model", NOMINAL, "--apply", "--toml"];
    args.push(toml.to_str().unwrap());
    args.push("--data");
    args.extend(files.iter().map(String::as_str));
    let run = sdnn(&args);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    assert_eq!(std::fs::read_to_string(&toml).unwrap(), before);
    assert!(!dir.path().join("arm.toml.bak").exists());
    let command = stderr
        .lines()
        .find_map(|l| l.trim().strip_prefix("sdnn evaluate "))
        .unwrap_or_else(|| panic!("no command printed: {stderr}"));
    assert!(command.contains("--torque-scale 2=1.08"), "{command}");
    assert!(command.contains("--torque-delay 0.01"), "{command}");
    let mse = |extra: &[&str]| -> Vec<f64> {
        let mut args = vec!["evaluate", "--model", NOMINAL, "--format", "json"];
        args.extend(extra);
        args.push("--data");
        args.extend(files.iter().map(String::as_str));
        sdnn_json(&args)["mse"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect()
    };
    let words: Vec<&str> = command.split_whitespace().collect();
    let corrections: Vec<&str> = words
        .windows(2)
        .filter(|w| w[0] == "--torque-scale" || w[0] == "--torque-delay")
        .flat_map(|w| w.iter().copied())
        .collect();
    let (raw, corrected) = (mse(&[]), mse(&corrections));
    for j in 0..3 {
        assert!(
            corrected[j] <= 0.3 * raw[j],
            "joint {}: {} -> {}",
            j + 1,
            raw[j],
            corrected[j]
        );
    }
}

/// "As logged" means the torque in the file, with or without a correction:
/// joint 2 logged 20% high and evaluated with `--torque-scale 2=1.2`, the
/// corrected MSE equals the unscaled recording's, and the MSE against the
/// torque as logged is 1.2^2 times it (the prediction scaled as the sensor
/// scales), not the corrected torque's.
#[test]
fn the_torque_as_logged_is_the_logged_torque_under_a_scale_correction() {
    let dir = Dir::new();
    let recording = &raw_recordings(&oracle("kinova_gen3_lite_3dof_plant"), 1)[0];
    let mut tau = recording.tau().clone();
    tau.column_mut(1).scale_mut(1.2);
    let (plain, scaled) = (dir.path().join("plain.csv"), dir.path().join("scaled.csv"));
    write_csv(&plain, recording).unwrap();
    write_csv(&scaled, &recording.with_tau(tau).unwrap()).unwrap();
    let evaluate = |path: &std::path::Path, extra: &[&str]| {
        let mut args = vec!["evaluate", "--model", NOMINAL, "--format", "json"];
        args.extend(extra);
        args.extend(["--data", path.to_str().unwrap()]);
        let report = sdnn_json(&args);
        let column = |name: &str| -> Vec<f64> {
            let values = report[name].as_array().unwrap();
            values.iter().map(|v| v.as_f64().unwrap()).collect()
        };
        (column("mse"), column("mse_torque_as_logged"))
    };
    let (mse, as_logged) = evaluate(&plain, &[]);
    let (corrected, corrected_as_logged) = evaluate(&scaled, &["--torque-scale", "2=1.2"]);
    for j in 0..3 {
        let factor = if j == 1 { 1.44 } else { 1.0 };
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * b.abs().max(1e-12);
        assert!(
            close(corrected[j], mse[j]),
            "joint {}: {corrected:?} {mse:?}",
            j + 1
        );
        assert!(
            close(corrected_as_logged[j], factor * as_logged[j]),
            "joint {}: {corrected_as_logged:?} {as_logged:?}",
            j + 1
        );
    }
}

/// Friction behind a torque sensor's scale: the fit meets it in the logged
/// torque (s times the robot's); the report gives the robot's value, which
/// `--apply` writes as reported. The plant's joint 2 has Coulomb friction
/// 0.55 N m and viscous 0.45 N m s/rad; its torque is logged 10% high.
#[test]
fn friction_behind_a_torque_scale_is_reported_as_the_robot_has_it() {
    let dir = Dir::new();
    let plant = oracle("kinova_gen3_lite_3dof_plant");
    let scaled = raw_recordings(&plant, 3).into_iter().map(|r| {
        let mut tau = r.tau().clone();
        tau.column_mut(1).scale_mut(1.1);
        r.with_tau(tau).unwrap()
    });
    let files = dir.recordings("r", scaled);
    let toml = dir.path().join("arm.toml");
    let source = crate::util::root()
        .join("models")
        .join(format!("{NOMINAL}.toml"));
    std::fs::copy(source, &toml).unwrap();
    let mut args = vec!["diagnose", "--model", NOMINAL, "--format", "json"];
    args.extend(["--apply", "--toml", toml.to_str().unwrap(), "--data"]);
    args.extend(files.iter().map(String::as_str));
    let report = sdnn_json(&args);
    let effects = report["effects"].as_array().unwrap();
    let on_joint_2 = |kind: &str| {
        effects
            .iter()
            .find(|e| e["kind"] == kind && e["joint"] == 2)
            .unwrap_or_else(|| panic!("no {kind} on joint 2: {effects:?}"))
    };
    let scale = on_joint_2("torque_scale")["parameters"]["scale"]
        .as_f64()
        .unwrap();
    assert!((scale - 1.1).abs() < 0.01, "scale {scale}");
    let level = on_joint_2("coulomb_friction")["parameters"]["level"]
        .as_f64()
        .unwrap();
    assert!((level - 0.55).abs() < 0.05 * 0.55, "Coulomb level {level}");
    let written = std::fs::read_to_string(&toml).unwrap();
    assert!(written.contains(&format!("coulomb = {level}")), "{written}");
}
