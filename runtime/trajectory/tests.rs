use super::*;
use proptest::prelude::*;

/// A unique scratch directory per test.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pipeline-traj-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn write_file(name: &str, body: &str) -> PathBuf {
    let path = scratch(name).join("in.csv");
    std::fs::write(&path, body).unwrap();
    path
}

const GOOD: &str = "t,q1,q2,qd1,qd2,tau1,tau2\n\
                    0.0,1,2,3,4,5,6\n\
                    0.01,1,2,3,4,5,6\n\
                    0.02,1,2,3,4,5,6\n";

#[test]
fn reads_contract_file() {
    let traj = read_csv(write_file("good", GOOD), &ReadOptions::default()).unwrap();
    assert_eq!((traj.len(), traj.dof()), (3, 2));
    assert_eq!(traj.qd()[(2, 1)], 4.0);
    assert!(traj.qdd().is_none());
}

#[test]
fn cells_and_names_are_read_without_the_blanks_around_them() {
    let padded = " t , q1,q2 ,qd1,qd2,tau1,tau2\n\
                  0.0, 1 ,2,3,4,5,6\n\
                  0.01,1,\t2,3,4,5,6 \n\
                  0.02,1,2,3,4,5,\u{a0}6\n";
    let plain = read_csv(write_file("plain", GOOD), &ReadOptions::default()).unwrap();
    let traj = read_csv(write_file("padded", padded), &ReadOptions::default()).unwrap();
    assert_eq!(
        (traj.t(), traj.q(), traj.tau()),
        (plain.t(), plain.q(), plain.tau())
    );
    // A bad cell is named without its blanks.
    let body = padded.replace(" 1 ,2", " x ,2");
    let msg = read_err("padded-bad", &body, &ReadOptions::default());
    assert!(msg.contains("'q1'") && msg.contains("'x'"), "{msg}");
}

#[test]
fn maps_columns_by_header_name() {
    let body = "tau1,qd1,time,q1,junk\n5,3,0,1,x\n6,4,1,2,y\n";
    let mut opts = ReadOptions::default();
    opts.renames.insert("time".into(), "t".into());
    opts.ignored.push("junk".into());
    let traj = read_csv(write_file("order", body), &opts).unwrap();
    assert_eq!(traj.t(), &[0.0, 1.0]);
    assert_eq!(traj.q()[(1, 0)], 2.0);
    assert_eq!(traj.tau()[(1, 0)], 6.0);
}

#[test]
fn converts_degrees_but_not_torque() {
    let body = "t,q1,qd1,qdd1,tau1\n0,180,90,45,7\n1,0,0,0,7\n";
    let opts = ReadOptions {
        units: Units {
            angles: AngleUnit::Degrees,
        },
        ..ReadOptions::default()
    };
    let traj = read_csv(write_file("deg", body), &opts).unwrap();
    assert!((traj.q()[(0, 0)] - std::f64::consts::PI).abs() < 1e-15);
    assert!((traj.qdd().unwrap()[(0, 0)] - std::f64::consts::FRAC_PI_4).abs() < 1e-15);
    assert_eq!(traj.tau()[(0, 0)], 7.0);
}

fn read_err(name: &str, body: &str, opts: &ReadOptions) -> String {
    read_csv(write_file(name, body), opts)
        .unwrap_err()
        .to_string()
}

#[test]
fn reports_bad_cells_with_line_and_column() {
    let body = GOOD.replace("0.01,1,2,3,4", "0.01,1,2,abc,4");
    let msg = read_err("parse", &body, &ReadOptions::default());
    assert!(
        msg.contains("line 3") && msg.contains("'qd1'") && msg.contains("'abc'"),
        "{msg}"
    );
    let body = GOOD.replace("0.02,1,2,3,4,5,6", "0.02,1,2,3,4,5,NaN");
    let msg = read_err("nan", &body, &ReadOptions::default());
    assert!(
        msg.contains("line 4") && msg.contains("tau2") && msg.contains("finite"),
        "{msg}"
    );
    let body = GOOD.replace("0.02,1,2,3,4,5,6", "0.02,1,2,3,4,5");
    let msg = read_err("ragged", &body, &ReadOptions::default());
    assert!(msg.contains("line 4") && msg.contains("7 fields"), "{msg}");
}

