//! Bad descriptions get errors naming the file, line, column and key; the
//! reduction lumps fixed and locked bodies like the hand computation.

use std::path::Path;

use codegen::{Description, DescriptionError};
use nalgebra::{Matrix3, Vector3};
use sdnn::oracle::{self, Model};

use crate::util::{Dir, States, assert_close};

const VALID: &str = r#"
name = "two links"

[[links]]
name = "base"

[[links]]
name = "a"
mass = 1.0
com = [0.1, 0.0, 0.0]
inertia = { ixx = 0.01, iyy = 0.02, izz = 0.02 }

[[links]]
name = "b"
mass = 0.5
com = [0.0, 0.0, 0.2]
inertia = { ixx = 0.01, iyy = 0.01, izz = 0.005 }

[[joints]]
name = "j1"
type = "revolute"
parent = "base"
child = "a"
axis = [0.0, 0.0, 1.0]

[[joints]]
name = "j2"
type = "revolute"
parent = "a"
child = "b"
origin = { xyz = [0.3, 0.0, 0.0] }
axis = [0.0, 1.0, 0.0]
"#;

fn parse(source: &str) -> Result<Description, DescriptionError> {
    Description::parse(source, "robot", Path::new("models/robot.toml"))
}

/// The error message of `source` with `from` replaced by `to`.
fn error_after(from: &str, to: &str) -> String {
    assert!(VALID.contains(from), "fixture lacks {from:?}");
    let source = VALID.replacen(from, to, 1);
    match parse(&source) {
        Ok(_) => panic!("expected an error after replacing {from:?} with {to:?}"),
        Err(e) => e.to_string(),
    }
}

#[track_caller]
fn assert_mentions(message: &str, parts: &[&str]) {
    for part in parts {
        assert!(
            message.contains(part),
            "`{message}` does not mention `{part}`"
        );
    }
}

#[test]
fn the_valid_fixture_parses() {
    let d = parse(VALID).unwrap();
    assert_eq!(d.dof(), 2);
    assert_eq!(d.robot, "two links");
    assert_eq!(d.gravity, [0.0, 0.0, -9.81]);
}

#[test]
fn syntax_error_names_file_line_and_column() {
    let message = error_after("mass = 1.0", "mass = = 1.0");
    assert_mentions(&message, &["models/robot.toml:9:"]);
}

#[test]
fn missing_key_is_named() {
    let message = error_after("parent = \"a\"\n", "");
    assert_mentions(&message, &["models/robot.toml:", "missing field `parent`"]);
}

#[test]
fn unknown_key_is_named_with_the_expected_ones() {
    let message = error_after("mass = 0.5", "mass = 0.5\nmas = 2.0");
    assert_mentions(
        &message,
        &[
            "models/robot.toml:16:",
            "unknown field `mas`",
            "expected one of",
        ],
    );
}

#[test]
fn wrong_type_is_named() {
    let message = error_after("mass = 1.0", "mass = \"heavy\"");
    assert_mentions(&message, &["models/robot.toml:9:", "invalid type"]);
}

#[test]
fn zero_or_negative_mass_is_rejected() {
    for bad in ["mass = 0.0", "mass = -1.0"] {
        let message = error_after("mass = 1.0", bad);
        assert_mentions(
            &message,
            &["models/robot.toml:9:", "`links[1].mass`", "> 0 kg"],
        );
    }
}

#[test]
fn non_finite_values_are_rejected() {
    assert_mentions(
        &error_after("mass = 1.0", "mass = nan"),
        &["`links[1].mass`", "finite"],
    );
    assert_mentions(
        &error_after("com = [0.1, 0.0, 0.0]", "com = [inf, 0.0, 0.0]"),
        &["`links[1].com`"],
    );
    assert_mentions(
        &error_after("axis = [0.0, 1.0, 0.0]", "axis = [0.0, nan, 0.0]"),
        &["`joints[1].axis`", "finite"],
    );
}

#[test]
fn non_symmetric_inertia_matrix_is_rejected() {
    let message = error_after(
        "inertia = { ixx = 0.01, iyy = 0.02, izz = 0.02 }",
        "inertia = [[0.01, 0.001, 0.0], [0.0, 0.02, 0.0], [0.0, 0.0, 0.02]]",
    );
    assert_mentions(&message, &["models/robot.toml:11:", "not symmetric"]);
}

