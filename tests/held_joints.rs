//! Held joints of every type: a locked prismatic or revolute joint, and a
//! mimic of a locked joint, lump exactly like a fixed joint at the held
//! position (oracle torques equal to rounding); a mimic of a moving joint
//! at the tip is coupled to it, and mimics that branch are refused.

use std::path::Path;

use codegen::Description;
use sdnn::oracle::{Model, rnea};

/// A 2-DOF arm whose tip carries a hand with two fingers, written by
/// `fingers` (joints from the hand to each finger).
fn arm_with_hand(fingers: &str) -> String {
    format!(
        r#"
        [[links]]
        name = "base"
        [[links]]
        name = "upper"
        mass = 2.0
        com = [0.2, 0.0, 0.0]
        inertia = {{ ixx = 0.002, iyy = 0.03, izz = 0.03 }}
        [[links]]
        name = "fore"
        mass = 1.2
        com = [0.15, 0.01, 0.0]
        inertia = {{ ixx = 0.001, iyy = 0.012, izz = 0.012 }}
        [[links]]
        name = "hand"
        mass = 0.6
        com = [0.0, 0.0, 0.04]
        inertia = {{ ixx = 0.0008, iyy = 0.0008, izz = 0.0005 }}
        [[links]]
        name = "left"
        mass = 0.05
        com = [0.0, 0.01, 0.03]
        inertia = {{ ixx = 0.0, iyy = 0.0, izz = 0.0 }}
        [[links]]
        name = "right"
        mass = 0.07
        com = [0.01, -0.01, 0.03]
        inertia = {{ ixx = 2e-5, iyy = 2e-5, izz = 1e-5 }}
        [[joints]]
        name = "shoulder"
        type = "revolute"
        parent = "base"
        child = "upper"
        axis = [0.0, 1.0, 0.0]
        [[joints]]
        name = "elbow"
        type = "revolute"
        parent = "upper"
        child = "fore"
        origin = {{ xyz = [0.4, 0.0, 0.0], rpy = [0.3, 0.0, 0.0] }}
        axis = [0.0, 1.0, 0.0]
        [[joints]]
        name = "wrist"
        type = "fixed"
        parent = "fore"
        child = "hand"
        origin = {{ xyz = [0.3, 0.0, 0.0], rpy = [0.0, 1.5707963267948966, 0.0] }}
        {fingers}
        "#
    )
}

fn finger(name: &str, kind: &str, xyz: [f64; 3], axis: [f64; 3], extra: &str) -> String {
    format!(
        r#"
        [[joints]]
        name = "{name}"
        type = "{kind}"
        parent = "hand"
        child = "{name}"
        origin = {{ xyz = {xyz:?}, rpy = [0.1, -0.2, 0.3] }}
        axis = {axis:?}
        {extra}
        "#
    )
}

fn model(source: &str) -> Model {
    let description = Description::parse(source, "hand", Path::new("hand.toml")).unwrap();
    assert_eq!(description.dof(), 2);
    Model::from_description(&description)
}

#[track_caller]
fn assert_same_torques(a: &Model, b: &Model) {
    let states = [
        ([0.3, -1.2], [1.1, -0.4], [2.0, 0.7]),
        ([-2.0, 0.5], [-0.3, 2.2], [-1.0, 3.0]),
    ];
    for (q, qd, qdd) in states {
        let (ta, tb) = (rnea(a, &q, &qd, &qdd), rnea(b, &q, &qd, &qdd));
        assert!(
            (&ta - &tb).norm() < 1e-12 * tb.norm().max(1.0),
            "{ta} vs {tb}"
        );
    }
}

/// Origin of a finger moved by `d` along its (unit) axis in its joint frame.
fn shifted(xyz: [f64; 3], d: f64, axis: [f64; 3]) -> [f64; 3] {
    let r = codegen::reduce::rpy_matrix(&[0.1, -0.2, 0.3]);
    let a = r * nalgebra::Vector3::from(axis);
    [xyz[0] + d * a.x, xyz[1] + d * a.y, xyz[2] + d * a.z]
}

#[test]
fn locked_prismatic_fingers_and_their_mimics_lump_like_fixed_joints() {
    let (left, right) = ([0.0, 0.02, 0.05], [0.0, -0.02, 0.05]);
    let (axis_l, axis_r) = ([0.0, 1.0, 0.0], [0.0, -0.6, 0.8]);
    let held = arm_with_hand(
        &(finger("left", "prismatic", left, axis_l, "locked = 0.03")
            + &finger(
                "right",
                "prismatic",
                right,
                axis_r,
                "mimic = { joint = \"left\", multiplier = -1.5, offset = 0.01 }",
            )),
    );
    let fixed = arm_with_hand(
        &(finger("left", "fixed", shifted(left, 0.03, axis_l), axis_l, "")
            + &finger(
                "right",
                "fixed",
                shifted(right, -1.5 * 0.03 + 0.01, axis_r),
                axis_r,
                "",
            )),
    );
    assert_same_torques(&model(&held), &model(&fixed));
}

