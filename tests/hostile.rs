//! Hostile input through the release binary: huge numbers, outputs over
//! inputs, read-only and linked files, implausible values, mismatched
//! networks. Each case must end in a clear error (exit 2) or a correct
//! result, never a panic, a hang or a destroyed input.

use std::path::Path;
use std::process::Output;

use crate::util::{Dir, sdnn};

/// The run failed cleanly: exit code 2 and a message containing `needle`.
fn refused(run: &Output, needle: &str) {
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains(needle), "expected `{needle}` in: {stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
}

/// `sdnn tau --model planar_2link --input INPUT [--output OUTPUT]`.
fn tau(input: &Path, output: Option<&Path>) -> Output {
    let mut args = vec![
        "tau",
        "--model",
        "planar_2link",
        "--input",
        input.to_str().unwrap(),
    ];
    if let Some(out) = output {
        args.extend(["--output", out.to_str().unwrap()]);
    }
    sdnn(&args)
}

/// Two small preprocessed 2-joint recordings for `train` (different
/// samples: one recording given twice is refused).
fn two_recordings(dir: &Dir) -> (std::path::PathBuf, std::path::PathBuf) {
    let rows = |phase: f64| {
        let mut rows = String::from("t,q1,q2,qd1,qd2,qdd1,qdd2,tau1,tau2\n");
        for k in 0..400 {
            let t = f64::from(k) * 0.01;
            let x = t + phase;
            rows.push_str(&format!(
                "{t},{},{},0,0,0,0,{},0\n",
                x.sin(),
                x.cos(),
                x.sin()
            ));
        }
        rows
    };
    (
        dir.write("d.csv", &rows(0.0)),
        dir.write("e.csv", &rows(0.5)),
    )
}

const STATES: &str = "q1,q2,qd1,qd2,qdd1,qdd2\n0.1,0.2,0.3,0.4,0.5,0.6\n";

#[test]
fn huge_counts_and_widths_are_refused_while_parsing() {
    let huge = "18446744073709551615";
    for args in [
        vec!["reproduce", "--seeds", huge],
        vec!["reproduce", "--trajectories", huge],
        vec!["simulate", "--count", huge],
        vec![
            "study",
            "--model",
            "planar_2link",
            "--data",
            "x.csv",
            "--test-from",
            "1",
            "--train-pieces",
            "1844674407370955162",
        ],
    ] {
        refused(&sdnn(&args), "at most");
    }
    let dir = Dir::new();
    let data = dir.write("d.csv", "t,q1,qd1,tau1\n0,0,0,0\n");
    let out = dir.path().join("net.json");
    for hidden in ["18446744073709551615", "100000000,100000000"] {
        let run = sdnn(&[
            "train",
            data.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--hidden",
            hidden,
        ]);
        refused(&run, "at most");
    }
    let run = sdnn(&["reproduce", "--duration", "nan"]);
    refused(&run, "finite");
    // Work beyond one study's budget, or too short to preprocess, is
    // refused before anything is recorded.
    let many = [
        "reproduce",
        "--trajectories",
        "1000",
        "--train",
        "999",
        "--duration",
        "3600",
    ];
    refused(&sdnn(&many), "more than one study records");
    refused(&sdnn(&["reproduce", "--duration", "0.5"]), "at least 1 s");
}

#[test]
fn an_output_never_replaces_the_commands_input() {
    let dir = Dir::new();
    let states = dir.write("states.csv", STATES);
    let path = states.to_str().unwrap();
    let run = sdnn(&[
        "tau",
        "--model",
        "planar_2link",
        "--input",
        path,
        "--output",
        path,
    ]);
    refused(&run, "refusing to write its output over it");
    assert_eq!(std::fs::read_to_string(&states).unwrap(), STATES);
    // preprocess and synth write DIR/<input name>: into the input's folder
    // that is the input itself.
    let mut rows = String::from("t,q1,q2,qd1,qd2,tau1,tau2\n");
    for k in 0..600 {
        let t = f64::from(k) * 0.01;
        rows.push_str(&format!("{t},{},{},0,0,1,2\n", t.sin(), t.cos()));
    }
    let recording = dir.write("rec.csv", &rows);
    let folder = dir.path().to_str().unwrap();
    for args in [
        vec!["preprocess", recording.to_str().unwrap(), "--out", folder],
        vec![
            "synth",
            "--model",
            "planar_2link",
            recording.to_str().unwrap(),
            "--out",
            folder,
        ],
    ] {
        let run = sdnn(&args);
        refused(&run, "refusing to write its output over it");
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(stderr.matches("refusing").count(), 1, "said once: {stderr}");
        assert_eq!(std::fs::read_to_string(&recording).unwrap(), rows);
    }
}

