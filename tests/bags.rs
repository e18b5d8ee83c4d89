//! ROS 2 bags through the command line: joints matched to the model's by
//! name, another publisher's joints on the same topic skipped, and the
//! outputs of bag inputs named `.csv`. The bags are written here with the
//! `mcap` crate and a CDR encoder of this file's own.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::util::{Dir, sdnn, sdnn_json, simulated_recordings};

/// One recording, columns `t, q.., qd.., tau..`, read from a CSV of the contract.
struct Recording {
    t: Vec<f64>,
    q: Vec<Vec<f64>>,
    qd: Vec<Vec<f64>>,
    tau: Vec<Vec<f64>>,
}

fn read_recording(path: &Path, dof: usize) -> Recording {
    let text = std::fs::read_to_string(path).unwrap();
    let mut rec = Recording {
        t: vec![],
        q: vec![],
        qd: vec![],
        tau: vec![],
    };
    for line in text.lines().skip(1) {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        rec.t.push(v[0]);
        rec.q.push(v[1..1 + dof].to_vec());
        rec.qd.push(v[1 + dof..1 + 2 * dof].to_vec());
        rec.tau.push(v[1 + 2 * dof..1 + 3 * dof].to_vec());
    }
    rec
}

/// Plain little-endian CDR of a sensor_msgs/msg/JointState.
fn encode(sec: i32, nanosec: u32, names: &[&str], values: [&[f64]; 3]) -> Vec<u8> {
    let mut out = vec![0u8, 1, 0, 0];
    let pad = |out: &mut Vec<u8>, size: usize| {
        while !(out.len() - 4).is_multiple_of(size) {
            out.push(0);
        }
    };
    let u32 = |out: &mut Vec<u8>, v: u32| {
        pad(out, 4);
        out.extend_from_slice(&v.to_le_bytes());
    };
    let string = |out: &mut Vec<u8>, s: &str| {
        u32(out, s.len() as u32 + 1);
        out.extend_from_slice(s.as_bytes());
        out.push(0);
    };
    u32(&mut out, sec as u32);
    u32(&mut out, nanosec);
    string(&mut out, "");
    u32(&mut out, names.len() as u32);
    names.iter().for_each(|n| string(&mut out, n));
    for field in values {
        u32(&mut out, field.len() as u32);
        for v in field {
            pad(&mut out, 8);
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    out
}

/// Writes `messages` (sequence of (stamp ns, CDR)) on `/joint_states`.
fn write_bag(path: &Path, messages: &[(u64, Vec<u8>)]) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut w = mcap::WriteOptions::new()
        .profile("ros2")
        .create(file)
        .unwrap();
    let schema = w
        .add_schema("sensor_msgs/msg/JointState", "ros2msg", b"")
        .unwrap();
    let channel = w
        .add_channel(schema, "/joint_states", "cdr", &BTreeMap::new())
        .unwrap();
    for (i, (ns, data)) in messages.iter().enumerate() {
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: i as u32,
            log_time: *ns,
            publish_time: *ns,
        };
        w.write_to_known_channel(&header, data).unwrap();
    }
    w.finish().unwrap();
}

/// The recording as a bag whose arm messages list the joints under
/// `names` in the order `order` (indices into the model's joints), each
/// followed, when `gripper`, by a gripper's own message on the same topic.
fn bag_of(rec: &Recording, path: &Path, names: &[&str], order: &[usize], gripper: bool) {
    let mut messages = Vec::new();
    for (s, &t) in rec.t.iter().enumerate() {
        let ns = 1_700_000_000_000_000_000u64 + (t * 1e9).round() as u64;
        let (sec, nanosec) = ((ns / 1_000_000_000) as i32, (ns % 1_000_000_000) as u32);
        let pick = |row: &[f64]| order.iter().map(|&j| row[j]).collect::<Vec<f64>>();
        let listed: Vec<&str> = order.iter().map(|&j| names[j]).collect();
        let values = [&pick(&rec.q[s])[..], &pick(&rec.qd[s]), &pick(&rec.tau[s])];
        messages.push((ns, encode(sec, nanosec, &listed, values)));
        if gripper {
            // A gripper driver publishing position only.
            let data = encode(sec, nanosec + 1, &["finger"], [&[0.01], &[], &[]]);
            messages.push((ns + 1, data));
        }
    }
    write_bag(path, &messages);
}

