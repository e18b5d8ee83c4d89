//! `sdnn qdd` and `sdnn pose` end to end: forward dynamics inverts `sdnn
//! tau` on a compiled model and on its description file, degrees in and
//! out, standard input, and the planar arm's tip at its closed form.

use crate::util::{Dir, root, sdnn};

/// Parses CSV output (header, then rows).
fn table(stdout: &[u8]) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = String::from_utf8(stdout.to_vec()).expect("UTF-8");
    let mut lines = text.lines();
    let header = lines
        .next()
        .expect("header")
        .split(',')
        .map(String::from)
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(|x| x.parse().expect("number")).collect())
        .collect();
    (header, rows)
}

fn run(args: &[&str]) -> (Vec<String>, Vec<Vec<f64>>) {
    let out = sdnn(args);
    assert!(
        out.status.success(),
        "sdnn {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    table(&out.stdout)
}

#[test]
fn qdd_inverts_tau_for_a_compiled_model_and_its_description_file() {
    let dir = Dir::new();
    let states = "q1,q2,q3,qd1,qd2,qd3,qdd1,qdd2,qdd3\n\
                  0.1,-0.4,0.9,0.5,-1.2,0.3,2.0,-3.0,1.5\n\
                  -1.0,0.7,-0.2,-0.1,0.0,2.2,-0.5,0.25,4.0\n";
    let states_path = dir.write("states.csv", states);
    let (_, tau) = run(&[
        "tau",
        "--model",
        "kinova_gen3_lite_3dof_plant",
        "--input",
        states_path.to_str().unwrap(),
    ]);
    let expected: Vec<Vec<f64>> = states
        .lines()
        .skip(1)
        .map(|l| l.split(',').skip(6).map(|x| x.parse().unwrap()).collect())
        .collect();
    let mut forward = String::from("q1,q2,q3,qd1,qd2,qd3,tau1,tau2,tau3\n");
    for (line, t) in states.lines().skip(1).zip(&tau) {
        let head: Vec<&str> = line.split(',').take(6).collect();
        let t: Vec<String> = t.iter().map(|x| format!("{x:?}")).collect();
        forward.push_str(&format!("{},{}\n", head.join(","), t.join(",")));
    }
    let forward_path = dir.write("forward.csv", &forward);
    let description = root().join("models/kinova_gen3_lite_3dof_plant.toml");
    for model in ["kinova_gen3_lite_3dof_plant", description.to_str().unwrap()] {
        let (header, qdd) = run(&[
            "qdd",
            "--model",
            model,
            "--input",
            forward_path.to_str().unwrap(),
        ]);
        assert_eq!(header, ["qdd1", "qdd2", "qdd3"]);
        for (got, want) in qdd.iter().flatten().zip(expected.iter().flatten()) {
            assert!((got - want).abs() < 1e-9, "{model}: {got} vs {want}");
        }
    }
    // The same file in degrees: accelerations come back in deg/s^2.
    let degrees: String = forward
        .lines()
        .enumerate()
        .map(|(k, line)| {
            if k == 0 {
                return format!("{line}\n");
            }
            let values: Vec<String> = line
                .split(',')
                .enumerate()
                .map(|(c, x)| {
                    let x: f64 = x.parse().unwrap();
                    format!("{:?}", if c < 6 { x.to_degrees() } else { x })
                })
                .collect();
            format!("{}\n", values.join(","))
        })
        .collect();
    let degrees_path = dir.write("degrees.csv", &degrees);
    let (_, qdd) = run(&[
        "qdd",
        "--model",
        "kinova_gen3_lite_3dof_plant",
        "--input",
        degrees_path.to_str().unwrap(),
        "--angles",
        "deg",
    ]);
    for (got, want) in qdd.iter().flatten().zip(expected.iter().flatten()) {
        assert!(
            (got - want.to_degrees()).abs() < 1e-7,
            "{got} vs {}",
            want.to_degrees()
        );
    }
}

#[test]
fn pose_gives_the_planar_arms_tip_at_its_closed_form_from_standard_input() {
    use std::io::Write;
    use std::process::{Command, Stdio};
    let (q1, q2) = (0.4_f64, -1.1_f64);
    let mut child = Command::new(env!("CARGO_BIN_EXE_sdnn"))
        .args(["pose", "--model", "planar_2link", "--input", "-"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run sdnn");
    let input = format!("t,q1,q2\n0.0,{q1:?},{q2:?}\n");
    child
        .stdin
        .take()
        .unwrap()
        .write_all(input.as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let (header, rows) = table(&out.stdout);
    assert_eq!(header[..4], ["x", "y", "z", "r11"]);
    // The forearm's frame sits at the elbow, turned by q1 + q2 about z.
    let (s, c) = (q1 + q2).sin_cos();
    let want = [
        0.8 * q1.cos(),
        0.8 * q1.sin(),
        0.0,
        c,
        -s,
        0.0,
        s,
        c,
        0.0,
        0.0,
        0.0,
        1.0,
    ];
    for (got, want) in rows[0].iter().zip(want) {
        assert!((got - want).abs() < 1e-14, "{got} vs {want}");
    }
}

#[test]
fn qdd_and_pose_name_what_is_missing() {
    let dir = Dir::new();
    let no_tau = dir.write("s.csv", "q1,q2,qd1,qd2\n0,0,0,0\n");
    let out = sdnn(&[
        "qdd",
        "--model",
        "planar_2link",
        "--input",
        no_tau.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let message = String::from_utf8_lossy(&out.stderr);
    assert!(message.contains("tau1"), "{message}");
    let three = dir.write("p.csv", "q1,q2,q3\n0,0,0\n");
    let out = sdnn(&[
        "pose",
        "--model",
        "planar_2link",
        "--input",
        three.to_str().unwrap(),
    ]);
    assert_eq!(
        out.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}