#[test]
fn non_positive_definite_inertia_is_rejected() {
    let message = error_after(
        "inertia = { ixx = 0.01, iyy = 0.02, izz = 0.02 }",
        "inertia = { ixx = 0.01, iyy = 0.02, izz = 0.02, ixy = 0.05 }",
    );
    assert_mentions(
        &message,
        &[
            "models/robot.toml:11:",
            "`links[1].inertia`",
            "not positive semi-definite",
        ],
    );
}

/// The inertias real files carry: a point mass, a thin rod, a rod whose
/// moments were rounded (slightly negative, a triangle breach of rounding)
/// are physical; a clear breach still needs `nonphysical_inertia`.
#[test]
fn point_masses_and_rounded_thin_rods_are_physical() {
    let from = "inertia = { ixx = 0.01, iyy = 0.02, izz = 0.02 }";
    for physical in [
        "inertia = { ixx = 0.0, iyy = 0.0, izz = 0.0 }",
        "inertia = { ixx = 0.0, iyy = 0.02, izz = 0.02 }",
        "inertia = { ixx = -1e-14, iyy = 0.0200001, izz = 0.02 }",
        "inertia = { ixx = 1e-9, iyy = 0.020000009, izz = 0.02 }",
    ] {
        assert!(VALID.contains(from));
        let source = VALID.replacen(from, physical, 1);
        assert!(
            parse(&source).is_ok(),
            "{physical}: {:?}",
            parse(&source).err()
        );
    }
    let message = error_after(from, "inertia = { ixx = 0.001, iyy = 0.01, izz = 0.02 }");
    assert_mentions(&message, &["triangle inequality", "nonphysical_inertia"]);
    let kept = VALID.replacen(
        from,
        "inertia = { ixx = 0.001, iyy = 0.01, izz = 0.02 }\nnonphysical_inertia = \"CAD export\"",
        1,
    );
    assert!(parse(&kept).is_ok());
}

#[test]
fn triangle_inequality_violation_is_rejected_unless_opted_in() {
    let bad = "inertia = { ixx = 0.01, iyy = 0.01, izz = 0.05 }";
    let message = error_after("inertia = { ixx = 0.01, iyy = 0.02, izz = 0.02 }", bad);
    assert_mentions(
        &message,
        &[
            "`links[1].inertia`",
            "triangle inequality",
            "nonphysical_inertia",
        ],
    );
    let opted_in = VALID.replacen(
        "inertia = { ixx = 0.01, iyy = 0.02, izz = 0.02 }",
        &format!("nonphysical_inertia = \"test\"\n{bad}"),
        1,
    );
    assert!(parse(&opted_in).is_ok());
}

#[test]
fn zero_axis_is_rejected() {
    let message = error_after("axis = [0.0, 1.0, 0.0]", "axis = [0.0, 0.0, 0.0]");
    assert_mentions(
        &message,
        &["models/robot.toml:32:", "`joints[1].axis`", "zero"],
    );
}

#[test]
fn duplicate_names_are_rejected() {
    let message = error_after("name = \"b\"", "name = \"a\"");
    assert_mentions(&message, &["`links[2].name`", "duplicate link name `a`"]);
    let message = error_after("name = \"j2\"", "name = \"j1\"");
    assert_mentions(&message, &["`joints[1].name`", "duplicate joint name `j1`"]);
}

#[test]
fn joint_to_a_missing_link_is_rejected() {
    let message = error_after("child = \"b\"", "child = \"c\"");
    assert_mentions(
        &message,
        &["models/robot.toml:30:", "`joints[1].child`", "link `c`"],
    );
}

#[test]
fn link_with_two_parents_is_rejected() {
    let message = error_after(
        "parent = \"a\"\nchild = \"b\"",
        "parent = \"a\"\nchild = \"a\"",
    );
    assert_mentions(&message, &["`joints[1].child`"]);
    let extra = format!(
        "{VALID}\n[[joints]]\nname = \"j3\"\ntype = \"fixed\"\nparent = \"base\"\nchild = \"b\"\n"
    );
    let message = parse(&extra).unwrap_err().to_string();
    assert_mentions(
        &message,
        &["`joints[2].child`", "two parents", "`j2`", "`j3`"],
    );
}

