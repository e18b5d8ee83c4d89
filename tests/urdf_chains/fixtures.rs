//! URDFs with the quirks of real robot files (issue 22), built from small
//! pieces so that each fixture shows its quirk. Values are made up but
//! physical (positive masses, inertias satisfying the triangle inequality)
//! unless the quirk is the point.

use std::f64::consts::FRAC_PI_2;

/// `<link>` with an `<inertial>`: mass, COM (xyz) and inertial rpy, inertia
/// ixx iyy izz ixy ixz iyz.
pub fn link(name: &str, mass: f64, com: [f64; 3], rpy: [f64; 3], i: [f64; 6]) -> String {
    format!(
        r#"  <link name="{name}">
    <inertial>
      <origin xyz="{} {} {}" rpy="{} {} {}"/>
      <mass value="{mass}"/>
      <inertia ixx="{}" iyy="{}" izz="{}" ixy="{}" ixz="{}" iyz="{}"/>
    </inertial>
    <visual><geometry><box size="0.05 0.05 0.1"/></geometry></visual>
  </link>
"#,
        com[0], com[1], com[2], rpy[0], rpy[1], rpy[2], i[0], i[1], i[2], i[3], i[4], i[5]
    )
}

/// A link without `<inertial>`.
pub fn frame(name: &str) -> String {
    format!("  <link name=\"{name}\"/>\n")
}

/// A plausible body: inertia (with small products) for a link of `mass`.
pub fn body(name: &str, mass: f64, com: [f64; 3]) -> String {
    let s = 0.01 * mass;
    link(
        name,
        mass,
        com,
        [0.1, -0.2, 0.3],
        [s, 1.2 * s, 0.8 * s, 0.05 * s, -0.03 * s, 0.02 * s],
    )
}

/// `<joint>`; `kind` is the URDF type, `extra` goes inside the element
/// (`<limit>`, `<mimic>`, `<dynamics>`). One argument per part of the
/// element.
#[allow(clippy::too_many_arguments)]
pub fn joint(
    name: &str,
    kind: &str,
    parent: &str,
    child: &str,
    xyz: [f64; 3],
    rpy: [f64; 3],
    axis: [f64; 3],
    extra: &str,
) -> String {
    format!(
        r#"  <joint name="{name}" type="{kind}">
    <parent link="{parent}"/>
    <child link="{child}"/>
    <origin xyz="{} {} {}" rpy="{} {} {}"/>
    <axis xyz="{} {} {}"/>
    {extra}
  </joint>
"#,
        xyz[0], xyz[1], xyz[2], rpy[0], rpy[1], rpy[2], axis[0], axis[1], axis[2]
    )
}

pub fn fixed(name: &str, parent: &str, child: &str, xyz: [f64; 3], rpy: [f64; 3]) -> String {
    joint(name, "fixed", parent, child, xyz, rpy, [1.0, 0.0, 0.0], "")
}

pub fn robot(name: &str, parts: &[String]) -> String {
    format!(
        "<?xml version=\"1.0\"?>\n<robot name=\"{name}\">\n{}</robot>\n",
        parts.concat()
    )
}

const LIMIT: &str = r#"<limit lower="-2.9" upper="2.9" effort="40" velocity="2.0"/>"#;

