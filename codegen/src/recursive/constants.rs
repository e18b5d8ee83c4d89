//! The chain's numbers as named constants: the leaves of the traced programs.
//!
//! Every number of the reduced chain gets a name by link or joint and
//! quantity (`LINK3_MASS`, `JOINT2_Y`, `JOINT2_R01`, `GRAVITY_Z`), and the
//! programs use the names, so an edit of one number changes one constant's
//! line. Exact zeros are structural: they prune terms (a zero becoming
//! non-zero changes the code). Rotation and axis entries within `SNAP` of
//! 0 or +-1 are taken as exact (angles like pi/2 in floating point) and are
//! structural too; any other entry is a named constant.
//!
//! The ten standard inertial parameters of a link (the regressor's: mass,
//! first moment m*c, inertia about the link origin) are derived constants
//! written as formulas of the link's mass, center of mass and inertia, so a
//! mass edit leaves their text alone.

use nalgebra::Vector3;

use super::V3;
use crate::program::{Dag, NodeId};
use crate::reduce::{Body, Chain};
use crate::schema::{EFFECTS_PER_JOINT, JointKind};

/// Rotation entries closer than this to 0 or +-1 are taken as exact.
pub const SNAP: f64 = 1e-15;

/// Quantity names of the ten standard parameters, Pinocchio's order.
const STANDARD: [&str; 10] = [
    "MASS", "MX", "MY", "MZ", "IXX", "IXY", "IYY", "IXZ", "IYZ", "IZZ",
];
const AXES: [&str; 3] = ["X", "Y", "Z"];

/// A group of named numbers, emitted together under one comment.
#[derive(Debug, Clone, PartialEq)]
pub struct Group {
    /// What the numbers are (names from the description already escaped).
    pub doc: String,
    /// Name and value of each number, or name and defining formula (Rust
    /// source over the other names) for derived ones.
    pub items: Vec<(String, Definition)>,
}

/// How a named constant is defined.
#[derive(Debug, Clone, PartialEq)]
pub enum Definition {
    Value(f64),
    Formula(String),
}

/// The program leaves of one joint.
pub struct JointLeaves {
    pub translation: V3,
    pub rotation: [V3; 3],
    pub axis: V3,
    /// The effect parameters in the order of `JointEffects::parameters`.
    pub effects: [NodeId; EFFECTS_PER_JOINT],
    /// The spring's rest angle.
    pub spring_rest: NodeId,
    /// The Stribeck velocity and the ripple's cycles (inputs' constants,
    /// used by the derivatives).
    pub stribeck_velocity: NodeId,
    pub ripple_cycles: NodeId,
    /// A coupled joint's multiplier and offset (1 and 0 otherwise).
    pub coupling: [NodeId; 2],
}

/// The chain's leaves and the listing the generated file starts with.
pub struct Leaves {
    pub gravity: V3,
    pub joints: Vec<JointLeaves>,
    /// Per link the standard parameters (m, m*c, inertia about the origin).
    pub standard: Vec<[NodeId; 10]>,
    pub groups: Vec<Group>,
}

/// Names every number of `chain` in `dag`.
pub fn leaves(dag: &mut Dag, chain: &Chain) -> Leaves {
    let mut groups = Vec::new();
    let mut joints = Vec::new();
    let mut standard = Vec::new();
    for (i, body) in chain.bodies.iter().enumerate() {
        let (group, leaves) = joint(dag, i + 1, body);
        groups.push(group);
        joints.push(leaves);
    }
    for (i, body) in chain.bodies.iter().enumerate() {
        let (description, derived, nodes) = link(dag, i + 1, body);
        groups.push(description);
        groups.push(derived);
        standard.push(nodes);
    }
    let mut gravity_items = Vec::new();
    let gravity = [0, 1, 2].map(|k| {
        let name = format!("GRAVITY_{}", AXES[k]);
        gravity_items.push((name.clone(), Definition::Value(chain.gravity[k])));
        leaf(dag, &name, chain.gravity[k])
    });
    groups.push(Group {
        doc: "Gravity acceleration in the base frame, m/s^2.".into(),
        items: gravity_items,
    });
    Leaves {
        gravity,
        joints,
        standard,
        groups,
    }
}

/// A named leaf; an exact zero is the literal 0.
fn leaf(dag: &mut Dag, name: &str, value: f64) -> NodeId {
    if value == 0.0 {
        dag.constant(0.0)
    } else {
        dag.param(name, value)
    }
}

/// A rotation or axis entry: 0 and +-1 (after snapping) are literals.
fn snapped(x: f64) -> f64 {
    [0.0, 1.0, -1.0]
        .into_iter()
        .find(|exact| (x - exact).abs() < SNAP)
        .unwrap_or(x)
}

fn structural_leaf(dag: &mut Dag, name: &str, value: f64) -> NodeId {
    if value.abs() == 1.0 {
        dag.constant(value)
    } else {
        leaf(dag, name, value)
    }
}

