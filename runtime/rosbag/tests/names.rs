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
