//! The second hostile round (issue 26): standard output on a full
//! device, size bounds, and what the tool leaves behind. Each case ends in
//! a clear error (exit 2) or a correct result, never a panic or a hang.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use crate::util::{Dir, sdnn};

/// The run failed cleanly: exit code 2 and a message containing `needle`.
fn refused(run: &Output, needle: &str) {
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains(needle), "expected `{needle}` in: {stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
}

/// Runs `sdnn` with standard output on `/dev/full` (every write fails with ENOSPC).
fn to_full_device(args: &[&str]) -> Output {
    let full = std::fs::OpenOptions::new()
        .write(true)
        .open("/dev/full")
        .expect("/dev/full");
    Command::new(env!("CARGO_BIN_EXE_sdnn"))
        .args(args)
        .stdout(Stdio::from(full))
        .output()
        .expect("run sdnn")
}

/// Two 5 s recordings of the default virtual robot in `dir/rec`.
fn recordings(dir: &Dir) -> [PathBuf; 2] {
    let out = dir.path().join("rec");
    let run = sdnn(&[
        "simulate",
        "--count",
        "2",
        "--duration",
        "5",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    [out.join("trajectory_01.csv"), out.join("trajectory_02.csv")]
}

fn s(path: &Path) -> &str {
    path.to_str().unwrap()
}

#[test]
fn every_command_on_a_full_standard_output_exits_2() {
    let dir = Dir::new();
    let [data, other] = recordings(&dir);
    let net = dir.path().join("net.json");
    let states = dir.write(
        "states.csv",
        "q1,q2,q3,qd1,qd2,qd3,qdd1,qdd2,qdd3\n0,0,0,0,0,0,0,0,0\n",
    );
    let model = ["--model", "kinova_gen3_lite_3dof"];
    let mut train = vec![
        "train",
        s(&data),
        s(&other),
        "--out",
        s(&net),
        "--epochs",
        "1",
        "--hidden",
        "4",
    ];
    let run = to_full_device(&train);
    refused(&run, "standard output");
    // The network was written before the summary failed.
    assert!(net.exists());
    train.truncate(4);
    train.extend(["-", "--epochs", "1", "--hidden", "4"]);
    let sim_out = dir.path().join("sim");
    let cases: Vec<Vec<&str>> = vec![
        vec!["models"],
        vec!["models", "--format", "json"],
        vec!["--help"],
        [&["evaluate"][..], &model, &["--data", s(&data)]].concat(),
        [
            &["evaluate"][..],
            &model,
            &["--data", s(&data), "--format", "json"],
        ]
        .concat(),
        [
            &["evaluate"][..],
            &model,
            &["--data", s(&data), "--nn", s(&net)],
        ]
        .concat(),
        [
            &["diagnose"][..],
            &model,
            &["--data", s(&data), "--format", "json"],
        ]
        .concat(),
        [&["tau"][..], &model, &["--input", s(&states)]].concat(),
        vec!["predict", "--nn", s(&net), "--input", s(&states)],
        vec![
            "simulate",
            "--count",
            "1",
            "--duration",
            "1",
            "--out",
            s(&sim_out),
        ],
        train,
    ];
    for args in cases {
        let run = to_full_device(&args);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(
            stderr.contains("No space left on device"),
            "{args:?}: {stderr}"
        );
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    }
}
