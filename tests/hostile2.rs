//! The second hostile round (issue 26): standard output on a full
//! device, size bounds, and what the tool leaves behind. Each case ends in
//! a clear error (exit 2) or a correct result, never a panic or a hang.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use crate::util::{Dir, sdnn, simulated_recordings};

/// The run failed cleanly: exit code 2 and a message containing `needle`.
fn refused(run: &Output, needle: &str) {
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains(needle), "expected `{needle}` in: {stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
}

/// Runs `sdnn` with standard output on `/dev/full` (every write fails with ENOSPC).
fn to_full_device(args: &[&str]) -> Output {
    on_full_device(args, |command, full| command.stdout(full))
}

/// Runs `sdnn` with standard error on `/dev/full`: its messages are lost.
fn errors_to_full_device(args: &[&str]) -> Output {
    on_full_device(args, |command, full| command.stderr(full))
}

/// Runs `sdnn` with the stream `attach` sets on `/dev/full`.
fn on_full_device(args: &[&str], attach: fn(&mut Command, Stdio) -> &mut Command) -> Output {
    let full = std::fs::OpenOptions::new()
        .write(true)
        .open("/dev/full")
        .expect("/dev/full");
    let mut command = Command::new(env!("CARGO_BIN_EXE_sdnn"));
    command.args(args);
    attach(&mut command, Stdio::from(full))
        .output()
        .expect("run sdnn")
}

