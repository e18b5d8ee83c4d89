//! Traps a new user falls into, each met as they would meet it: a
//! Windows recording, a mistyped model name, a plant without its
//! controller's model.

use std::process::{Command, Output};

use crate::util::{Dir, sdnn};

fn stderr(run: &Output) -> String {
    String::from_utf8_lossy(&run.stderr).into_owned()
}

/// `sdnn` run from `dir` (outside the repository).
fn sdnn_in(dir: &Dir, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_sdnn"))
        .current_dir(dir.path())
        .args(args)
        .output()
        .expect("run sdnn")
}

#[test]
fn a_windows_recording_names_the_line_an_editor_shows() {
    let dir = Dir::new();
    // The bad value is on line 5 of the file, right after a blank line.
    let lines = [
        "q1,q2,qd1,qd2,qdd1,qdd2",
        "0,0,0,0,0,0",
        "0,0,0,0,0,0",
        "",
        "0,x,0,0,0,0",
    ];
    for (name, ending) in [
        ("unix.csv", "\n"),
        ("windows.csv", "\r\n"),
        ("mac.csv", "\r"),
    ] {
        let body: String = lines.iter().map(|l| format!("{l}{ending}")).collect();
        let states = dir.write(name, &body);
        let run = sdnn(&[
            "tau",
            "--model",
            "planar_2link",
            "--input",
            states.to_str().unwrap(),
        ]);
        assert_eq!(run.status.code(), Some(2), "{name}");
        assert!(
            stderr(&run).contains("line 5, column 'q2'"),
            "{name}: {}",
            stderr(&run)
        );
    }
}

#[test]
fn a_mistyped_model_name_is_answered_with_the_near_one() {
    let dir = Dir::new();
    let input = dir.write("q.csv", "t,q1,qd1,tau1\n0,0,0,0\n");
    let input = input.to_str().unwrap();
    let runs: [&[&str]; 6] = [
        &["tau", "--model", "pand", "--input", input],
        &["pose", "--model", "Panda", "--input", input],
        &["evaluate", "--model", "pnada", "--data", input],
        &["diagnose", "--model", "pand", "--data", input],
        &["excite", "--model", "pand", "--out", "plan.csv"],
        &["simulate", "--plant", "pand", "--out", "rec"],
    ];
    for args in runs {
        let run = sdnn_in(&dir, args);
        let said = stderr(&run);
        assert_eq!(run.status.code(), Some(2), "{args:?}: {said}");
        assert!(
            said.contains("did you mean `panda`?") && said.contains("planar_2link"),
            "{args:?}: {said}"
        );
    }
    let run = sdnn_in(&dir, &["tau", "--model", "ur10e", "--input", input]);
    assert!(!stderr(&run).contains("did you mean"), "{}", stderr(&run));
}

#[test]
fn a_missing_description_file_is_named_as_missing() {
    let dir = Dir::new();
    let input = dir.write("q.csv", "q1\n0\n");
    let input = input.to_str().unwrap();
    let run = sdnn_in(&dir, &["pose", "--model", "myarm.toml", "--input", input]);
    let said = stderr(&run);
    assert_eq!(run.status.code(), Some(2), "{said}");
    assert!(said.contains("myarm.toml not found"), "{said}");
    // Outside the repository, `models/panda.toml` is not there; `panda` is.
    let run = sdnn_in(
        &dir,
        &["pose", "--model", "models/panda.toml", "--input", input],
    );
    assert!(
        stderr(&run).contains("`panda` is a compiled model: name it without `.toml`"),
        "{}",
        stderr(&run)
    );
    // A description's path without its `.toml`.
    std::fs::create_dir(dir.path().join("arms")).unwrap();
    dir.write("arms/arm.toml", "");
    let run = sdnn_in(&dir, &["pose", "--model", "arms/arm", "--input", input]);
    assert!(
        stderr(&run).contains("did you mean `arms/arm.toml`?"),
        "{}",
        stderr(&run)
    );
    // A URDF given as the model.
    dir.write("arm.urdf", "<robot name='a'/>");
    let run = sdnn_in(&dir, &["pose", "--model", "arm.urdf", "--input", input]);
    assert!(
        stderr(&run).contains("`sdnn import-urdf arm.urdf --out arm.toml`"),
        "{}",
        stderr(&run)
    );
}

