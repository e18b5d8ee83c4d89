//! The `sdnn` command line: outputs, errors and exit codes.

use crate::util::{Dir, root, sdnn, sdnn_json};

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
    let list = sdnn_json(&["models", "--format", "json"]);
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

/// The committed Gen3 Lite descriptions are what `import-urdf` makes of
/// Kinova's URDF with the options their headers record.
#[test]
fn import_urdf_reproduces_the_committed_gen3_lite_models() {
    let urdf = root().join("data/gen3_lite/GEN3-LITE.urdf");
    let urdf = urdf.to_str().expect("utf-8 path");
    let tool = "END_EFFECTOR:mass=0.2018,com=2e-5;0.0024;0.052328,\
                inertia=0.000308449;0.000211325;0.000187185;-5e-8;-3.5e-8;-2.9196e-5";
    let cases: [(&str, Vec<&str>); 2] = [
        (
            "kinova_gen3_lite",
            vec!["--name", "Kinova Gen3 Lite (6 DOF, Kinova URDF)"],
        ),
        (
            "kinova_gen3_lite_3dof_locked",
            vec![
                "--lock",
                "J3=0",
                "--lock",
                "J4=0",
                "--lock",
                "J5=0",
                "--attach",
                tool,
                "--name",
                "Kinova Gen3 Lite (3 DOF, joints 4-6 locked, thesis tool)",
            ],
        ),
    ];
    for (model, options) in cases {
        let mut args = vec!["import-urdf", urdf, "--base", "BASE", "--tip", "DUMMY"];
        args.extend(options);
        let output = sdnn(&args);
        assert!(
            output.status.success(),
            "{}",
            String::from_utf8_lossy(&output.stderr)
        );
        let imported = String::from_utf8(output.stdout).expect("utf-8 TOML");
        let path = root().join(format!("models/{model}.toml"));
        let committed = std::fs::read_to_string(&path).expect("committed model");
        let parse = |text: &str| codegen::Description::parse(text, model, &path).expect("valid");
        assert_eq!(parse(&imported), parse(&committed), "{model}");
    }
}

