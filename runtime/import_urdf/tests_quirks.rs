//! What real URDFs carry: point masses, rounded rods, triangle breaches,
//! hands with prismatic fingers, grippers of mimic joints, lifts, floating
//! roots, malformed visuals and elements without dynamics. Torques are
//! checked against a static computation on the URDF tree itself.

use std::collections::HashMap;

use nalgebra::{Matrix3, Rotation3, Unit, Vector3};

use super::*;

fn inertial(mass: f64, inertia: [f64; 3]) -> String {
    format!(
        "<inertial><origin xyz='0.01 0.02 0.05'/><mass value='{mass}'/><inertia ixx='{}' \
         iyy='{}' izz='{}' ixy='0' ixz='0' iyz='0'/></inertial>",
        inertia[0], inertia[1], inertia[2]
    )
}

fn link(name: &str, body: &str) -> String {
    format!(
        "<link name='{name}'>{body}<visual><geometry><box size='0.1 0.1 0.1'/></geometry>\
         </visual></link>"
    )
}

fn joint(name: &str, kind: &str, parent: &str, child: &str, extra: &str) -> String {
    format!(
        "<joint name='{name}' type='{kind}'><parent link='{parent}'/><child link='{child}'/>\
         <origin xyz='0 0.05 0.3' rpy='0.3 0 0.2'/><axis xyz='0 1 0'/>{extra}</joint>"
    )
}

const LIMIT: &str = "<limit lower='-2' upper='2' effort='30' velocity='1.5'/>";

/// base -J1-> l1 -J2-> l2 -J3-> l3, then `extra`, one element a line.
fn arm(extra: &[String]) -> String {
    let body = inertial(1.5, [0.02, 0.03, 0.01]);
    let mut parts = vec![
        link("base", ""),
        link("l1", &body),
        link("l2", &body),
        link("l3", &body),
        joint("J1", "revolute", "base", "l1", LIMIT),
        joint("J2", "revolute", "l1", "l2", LIMIT),
        joint("J3", "revolute", "l2", "l3", LIMIT),
    ];
    parts.extend_from_slice(extra);
    format!("<robot name='quirks'>\n{}\n</robot>\n", parts.join("\n"))
}

fn run(urdf: &str, options: &ImportOptions) -> Imported {
    import_urdf(urdf, "quirks.urdf", options).unwrap_or_else(|e| panic!("{e}\n{urdf}"))
}

fn description(imported: &Imported) -> codegen::Description {
    codegen::Description::parse(&imported.toml, "quirks", std::path::Path::new("q.toml"))
        .unwrap_or_else(|e| panic!("{e}\n{}", imported.toml))
}

/// A hand on l3 with two prismatic fingers, the second a mimic of the first.
fn hand() -> Vec<String> {
    let finger = inertial(0.015, [2e-6, 2e-6, 1e-6]);
    vec![
        link("hand", &inertial(0.73, [0.001, 0.0025, 0.0017])),
        link("finger_l", &finger),
        link("finger_r", &finger),
        joint("hand_mount", "fixed", "l3", "hand", ""),
        joint(
            "finger_1",
            "prismatic",
            "hand",
            "finger_l",
            "<limit lower='0' upper='0.04' effort='20' velocity='0.2'/>",
        ),
        joint(
            "finger_2",
            "prismatic",
            "hand",
            "finger_r",
            "<limit lower='0' upper='0.04' effort='20' velocity='0.2'/><mimic joint='finger_1'/>",
        ),
    ]
}

/// Gravity torques of the URDF tree at `q` (moving joints by name, held
/// ones at `held`), by forward kinematics and `a . ((c - p) x m g)` over
/// every link below each joint: independent of the importer's lumping.
fn tree_gravity(urdf: &str, q: &HashMap<&str, f64>, moving: &[&str], g: Vector3<f64>) -> Vec<f64> {
    let parsed = parse::parse(urdf).expect("parses");
    let tree = tree::Tree::new(&parsed).expect("a tree");
    let mut frames = vec![(Matrix3::identity(), Vector3::zeros()); tree.link_count()];
    let mut axes = Vec::new();
    let mut stack = vec![tree.root];
    while let Some(l) = stack.pop() {
        for &j in tree.child_joints(l) {
            let joint = tree.joint(j);
            let data = joint.data.as_ref().expect("joint data");
            let (r, p) = frames[l];
            let r = r * codegen::reduce::rpy_matrix(&data.rpy);
            let p = p + frames[l].0 * Vector3::from(data.xyz);
            let axis = Unit::new_normalize(Vector3::from(data.axis));
            let value = q.get(joint.name.as_str()).copied().unwrap_or(0.0);
            let child = tree.child_link(j);
            frames[child] = match joint.kind {
                parse::Kind::Revolute => (r * Rotation3::from_axis_angle(&axis, value), p),
                parse::Kind::Prismatic => (r, p + r * axis.into_inner() * value),
                _ => (r, p),
            };
            if moving.contains(&joint.name.as_str()) {
                axes.push((
                    j,
                    joint.kind == parse::Kind::Prismatic,
                    r * axis.into_inner(),
                    p,
                ));
            }
            stack.push(child);
        }
    }
    let mut order: Vec<_> = axes.into_iter().collect();
    order.sort_by_key(|a| tree.joints_above(tree.child_link(a.0)).len());
    order
        .iter()
        .map(|&(j, prismatic, a, p)| {
            let mut tau = 0.0;
            for l in tree.subtree_links(tree.child_link(j)) {
                let Ok(Some(i)) = &tree.link(l).inertial else {
                    continue;
                };
                let c = frames[l].1 + frames[l].0 * Vector3::from(i.xyz);
                let w = i.mass * g;
                tau -= if prismatic {
                    a.dot(&w)
                } else {
                    a.dot(&(c - p).cross(&w))
                };
            }
            tau
        })
        .collect()
}