#[test]
fn a_plant_alone_is_controlled_with_its_own_model() {
    let dir = Dir::new();
    let run = sdnn_in(
        &dir,
        &[
            "simulate",
            "--plant",
            "planar_2link",
            "--count",
            "1",
            "--duration",
            "2",
            "--out",
            "rec",
        ],
    );
    assert!(run.status.success(), "{}", stderr(&run));
    let recorded = std::fs::read_to_string(dir.path().join("rec/trajectory_01.csv")).unwrap();
    assert!(
        recorded.starts_with("t,q1,q2,qd1,qd2,tau1,tau2"),
        "{recorded:.80}"
    );
    // A controller's model of another arm is refused, naming the flag.
    let run = sdnn_in(
        &dir,
        &[
            "simulate",
            "--plant",
            "planar_2link",
            "--nominal",
            "panda",
            "--out",
            "rec2",
        ],
    );
    let said = stderr(&run);
    assert_eq!(run.status.code(), Some(2), "{said}");
    assert!(
        said.contains("--nominal panda has 7 joints") && said.contains("leave --nominal out"),
        "{said}"
    );
}

#[test]
fn a_plan_for_another_arm_names_the_plant_flag() {
    let dir = Dir::new();
    let plan = dir.write(
        "plan.csv",
        "t,q1,q2,qd1,qd2,qdd1,qdd2\n0,0,0,0,0,0,0\n0.001,0,0,0,0,0,0\n",
    );
    let run = sdnn_in(
        &dir,
        &[
            "simulate",
            "--trajectory",
            plan.to_str().unwrap(),
            "--out",
            "rec",
        ],
    );
    let said = stderr(&run);
    assert_eq!(run.status.code(), Some(2), "{said}");
    assert!(
        said.contains("the default when `--plant` is not given") && said.contains("--plant MODEL"),
        "{said}"
    );
}

#[test]
fn a_path_that_is_no_recording_says_what_it_is() {
    let dir = Dir::new();
    std::fs::create_dir(dir.path().join("rec")).unwrap();
    dir.write("rec/trajectory_01.csv", "t,q1,qd1,tau1\n0,0,0,0\n");
    let cases = [
        (
            "rec",
            "a folder, not a file: pass its files (for example rec/*.csv)",
        ),
        ("rec/trajectory_1.csv", "did you mean `trajectory_01.csv`?"),
        ("rec/*.cvs", "a pattern that matched no file"),
    ];
    for (data, expected) in cases {
        let run = sdnn_in(&dir, &["diagnose", "--data", data]);
        assert_eq!(run.status.code(), Some(2), "{data}");
        assert!(stderr(&run).contains(expected), "{data}: {}", stderr(&run));
    }
}

#[test]
fn a_study_of_another_arm_names_the_nominal_flag() {
    let dir = Dir::new();
    let run = sdnn_in(
        &dir,
        &["reproduce", "--plant", "planar_2link", "--out", "r"],
    );
    let said = stderr(&run);
    assert_eq!(run.status.code(), Some(2), "{said}");
    assert!(
        said.contains("(the default of --nominal) has 3") && said.contains("`--nominal MODEL`"),
        "{said}"
    );
}

#[test]
fn the_other_direction_of_the_dynamics_is_named() {
    let dir = Dir::new();
    let torques = dir.write("forces.csv", "q1,q2,qd1,qd2,tau1,tau2\n0,0,0,0,1,1\n");
    let states = dir.write("states.csv", "q1,q2,qd1,qd2,qdd1,qdd2\n0,0,0,0,1,1\n");
    for (command, input, expected) in [
        (
            "tau",
            &torques,
            "`sdnn qdd` computes qdd from q, qd and tau",
        ),
        ("qdd", &states, "`sdnn tau` computes tau from q, qd and qdd"),
    ] {
        let input = input.to_str().unwrap();
        let run = sdnn(&[command, "--model", "planar_2link", "--input", input]);
        assert_eq!(run.status.code(), Some(2), "{command}");
        assert!(
            stderr(&run).contains(expected),
            "{command}: {}",
            stderr(&run)
        );
    }
}