#[test]
fn import_urdf_takes_a_prismatic_joint_and_names_the_line_of_a_bad_value() {
    let dir = Dir::new();
    let slider = r#"<robot name="slider">
             <link name="base"/>
             <link name="carriage"><inertial><mass value="1"/>
               <inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial>
               <visual><material name="m"><color rgba="red"/><texture/></material></visual></link>
             <joint name="rail" type="prismatic"><parent link="base"/><child link="carriage"/>
               <axis xyz="1 0 0"/><limit lower="0" upper="1" effort="10" velocity="1"/></joint>
             <transmission name="t"/>
           </robot>"#;
    let urdf = dir.write("slider.urdf", slider);
    let output = sdnn(&["import-urdf", urdf.to_str().expect("utf-8 path")]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    let toml = String::from_utf8_lossy(&output.stdout);
    assert!(toml.contains("type = \"prismatic\""), "{toml}");
    assert!(
        stderr.contains("note: ") && stderr.contains("skipped 1 <transmission>"),
        "{stderr}"
    );
    let bad = dir.write("bad.urdf", &slider.replace("upper=\"1\"", "upper=\"1.O\""));
    let output = sdnn(&["import-urdf", bad.to_str().expect("utf-8 path")]);
    assert_eq!(output.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("joint 'rail' <limit> (line 7): upper='1.O'"),
        "{stderr}"
    );
}

/// A velocity no arm reaches (finite, but it overflows once squared) is a
/// located error before any filtering or fit: no hang, no NaN.
#[test]
fn an_implausible_value_is_a_located_error() {
    let dir = Dir::new();
    let mut text = String::from("t,q1,q2,q3,qd1,qd2,qd3,tau1,tau2,tau3\n");
    for i in 0..400 {
        let qd = if i == 123 { "1e200" } else { "0.1" };
        text.push_str(&format!("{},0,0,0,{qd},0,0,0,0,0\n", i as f64 * 0.01));
    }
    let file = dir.write("bad.csv", &text);
    for command in ["diagnose", "evaluate"] {
        let run = sdnn(&[command, "--data", file.to_str().unwrap()]);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{command}: {stderr}");
        assert!(
            stderr.contains("bad.csv: line 125, column 'qd1'") && stderr.contains("1e200"),
            "{command}: {stderr}"
        );
    }
}

/// A recording too short to cross-validate is refused, not diagnosed.
#[test]
fn a_recording_under_four_seconds_is_refused() {
    let dir = Dir::new();
    let mut text = String::from("t,q1,q2,q3,qd1,qd2,qd3,tau1,tau2,tau3\n");
    for i in 0..1000 {
        let t = i as f64 * 0.001;
        text.push_str(&format!("{t},{},0,0,{},0,0,0,0,0\n", t.sin(), t.cos()));
    }
    let file = dir.write("short.csv", &text);
    let run = sdnn(&["diagnose", "--data", file.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("at least 4 s"), "{stderr}");
}

/// An interrupted command ends with exit code 130 and leaves no temporary
/// file of a write in progress beside its outputs.
#[test]
fn an_interrupt_leaves_no_temporary_files() {
    use std::process::{Command, Stdio};
    let dir = Dir::new();
    let out = dir.path().join("results");
    for delay_ms in [300, 1500] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_sdnn"))
            .args(["reproduce", "--out", out.to_str().unwrap()])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("run sdnn");
        std::thread::sleep(std::time::Duration::from_millis(delay_ms));
        // SAFETY: kill(2) on the child's own process id.
        unsafe {
            libc::kill(child.id() as libc::pid_t, libc::SIGINT);
        }
        let status = child.wait().unwrap();
        assert_eq!(status.code(), Some(130), "after {delay_ms} ms: {status:?}");
        let mut stack = vec![dir.path().to_path_buf()];
        while let Some(folder) = stack.pop() {
            for entry in std::fs::read_dir(&folder).unwrap().flatten() {
                let name = entry.file_name().to_string_lossy().into_owned();
                assert!(
                    !name.starts_with(".sdnn-"),
                    "{name} left in {}",
                    folder.display()
                );
                if entry.path().is_dir() {
                    stack.push(entry.path());
                }
            }
        }
    }
}

/// Positions far beyond the description's limits are still computed (the
/// result is well defined) but warned about, naming the joint, its value
/// and the limits, with `--angles deg` when they read as degrees.
#[test]
fn pointwise_commands_warn_of_positions_beyond_the_limits() {
    let dir = Dir::new();
    let inside = dir.write("inside.csv", "q1,q2,q3\n0.1,0.2,0.3\n");
    let degrees = dir.write("degrees.csv", "q1,q2,q3\n30,0.2,0.3\n");
    let forces = dir.write(
        "forces.csv",
        "q1,q2,q3,qd1,qd2,qd3,tau1,tau2,tau3\n30,0.2,0.3,0,0,0,0,0,0\n",
    );
    let states = dir.write(
        "states.csv",
        "q1,q2,q3,qd1,qd2,qd3,qdd1,qdd2,qdd3\n30,0.2,0.3,0,0,0,0,0,0\n",
    );
    let run = |command: &str, input: &std::path::Path, extra: &[&str]| {
        let mut args = vec![command, "--model", "kinova_gen3_lite_3dof", "--input"];
        args.push(input.to_str().unwrap());
        args.extend(extra);
        let run = sdnn(&args);
        let stderr = String::from_utf8_lossy(&run.stderr).into_owned();
        assert!(run.status.success(), "{command}: {stderr}");
        assert_eq!(run.stdout.iter().filter(|&&b| b == b'\n').count(), 2);
        stderr
    };
    assert_eq!(run("pose", &inside, &[]), "");
    for (command, input) in [("pose", &degrees), ("tau", &states), ("qdd", &forces)] {
        let stderr = run(command, input, &[]);
        assert!(
            stderr.contains("warning: ")
                && stderr.contains("joint 1: position 30.0 rad leaves")
                && stderr.contains("limits [-2.69, 2.69] rad")
                && stderr.contains("look like degrees: pass `--angles deg`"),
            "{command}: {stderr}"
        );
        assert!(!stderr.contains("joint 2"), "{command}: {stderr}");
    }
    assert_eq!(run("pose", &degrees, &["--angles", "deg"]), "");
}

/// `evaluate` runs the sanity gate's position checks: a recording with its
/// angles (and rates) converted to degrees exits 3 with the hint, as
/// `diagnose` does, unless `--angles deg` reads it or `--no-sanity-gate`
/// evaluates it anyway.
#[test]
fn evaluate_refuses_a_recording_in_degrees() {
    let dir = Dir::new();
    let recording = crate::util::simulated_recordings(&dir, 1, 6.0).remove(0);
    let text = std::fs::read_to_string(&recording).unwrap();
    let mut lines = text.lines();
    let mut converted = format!("{}\n", lines.next().unwrap());
    for line in lines {
        let values: Vec<String> = line
            .split(',')
            .enumerate()
            .map(|(k, v)| match k {
                1..=6 => (v.parse::<f64>().unwrap().to_degrees()).to_string(),
                _ => v.to_string(),
            })
            .collect();
        converted.push_str(&values.join(","));
        converted.push('\n');
    }
    let degrees = dir.write("degrees.csv", &converted);
    let evaluate = |path: &std::path::Path, extra: &[&str]| {
        let mut args = vec!["evaluate", "--data", path.to_str().unwrap()];
        args.extend(extra);
        sdnn(&args)
    };
    assert!(evaluate(&recording, &[]).status.success());
    let refused = evaluate(&degrees, &[]);
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(3), "{stderr}");
    assert!(
        stderr.contains("nothing is evaluated")
            && stderr.contains("the angles look like degrees: pass `--angles deg`"),
        "{stderr}"
    );
    assert!(refused.stdout.is_empty());
    let json = evaluate(&degrees, &["--format", "json"]);
    assert_eq!(json.status.code(), Some(3));
    let findings: serde_json::Value = serde_json::from_slice(&json.stdout).unwrap();
    assert_eq!(findings["findings"][0]["check"], "degrees");
    assert!(evaluate(&degrees, &["--angles", "deg"]).status.success());
    let anyway = evaluate(&degrees, &["--no-sanity-gate"]);
    assert!(anyway.status.success());
    assert!(String::from_utf8_lossy(&anyway.stderr).contains("evaluated anyway"));
}