fn assert_gravity_matches(
    urdf: &str,
    imported: &Imported,
    q: &[(&str, f64)],
    held: &[(&str, f64)],
) {
    let d = description(imported);
    let model = crate::oracle::Model::from_description(&d);
    let moving: Vec<f64> = q.iter().map(|(_, v)| *v).collect();
    let tau = crate::oracle::gravity(&model, &moving);
    let all: HashMap<&str, f64> = q.iter().chain(held).copied().collect();
    let names: Vec<&str> = q.iter().map(|(n, _)| *n).collect();
    let expected = tree_gravity(urdf, &all, &names, Vector3::new(0.0, 0.0, -9.81));
    assert_eq!(tau.len(), expected.len());
    for (a, b) in tau.iter().zip(&expected) {
        assert!(
            (a - b).abs() <= 1e-10 * b.abs().max(1.0),
            "{tau:?} vs {expected:?}"
        );
    }
}

#[test]
fn point_masses_and_zero_inertia_frames_are_lumped() {
    let urdf = arm(&[
        link("sensor", &inertial(1e-9, [0.0, 0.0, 0.0])),
        link("tool", "<inertial><mass value='0.1'/></inertial>"),
        joint("ft_mount", "fixed", "l3", "sensor", ""),
        joint("tool_mount", "fixed", "sensor", "tool", ""),
    ]);
    let imported = run(&urdf, &ImportOptions::default());
    assert!(imported.warnings.is_empty(), "{:?}", imported.warnings);
    let d = description(&imported);
    assert!((d.chain().bodies[2].inertial.mass - (1.5 + 0.1 + 1e-9)).abs() < 1e-12);
    let q = [("J1", 0.3), ("J2", -0.7), ("J3", 1.1)];
    assert_gravity_matches(&urdf, &imported, &q, &[]);
}

#[test]
fn a_triangle_breach_is_imported_with_a_warning_and_a_rounded_rod_says_so() {
    let breach = link("l2", &inertial(1.5, [0.01, 0.01, 0.05]));
    let urdf = arm(&[]).replacen(&link("l2", &inertial(1.5, [0.02, 0.03, 0.01])), &breach, 1);
    let imported = run(&urdf, &ImportOptions::default());
    assert_eq!(imported.warnings.len(), 1, "{:?}", imported.warnings);
    let warning = &imported.warnings[0];
    assert!(warning.starts_with("link 'l2' <inertial> (line 4): principal moments 1.000000e-2 + 1.000000e-2 < 5.000000e-2"), "{warning}");
    assert!(
        imported
            .toml
            .contains("nonphysical_inertia = \"imported from URDF: principal moments")
    );
    description(&imported);
    let rod = link("l2", &inertial(1.5, [0.0, 0.08333, 0.083333]));
    let urdf = arm(&[]).replacen(&link("l2", &inertial(1.5, [0.02, 0.03, 0.01])), &rod, 1);
    let imported = run(&urdf, &ImportOptions::default());
    assert!(
        imported.warnings[0].contains("rounding of a thin body"),
        "{:?}",
        imported.warnings
    );
    description(&imported);
}