/// Three revolute joints (tilted origins, a non-unit axis, damping) from
/// `parent` to `<prefix>link3`.
pub fn arm3(prefix: &str, parent: &str) -> Vec<String> {
    let n = |s: &str| format!("{prefix}{s}");
    vec![
        body(&n("link1"), 1.3, [0.01, 0.02, 0.08]),
        joint(
            &n("joint1"),
            "revolute",
            parent,
            &n("link1"),
            [0.0, 0.0, 0.12],
            [0.0, 0.0, 0.3],
            [0.0, 0.0, 1.0],
            LIMIT,
        ),
        body(&n("link2"), 1.1, [0.15, 0.0, 0.01]),
        joint(
            &n("joint2"),
            "revolute",
            &n("link1"),
            &n("link2"),
            [0.0, 0.03, 0.1],
            [FRAC_PI_2, 0.0, 0.2],
            [0.0, 0.0, 2.0],
            &format!(r#"{LIMIT}<dynamics damping="0.3" friction="0.2"/>"#),
        ),
        body(&n("link3"), 0.7, [0.1, -0.01, 0.0]),
        joint(
            &n("joint3"),
            "revolute",
            &n("link2"),
            &n("link3"),
            [0.3, 0.0, 0.0],
            [0.0, -0.4, 0.0],
            [0.0, 0.6, 0.8],
            LIMIT,
        ),
    ]
}

/// Serial arm without quirks: the control.
pub fn plain_arm() -> String {
    let mut parts = vec![body("base_link", 4.0, [0.0, 0.0, 0.05])];
    parts.extend(arm3("", "base_link"));
    parts.push(body("tool", 0.3, [0.0, 0.0, 0.04]));
    parts.push(fixed(
        "tool_joint",
        "link3",
        "tool",
        [0.2, 0.0, 0.0],
        [0.0, 1.2, 0.0],
    ));
    robot("plain_arm", &parts)
}

/// A dummy inertia on the fixed base, a point mass (zero inertia), an F/T
/// sensor of 1e-9 kg and a tool of 0.1 kg with zero inertia, a bare TCP frame.
pub fn point_masses() -> String {
    let zero = [0.0; 6];
    let mut parts = vec![
        frame("world"),
        link(
            "base_link",
            1e-3,
            [0.0; 3],
            [0.0; 3],
            [1e-6, 1e-6, 1e-6, 0.0, 0.0, 0.0],
        ),
        fixed("world_joint", "world", "base_link", [0.0; 3], [0.0; 3]),
    ];
    parts.extend(arm3("", "base_link"));
    parts.extend([
        link("elbow_mass", 0.6, [0.02, 0.0, 0.0], [0.0; 3], zero),
        fixed(
            "elbow_mass_joint",
            "link2",
            "elbow_mass",
            [0.3, 0.0, 0.0],
            [0.0; 3],
        ),
        link("ft_sensor", 1e-9, [0.0, 0.0, 0.01], [0.0; 3], zero),
        fixed(
            "ft_joint",
            "link3",
            "ft_sensor",
            [0.2, 0.0, 0.0],
            [0.0, FRAC_PI_2, 0.0],
        ),
        link("tool", 0.1, [0.0, 0.0, 0.05], [0.0; 3], zero),
        fixed(
            "tool_joint",
            "ft_sensor",
            "tool",
            [0.0, 0.0, 0.02],
            [0.0; 3],
        ),
        frame("tcp"),
        fixed("tcp_joint", "tool", "tcp", [0.0, 0.0, 0.1], [0.0; 3]),
    ]);
    robot("point_masses", &parts)
}

/// A thin rod (izz exactly 0) and a rod whose izz rounded below zero.
pub fn thin_rods() -> String {
    let mut parts = vec![body("base_link", 2.0, [0.0; 3])];
    parts.extend(arm3("", "base_link"));
    let rod = 1.0 * 0.5 * 0.5 / 12.0;
    parts.extend([
        link(
            "rod",
            1.0,
            [0.0, 0.0, 0.25],
            [0.0; 3],
            [rod, rod, 0.0, 0.0, 0.0, 0.0],
        ),
        fixed("rod_joint", "link3", "rod", [0.2, 0.0, 0.0], [0.0; 3]),
        link(
            "antenna",
            0.05,
            [0.0, 0.0, 0.1],
            [0.3, 0.0, 0.0],
            [1.7e-4, 1.7e-4, -1e-19, 0.0, 0.0, 0.0],
        ),
        fixed(
            "antenna_joint",
            "link1",
            "antenna",
            [0.0, 0.05, 0.1],
            [0.0; 3],
        ),
    ]);
    robot("thin_rods", &parts)
}

/// An inertia that no rigid body has: ixx > iyy + izz.
pub fn triangle_breach() -> String {
    let mut parts = vec![body("base_link", 2.0, [0.0; 3])];
    parts.extend(arm3("", "base_link"));
    parts[5] = link(
        "link3",
        0.7,
        [0.1, -0.01, 0.0],
        [0.0; 3],
        [0.1, 0.01, 0.01, 0.0, 0.0, 0.0],
    );
    robot("triangle_breach", &parts)
}

/// A prismatic lift between the base and a three-joint arm.
pub fn lift_under_arm() -> String {
    let mut parts = vec![
        body("base_link", 20.0, [0.0, 0.0, 0.2]),
        body("torso", 8.0, [0.0, 0.0, 0.3]),
        joint(
            "torso_lift",
            "prismatic",
            "base_link",
            "torso",
            [-0.06, 0.0, 0.5],
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 1.0],
            r#"<limit lower="0" upper="0.35" effort="2000" velocity="0.07"/>"#,
        ),
    ];
    parts.extend(arm3("", "torso"));
    robot("lift_under_arm", &parts)
}

