//! `sdnn excite`: a designed 20 s motion is better conditioned than the
//! default recordings of the same length and keeps every limit of the
//! description at every written sample (the model's own torque included);
//! `sdnn simulate --trajectory` records it; recording it answers the
//! diagnosis's "record motions that rest" for an offset that the default
//! recording leaves ambiguous with direction-dependent friction.

use sdnn::trajectory::{ReadOptions, read_plan_csv};

use crate::util::{Dir, root, sdnn, sdnn_json};

/// The study's acceleration cap (rad/s^2) the default recordings keep,
/// which the design keeps too, and the waypoints' margin from each
/// position limit (rad).
const ACCELERATION: f64 = 2.0;
const MARGIN: f64 = 0.1;
/// Share of each effort limit the planned torque may use.
const TORQUE_SHARE: f64 = 0.9;

/// Per joint (lower, upper, velocity, effort) from the description itself.
fn limits(model: &str) -> Vec<(f64, f64, f64, f64)> {
    let path = root().join("models").join(format!("{model}.toml"));
    let d = codegen::Description::load(&path).unwrap();
    d.chain()
        .free_bodies()
        .map(|b| {
            let l = b.limits.unwrap();
            (
                l.lower.unwrap(),
                l.upper.unwrap(),
                l.velocity.unwrap(),
                l.effort.unwrap(),
            )
        })
        .collect()
}

/// Designs for `model`, checks the limits, returns the condition numbers
/// (designed, default).
fn designed(model: &str, dir: &Dir) -> (f64, f64) {
    let out = dir.path().join(format!("{model}.csv"));
    let report = sdnn_json(&[
        "excite",
        "--model",
        model,
        "--duration",
        "20",
        "--seed",
        "1",
        "--format",
        "json",
        "--out",
        out.to_str().unwrap(),
    ]);
    let plan = read_plan_csv(&out, &ReadOptions::default()).unwrap();
    let dynamics = sdnn::model(model).unwrap();
    let (q, qd, qdd) = (plan.q(), plan.qd(), plan.qdd().unwrap());
    assert!((plan.t()[plan.len() - 1] - 20.0).abs() < 1e-9);
    for (j, &(lower, upper, velocity, effort)) in limits(model).iter().enumerate() {
        for i in 0..plan.len() {
            let at = format!("{model} joint {} at t = {}", j + 1, plan.t()[i]);
            assert!(
                q[(i, j)] >= lower + MARGIN && q[(i, j)] <= upper - MARGIN,
                "{at}: q {}",
                q[(i, j)]
            );
            assert!(qd[(i, j)].abs() <= velocity, "{at}: qd {}", qd[(i, j)]);
            assert!(
                qdd[(i, j)].abs() <= ACCELERATION,
                "{at}: qdd {}",
                qdd[(i, j)]
            );
        }
        // It starts and ends at rest, in the same place.
        for i in [0, plan.len() - 1] {
            assert!(qd[(i, j)].abs() < 1e-9 && qdd[(i, j)].abs() < 1e-9);
        }
        assert!((q[(0, j)] - q[(plan.len() - 1, j)]).abs() < 1e-9);
        let _ = effort;
    }
    let efforts: Vec<f64> = limits(model).iter().map(|l| l.3).collect();
    for i in 0..plan.len() {
        let row = |m: &nalgebra::DMatrix<f64>| m.row(i).iter().copied().collect::<Vec<f64>>();
        let tau = dynamics.tau(&row(q), &row(qd), &row(qdd)).unwrap();
        for (j, e) in efforts.iter().enumerate() {
            assert!(
                tau[j].abs() <= TORQUE_SHARE * e,
                "{model} joint {} torque {} at sample {i}",
                j + 1,
                tau[j]
            );
        }
    }
    let number = |key: &str| report[key].as_f64().unwrap();
    (
        number("condition_number"),
        number("condition_number_default"),
    )
}

/// The designed motion's condition number is this many times better than
/// the median default recording's, at seed 1, at least (measured: see
/// docs/excitation.md).
const BETTER: f64 = 3.0;

#[test]
fn a_designed_motion_of_the_3dof_arm_is_better_conditioned_and_keeps_every_limit() {
    let dir = Dir::new();
    let (designed, default) = designed("kinova_gen3_lite_3dof", &dir);
    assert!(
        default / designed >= BETTER,
        "designed {designed}, default {default}"
    );
}

#[test]
fn a_designed_motion_of_the_panda_is_better_conditioned_and_keeps_every_limit() {
    let dir = Dir::new();
    let (designed, default) = designed("panda", &dir);
    assert!(
        default / designed >= BETTER,
        "designed {designed}, default {default}"
    );
}