#[test]
fn a_negative_moment_needs_the_option_that_reaches_nonphysical_inertia() {
    let bad = link("l2", &inertial(1.5, [-0.01, 0.03, 0.03]));
    let urdf = arm(&[]).replacen(&link("l2", &inertial(1.5, [0.02, 0.03, 0.01])), &bad, 1);
    let message = import_urdf(&urdf, "q.urdf", &ImportOptions::default())
        .expect_err("negative moment")
        .to_string();
    assert!(
        message.starts_with(
            "link 'l2' <inertial> (line 4): the inertia is not positive semi-definite"
        ),
        "{message}"
    );
    assert!(message.ends_with("--nonphysical-inertia l2"), "{message}");
    let options = ImportOptions {
        nonphysical_inertia: vec!["l2".into()],
        ..ImportOptions::default()
    };
    let imported = run(&urdf, &options);
    assert!(imported.toml.contains("--nonphysical-inertia \"l2\""));
    assert!(
        imported
            .toml
            .contains("with --nonphysical-inertia: principal moments")
    );
    description(&imported);
}

#[test]
fn a_hand_with_prismatic_fingers_is_kept_held_and_reported() {
    let urdf = arm(&hand());
    // The default tip stops where the fingers split.
    let imported = run(&urdf, &ImportOptions::default());
    assert!(
        imported.toml.contains("--tip \"hand\""),
        "{}",
        imported.toml
    );
    assert_eq!(imported.notes.len(), 1, "{:?}", imported.notes);
    let split = "kept 2 branches at link 'hand' (finger_1, finger_2; 0.0300 kg";
    assert!(imported.notes[0].starts_with(split), "{:?}", imported.notes);
    // Cut at the wrist, the whole hand is one branch.
    let wrist = ImportOptions {
        tip: Some("l3".into()),
        ..ImportOptions::default()
    };
    let imported = run(&urdf, &wrist);
    assert!(imported.toml.contains("type = \"prismatic\""));
    assert!(
        imported
            .toml
            .contains("mimic = { joint = \"finger_1\", multiplier = 1.0, offset = 0.0 }")
    );
    let d = description(&imported);
    assert_eq!(d.dof(), 3);
    assert!((d.chain().bodies[2].inertial.mass - (1.5 + 0.73 + 0.03)).abs() < 1e-12);
    let report = imported
        .notes
        .iter()
        .find(|n| n.contains("(hand_mount;"))
        .expect("reported");
    assert!(
        report.contains("0.7600 kg") && report.contains("N m of gravity torque on 'J"),
        "{report}"
    );
    assert!(
        report.ends_with("joints held: 1 at 0 (finger_1), 1 mimic joint(s) following their master"),
        "{report}"
    );
    let q = [("J1", 0.4), ("J2", 1.2), ("J3", -0.8)];
    assert_gravity_matches(&urdf, &imported, &q, &[]);
    // Locking the master finger moves both.
    let options = ImportOptions {
        lock: vec![("finger_1".into(), 0.03)],
        ..ImportOptions::default()
    };
    let imported = run(&urdf, &options);
    assert_gravity_matches(
        &urdf,
        &imported,
        &q,
        &[("finger_1", 0.03), ("finger_2", 0.03)],
    );
}

#[test]
fn a_gripper_of_mimic_joints_follows_its_locked_master() {
    let small = inertial(0.02, [1e-5, 1e-5, 1e-5]);
    let mimic = |master: &str, m: f64, o: f64| {
        format!("{LIMIT}<mimic joint='{master}' multiplier='{m}' offset='{o}'/>")
    };
    let urdf = arm(&[
        link("knuckle", &small),
        link("finger", &small),
        link("other", &small),
        joint("finger_joint", "revolute", "l3", "knuckle", LIMIT),
        joint(
            "inner",
            "revolute",
            "knuckle",
            "finger",
            &mimic("finger_joint", -1.0, 0.0),
        ),
        // A mimic of a mimic: written against the master, coupling composed.
        joint("tip", "revolute", "l3", "other", &mimic("inner", 2.0, 0.1)),
    ]);
    let options = ImportOptions {
        tip: Some("l3".into()),
        lock: vec![("finger_joint".into(), 0.3)],
        ..ImportOptions::default()
    };
    let imported = run(&urdf, &options);
    assert!(
        imported
            .toml
            .contains("mimic = { joint = \"finger_joint\", multiplier = -2.0, offset = 0.1 }"),
        "{}",
        imported.toml
    );
    let q = [("J1", -0.4), ("J2", 0.9), ("J3", 0.5)];
    let held = [("finger_joint", 0.3), ("inner", -0.3), ("tip", -0.5)];
    assert_gravity_matches(&urdf, &imported, &q, &held);
}

#[test]
fn continuous_joints_keep_effort_and_velocity() {
    let urdf = arm(&[]).replacen(
        &joint("J3", "revolute", "l2", "l3", LIMIT),
        &joint(
            "J3",
            "continuous",
            "l2",
            "l3",
            "<limit effort='12' velocity='3'/>",
        ),
        1,
    );
    let imported = run(&urdf, &ImportOptions::default());
    assert!(
        imported
            .toml
            .contains("limits = { velocity = 3.0, effort = 12.0 }"),
        "{}",
        imported.toml
    );
    assert!(imported.warnings.is_empty(), "{:?}", imported.warnings);
}