/// Panda-like hand on an arm: two prismatic fingers, the second a mimic.
pub fn panda_hand() -> String {
    let mut parts = vec![body("base_link", 3.0, [0.0; 3])];
    parts.extend(arm3("", "base_link"));
    let finger = r#"<limit lower="0" upper="0.04" effort="20" velocity="0.2"/>"#;
    parts.extend([
        body("hand", 0.73, [-0.01, 0.0, 0.03]),
        fixed(
            "hand_joint",
            "link3",
            "hand",
            [0.2, 0.0, 0.0],
            [0.0, FRAC_PI_2, 0.0],
        ),
        body("leftfinger", 0.015, [0.0, 0.01, 0.02]),
        body("rightfinger", 0.015, [0.0, -0.01, 0.02]),
        joint(
            "finger_joint1",
            "prismatic",
            "hand",
            "leftfinger",
            [0.0, 0.0, 0.0584],
            [0.0; 3],
            [0.0, 1.0, 0.0],
            finger,
        ),
        joint(
            "finger_joint2",
            "prismatic",
            "hand",
            "rightfinger",
            [0.0, 0.0, 0.0584],
            [0.0; 3],
            [0.0, -1.0, 0.0],
            &format!(r#"{finger}<mimic joint="finger_joint1"/>"#),
        ),
        frame("hand_tcp"),
        fixed(
            "hand_tcp_joint",
            "hand",
            "hand_tcp",
            [0.0, 0.0, 0.1034],
            [0.0; 3],
        ),
    ]);
    robot("panda_hand", &parts)
}

/// A linkage gripper (Robotiq-like): the master `finger_joint` and four
/// mimic joints, two of them nested and one with an offset.
pub fn linkage_gripper() -> String {
    let mut parts = vec![body("base_link", 3.0, [0.0; 3])];
    parts.extend(arm3("", "base_link"));
    parts.extend([
        body("gripper_base", 0.6, [0.0, 0.0, 0.04]),
        fixed(
            "gripper_mount",
            "link3",
            "gripper_base",
            [0.2, 0.0, 0.0],
            [0.0, FRAC_PI_2, 0.0],
        ),
    ]);
    let limit = r#"<limit lower="0" upper="0.8" effort="1000" velocity="2.0"/>"#;
    let mimic = |m: f64, o: f64| {
        format!(r#"{limit}<mimic joint="finger_joint" multiplier="{m}" offset="{o}"/>"#)
    };
    for (side, y, s) in [("left", 0.03, 1.0), ("right", -0.03, -1.0)] {
        let n = |x: &str| format!("{side}_{x}");
        parts.extend([
            body(&n("outer_knuckle"), 0.05, [0.0, s * 0.01, 0.02]),
            body(&n("inner_knuckle"), 0.03, [0.0, s * 0.01, 0.03]),
            body(&n("finger_tip"), 0.02, [0.0, -s * 0.005, 0.02]),
        ]);
        let outer_extra = if side == "left" {
            limit.to_string()
        } else {
            mimic(1.0, 0.0)
        };
        let outer_name = if side == "left" {
            "finger_joint".to_string()
        } else {
            n("outer_knuckle_joint")
        };
        parts.extend([
            joint(
                &outer_name,
                "revolute",
                "gripper_base",
                &n("outer_knuckle"),
                [0.0, y, 0.06],
                [0.0, 0.0, 0.0],
                [s, 0.0, 0.0],
                &outer_extra,
            ),
            joint(
                &n("inner_knuckle_joint"),
                "revolute",
                "gripper_base",
                &n("inner_knuckle"),
                [0.0, y / 2.0, 0.07],
                [0.0; 3],
                [s, 0.0, 0.0],
                &mimic(1.0, 0.0),
            ),
            joint(
                &n("finger_tip_joint"),
                "revolute",
                &n("outer_knuckle"),
                &n("finger_tip"),
                [0.0, s * 0.03, 0.05],
                [0.0; 3],
                [s, 0.0, 0.0],
                &mimic(-1.0, 0.1),
            ),
        ]);
    }
    robot("linkage_gripper", &parts)
}

/// A mimic joint on the chain: `joint3` follows `joint2` (one DOF drives
/// both), then a fourth joint.
pub fn mimic_on_chain() -> String {
    let mut parts = vec![body("base_link", 3.0, [0.0; 3])];
    parts.extend(arm3("", "base_link"));
    parts[6] = joint(
        "joint3",
        "revolute",
        "link2",
        "link3",
        [0.3, 0.0, 0.0],
        [0.0, -0.4, 0.0],
        [0.0, 0.6, 0.8],
        r#"<mimic joint="joint2" multiplier="0.5" offset="0.2"/>"#,
    );
    parts.extend([
        body("link4", 0.4, [0.05, 0.0, 0.02]),
        joint(
            "joint4",
            "continuous",
            "link3",
            "link4",
            [0.2, 0.0, 0.0],
            [0.0; 3],
            [1.0, 0.0, 0.0],
            "",
        ),
    ]);
    robot("mimic_on_chain", &parts)
}

/// What real files carry besides dynamics: a `<color>` with three numbers,
/// a `<texture/>` without a filename, transmissions, gazebo tags, and
/// continuous joints with effort and velocity limits.
pub fn cosmetics() -> String {
    let mut parts = vec![
        r#"  <material name="grey"><color rgba="0.5 0.5 0.5"/></material>
  <material name="steel"><texture/></material>
"#
        .to_string(),
        r#"  <link name="base_link">
    <inertial><mass value="2.0"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <visual><geometry><cylinder radius="0.05" length="0.1"/></geometry><material name="grey"><color rgba="0.5 0.5 0.5"/></material></visual>
    <visual><geometry><mesh filename="package://arm/meshes/base.stl"/></geometry><material name="steel"><texture/></material></visual>
    <collision><geometry><sphere radius="0.06"/></geometry></collision>
  </link>
"#
        .to_string(),
    ];
    parts.extend(arm3("", "base_link"));
    let continuous = r#"<limit effort="30" velocity="3.1"/><safety_controller k_velocity="10"/>"#;
    parts[3] = joint(
        "joint1",
        "continuous",
        "base_link",
        "link1",
        [0.0, 0.0, 0.12],
        [0.0, 0.0, 0.3],
        [0.0, 0.0, 1.0],
        continuous,
    );
    parts.extend([
        body("link4", 0.4, [0.05, 0.0, 0.02]),
        joint("joint4", "continuous", "link3", "link4", [0.2, 0.0, 0.0], [0.0; 3], [1.0, 0.0, 0.0], continuous),
        r#"  <transmission name="trans1">
    <type>transmission_interface/SimpleTransmission</type>
    <joint name="joint1"><hardwareInterface>hardware_interface/EffortJointInterface</hardwareInterface></joint>
    <actuator name="motor1"><mechanicalReduction>100</mechanicalReduction></actuator>
  </transmission>
  <gazebo reference="link1"><material>Gazebo/Grey</material><mu1>0.2</mu1></gazebo>
  <gazebo><plugin name="gazebo_ros_control" filename="libgazebo_ros_control.so"><robotNamespace>/arm</robotNamespace></plugin></gazebo>
"#
        .to_string(),
    ]);
    robot("cosmetics", &parts)
}

/// A floating root (`world` -> `base_link`, as in humanoid and mobile
/// files), the arm mounted below it.
pub fn floating_root() -> String {
    let mut parts = vec![
        frame("world"),
        body("base_link", 5.0, [0.0; 3]),
        joint(
            "root_joint",
            "floating",
            "world",
            "base_link",
            [0.0, 0.0, 0.8],
            [0.0; 3],
            [1.0, 0.0, 0.0],
            "",
        ),
    ];
    parts.extend(arm3("", "base_link"));
    robot("floating_root", &parts)
}

/// A humanoid upper body: a waist joint and a tilted chest above two arms
/// and a head, a two-finger mimic gripper on the left hand. The chain is
/// one arm cut from its shoulder mount; the waist is held (or locked).
pub fn humanoid() -> String {
    let mut parts = vec![
        body("pelvis", 10.0, [0.0, 0.0, 0.05]),
        body("torso", 15.0, [0.0, 0.0, 0.2]),
        joint(
            "waist",
            "revolute",
            "pelvis",
            "torso",
            [0.0, 0.0, 0.1],
            [0.0; 3],
            [0.0, 1.0, 0.0],
            LIMIT,
        ),
        body("chest", 6.0, [0.0, 0.0, 0.1]),
        fixed(
            "chest_joint",
            "torso",
            "chest",
            [0.0, 0.0, 0.3],
            [0.05, 0.1, 0.0],
        ),
        body("head", 3.0, [0.0, 0.0, 0.1]),
        joint(
            "neck",
            "revolute",
            "chest",
            "head",
            [0.0, 0.0, 0.25],
            [0.0; 3],
            [0.0, 0.0, 1.0],
            LIMIT,
        ),
    ];
    for (side, y, roll) in [("l_", 0.2, -FRAC_PI_2), ("r_", -0.2, FRAC_PI_2)] {
        let mount = format!("{side}shoulder_mount");
        parts.push(frame(&mount));
        parts.push(fixed(
            &format!("{mount}_joint"),
            "chest",
            &mount,
            [0.0, y, 0.2],
            [roll, 0.0, 0.0],
        ));
        parts.extend(arm3(side, &mount));
    }
    let finger = r#"<limit lower="0" upper="0.04" effort="20" velocity="0.2"/>"#;
    parts.extend([
        body("l_hand", 0.5, [0.0, 0.0, 0.04]),
        fixed(
            "l_wrist",
            "l_link3",
            "l_hand",
            [0.2, 0.0, 0.0],
            [0.0, FRAC_PI_2, 0.0],
        ),
        body("l_finger_a", 0.04, [0.0, 0.01, 0.03]),
        body("l_finger_b", 0.04, [0.0, -0.01, 0.03]),
        joint(
            "l_gripper",
            "revolute",
            "l_hand",
            "l_finger_a",
            [0.0, 0.02, 0.08],
            [0.0; 3],
            [1.0, 0.0, 0.0],
            finger,
        ),
        joint(
            "l_gripper_mimic",
            "revolute",
            "l_hand",
            "l_finger_b",
            [0.0, -0.02, 0.08],
            [0.0; 3],
            [1.0, 0.0, 0.0],
            &format!(r#"{finger}<mimic joint="l_gripper" multiplier="-1.0" offset="0.0"/>"#),
        ),
    ]);
    robot("humanoid", &parts)
}

/// A gripper on its own, its palm the fixed base: the left finger is the
/// chain, the right finger hangs from the palm and mimics the left one's
/// joint, with damping (it moves with the chain, it is no fixed branch).
pub fn palm_gripper() -> String {
    let finger = |side: &str, sign: f64, extra: &str| {
        [
            body(&format!("knuckle_{side}"), 0.08, [0.0, 0.01 * sign, 0.03]),
            joint(
                &format!("knuckle_{side}_joint"),
                "revolute",
                "palm",
                &format!("knuckle_{side}"),
                [0.0, 0.03 * sign, 0.05],
                [0.0, 0.0, 0.2 * sign],
                [1.0, 0.0, 0.0],
                &format!(r#"<limit lower="-0.5" upper="0.8" effort="5" velocity="2"/>{extra}"#),
            ),
            body(&format!("dist_{side}"), 0.05, [0.0, 0.0, 0.02]),
            joint(
                &format!("dist_{side}_joint"),
                "revolute",
                &format!("knuckle_{side}"),
                &format!("dist_{side}"),
                [0.0, 0.0, 0.06],
                [0.1, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                r#"<limit lower="-0.5" upper="0.8" effort="5" velocity="2"/>"#,
            ),
        ]
    };
    let mut parts = vec![body("palm", 0.3, [0.0, 0.0, 0.02])];
    parts.extend(finger("l", 1.0, ""));
    parts.extend(finger(
        "r",
        -1.0,
        r#"<mimic joint="knuckle_l_joint" multiplier="-1.0" offset="0.05"/><dynamics damping="0.2"/>"#,
    ));
    robot("palm_gripper", &parts)
}