#[test]
fn cycle_is_rejected() {
    let cyclic = format!(
        "{VALID}\n[[links]]\nname = \"c\"\n\n[[joints]]\nname = \"j3\"\ntype = \"fixed\"\nparent = \"b\"\nchild = \"base\"\n"
    );
    let message = parse(&cyclic).unwrap_err().to_string();
    assert_mentions(&message, &["cycle"]);
}

#[test]
fn empty_chain_is_rejected() {
    let message = parse("[[links]]\nname = \"base\"\n")
        .unwrap_err()
        .to_string();
    assert_mentions(&message, &["no moving joint"]);
    let message = parse("").unwrap_err().to_string();
    assert_mentions(&message, &["no [[links]]"]);
}

#[test]
fn branched_chain_is_rejected() {
    let branched = format!(
        "{VALID}\n[[links]]\nname = \"c\"\nmass = 0.1\ninertia = {{ ixx = 0.001, iyy = 0.001, izz = 0.001 }}\n\n\
         [[joints]]\nname = \"j3\"\ntype = \"revolute\"\nparent = \"a\"\nchild = \"c\"\n"
    );
    let message = parse(&branched).unwrap_err().to_string();
    assert_mentions(&message, &["only serial chains"]);
}

#[test]
fn a_negative_coulomb_level_is_named_as_such() {
    let message = error_after(
        "type = \"revolute\"\nparent = \"a\"",
        "type = \"revolute\"\neffects = { coulomb = -4.0 }\nparent = \"a\"",
    );
    assert_mentions(&message, &["`joints[1].effects.coulomb`", "must be >= 0"]);
}

#[test]
fn effects_on_a_fixed_joint_are_rejected() {
    let message = error_after(
        "type = \"revolute\"\nparent = \"a\"",
        "type = \"fixed\"\neffects = { viscous = 0.1 }\nparent = \"a\"",
    );
    assert_mentions(&message, &["`joints[1].effects`", "does not move"]);
}

#[test]
fn missing_file_is_named() {
    let message = Description::load("models/does_not_exist.toml")
        .unwrap_err()
        .to_string();
    assert_mentions(&message, &["models/does_not_exist.toml", "cannot read"]);
}

#[test]
fn garbage_never_panics() {
    let dir = Dir::new();
    for (i, source) in [
        "\u{0}\u{1}",
        "[[links]]\nname = 3",
        "links = 5",
        "[[joints]]\n",
        "gravity = [1]",
    ]
    .iter()
    .enumerate()
    {
        let path = dir.write(&format!("g{i}.toml"), source);
        assert!(Description::load(&path).is_err());
    }
}

/// A body attached by a fixed joint, and the same body lumped by hand
/// (parallel-axis theorem in the parent frame), give the same torques.
#[test]
fn fixed_child_body_equals_hand_lumped_link() {
    let tool = format!(
        "{VALID}\n[[links]]\nname = \"tool\"\nmass = 0.4\ncom = [0.02, 0.0, 0.05]\n\
         inertia = {{ ixx = 0.002, iyy = 0.003, izz = 0.001 }}\n\n\
         [[joints]]\nname = \"mount\"\ntype = \"fixed\"\nparent = \"b\"\nchild = \"tool\"\n\
         origin = {{ xyz = [0.0, 0.0, 0.3], rpy = [0.0, 1.5707963267948966, 0.0] }}\n"
    );
    let with_tool = Model::from_description(&parse(&tool).unwrap());

    // By hand: the tool frame is rotated +90 deg about y and 0.3 m up in b's frame.
    let r = Matrix3::new(0.0, 0.0, 1.0, 0.0, 1.0, 0.0, -1.0, 0.0, 0.0);
    let (m_b, c_b, i_b) = (
        0.5,
        Vector3::new(0.0, 0.0, 0.2),
        Matrix3::from_diagonal(&Vector3::new(0.01, 0.01, 0.005)),
    );
    let (m_t, c_t) = (
        0.4,
        r * Vector3::new(0.02, 0.0, 0.05) + Vector3::new(0.0, 0.0, 0.3),
    );
    let i_t = r * Matrix3::from_diagonal(&Vector3::new(0.002, 0.003, 0.001)) * r.transpose();
    let mass = m_b + m_t;
    let com = (m_b * c_b + m_t * c_t) / mass;
    let shift = |m: f64, d: Vector3<f64>| m * (d.dot(&d) * Matrix3::identity() - d * d.transpose());
    let inertia = i_b + shift(m_b, c_b - com) + i_t + shift(m_t, c_t - com);
    let lumped = VALID.replacen(
        "mass = 0.5\ncom = [0.0, 0.0, 0.2]\ninertia = { ixx = 0.01, iyy = 0.01, izz = 0.005 }",
        &format!(
            "mass = {mass:?}\ncom = [{:?}, {:?}, {:?}]\ninertia = [[{:?}, {:?}, {:?}], [{:?}, {:?}, {:?}], [{:?}, {:?}, {:?}]]",
            com.x, com.y, com.z,
            inertia[(0, 0)], inertia[(0, 1)], inertia[(0, 2)],
            inertia[(1, 0)], inertia[(1, 1)], inertia[(1, 2)],
            inertia[(2, 0)], inertia[(2, 1)], inertia[(2, 2)],
        ),
        1,
    );
    assert_ne!(lumped, VALID, "fixture replacement failed");
    let by_hand = Model::from_description(&parse(&lumped).unwrap());
    let mut states = States::new(2, 7);
    for _ in 0..500 {
        let (q, qd, qdd) = states.next();
        let a = oracle::rnea(&with_tool, &q, &qd, &qdd);
        let b = oracle::rnea(&by_hand, &q, &qd, &qdd);
        for i in 0..2 {
            assert_close(a[i], b[i], "fixed child vs hand-lumped");
        }
    }
}