#[test]
fn visuals_textures_transmissions_and_gazebo_never_stop_an_import() {
    let visual = "<visual><geometry><mesh filename='x.stl'/></geometry><material name='m'>\
                  <color rgba='red'/><texture/></material></visual>";
    let mut extra = vec![
        format!(
            "<link name='tool'>{visual}<collision><geometry><sphere radius='bad'/></geometry></collision></link>"
        ),
        joint("tool_mount", "fixed", "l3", "tool", ""),
        "<material name='grey'><color rgba='0.5 0.5'/><texture/></material>".to_string(),
        "<gazebo reference='l1'><mu1>0.2</mu1></gazebo>".to_string(),
    ];
    for k in 0..5 {
        extra.push(format!(
            "<transmission name='t{k}'><type>x</type><joint name='J1'/></transmission>"
        ));
    }
    let imported = run(&arm(&extra), &ImportOptions::default());
    assert!(imported.warnings.is_empty(), "{:?}", imported.warnings);
    assert_eq!(
        imported.notes,
        ["skipped 1 <gazebo>, 5 <transmission>: no rigid-body dynamics in them"]
    );
}

#[test]
fn a_prismatic_lift_carries_the_arm() {
    let urdf = arm(&[]).replacen(
        &joint("J1", "revolute", "base", "l1", LIMIT),
        &joint(
            "J1",
            "prismatic",
            "base",
            "l1",
            "<limit lower='0' upper='0.35' effort='2000' velocity='0.07'/>",
        ),
        1,
    );
    let imported = run(&urdf, &ImportOptions::default());
    assert!(
        imported
            .toml
            .contains("limits = { lower = 0.0, upper = 0.35, velocity = 0.07, effort = 2000.0 }")
    );
    let q = [("J1", 0.2), ("J2", 0.9), ("J3", 0.5)];
    assert_gravity_matches(&urdf, &imported, &q, &[]);
}

#[test]
fn a_floating_root_is_taken_as_fixed_and_named() {
    let urdf = arm(&[
        link("world", ""),
        joint("float", "floating", "world", "base", ""),
        link("ball", &inertial(0.5, [1e-3, 1e-3, 1e-3])),
        joint("ball_joint", "floating", "l2", "ball", ""),
    ]);
    let imported = run(&urdf, &ImportOptions::default());
    assert!(
        imported.notes[0].ends_with("by the floating joint 'float': taken as fixed at base"),
        "{:?}",
        imported.notes
    );
    assert!(
        imported.warnings.iter().any(|w| w
            .starts_with("dropped the branch below the floating joint 'ball_joint' (0.5000 kg")),
        "{:?}",
        imported.warnings
    );
    assert!(!imported.toml.contains("world") && !imported.toml.contains("ball"));
}

#[test]
fn branches_on_the_fixed_base_are_left_out_without_advice_even_when_malformed() {
    let urdf = arm(&[
        link("head", &inertial(2.0, [0.01, 0.01, 0.01])),
        joint(
            "head_pan",
            "revolute",
            "base",
            "head",
            "<limit lower='x' upper='1'/>",
        ),
    ]);
    let imported = run(
        &urdf,
        &ImportOptions {
            tip: Some("l3".into()),
            ..ImportOptions::default()
        },
    );
    assert!(imported.warnings.is_empty(), "{:?}", imported.warnings);
    assert_eq!(
        imported.notes[1..],
        [
            "left out 1 branch(es) on the fixed base (at head_pan): they change no torque of the chain"
        ]
    );
    assert!(imported.notes[0].starts_with("the URDF root 'base' holds several moving branches"));
}

#[test]
fn a_mimic_of_a_joint_that_does_not_exist_is_ignored_with_a_warning() {
    let urdf = arm(&[
        link("jaw", &inertial(0.02, [1e-5, 1e-5, 1e-5])),
        joint(
            "jaw_joint",
            "revolute",
            "l3",
            "jaw",
            &format!("{LIMIT}<mimic joint='nope'/>"),
        ),
    ]);
    let options = ImportOptions {
        tip: Some("l3".into()),
        ..ImportOptions::default()
    };
    let imported = run(&urdf, &options);
    assert!(
        imported.warnings[0]
            .starts_with("joint 'jaw_joint' <mimic> (line 10): joint='nope' names no joint"),
        "{:?}",
        imported.warnings
    );
    assert!(imported.toml.contains("locked = 0.0"), "{}", imported.toml);
}