#[test]
fn reports_header_problems() {
    let opts = ReadOptions::default();
    let msg = read_err(
        "missing",
        "t,q1,q2,qd1,tau1,tau2\n0,1,1,1,1,1\n1,1,1,1,1,1\n",
        &opts,
    );
    assert!(msg.contains("missing column 'qd2'"), "{msg}");
    let msg = read_err("extra", "t,q1,qd1,tau1,temp\n0,1,1,1,1\n1,1,1,1,1\n", &opts);
    assert!(
        msg.contains("unexpected column 'temp'") && msg.contains("--ignore-column temp"),
        "{msg}"
    );
    assert!(msg.contains("--column temp=NAME"), "{msg}");
    let msg = read_err("named", "t,q1,qd1,torque1\n0,1,1,1\n1,1,1,1\n", &opts);
    assert!(msg.contains("--column torque1=tau1"), "{msg}");
    let msg = read_err("effort", "time_s,q1,qd1,joint_effort_1\n0,1,1,1\n", &opts);
    assert!(msg.contains("--column time_s=t"), "{msg}");
    let msg = read_err("spaced", "t,q1,qd1,tau1,motor temp\n0,1,1,1,1\n", &opts);
    assert!(msg.contains("--ignore-column 'motor temp'"), "{msg}");
    let msg = read_err("semicolons", "t;q1;qd1;tau1\n0;1;1;1\n1;1;1;1\n", &opts);
    assert!(msg.contains("separated by semicolons"), "{msg}");
    let msg = read_err("tabs", "t\tq1\tqd1\ttau1\n0\t1\t1\t1\n", &opts);
    assert!(msg.contains("separated by tabs"), "{msg}");
    let msg = read_err("dup", "t,q1,q1,qd1,tau1\n0,1,1,1,1\n1,1,1,1,1\n", &opts);
    assert!(msg.contains("'q1' appears twice"), "{msg}");
    let msg = read_err("partial-qdd", "t,q1,q2,qd1,qd2,qdd1,tau1,tau2\n", &opts);
    assert!(msg.contains("missing column 'qdd2'"), "{msg}");
    let three = ReadOptions {
        dof: Some(3),
        ..ReadOptions::default()
    };
    let msg = read_err("dof", GOOD, &three);
    assert!(
        msg.contains("expected 3 joints") && msg.contains("has 2"),
        "{msg}"
    );
    let msg = read_err("empty", "", &opts);
    assert!(msg.contains("empty file"), "{msg}");
    assert!(
        read_err("missing-1", "t,q1,q2,qd1,tau1,tau2\n0,1,1,1,1,1\n", &opts).contains("(line 1)")
    );
}