/// A locked revolute joint behaves as a fixed joint at its angle.
#[test]
fn locked_joint_is_a_fixed_joint_at_its_angle() {
    let locked = VALID.replacen(
        "axis = [0.0, 1.0, 0.0]",
        "axis = [0.0, 1.0, 0.0]\nlocked = 0.7",
        1,
    );
    let three = format!(
        "{locked}\n[[links]]\nname = \"c\"\nmass = 0.3\ncom = [0.1, 0.0, 0.0]\n\
         inertia = {{ ixx = 0.001, iyy = 0.002, izz = 0.002 }}\n\n\
         [[joints]]\nname = \"j3\"\ntype = \"revolute\"\nparent = \"b\"\nchild = \"c\"\n\
         origin = {{ xyz = [0.0, 0.0, 0.25] }}\naxis = [1.0, 0.0, 0.0]\n"
    );
    let fixed = three.replacen(
        "type = \"revolute\"\nparent = \"a\"",
        "type = \"fixed\"\nparent = \"a\"",
        1,
    );
    let fixed = fixed.replacen(
        "origin = { xyz = [0.3, 0.0, 0.0] }",
        "origin = { xyz = [0.3, 0.0, 0.0], rpy = [0.0, 0.7, 0.0] }",
        1,
    );
    let fixed = fixed.replacen("\nlocked = 0.7", "", 1);
    let a = Model::from_description(&parse(&three).unwrap());
    let b = Model::from_description(&parse(&fixed).unwrap());
    assert_eq!(a.dof(), 2);
    let mut states = States::new(2, 8);
    for _ in 0..200 {
        let (q, qd, qdd) = states.next();
        let (ta, tb) = (
            oracle::rnea(&a, &q, &qd, &qdd),
            oracle::rnea(&b, &q, &qd, &qdd),
        );
        for i in 0..2 {
            assert_close(ta[i], tb[i], "locked vs fixed");
        }
    }
}

#[test]
fn values_beyond_any_arm_are_located_errors() {
    for (from, to, key) in [
        ("mass = 1.0", "mass = 1e200", "links[1].mass"),
        (
            "com = [0.1, 0.0, 0.0]",
            "com = [1e5, 0.0, 0.0]",
            "links[1].com",
        ),
        (
            "ixx = 0.01, iyy = 0.02, izz = 0.02",
            "ixx = 1e300, iyy = 1e300, izz = 1e300",
            "links[1].inertia",
        ),
        (
            "name = \"two links\"",
            "name = \"two links\"\ngravity = [0.0, 0.0, -1e9]",
            "gravity",
        ),
    ] {
        let message = error_after(from, to);
        assert_mentions(&message, &[key, "beyond any arm"]);
    }
}

#[test]
fn a_huge_axis_is_normalized_without_overflow() {
    let description =
        parse(&VALID.replacen("axis = [0.0, 0.0, 1.0]", "axis = [0.0, 0.0, 1e200]", 1))
            .expect("a long axis is a direction");
    let axis = description.chain().bodies[0].axis;
    assert_eq!(axis, Vector3::new(0.0, 0.0, 1.0));
}