/// A recording of the default virtual robot, 3 s.
fn simulated(dir: &Dir) -> PathBuf {
    simulated_recordings(dir, 1, 3.0).remove(0)
}

fn evaluate_mse(data: &Path) -> Vec<f64> {
    let json = sdnn_json(&[
        "evaluate",
        "--model",
        "kinova_gen3_lite_3dof",
        "--data",
        data.to_str().unwrap(),
        "--format",
        "json",
    ]);
    let mse = json["mse"].as_array().expect("mse per joint");
    mse.iter().map(|v| v.as_f64().unwrap()).collect()
}

const JOINTS: [&str; 3] = ["joint1", "joint2", "joint3"];

/// The bag: the model's joint names in the order 3, 1, 2, with a
/// gripper's messages on the same topic. It gives the CSV's MSE (read
/// in message order it was 72 times too large), and `preprocess` of it
/// writes a `.csv` that `evaluate` reads.
#[test]
fn a_bag_in_another_joint_order_with_a_gripper_gives_the_csvs_mse() {
    let dir = Dir::new();
    let csv = simulated(&dir);
    let rec = read_recording(&csv, 3);
    let bag = dir.path().join("run.mcap");
    bag_of(&rec, &bag, &JOINTS, &[2, 0, 1], true);
    let (from_csv, from_bag) = (evaluate_mse(&csv), evaluate_mse(&bag));
    for (a, b) in from_csv.iter().zip(&from_bag) {
        assert!(
            (a - b).abs() <= 1e-9 * a.abs(),
            "{from_csv:?} vs {from_bag:?}"
        );
    }

    let out = dir.path().join("pre");
    let run = sdnn(&[
        "preprocess",
        bag.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    // Without a model nothing says which joint set is the arm's: refused,
    // naming both sets and --joints.
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("'finger'") && stderr.contains("'joint3'") && stderr.contains("--joints"),
        "{stderr}"
    );
    assert!(!out.join("run.mcap").exists());
    let run = sdnn(&[
        "preprocess",
        bag.to_str().unwrap(),
        "--joints",
        "joint1,joint2,joint3",
        "--out",
        out.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    assert!(stderr.contains("skipped"), "{stderr}");
    assert!(out.join("run.csv").exists() && !out.join("run.mcap").exists());
    let preprocessed = out.join("run.csv");
    let run = sdnn(&[
        "evaluate",
        "--model",
        "kinova_gen3_lite_3dof",
        "--data",
        preprocessed.to_str().unwrap(),
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
}

/// Names that match the model's only in part are refused (pairing by
/// position would mix joints); names that match none are read in the
/// bag's order, with a note saying so.
#[test]
fn a_bag_naming_some_model_joints_is_refused_and_one_naming_none_is_noted() {
    let dir = Dir::new();
    let csv = simulated(&dir);
    let rec = read_recording(&csv, 3);
    let partial = dir.path().join("partial.mcap");
    bag_of(
        &rec,
        &partial,
        &["joint1", "elbow", "wrist"],
        &[0, 1, 2],
        false,
    );
    let run = sdnn(&[
        "evaluate",
        "--model",
        "kinova_gen3_lite_3dof",
        "--data",
        partial.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("partial.mcap")
            && stderr.contains("'joint2'")
            && stderr.contains("--joints"),
        "{stderr}"
    );

    let other = dir.path().join("other.mcap");
    bag_of(&rec, &other, &["a", "b", "c"], &[0, 1, 2], false);
    let run = sdnn(&[
        "evaluate",
        "--model",
        "kinova_gen3_lite_3dof",
        "--data",
        other.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    assert!(stderr.contains("read in the bag's order"), "{stderr}");
}