/// Blank lines before the header: every header error names the header's
/// own line, and a data row's error its line.
#[test]
fn header_errors_name_the_line_after_blank_lines() {
    let opts = ReadOptions::default();
    let header = |names: &str| format!("\n\r\n{names}\n0,1,1,1,1\n0.01,1,1,1,1\n");
    let msg = read_err("blank-extra", &header("t,q1,qd1,tau1,temp"), &opts);
    assert!(msg.contains("(line 3)"), "{msg}");
    let msg = read_err("blank-missing", &header("t,q1,q2,qd1,tau1"), &opts);
    assert!(
        msg.contains("missing column") && msg.contains("(line 3)"),
        "{msg}"
    );
    let msg = read_err("blank-dup", &header("t,q1,q1,qd1,tau1"), &opts);
    assert!(msg.contains("twice") && msg.contains("(line 3)"), "{msg}");
    let three = ReadOptions {
        dof: Some(3),
        ..ReadOptions::default()
    };
    let msg = read_err("blank-dof", &header("t,q1,qd1,tau1,tau1x"), &three);
    assert!(msg.contains("(line 3)"), "{msg}");
    let msg = read_err("blank-spaces", "\n   \nt,q1,qd1,tau1\n0,1,1,1\n", &opts);
    assert!(msg.contains("line 2 holds only blanks"), "{msg}");
    let bom = "\n\u{feff}t,q1,qd1,tau1\n0,1,1,1\n0.01,1,1,1\n";
    let read = read_csv(write_file("blank-bom", bom), &opts).unwrap();
    assert_eq!(read.len(), 2);
    let body = "\n\nt,q1,qd1,tau1\n0,1,1,1\n0.01,1,x,1\n";
    let msg = read_err("blank-cell", body, &opts);
    assert!(msg.contains("line 5"), "{msg}");
}

#[test]
fn rejects_bad_time() {
    let body = GOOD.replace("0.02,", "0.01,");
    let msg = read_err("repeat", &body, &ReadOptions::default());
    assert!(
        msg.contains("line 4") && msg.contains("strictly increase"),
        "{msg}"
    );
    let few = ReadOptions {
        min_samples: 10,
        ..ReadOptions::default()
    };
    let msg = read_err("few", GOOD, &few);
    assert!(msg.contains("3 samples, at least 10"), "{msg}");
    let epoch = GOOD.replace("\n0.0", "\n1764160000.0");
    let msg = read_err("epoch", &epoch, &ReadOptions::default());
    assert!(msg.contains("line 2") && msg.contains("Unix time"), "{msg}");
}

#[test]
fn jitter_needs_resampling() {
    let body = "t,q1,qd1,tau1\n0,0,0,0\n0.01,1,1,1\n0.025,2,2,2\n0.03,3,3,3\n";
    let msg = read_err("jitter", body, &ReadOptions::default());
    assert!(
        msg.contains("--resample HZ") && msg.contains("0.015"),
        "{msg}"
    );
    let opts = ReadOptions {
        resample_hz: Some(100.0),
        ..ReadOptions::default()
    };
    let traj = read_csv(write_file("jitter-ok", body), &opts).unwrap();
    assert_eq!(traj.len(), 4);
    // At t = 0.02 the value lies 2/3 of the way from 1 (t=0.01) to 2 (t=0.025).
    assert!((traj.q()[(2, 0)] - (1.0 + 2.0 / 3.0)).abs() < 1e-12);
    assert!(matches!(
        resample(&traj, f64::NAN),
        Err(TrajectoryError::InvalidResampleRate { .. })
    ));
}

#[test]
fn states_and_torques_round_trip() {
    let dir = scratch("states");
    let m = |k: f64| DMatrix::from_fn(3, 2, |r, c| k + r as f64 * 0.1 + c as f64);
    let states = States::new(m(1.0), m(2.0), m(3.0)).unwrap();
    write_states_csv(dir.join("s.csv"), &states).unwrap();
    let back = read_states_csv(dir.join("s.csv"), &ReadOptions::default()).unwrap();
    assert_eq!(back, states);
    write_torques_csv(dir.join("tau.csv"), &m(4.0)).unwrap();
    let tau = read_torques_csv(dir.join("tau.csv"), &ReadOptions::default()).unwrap();
    assert_eq!(tau, m(4.0));
    let err = read_states_csv(dir.join("tau.csv"), &ReadOptions::default()).unwrap_err();
    assert!(err.to_string().contains("missing column 'q1'"), "{err}");
}