#[test]
fn the_same_seed_designs_the_same_motion() {
    let dir = Dir::new();
    let run = |name: &str| {
        let out = dir.path().join(name);
        let r = sdnn(&[
            "excite",
            "--model",
            "planar_2link",
            "--duration",
            "8",
            "--rate",
            "100",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        std::fs::read_to_string(out).unwrap()
    };
    assert_eq!(run("a.csv"), run("b.csv"));
    for written in ["a.md", "a.svg"] {
        assert!(dir.path().join(written).exists(), "{written}");
    }
}

#[test]
fn bad_arguments_are_named() {
    let dir = Dir::new();
    let out = dir.path().join("x.csv");
    let out = out.to_str().unwrap();
    let fails = |args: &[&str], expected: &str| {
        let r = sdnn(args);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(expected), "{args:?}: {err}");
    };
    fails(
        &[
            "excite",
            "--model",
            "planar_2link",
            "--harmonics",
            "1",
            "--out",
            out,
        ],
        "at least 2",
    );
    fails(
        &[
            "excite",
            "--model",
            "planar_2link",
            "--harmonics",
            "2",
            "--out",
            out,
        ],
        "--pause 0",
    );
    fails(
        &[
            "excite",
            "--model",
            "planar_2link",
            "--duration",
            "3",
            "--rest",
            "1",
            "--pause",
            "1",
            "--out",
            out,
        ],
        "leaves no time to move",
    );
    let not_json = dir.write("d.json", "t,q1\n0,1\n");
    fails(
        &[
            "excite",
            "--model",
            "planar_2link",
            "--from",
            not_json.to_str().unwrap(),
            "--out",
            out,
        ],
        "not a diagnosis JSON",
    );
    fails(
        &["excite", "--model", "nonesuch", "--out", out],
        "no compiled model named `nonesuch`",
    );
    let plan = dir.write("plan.csv", "t,q1,qd1,qdd1\n0,0,0,0\n0.001,0,0\n");
    fails(
        &[
            "simulate",
            "--plant",
            "planar_2link",
            "--nominal",
            "planar_2link",
            "--trajectory",
            plan.to_str().unwrap(),
            "--out",
            dir.path().join("rec").to_str().unwrap(),
        ],
        "plan.csv",
    );
}

/// The share of joint 2's samples at rest that a diagnosis's note on an
/// offset against direction-dependent friction states, and the note.
fn rest_note(diagnosis: &serde_json::Value) -> (f64, String) {
    let notes = diagnosis["notes"].as_array().unwrap();
    let note = notes
        .iter()
        .filter_map(|n| n.as_str())
        .find(|n| n.starts_with("joint 2: a torque offset"))
        .unwrap_or_else(|| panic!("no note on joint 2's offset: {notes:?}"))
        .to_string();
    let at = note.find("only the ").unwrap() + "only the ".len();
    let share: f64 = note[at..].split('%').next().unwrap().parse().unwrap();
    (share, note)
}

#[test]
fn recording_the_designed_motion_gives_the_rests_a_hidden_offset_needs() {
    let dir = Dir::new();
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let plant =
        std::fs::read_to_string(root().join("models/kinova_gen3_lite_3dof_plant.toml")).unwrap();
    let hidden = plant.replace(
        "effects = { viscous = 0.45, coulomb = 0.55, armature = 0.015 }",
        "effects = { viscous = 0.45, coulomb = 0.55, armature = 0.015, offset = 0.25 }",
    );
    assert_ne!(hidden, plant);
    dir.write("hidden.toml", &hidden);
    let nominal = "kinova_gen3_lite_3dof_plant";
    let plant_path = path("hidden.toml");
    let record = |extra: &[&str], out: &str| {
        let mut args = vec![
            "simulate",
            "--plant",
            &plant_path,
            "--nominal",
            nominal,
            "--out",
            out,
        ];
        args.extend_from_slice(extra);
        let r = sdnn(&args);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    };
    let diagnose = |folder: &str| {
        let data = format!("{folder}/trajectory_01.csv");
        sdnn_json(&[
            "diagnose", "--model", nominal, "--data", &data, "--format", "json",
        ])
    };
    // The default recording: the offset is named, but direction-dependent
    // friction fits almost as well (few samples at rest).
    record(&["--count", "1"], &path("default"));
    let before = diagnose(&path("default"));
    std::fs::write(dir.path().join("before.json"), before.to_string()).unwrap();
    let (share_before, note_before) = rest_note(&before);
    assert!(
        share_before < 20.0 && note_before.contains("almost as well"),
        "{note_before}"
    );
    // Designed from that diagnosis, recorded, diagnosed again.
    let plan = path("plan.csv");
    let r = sdnn(&[
        "excite",
        "--model",
        nominal,
        "--from",
        &path("before.json"),
        "--out",
        &plan,
    ]);
    let text = String::from_utf8_lossy(&r.stdout);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(
        text.contains("Weighted from the diagnosis: ") && text.contains("offset2"),
        "{text}"
    );
    record(&["--trajectory", &plan], &path("designed"));
    let after = diagnose(&path("designed"));
    let (share_after, note_after) = rest_note(&after);
    assert!(
        share_after >= 2.0 * share_before && note_after.contains("less well here"),
        "{note_after}"
    );
    let offset = after["effects"]
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["kind"] == "torque_offset" && e["joint"] == 2)
        .expect("the offset is named");
    let value = offset["parameters"]["offset"].as_f64().unwrap();
    assert!((value - 0.25).abs() < 0.05, "offset {value}");
}