#[cfg(unix)]
#[test]
fn a_read_only_output_is_refused_and_a_linked_one_written_through() {
    use std::os::unix::fs::PermissionsExt;
    let dir = Dir::new();
    let states = dir.write("states.csv", STATES);
    let out = dir.write("tau.csv", "keep\n");
    std::fs::set_permissions(&out, std::fs::Permissions::from_mode(0o444)).unwrap();
    let run = tau(&states, Some(&out));
    refused(&run, "read-only");
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "keep\n");
    let target = dir.write("target.csv", "old\n");
    let link = dir.path().join("link.csv");
    std::os::unix::fs::symlink(&target, &link).unwrap();
    let run = tau(&states, Some(&link));
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(
        std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert!(
        std::fs::read_to_string(&target)
            .unwrap()
            .starts_with("tau1,tau2")
    );
}

#[test]
fn implausible_values_and_time_steps_are_located_errors() {
    let dir = Dir::new();
    let fast = dir.write(
        "fast.csv",
        "q1,q2,qd1,qd2,qdd1,qdd2\n0.1,0.2,1e200,0.4,0.5,0.6\n",
    );
    let run = tau(&fast, None);
    refused(&run, "line 2, column 'qd1'");
    let tiny = dir.write(
        "tiny.csv",
        "t,q1,q2,qd1,qd2,tau1,tau2\n0,0,0,0,0,0,0\n1e-320,0,0,0,0,0,0\n",
    );
    let out = dir.path().join("out");
    let run = sdnn(&[
        "preprocess",
        tiny.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    refused(&run, "column 't'");
}

#[test]
fn a_network_for_another_arm_is_refused() {
    let dir = Dir::new();
    let (data, more) = two_recordings(&dir);
    let net = dir.path().join("net.json");
    let run = sdnn(&[
        "train",
        data.to_str().unwrap(),
        more.to_str().unwrap(),
        "--out",
        net.to_str().unwrap(),
        "--epochs",
        "2",
        "--hidden",
        "4",
        "--preprocessed",
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let mut three = String::from("t,q1,q2,q3,qd1,qd2,qd3,tau1,tau2,tau3\n");
    for k in 0..600 {
        three.push_str(&format!("{},0,0,0,0,0,0,0,0,0\n", f64::from(k) * 0.01));
    }
    let three = dir.write("three.csv", &three);
    let run = sdnn(&[
        "evaluate",
        "--model",
        "kinova_gen3_lite_3dof",
        "--nn",
        net.to_str().unwrap(),
        "--data",
        three.to_str().unwrap(),
    ]);
    refused(&run, "pass the --model it was trained for");
}

#[test]
fn tau_reads_a_recording_from_standard_input_with_column_options() {
    use std::io::Write;
    use std::process::{Command, Stdio};
    let recording =
        "t,pos1,q2,qd1,qd2,qdd1,qdd2,tau1,tau2,extra\n0,0.1,0.2,0.3,0.4,0.5,0.6,0,0,9\n";
    let mut child = Command::new(env!("CARGO_BIN_EXE_sdnn"))
        .args([
            "tau",
            "--model",
            "planar_2link",
            "--input",
            "-",
            "--output",
            "-",
        ])
        .args(["--column", "pos1=q1", "--ignore-column", "extra"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run sdnn");
    child
        .stdin
        .take()
        .unwrap()
        .write_all(recording.as_bytes())
        .unwrap();
    let run = child.wait_with_output().unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let from_file = {
        let dir = Dir::new();
        let states = dir.write("s.csv", STATES);
        tau(&states, None).stdout
    };
    assert_eq!(
        run.stdout, from_file,
        "the same states give the same torques"
    );
}

#[test]
fn time_in_milliseconds_is_warned_about() {
    let dir = Dir::new();
    let mut text = String::from("t,q1,q2,qd1,qd2,tau1,tau2\n");
    for k in 0..600 {
        text.push_str(&format!("{k},0.1,0.2,0.3,0.4,1,2\n"));
    }
    let file = dir.write("ms.csv", &text);
    let run = sdnn(&[
        "evaluate",
        "--model",
        "planar_2link",
        "--data",
        file.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(stderr.contains("milliseconds"), "{stderr}");
}

#[test]
fn file_errors_say_the_os_error_once_and_binary_text_plainly() {
    let run = sdnn(&[
        "tau",
        "--model",
        "planar_2link",
        "--input",
        "/nonexistent/states.csv",
    ]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert_eq!(stderr.matches("no such file").count(), 1, "{stderr}");
    let dir = Dir::new();
    let binary = dir.path().join("binary.csv");
    std::fs::write(&binary, b"q1,q2,qd1,qd2,qdd1,qdd2\n\xff,1,2,3,4,5\n").unwrap();
    let run = tau(&binary, None);
    refused(&run, "line 2: malformed CSV: field 1 is not valid UTF-8");
}

#[test]
fn dash_is_standard_output_for_files_and_refused_for_folders() {
    let dir = Dir::new();
    let (data, more) = two_recordings(&dir);
    let data_args = [data.to_str().unwrap(), more.to_str().unwrap()];
    let mut args = vec!["train", "--out", "-", "--epochs", "2", "--hidden", "4"];
    args.extend(["--preprocessed", "--format", "json"]);
    args.extend(data_args);
    let run = sdnn(&args);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    // The network alone on stdout, the summary on stderr.
    let network: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert!(network.is_object());
    assert!(String::from_utf8_lossy(&run.stderr).contains("\"epochs\""));
    let net = dir.write("net.json", &String::from_utf8_lossy(&run.stdout));
    let states = dir.write("states.csv", STATES);
    let run = sdnn(&[
        "predict",
        "--nn",
        net.to_str().unwrap(),
        "--input",
        states.to_str().unwrap(),
        "--output",
        "-",
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let text = String::from_utf8_lossy(&run.stdout);
    assert!(text.starts_with("tau1,tau2\n"), "{text}");
    assert_eq!(text.lines().count(), 2, "{text}");
    assert!(!dir.path().join("-").exists());
    for command in [
        vec!["simulate", "--out", "-", "--count", "1"],
        vec!["preprocess", "--out", "-", data_args[0]],
    ] {
        refused(&sdnn(&command), "cannot hold a folder");
    }
}

#[test]
fn endless_lines_gaps_and_devices_are_handled() {
    let dir = Dir::new();
    // A line without end (a binary file, /dev/zero): refused, bounded.
    let endless = dir.write("endless.csv", &"1".repeat(2 << 20));
    refused(
        &sdnn(&["evaluate", "--data", endless.to_str().unwrap()]),
        "longer than 1 MiB",
    );
    // A 10 s hole in a 1 kHz log is not jitter to interpolate over.
    let mut rows = String::from("t,q1,q2,q3,qd1,qd2,qd3,tau1,tau2,tau3\n");
    for k in 0..3000 {
        let t = f64::from(k) * 1e-3 + if k >= 1500 { 10.0 } else { 0.0 };
        rows.push_str(&format!("{t},0.1,0.2,0.3,0,0,0,0,1,0\n"));
    }
    let gap = dir.write("gap.csv", &rows);
    refused(
        &sdnn(&["evaluate", "--data", gap.to_str().unwrap()]),
        "a gap of 10.001 s",
    );
    // A device is written into, not replaced by a file.
    let states = dir.write("s.csv", STATES);
    let run = tau(&states, Some(Path::new("/dev/null")));
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    use std::os::unix::fs::FileTypeExt;
    assert!(
        std::fs::metadata("/dev/null")
            .unwrap()
            .file_type()
            .is_char_device()
    );
    // Two inputs with one name would write one output over the other.
    let other = dir.path().join("other");
    std::fs::create_dir_all(&other).unwrap();
    let twin = other.join("s.csv");
    std::fs::write(&twin, STATES).unwrap();
    let out = dir.path().join("out");
    refused(
        &sdnn(&[
            "synth",
            states.to_str().unwrap(),
            twin.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]),
        "give the same output file name",
    );
}

#[test]
fn a_column_target_outside_the_contract_and_a_malformed_network_are_named() {
    let dir = Dir::new();
    let states = dir.write("s.csv", STATES);
    refused(
        &sdnn(&[
            "tau",
            "--model",
            "planar_2link",
            "--input",
            states.to_str().unwrap(),
            "--column",
            "q1=bogus",
        ]),
        "`bogus` is not a column of the contract",
    );
}