#[test]
fn shape_mismatch_is_an_error() {
    let z = |r, c| DMatrix::zeros(r, c);
    let err = Trajectory::new(vec![0.0, 1.0], z(2, 3), z(2, 3), None, z(2, 2)).unwrap_err();
    assert!(err.to_string().contains("tau has shape 2x2, expected 2x3"));
    let err = Trajectory::new(vec![0.0, 0.0], z(2, 1), z(2, 1), None, z(2, 1)).unwrap_err();
    assert!(err.to_string().contains("sample 1 (0-based)"), "{err}");
    let ok = Trajectory::new(vec![0.0, 1e9], z(2, 1), z(2, 1), None, z(2, 1)).unwrap();
    assert!(matches!(
        resample(&ok, 1e6),
        Err(TrajectoryError::ResampleTooLarge { .. })
    ));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]
    #[test]
    fn write_read_is_bit_exact(
        values in prop::collection::vec(-1e3f64..1e3, 12),
        tiny in 1e-300f64..1e-290,
    ) {
        let n = 4;
        let t: Vec<f64> = (0..n).map(|i| i as f64 * 0.001).collect();
        let m = |k: usize| DMatrix::from_fn(n, 1, |r, _| values[(k * n + r) % 12] * if r == 0 { tiny } else { 1.0 });
        let traj = Trajectory::new(t, m(0), m(1), Some(m(2)), m(0)).unwrap();
        let path = scratch("prop").join("rt.csv");
        write_csv(&path, &traj).unwrap();
        let back = read_csv(&path, &ReadOptions::default()).unwrap();
        prop_assert_eq!(back, traj);
    }
}

/// A recording of `rows` good rows with one fault on row `bad` (0-based),
/// a blank line after row `blank` when it is one, every line ended by
/// `ending`; and the line an editor shows the fault on.
fn faulty_recording(
    rows: usize,
    bad: usize,
    fault: &str,
    blank: usize,
    ending: &str,
) -> (String, u64) {
    let mut lines = vec!["t,q1,qd1,tau1".to_owned()];
    let mut fault_line = 0;
    for r in 0..rows {
        let t = if r == bad && fault == "time" {
            0.0
        } else {
            r as f64 * 0.01
        };
        let row = match fault {
            _ if r != bad => format!("{t},0.1,0.2,0.3"),
            "text" => format!("{t},abc,0.2,0.3"),
            "nan" => format!("{t},0.1,NaN,0.3"),
            "ragged" => format!("{t},0.1,0.2"),
            "huge" => format!("{t},0.1,0.2,1e9"),
            "utf8" => format!("{t},0.1,0.2,0.3\u{1}"),
            _ => format!("{t},0.1,0.2,0.3"),
        };
        lines.push(row);
        if r == bad {
            fault_line = lines.len() as u64;
        }
        if r == blank {
            lines.push(String::new());
        }
    }
    let text = lines.iter().map(|l| format!("{l}{ending}")).collect();
    (text, fault_line)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// Windows (CRLF) and classic Mac (CR) files name the same line as a
    /// Unix file: the editor's.
    #[test]
    fn errors_name_the_editors_line_for_any_line_ending(
        rows in 2usize..12,
        bad in 1usize..12,
        blank in 0usize..14,
        fault in prop::sample::select(vec!["text", "nan", "ragged", "huge", "time", "utf8"]),
        ending in prop::sample::select(vec!["\n", "\r\n", "\r"]),
    ) {
        let bad = bad.min(rows - 1);
        let (body, line) = faulty_recording(rows, bad, fault, blank, ending);
        // `\u{1}` marks the byte that makes the row invalid UTF-8.
        let bytes: Vec<u8> = body.bytes().map(|b| if b == 1 { 0xff } else { b }).collect();
        let path = scratch("endings").join("in.csv");
        std::fs::write(&path, bytes).unwrap();
        let msg = read_csv(&path, &ReadOptions::default()).unwrap_err().to_string();
        let named = format!("line {line}");
        prop_assert!(
            msg.contains(&format!("{named},")) || msg.contains(&format!("{named}:")),
            "{:?} ended by {:?}: {}", fault, ending, msg
        );
    }
}