/// A named number listed in `items`; structural ones (rotation and axis
/// entries) are literals when 0 or +-1.
fn listed(
    items: &mut Vec<(String, Definition)>,
    dag: &mut Dag,
    name: String,
    value: f64,
    structural: bool,
) -> NodeId {
    items.push((name.clone(), Definition::Value(value)));
    if structural {
        structural_leaf(dag, &name, value)
    } else {
        leaf(dag, &name, value)
    }
}

fn joint(dag: &mut Dag, i: usize, body: &Body) -> (Group, JointLeaves) {
    let mut items = Vec::new();
    let mut named = |dag: &mut Dag, name: String, value: f64, structural: bool| {
        listed(&mut items, dag, name, value, structural)
    };
    let translation = [0, 1, 2].map(|k| {
        named(
            dag,
            format!("JOINT{i}_{}", AXES[k]),
            body.translation[k],
            false,
        )
    });
    let rotation = [0, 1, 2].map(|r| {
        [0, 1, 2].map(|c| {
            let value = snapped(body.rotation[(r, c)]);
            named(dag, format!("JOINT{i}_R{r}{c}"), value, true)
        })
    });
    let axis = [0, 1, 2].map(|k| {
        let value = snapped(body.axis[k]);
        named(dag, format!("JOINT{i}_AXIS_{}", AXES[k]), value, true)
    });
    let e = body.effects;
    let effects = std::array::from_fn(|k| {
        let quantity = crate::schema::EFFECT_CONSTANTS[k];
        named(
            dag,
            format!("JOINT{i}_{quantity}"),
            e.parameters()[k],
            false,
        )
    });
    let spring_rest = named(dag, format!("JOINT{i}_SPRING_REST"), e.spring_rest, false);
    // Used by the generated prologue (the Stribeck and ripple inputs) and
    // by the derivatives.
    let stribeck_velocity = named(dag, stribeck_velocity(i), e.stribeck_velocity, false);
    let ripple_cycles = named(dag, ripple_cycles(i), e.ripple_cycles, false);
    let coupling = match &body.coupling {
        Some(c) => [
            named(
                dag,
                format!("JOINT{i}_MIMIC_MULTIPLIER"),
                c.multiplier,
                false,
            ),
            named(dag, format!("JOINT{i}_MIMIC_OFFSET"), c.offset, false),
        ],
        None => [dag.constant(1.0), dag.constant(0.0)],
    };
    let doc = match body.kind {
        JointKind::Prismatic => format!(
            "Joint {i} ({:?}, prismatic): origin in the previous link's axes (m), rotation \
             of its frame (entries within 1e-15 of 0 or +-1 made exact), unit direction of \
             travel; armature (kg), viscous (N s/m), Coulomb (N), offset (N), Coulomb \
             asymmetry (N), spring (N/m), Stribeck excess (N), ripple sine and cosine \
             amplitudes (N); the spring's rest position (m), the Stribeck velocity (m/s) \
             and the ripple's periods per 2 pi m of travel.",
            body.joint
        ),
        _ => format!(
            "Joint {i} ({:?}): origin in the previous link's axes (m), rotation of its \
             frame (entries within 1e-15 of 0 or +-1 made exact), unit axis; armature \
             (kg m^2), viscous (N m s/rad), Coulomb (N m), offset (N m), Coulomb \
             asymmetry (N m), spring (N m/rad), Stribeck excess (N m), ripple sine and \
             cosine amplitudes (N m); the spring's rest angle (rad), the Stribeck \
             velocity (rad/s) and the ripple's periods per revolution.",
            body.joint
        ),
    };
    let leaves = JointLeaves {
        translation,
        rotation,
        axis,
        effects,
        spring_rest,
        stribeck_velocity,
        ripple_cycles,
        coupling,
    };
    (Group { doc, items }, leaves)
}

/// The tool frame's named numbers (origin in the tip link's frame, then
/// rotation, structural 0 and +-1 as literals), their listing group, and
/// the leaves: rotation rows and origin.
pub fn tool(dag: &mut Dag, tool: &crate::tool::ToolFrame) -> (Group, [V3; 3], V3) {
    let mut items = Vec::new();
    let mut named = |dag: &mut Dag, name: String, value: f64, structural: bool| {
        listed(&mut items, dag, name, value, structural)
    };
    let translation =
        [0, 1, 2].map(|k| named(dag, format!("TOOL_{}", AXES[k]), tool.translation[k], false));
    let rotation = [0, 1, 2].map(|r| {
        [0, 1, 2].map(|c| {
            let value = snapped(tool.rotation[(r, c)]);
            named(dag, format!("TOOL_R{r}{c}"), value, true)
        })
    });
    let doc = format!(
        "The tool frame ({:?}, fixed to the tip link): origin in the tip link's axes (m), \
         rotation (entries within 1e-15 of 0 or +-1 made exact).",
        tool.link
    );
    (Group { doc, items }, rotation, translation)
}

/// The name of joint `i`'s (1-based) Stribeck velocity constant.
pub fn stribeck_velocity(i: usize) -> String {
    format!("JOINT{i}_STRIBECK_VELOCITY")
}