/// `evaluate` warns when the recording leaves too few samples to compare
/// (its first 40 rows of a simulated recording: fewer than 100 after the
/// trim), and not on the whole recording.
#[test]
fn evaluate_warns_about_a_comparison_of_few_samples() {
    let dir = Dir::new();
    let recording = crate::util::simulated_recordings(&dir, 1, 6.0).remove(0);
    let text = std::fs::read_to_string(&recording).unwrap();
    let head: Vec<&str> = text.lines().take(41).collect();
    let short = dir.write("short.csv", &(head.join("\n") + "\n"));
    let stderr = |path: &std::path::Path| {
        let out = sdnn(&["evaluate", "--data", path.to_str().unwrap()]);
        assert!(out.status.success(), "{out:?}");
        String::from_utf8_lossy(&out.stderr).to_string()
    };
    let warned = stderr(&short);
    assert!(warned.contains("samples compared"), "{warned}");
    assert!(!stderr(&recording).contains("samples compared"));
}

/// `evaluate --preprocessed` compares a file that already carries filtered
/// states as it is: the model on its rows against its torque, every row.
/// Without the flag such a file is filtered again, and a note says so.
#[test]
fn evaluate_compares_preprocessed_files_as_they_are() {
    let model = sdnn::model("kinova_gen3_lite_3dof").unwrap();
    let shift = [0.1, -0.2, 0.3];
    let mut body = String::from("t,q1,q2,q3,qd1,qd2,qd3,qdd1,qdd2,qdd3,tau1,tau2,tau3\n");
    for k in 0..8 {
        let s = k as f64 * 0.1;
        let (q, qd, qdd) = ([s, 0.5 - s, 0.2], [0.3, -0.1, s], [0.0, 0.2, -0.4]);
        let tau = model.tau(&q, &qd, &qdd).unwrap();
        let row: Vec<String> = [s]
            .iter()
            .chain(&q)
            .chain(&qd)
            .chain(&qdd)
            .copied()
            .chain((0..3).map(|j| tau[j] + shift[j]))
            .map(|v| format!("{v:?}"))
            .collect();
        body.push_str(&(row.join(",") + "\n"));
    }
    let dir = Dir::new();
    let file = dir.write("pre.csv", &body);
    let file = file.to_str().unwrap();
    let report = sdnn_json(&[
        "evaluate",
        "--model",
        "kinova_gen3_lite_3dof",
        "--data",
        file,
        "--preprocessed",
        "--format",
        "json",
    ]);
    assert_eq!(report["samples"], 8);
    for (j, s) in shift.iter().enumerate() {
        let mse = report["mse"][j].as_f64().unwrap();
        assert!((mse - s * s).abs() < 1e-12, "{report}");
        assert_eq!(report["mse_torque_as_logged"][j], report["mse"][j]);
    }
    let again = sdnn(&[
        "evaluate",
        "--model",
        "kinova_gen3_lite_3dof",
        "--data",
        file,
    ]);
    let stderr = String::from_utf8_lossy(&again.stderr);
    assert!(stderr.contains("pass --preprocessed"), "{stderr}");
    let raw = dir.write(
        "raw.csv",
        "t,q1,q2,q3,qd1,qd2,qd3,tau1,tau2,tau3\n0,0,0,0,0,0,0,0,0,0\n0.1,0,0,0,0,0,0,0,0,0\n",
    );
    let refused = sdnn(&[
        "evaluate",
        "--model",
        "kinova_gen3_lite_3dof",
        "--data",
        raw.to_str().unwrap(),
        "--preprocessed",
    ]);
    assert_eq!(refused.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&refused.stderr).contains("needs qdd1..qddN"));
    // What the files had done to them when they were written is not done again.
    for twice in [
        ["--torque-scale", "1=1.1"],
        ["--resample", "50"],
        ["--cutoff", "3"],
    ] {
        let args = [
            "evaluate",
            "--data",
            file,
            "--preprocessed",
            twice[0],
            twice[1],
        ];
        let run = sdnn(&args);
        assert_eq!(run.status.code(), Some(2), "{twice:?}");
        assert!(String::from_utf8_lossy(&run.stderr).contains("cannot be used with"));
    }
}