/// Two 5 s recordings of the default virtual robot in `dir/rec`.
fn recordings(dir: &Dir) -> [PathBuf; 2] {
    simulated_recordings(dir, 2, 5.0)
        .try_into()
        .expect("two recordings")
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

/// With standard error on a full device, commands that print notes there
/// do their work and exit 0, and a refused command exits 2: the lost
/// messages never make one panic (exit 101).
#[test]
fn a_full_standard_error_loses_messages_not_the_exit_code() {
    let dir = Dir::new();
    let [data, other] = recordings(&dir);
    let (results, preprocessed) = (dir.path().join("results"), dir.path().join("pre"));
    let worked: [&[&str]; 3] = [
        &["preprocess", s(&data), "--out", s(&preprocessed)],
        &[
            "train",
            s(&data),
            s(&other),
            "--out",
            "-",
            "--epochs",
            "1",
            "--hidden",
            "4",
        ],
        &[
            "reproduce",
            "--trajectories",
            "3",
            "--train",
            "2",
            "--duration",
            "2",
            "--seeds",
            "1",
            "--epochs",
            "1",
            "--out",
            s(&results),
        ],
    ];
    for args in worked {
        let run = errors_to_full_device(args);
        assert_eq!(run.status.code(), Some(0), "{args:?}");
    }
    assert!(results.join("results.md").exists());
    let refused: [&[&str]; 2] = [
        &["evaluate", "--model", "no_such_model", "--data", s(&data)],
        &["no-such-command"],
    ];
    for args in refused {
        let run = errors_to_full_device(args);
        assert_eq!(run.status.code(), Some(2), "{args:?}");
    }
}

/// A serial chain of `n` revolute joints as a description.
fn chain_toml(n: usize) -> String {
    let mut text = String::from("name = \"chain\"\n\n[[links]]\nname = \"l0\"\n");
    for i in 1..=n {
        text.push_str(&format!(
            "\n[[links]]\nname = \"l{i}\"\nmass = 0.1\ncom = [0.01, 0.0, 0.0]\n\
             inertia = {{ ixx = 0.001, iyy = 0.001, izz = 0.001 }}\n"
        ));
    }
    for i in 1..=n {
        text.push_str(&format!(
            "\n[[joints]]\nname = \"j{i}\"\ntype = \"revolute\"\nparent = \"l{}\"\n\
             child = \"l{i}\"\norigin = {{ xyz = [0.01, 0.0, 0.0] }}\naxis = [0.0, 0.0, 1.0]\n",
            i - 1
        ));
    }
    text
}

/// Loading is linear in the chain (the criterion benchmark `loading`
/// measures it); here, a long chain loads and its joints come in order,
/// and a description larger than any arm's is refused before it is read.
#[test]
fn long_and_oversized_descriptions() {
    let dir = Dir::new();
    let long = dir.write("long.toml", &chain_toml(2000));
    let d = codegen::Description::load(&long).unwrap();
    assert_eq!(d.dof(), 2000);
    let last = d.chain().free_bodies().last().unwrap();
    assert_eq!(last.joint, "j2000");

    let big = dir.path().join("big.toml");
    let file = std::fs::File::create(&big).unwrap();
    file.set_len(17 << 20).unwrap();
    let run = sdnn(&["evaluate", "--model", s(&big), "--data", s(&big)]);
    refused(&run, "larger than 16 MiB");
    let e = codegen::Description::load(&big).unwrap_err().to_string();
    assert!(e.contains("larger than 16 MiB"), "{e}");
}

/// 100,000 links without joints: the error names ten and counts the rest.
#[test]
fn unconnected_links_are_counted_not_listed() {
    let mut text = String::from("[[links]]\nname = \"l0\"\n");
    for i in 1..100_000 {
        text.push_str(&format!("[[links]]\nname = \"l{i}\"\n"));
    }
    let e = codegen::Description::parse(&text, "m", Path::new("m.toml"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("100000 links have no parent") && e.contains("and 99990 more"),
        "{e}"
    );
    assert!(e.len() < 1000, "{} bytes", e.len());
}

/// The simulated seconds shrink with the cube of the plant's joints.
#[test]
fn simulate_is_bounded_by_joints_and_steps() {
    let dir = Dir::new();
    let plant = dir.write("chain30.toml", &chain_toml(30));
    let out = dir.path().join("out");
    let run = sdnn(&[
        "simulate",
        "--plant",
        s(&plant),
        "--nominal",
        s(&plant),
        "--count",
        "1",
        "--duration",
        "600",
        "--out",
        s(&out),
    ]);
    refused(&run, "30-joint plant");
    assert!(!out.exists());
}

/// A URDF of `n` links, unconnected (no joints).
fn loose_urdf(n: usize) -> String {
    let links: String = (0..n).map(|i| format!("<link name=\"l{i}\"/>\n")).collect();
    format!("<robot name=\"r\">\n{links}</robot>\n")
}

/// A URDF chain of `n` links joined by revolute joints, each link also
/// holding a one-link branch by a revolute joint when `branches`.
fn chain_urdf(n: usize, branches: bool) -> String {
    let inertial = "<inertial><mass value=\"1\"/><inertia ixx=\"0.01\" ixy=\"0\" \
                    ixz=\"0\" iyy=\"0.01\" iyz=\"0\" izz=\"0.01\"/></inertial>";
    let joint = |name: String, parent: String, child: String| {
        format!(
            "<joint name=\"{name}\" type=\"revolute\"><parent link=\"{parent}\"/>\
             <child link=\"{child}\"/><origin xyz=\"0 0 0.1\"/><axis xyz=\"0 1 0\"/>\
             <limit lower=\"-3\" upper=\"3\" effort=\"10\" velocity=\"2\"/></joint>\n"
        )
    };
    let mut text = String::from("<robot name=\"r\">\n");
    for i in 0..n {
        text.push_str(&format!("<link name=\"l{i}\">{inertial}</link>\n"));
        if i > 0 {
            text.push_str(&joint(
                format!("j{i}"),
                format!("l{}", i - 1),
                format!("l{i}"),
            ));
        }
        if branches {
            text.push_str(&format!("<link name=\"b{i}\">{inertial}</link>\n"));
            text.push_str(&joint(format!("k{i}"), format!("l{i}"), format!("b{i}")));
        }
    }
    text + "</robot>\n"
}

/// Long chains import in time about linear in the links (a chain of 9,000
/// links took 2.8 s; a comb of 500 branches 122 s, and this one of 1,000
/// over 14 minutes; both now take under a second), every joint of the
/// chain kept.
#[test]
fn large_chains_and_combs_import() {
    let dir = Dir::new();
    let chain = dir.write("chain.urdf", &chain_urdf(9_000, false));
    let run = sdnn(&["import-urdf", s(&chain)]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let toml = String::from_utf8_lossy(&run.stdout);
    assert_eq!(toml.matches("type = \"revolute\"").count(), 8_999);
    let comb = dir.write("comb.urdf", &chain_urdf(1_000, true));
    let run = sdnn(&["import-urdf", s(&comb), "--tip", "l999"]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    assert!(stderr.contains("kept a branch at link 'l998'"), "{stderr}");
}

/// URDF link counts are bounded with a message saying so, and an error
/// about thousands of links names ten.
#[test]
fn urdf_link_counts_are_bounded_and_long_lists_cut() {
    let dir = Dir::new();
    let many = dir.write("many.urdf", &loose_urdf(10_001));
    refused(
        &sdnn(&["import-urdf", s(&many)]),
        "10001 <link> elements, more than this importer takes (10000",
    );
    let loose = dir.write("loose.urdf", &loose_urdf(5_000));
    let run = sdnn(&["import-urdf", s(&loose)]);
    refused(&run, "5000 links have no parent (l0, l1,");
    assert!(String::from_utf8_lossy(&run.stderr).contains("and 4990 more"));
    assert!(run.stderr.len() < 1000, "{} bytes", run.stderr.len());
}

/// One recording given twice (under two names) is refused by every
/// command that fits or evaluates on several, naming both files.
#[test]
fn one_recording_given_twice_is_refused() {
    let dir = Dir::new();
    let [data, _] = recordings(&dir);
    let copy = dir.path().join("copy.csv");
    std::fs::copy(&data, &copy).unwrap();
    let net = dir.path().join("net.json");
    let out = dir.path().join("study");
    let model = ["--model", "kinova_gen3_lite_3dof"];
    let both = [s(&data), s(&copy)];
    let pre = dir.path().join("pre");
    let run = sdnn(&[&["preprocess"][..], &both, &["--out", s(&pre)]].concat());
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let (pre_data, pre_copy) = (pre.join("trajectory_01.csv"), pre.join("copy.csv"));
    let cases: Vec<Vec<&str>> = vec![
        [&["train"][..], &both, &["--out", s(&net)]].concat(),
        vec![
            "train",
            "--preprocessed",
            s(&pre_data),
            s(&pre_copy),
            "--out",
            s(&net),
        ],
        [&["evaluate"][..], &model, &["--data"], &both].concat(),
        [&["diagnose"][..], &model, &["--data"], &both].concat(),
        [
            &["study"][..],
            &model,
            &["--test-from", "2", "--out", s(&out), "--data"],
            &both,
        ]
        .concat(),
    ];
    for args in cases {
        let run = sdnn(&args);
        refused(&run, "copy.csv hold the same samples");
    }
    assert!(!net.exists());
}

/// `import-log` refuses a time step the readers refuse (1e-7 s), naming
/// the time file and line, and takes a byte-order mark and trailing blank
/// lines.
#[test]
fn import_log_writes_only_what_the_readers_take() {
    let dir = Dir::new();
    let time = dir.write("t.txt", "\u{feff}0\n0.0000001\n0.001\n\n\n");
    let q = dir.write("q.txt", "0.1\n0.2\n0.3\n");
    let qd = dir.write("qd.txt", "0\n0\n0\n");
    let tau = dir.write("tau.txt", "1\n2\n3\n\n");
    let out = dir.path().join("log.csv");
    let args = |t: &Path| {
        vec![
            "import-log".to_string(),
            "--time".into(),
            s(t).into(),
            "--positions".into(),
            s(&q).into(),
            "--velocities".into(),
            s(&qd).into(),
            "--torques".into(),
            s(&tau).into(),
            "--dof".into(),
            "1".into(),
            "--out".into(),
            s(&out).into(),
        ]
    };
    let run = |t: &Path| {
        let a = args(t);
        sdnn(&a.iter().map(String::as_str).collect::<Vec<_>>())
    };
    refused(
        &run(&time),
        "t.txt: line 2: 1e-7 s after the previous sample",
    );
    assert!(!out.exists());
    let time = dir.write("t.txt", "\u{feff}0\n0.001\n0.002\n\n\n");
    let ok = run(&time);
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    dir.write("tau.txt", "1\n2e7\n3\n");
    refused(
        &run(&time),
        "tau.txt: line 2 (sample 2, joint 1): torque (N m) 2e7",
    );
}

/// `reproduce --map` takes --seeds, --epochs, --duration and --splits (a
/// run that took 474 s at the map's defaults takes about a second) and
/// refuses the options its grid fixes by name.
#[test]
fn reproduce_map_honours_or_refuses_its_options() {
    let dir = Dir::new();
    let out = dir.path().join("map");
    refused(
        &sdnn(&[
            "reproduce",
            "--map",
            "--trajectories",
            "3",
            "--out",
            s(&out),
        ]),
        "--trajectories does not apply to --map",
    );
    let run = sdnn(&[
        "reproduce",
        "--map",
        "--seeds",
        "1",
        "--epochs",
        "1",
        "--duration",
        "2",
        "--splits",
        "1",
        "--format",
        "json",
        "--out",
        s(&out),
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let cells: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    let cells = cells.as_array().unwrap();
    assert_eq!(cells.len(), 48);
    // One seed and one split: no spread.
    assert!(
        cells
            .iter()
            .all(|c| c["sdnn_over_analytical"]["std"] == 0.0)
    );
}

/// `simulate --count 2` into a folder of 5 recordings is refused, naming
/// the 3 it would leave stale; rewriting the same count is fine.
#[test]
fn simulate_refuses_to_leave_stale_recordings() {
    let dir = Dir::new();
    let out = dir.path().join("rec");
    let sim = |count: &str| {
        sdnn(&[
            "simulate",
            "--count",
            count,
            "--duration",
            "1",
            "--out",
            s(&out),
        ])
    };
    assert!(sim("5").status.success());
    refused(
        &sim("2"),
        "holds 3 recording(s) of an earlier run beyond --count 2 (trajectory_03.csv",
    );
    assert!(sim("5").status.success());
    assert!(out.join("trajectory_05.csv").exists());
}

/// A duplicate TOML key is named, an empty name refused, and a payload
/// on the base (which changes no torque) refused.
#[test]
fn duplicate_keys_empty_names_and_a_payload_on_the_base() {
    let dup = "[[links]]\nname = \"a\"\nmass = 1.0\nmass = 2.0\n";
    let e = codegen::Description::parse(dup, "m", Path::new("m.toml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("m.toml:4:1: duplicate key `mass`"), "{e}");
    let empty = "[[links]]\nname = \"b\"\n[[links]]\nname = \"c\"\nmass = 1.0\ninertia = { ixx = 0.1, iyy = 0.1, izz = 0.1 }\n\
                 [[joints]]\nname = \" \"\ntype = \"revolute\"\nparent = \"b\"\nchild = \"c\"\n";
    let e = codegen::Description::parse(empty, "m", Path::new("m.toml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("joints[0].name") && e.contains("empty"), "{e}");
    let urdf = crate::util::root().join("data/gen3_lite/GEN3-LITE.urdf");
    refused(
        &sdnn(&["import-urdf", s(&urdf), "--attach", "BASE:mass=5"]),
        "link 'BASE' does not move",
    );
}
