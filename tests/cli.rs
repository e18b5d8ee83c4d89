//! The `sdnn` command line: outputs, errors and exit codes.

use crate::util::{Dir, sdnn};

#[test]
fn tau_command_evaluates_the_compiled_model() {
    let dir = Dir::new();
    let states = dir.write(
        "states.csv",
        "q1,q2,q3,qd1,qd2,qd3,qdd1,qdd2,qdd3\n0.1,0.2,0.3,0.4,0.5,0.6,0.7,0.8,0.9\n-1,0.5,2,0,0,0,0,0,0\n",
    );
    let out = dir.path().join("tau.csv");
    let run = sdnn(&[
        "tau",
        "--model",
        "kinova_gen3_lite_3dof",
        "--input",
        states.to_str().unwrap(),
        "--output",
        out.to_str().unwrap(),
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let written = std::fs::read_to_string(&out).unwrap();
    let mut lines = written.lines();
    assert_eq!(lines.next(), Some("tau1,tau2,tau3"));
    let model = sdnn::model("kinova_gen3_lite_3dof").unwrap();
    let expected = [
        model
            .tau(&[0.1, 0.2, 0.3], &[0.4, 0.5, 0.6], &[0.7, 0.8, 0.9])
            .unwrap(),
        model.tau(&[-1.0, 0.5, 2.0], &[0.0; 3], &[0.0; 3]).unwrap(),
    ];
    for (line, tau) in lines.zip(expected) {
        let values: Vec<f64> = line.split(',').map(|v| v.parse().unwrap()).collect();
        assert_eq!(values, tau.iter().copied().collect::<Vec<_>>());
    }
}

#[test]
fn tau_command_reads_degrees_when_asked() {
    let dir = Dir::new();
    let states = dir.write("s.csv", "q1,q2,qd1,qd2,qdd1,qdd2\n90,0,0,0,0,0\n");
    let run = sdnn(&[
        "tau",
        "--model",
        "planar_2link",
        "--input",
        states.to_str().unwrap(),
        "--angles",
        "deg",
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let stdout = String::from_utf8(run.stdout).unwrap();
    let tau =
        sdnn::models::planar_2link::tau(&[std::f64::consts::FRAC_PI_2, 0.0], &[0.0; 2], &[0.0; 2]);
    assert_eq!(stdout, format!("tau1,tau2\n{:?},{:?}\n", tau[0], tau[1]));
}

#[test]
fn bad_state_file_fails_with_file_row_and_column() {
    let dir = Dir::new();
    let states = dir.write(
        "bad.csv",
        "q1,q2,qd1,qd2,qdd1,qdd2\n0,0,0,0,0,0\n0,x,0,0,0,0\n",
    );
    let run = sdnn(&[
        "tau",
        "--model",
        "planar_2link",
        "--input",
        states.to_str().unwrap(),
    ]);
    assert_eq!(run.status.code(), Some(2));
    let stderr = String::from_utf8(run.stderr).unwrap();
    assert!(stderr.starts_with("sdnn: "), "{stderr}");
    assert!(
        stderr.contains("bad.csv") && stderr.contains("q2") && stderr.contains('3'),
        "{stderr}"
    );
}

#[test]
fn wrong_joint_count_and_unknown_model_are_errors() {
    let dir = Dir::new();
    let states = dir.write("s.csv", "q1,qd1,qdd1\n0,0,0\n");
    let run = sdnn(&[
        "tau",
        "--model",
        "planar_2link",
        "--input",
        states.to_str().unwrap(),
    ]);
    assert_eq!(run.status.code(), Some(2));
    let run = sdnn(&[
        "tau",
        "--model",
        "nope",
        "--input",
        states.to_str().unwrap(),
    ]);
    assert_eq!(run.status.code(), Some(2));
    let stderr = String::from_utf8(run.stderr).unwrap();
    assert!(
        stderr.contains("no compiled model named `nope`") && stderr.contains("planar_2link"),
        "{stderr}"
    );
}

#[test]
fn models_command_lists_models_as_json() {
    let run = sdnn(&["models", "--format", "json"]);
    assert!(run.status.success());
    let list: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    let names: Vec<&str> = list
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["name"].as_str().unwrap())
        .collect();
    assert!(names.contains(&"kinova_gen3_lite_3dof") && names.contains(&"planar_2link"));
}

#[test]
fn usage_errors_exit_2() {
    let run = sdnn(&["tau", "--model"]);
    assert_eq!(run.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&run.stderr).starts_with("sdnn: "));
}