/// The name of joint `i`'s (1-based) ripple-cycles constant.
pub fn ripple_cycles(i: usize) -> String {
    format!("JOINT{i}_RIPPLE_CYCLES")
}

/// The description group of link `i`, its standard-parameter group and
/// the standard parameters as program leaves.
fn link(dag: &mut Dag, i: usize, body: &Body) -> (Group, Group, [NodeId; 10]) {
    let inertial = &body.inertial;
    let com = inertial.com;
    let inertia = inertial.inertia;
    let name = |quantity: &str| format!("LINK{i}_{quantity}");
    let mut items = vec![(name("MASS"), Definition::Value(inertial.mass))];
    for k in 0..3 {
        items.push((name(&format!("COM_{}", AXES[k])), Definition::Value(com[k])));
    }
    for (r, c) in [(0, 0), (0, 1), (1, 1), (0, 2), (1, 2), (2, 2)] {
        let quantity = format!("INERTIA_{}{}", AXES[r], AXES[c]);
        items.push((name(&quantity), Definition::Value(inertia[(r, c)])));
    }
    let description = Group {
        doc: format!(
            "Link {i}, moved by joint {i} (frame of link {:?}): mass (kg), center of \
             mass (m) and inertia about it (kg m^2), in link axes.",
            body.link
        ),
        items,
    };
    let (formulas, values) = standard_parameters(i, inertial.mass, &com, &inertia);
    let derived = Group {
        doc: format!(
            "Link {i}'s standard inertial parameters (the regressor's): first moment \
             m*c (kg m) and inertia about the link origin (kg m^2)."
        ),
        items: formulas
            .into_iter()
            .skip(1)
            .map(|(n, f)| (n, Definition::Formula(f)))
            .collect(),
    };
    let nodes =
        [0usize, 1, 2, 3, 4, 5, 6, 7, 8, 9].map(|k| leaf(dag, &name(STANDARD[k]), values[k]));
    (description, derived, nodes)
}

/// Names, formulas and values of link `i`'s standard parameters; the values
/// are computed in the formulas' order, so they equal the compiled constants.
fn standard_parameters(
    i: usize,
    mass: f64,
    com: &Vector3<f64>,
    inertia: &nalgebra::Matrix3<f64>,
) -> (Vec<(String, String)>, [f64; 10]) {
    let n = |quantity: &str| format!("LINK{i}_{quantity}");
    let c = |k: usize| n(&format!("COM_{}", AXES[k]));
    let mut formulas = vec![(n("MASS"), n("MASS"))];
    let mut values = [0.0; 10];
    values[0] = mass;
    for k in 0..3 {
        formulas.push((n(STANDARD[1 + k]), format!("{} * {}", n("MASS"), c(k))));
        values[1 + k] = mass * com[k];
    }
    for (slot, (r, col)) in [(0, 0), (0, 1), (1, 1), (0, 2), (1, 2), (2, 2)]
        .into_iter()
        .enumerate()
    {
        let about_com = n(&format!("INERTIA_{}{}", AXES[r], AXES[col]));
        let (formula, value) = if r == col {
            let (j, k) = ((r + 1) % 3, (r + 2) % 3);
            let (j, k) = (j.min(k), j.max(k));
            (
                format!(
                    "{about_com} + {} * ({} * {} + {} * {})",
                    n("MASS"),
                    c(j),
                    c(j),
                    c(k),
                    c(k)
                ),
                inertia[(r, r)] + mass * (com[j] * com[j] + com[k] * com[k]),
            )
        } else {
            (
                format!("{about_com} - {} * ({} * {})", n("MASS"), c(r), c(col)),
                inertia[(r, col)] - mass * (com[r] * com[col]),
            )
        };
        formulas.push((n(STANDARD[4 + slot]), formula));
        values[4 + slot] = value;
    }
    (formulas, values)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reduce::Inertial;
    use nalgebra::Matrix3;

    #[test]
    fn standard_parameters_equal_the_parallel_axis_theorem() {
        let inertial = Inertial {
            mass: 1.3,
            com: Vector3::new(0.1, -0.25, 0.4),
            inertia: Matrix3::new(0.02, 0.001, -0.002, 0.001, 0.03, 0.003, -0.002, 0.003, 0.01),
        };
        let (formulas, values) =
            standard_parameters(2, inertial.mass, &inertial.com, &inertial.inertia);
        let want = inertial.standard_parameters();
        for k in 0..10 {
            assert!((values[k] - want[k]).abs() < 1e-15, "{k}");
        }
        assert_eq!(formulas[1].1, "LINK2_MASS * LINK2_COM_X");
        assert_eq!(
            formulas[6].1,
            "LINK2_INERTIA_YY + LINK2_MASS * (LINK2_COM_X * LINK2_COM_X + LINK2_COM_Z * LINK2_COM_Z)"
        );
    }

    #[test]
    fn rotation_artefacts_snap_to_exact_values() {
        assert_eq!(snapped(6.123233995736766e-17), 0.0);
        assert_eq!(snapped(-0.9999999999999999), -1.0);
        assert_eq!(snapped(0.5), 0.5);
    }
}