#[test]
fn asymmetric_friction_and_springs_are_validated_and_in_the_dynamics() {
    let joint = "axis = [0.0, 1.0, 0.0]\n";
    let with = |effects: &str| format!("{joint}effects = {{ {effects} }}\n");
    let e = error_after(joint, &with("coulomb = 0.1, coulomb_asymmetry = 0.2"));
    assert_mentions(&e, &["coulomb_asymmetry", "j2", "negative"]);
    let e = error_after(joint, &with("spring = -1.0"));
    assert_mentions(&e, &["spring", "j2", ">= 0"]);
    let e = error_after(joint, &with("spring = 1.0, spring_rest = 1e5"));
    assert_mentions(&e, &["spring_rest"]);
    // Valid: the numeric dynamics hold both (the spring in g(q) too).
    let source = VALID.replacen(
        joint,
        &with("coulomb = 0.3, coulomb_asymmetry = -0.1, spring = 2.0, spring_rest = 0.25"),
        1,
    );
    let model = Model::from_description(&parse(&source).unwrap());
    let plain = Model::from_description(&parse(VALID).unwrap());
    let (q, qdd) = ([0.2, 0.7], [0.0, 0.0]);
    for (qd, friction) in [(0.5, 0.3 - 0.1), (-0.5, -0.3 - 0.1), (0.0, 0.0)] {
        let qd = [0.1, qd];
        let difference =
            oracle::rnea(&model, &q, &qd, &qdd)[1] - oracle::rnea(&plain, &q, &qd, &qdd)[1];
        assert_close(difference, friction + 2.0 * (0.7 - 0.25), "tau difference");
    }
    let g = oracle::gravity(&model, &q)[1] - oracle::gravity(&plain, &q)[1];
    assert_close(g, 2.0 * (0.7 - 0.25), "spring in g(q)");
}

#[test]
fn stribeck_friction_and_ripple_are_validated_and_in_the_dynamics() {
    let joint = "axis = [0.0, 1.0, 0.0]\n";
    let with = |effects: &str| format!("{joint}effects = {{ {effects} }}\n");
    let e = error_after(joint, &with("stribeck = 0.2"));
    assert_mentions(&e, &["stribeck_velocity", "j2", "> 0"]);
    let e = error_after(joint, &with("stribeck = -0.2, stribeck_velocity = 0.1"));
    assert_mentions(&e, &["stribeck", "j2", ">= 0"]);
    let e = error_after(joint, &with("ripple_cos = 0.1"));
    assert_mentions(&e, &["ripple_cycles", "j2", "> 0"]);
    let e = error_after(joint, &with("ripple_sin = 0.1, ripple_cycles = 1e6"));
    assert_mentions(&e, &["ripple_cycles", "beyond"]);
    let e = error_after(joint, &with("stribeck_velocity = -1"));
    assert_mentions(&e, &["stribeck_velocity", ">= 0"]);
    // Valid: friction fades past the Stribeck velocity, the ripple is in
    // g(q) too.
    let source = VALID.replacen(
        joint,
        &with(
            "stribeck = 0.4, stribeck_velocity = 0.05, ripple_sin = 0.1, ripple_cos = 0.2, \
             ripple_cycles = 7",
        ),
        1,
    );
    let model = Model::from_description(&parse(&source).unwrap());
    let plain = Model::from_description(&parse(VALID).unwrap());
    let (q, qdd) = ([0.2, 0.7], [0.0, 0.0]);
    let ripple = 0.1 * (7.0 * 0.7_f64).sin() + 0.2 * (7.0 * 0.7_f64).cos();
    for (qd, friction) in [
        (0.05, 0.4 * (-1.0_f64).exp()),
        (-0.1, -0.4 * (-4.0_f64).exp()),
        (0.0, 0.0),
    ] {
        let qd = [0.1, qd];
        let difference =
            oracle::rnea(&model, &q, &qd, &qdd)[1] - oracle::rnea(&plain, &q, &qd, &qdd)[1];
        assert_close(difference, friction + ripple, "tau difference");
    }
    let g = oracle::gravity(&model, &q)[1] - oracle::gravity(&plain, &q)[1];
    assert_close(g, ripple, "ripple in g(q)");
}