#[test]
fn a_revolute_mimic_follows_its_locked_master() {
    let xyz = [0.0, 0.0, 0.05];
    let axis = [1.0, 0.0, 0.0];
    let held = arm_with_hand(
        &(finger("left", "revolute", xyz, axis, "locked = 0.4")
            + &finger(
                "right",
                "revolute",
                xyz,
                axis,
                "mimic = { joint = \"left\", multiplier = -1.0 }",
            )),
    );
    // A fixed joint with rpy turning by the same angle about x (the joint
    // frame's rotation first, then the turn).
    let turn = |angle: f64| {
        let r = codegen::reduce::rpy_matrix(&[0.1, -0.2, 0.3])
            * codegen::reduce::axis_angle(&nalgebra::Vector3::from(axis), angle);
        let (roll, pitch, yaw) = nalgebra::Rotation3::from_matrix(&r).euler_angles();
        format!(
            r#"
            [[joints]]
            type = "fixed"
            parent = "hand"
            origin = {{ xyz = {xyz:?}, rpy = [{roll:?}, {pitch:?}, {yaw:?}] }}
            "#
        )
    };
    let fixed = arm_with_hand(&format!(
        "{}\n name = \"left\"\n child = \"left\"\n{}\n name = \"right\"\n child = \"right\"",
        turn(0.4),
        turn(-0.4)
    ));
    assert_same_torques(&model(&held), &model(&fixed));
}

/// Two fingers following the elbow both hang from the hand: coupled bodies
/// on two branches (a tree) are fine; two joints that move alone on two
/// branches are refused.
#[test]
fn coupled_fingers_may_branch_free_joints_may_not() {
    let mimic = "mimic = { joint = \"elbow\" }";
    let source = arm_with_hand(
        &(finger("left", "prismatic", [0.0; 3], [0.0, 1.0, 0.0], mimic)
            + &finger("right", "revolute", [0.0; 3], [1.0, 0.0, 0.0], mimic)),
    );
    let description = Description::parse(&source, "hand", Path::new("hand.toml")).unwrap();
    assert_eq!(
        (description.dof(), description.chain().bodies.len()),
        (2, 4)
    );
    let free = arm_with_hand(
        &(finger("left", "prismatic", [0.0; 3], [0.0, 1.0, 0.0], "")
            + &finger("right", "revolute", [0.0; 3], [1.0, 0.0, 0.0], "")),
    );
    let error = Description::parse(&free, "hand", Path::new("hand.toml"))
        .unwrap_err()
        .to_string();
    for part in ["`left`", "`right`", "different branches"] {
        assert!(error.contains(part), "{error}");
    }
}

/// A mimic at the end of the chain is a coupling: no degree of freedom of
/// its own, and its torque lands on its master's.
#[test]
fn a_mimic_at_the_tip_is_coupled_to_its_master() {
    let source = arm_with_hand(
        &(finger(
            "left",
            "prismatic",
            [0.0; 3],
            [0.0, 1.0, 0.0],
            "locked = 0.0",
        ) + &finger(
            "right",
            "revolute",
            [0.0; 3],
            [1.0, 0.0, 0.0],
            "mimic = { joint = \"elbow\", multiplier = 2.0 }",
        )),
    );
    let description = Description::parse(&source, "hand", Path::new("hand.toml")).unwrap();
    assert_eq!(
        (description.dof(), description.chain().bodies.len()),
        (2, 3)
    );
    // A light coupled finger changes the elbow's torque only a little, and
    // the coupled torque is the projection (checked against an independent
    // whole-tree computation in urdf_chains::mimic_joint_on_the_chain).
    let model = Model::from_description(&description);
    let tau = rnea(&model, &[0.3, -0.5], &[0.0; 2], &[0.0; 2]);
    assert_eq!(tau.len(), 2);
}

#[test]
fn continuous_joints_keep_speed_and_effort_limits_without_a_range() {
    let source = arm_with_hand(
        &(finger("left", "fixed", [0.0; 3], [1.0, 0.0, 0.0], "")
            + &finger("right", "fixed", [0.0; 3], [1.0, 0.0, 0.0], "")),
    )
    .replacen(
        "axis = [0.0, 1.0, 0.0]",
        "axis = [0.0, 1.0, 0.0]\nlimits = { velocity = 2.0, effort = 30.0 }",
        1,
    );
    let description = Description::parse(&source, "hand", Path::new("hand.toml")).unwrap();
    let limits = description.chain().bodies[0].limits.unwrap();
    assert_eq!(
        (limits.position(), limits.velocity, limits.effort),
        (None, Some(2.0), Some(30.0))
    );
    let one_sided = source.replacen("{ velocity = 2.0", "{ lower = -1.0, velocity = 2.0", 1);
    let error = Description::parse(&one_sided, "hand", Path::new("hand.toml")).unwrap_err();
    assert!(
        error.to_string().contains("both `lower` and `upper`"),
        "{error}"
    );
}

/// A mimic with multiplier 0 never moves: refused with the lock to write.
#[test]
fn a_mimic_with_multiplier_zero_is_refused() {
    let source = arm_with_hand(
        &(finger(
            "left",
            "prismatic",
            [0.0; 3],
            [0.0, 1.0, 0.0],
            "locked = 0.0",
        ) + &finger(
            "right",
            "revolute",
            [0.0; 3],
            [1.0, 0.0, 0.0],
            "mimic = { joint = \"left\", multiplier = 0.0, offset = 0.1 }",
        )),
    );
    let error = Description::parse(&source, "hand", Path::new("hand.toml"))
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("mimic.multiplier") && error.contains("locked = 0.1"),
        "{error}"
    );
}
