//! Joints matched by name: the model's names in any order, another
//! publisher's messages on the topic skipped, partial matches refused.

use super::*;

fn read_for_model(path: &Path, model: &[&str]) -> Result<JointStates, BagError> {
    let options = BagOptions {
        topic: None,
        joints: None,
        model: Some(names(model)),
    };
    read_joint_states(path, &options)
}

/// A gripper's message: position only (a common driver's).
fn gripper(i: usize) -> JointStateMsg {
    JointStateMsg {
        velocity: vec![],
        effort: vec![],
        ..sample(i, &["finger"])
    }
}

#[test]
fn the_models_names_pick_columns_in_the_models_order() {
    let msgs: Vec<_> = (0..4)
        .map(|i| sample(i, &["wrist", "shoulder", "elbow"]))
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let path = bag_of(dir.path(), &msgs);
    let js = read_for_model(&path, &J3).unwrap();
    assert_eq!(js.joints, names(&J3));
    assert_eq!(js.order, JointOrder::ModelNames);
    let m = &msgs[3].position;
    assert_eq!(js.position[3], vec![m[1], m[2], m[0]]);
    // --joints wins over the model's names.
    let js = read(&path, None, Some(&["elbow", "wrist", "shoulder"])).unwrap();
    assert_eq!(js.order, JointOrder::Requested);
    assert_eq!(js.position[3], vec![m[2], m[0], m[1]]);
}

#[test]
fn another_publishers_messages_are_skipped_when_the_joints_are_chosen() {
    let mut msgs = Vec::new();
    for i in 0..5 {
        msgs.push(gripper(i));
        msgs.push(sample(i, &J3));
    }
    let dir = tempfile::tempdir().unwrap();
    let path = bag_of(dir.path(), &msgs);
    for js in [
        read_for_model(&path, &J3).unwrap(),
        read(&path, None, Some(&J3)).unwrap(),
    ] {
        assert_eq!(js.t.len(), 5);
        assert_eq!(js.ignored_messages, 5);
        assert_eq!(js.effort[4], msgs[9].effort);
        // Times are the arm's messages' own.
        assert!((js.t[1] - 0.01).abs() < 1e-12, "{:?}", js.t);
    }
    // Without names to choose by, the first message (the gripper's) does
    // not say which set is the arm: refused naming both.
    let text = err_text(&path, read(&path, None, None));
    assert!(
        text.contains("message 1") && text.contains("'finger'") && text.contains("--joints"),
        "{text}"
    );
}

#[test]
fn a_partial_match_of_the_models_names_is_refused() {
    let msgs: Vec<_> = (0..3)
        .map(|i| sample(i, &["shoulder", "elbow", "hand"]))
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let path = bag_of(dir.path(), &msgs);
    let text = err_text(&path, read_for_model(&path, &J3));
    assert!(
        text.contains("model's joint 'wrist'") && text.contains("'hand'"),
        "{text}"
    );
    // No name in common: the bag's order, said so by the caller.
    let js = read_for_model(&path, &["a", "b", "c"]).unwrap();
    assert_eq!(js.order, JointOrder::FirstMessage);
    assert_eq!(js.joints, names(&["shoulder", "elbow", "hand"]));
}

#[test]
fn a_requested_joint_of_a_later_message_is_found() {
    let mut msgs = vec![gripper(0)];
    msgs.extend((1..4).map(|i| sample(i, &J3)));
    let dir = tempfile::tempdir().unwrap();
    let path = bag_of(dir.path(), &msgs);
    let js = read(&path, None, Some(&["elbow"])).unwrap();
    assert_eq!(js.t.len(), 3);
    assert_eq!(js.position[0], vec![msgs[1].position[1]]);
}

/// A virtual-robot recording written as a bag (joints in another order,
/// with a gripper joint the model lacks), read through the command line's
/// reader with `--joints` in the model's order, diagnosed at the defaults:
/// the plant's Coulomb friction is named on every joint.
#[test]
fn a_bag_is_diagnosed_like_a_csv() {
    use crate::sim::reference::WaypointConfig;
    use crate::study::{self, StudyConfig};
    let plant = crate::model("kinova_gen3_lite_3dof_plant").unwrap();
    let nominal = crate::model("kinova_gen3_lite_3dof").unwrap();
    let waypoints = WaypointConfig {
        limits: study::limits(nominal, &StudyConfig::default()).unwrap(),
        ..WaypointConfig::default()
    };
    let recording = study::record_trajectory(plant, nominal, &waypoints, 3)
        .unwrap()
        .measured;
    let order = ["gripper", "joint3", "joint1", "joint2"];
    let messages: Vec<Vec<u8>> = (0..recording.len())
        .map(|s| {
            let pick = |m: &nalgebra::DMatrix<f64>| -> Vec<f64> {
                [0.0, m[(s, 2)], m[(s, 0)], m[(s, 1)]].to_vec()
            };
            let t = recording.t()[s];
            let message = JointStateMsg {
                sec: 1_700_000_000 + t.floor() as i32,
                nanosec: (t.fract() * 1e9).round() as u32,
                frame_id: String::new(),
                name: names(&order),
                position: pick(recording.q()),
                velocity: pick(recording.qd()),
                effort: pick(recording.tau()),
            };
            encode(&message, true)
        })
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let path = write_bag(
        dir.path(),
        Some(Compression::Zstd),
        &[js_topic("/joint_states", messages)],
    );
    let input = crate::inputs::InputArgs {
        angles: Default::default(),
        resample: Some(1000.0),
        columns: vec![],
        ignored: vec![],
        topic: None,
        joints: Some(names(&["joint1", "joint2", "joint3"])),
        torque_scales: vec![],
        torque_delay: None,
    };
    let traj = input.read(&path, Some(nominal.joint_names())).unwrap();
    assert!((traj.q()[(100, 1)] - recording.q()[(100, 1)]).abs() < 1e-9);
    let recordings = [traj];
    let pipeline = crate::preprocess::Pipeline::auto(&recordings, None, None).unwrap();
    let d = crate::diagnose::diagnose(
        nominal,
        &recordings,
        &pipeline,
        crate::diagnose::Settings::default(),
    )
    .unwrap();
    for j in 1..=3 {
        assert!(
            d.effects
                .iter()
                .any(|e| e.kind == crate::diagnose::Kind::CoulombFriction && e.joint == Some(j)),
            "{}",
            d.text(true)
        );
    }
    // Without --joints the model's joint names pick the same columns.
    let by_name = crate::inputs::InputArgs {
        joints: None,
        ..input.clone()
    };
    let again = by_name.read(&path, Some(nominal.joint_names())).unwrap();
    assert_eq!(again.q(), recordings[0].q());
    // Without a model the bag's four joints do not fit three.
    let error = by_name
        .read(&path, Some(&["a", "b", "c"]))
        .unwrap_err()
        .to_string();
    assert!(error.contains("--joints"), "{error}");
}
