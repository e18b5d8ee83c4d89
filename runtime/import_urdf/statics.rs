//! What a held or dropped branch weighs on the chain: its mass and the
//! largest gravity torque it puts on a moving joint over poses of the chain
//! within its limits. Held branches are kept, so this is what their hold
//! position can matter at most; dropped branches are missing that much.
//! A static computation on the URDF tree itself (forward kinematics and
//! `a . ((c - p) x m g)`), independent of the generator.

use std::collections::BTreeMap;
use std::f64::consts::PI;

use codegen::reduce::rpy_matrix;
use nalgebra::{Matrix3, Rotation3, Unit, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::chain::{Locks, Role, Selection, held_position};
use super::parse::Kind;
use super::tree::Tree;

/// Poses sampled within the limits, besides the zero pose: enough to find
/// a branch's largest lever within a few percent.
const POSES: usize = 64;

/// Most joint-and-branch pairs evaluated over all poses. A robot (a hand's
/// twenty branches on a 7-joint arm) gets every pose; a URDF with
/// thousands of branches on a chain of thousands of joints gets fewer, down
/// to the zero pose alone, so the import stays quick on any URDF (a comb
/// of 500 branches took 122 s with every pose for every branch).
const MOST_PAIRS: usize = 2_000_000;

/// A link's frame in the base frame.
#[derive(Clone, Copy)]
struct Frame {
    rotation: Matrix3<f64>,
    origin: Vector3<f64>,
}

/// A moving joint's axis and origin in the base frame.
struct Axis {
    joint: usize,
    prismatic: bool,
    axis: Vector3<f64>,
    origin: Vector3<f64>,
}

/// What a group of branches weighs on the chain.
pub(super) struct Load {
    /// Mass of the subtrees below the group's joints, kg.
    pub mass: f64,
    /// The largest gravity torque (N m, or N on a prismatic joint) they put
    /// on a moving joint of the chain, and that joint.
    pub torque: f64,
    pub joint: Option<usize>,
}

/// The load of each group of `branches` (joints hanging from one link),
/// over the same poses of the chain: each pose's kinematics computed once
/// for all groups.
pub(super) fn branches_loads(
    tree: &Tree<'_>,
    s: &Selection,
    locks: &Locks,
    gravity: Vector3<f64>,
    groups: &[Vec<usize>],
) -> Vec<Load> {
    let links: Vec<Vec<usize>> = groups
        .iter()
        .map(|g| {
            g.iter()
                .flat_map(|&b| tree.subtree_links(tree.child_link(b)))
                .collect()
        })
        .collect();
    let mut loads: Vec<Load> = links
        .iter()
        .map(|l| Load {
            mass: l.iter().map(|&l| link_mass(tree, l)).sum(),
            torque: 0.0,
            joint: None,
        })
        .collect();
    let pairs: usize = groups
        .iter()
        .filter_map(|g| g.first())
        .map(|&b| tree.joints_above(tree.child_link(b)).len())
        .sum();
    let poses = POSES.min(MOST_PAIRS / pairs.max(1));
    let mut rng = ChaCha8Rng::seed_from_u64(22);
    for pose in 0..=poses {
        let q = positions(tree, s, locks, (pose > 0).then_some(&mut rng));
        let (frames, axes) = forward(tree, s, &q);
        let mut axis_of = vec![None; tree.joint_count()];
        for a in &axes {
            axis_of[a.joint] = Some(a);
        }
        for ((group, links), load) in groups.iter().zip(&links).zip(&mut loads) {
            let (Some(&branch), Some((m, c))) = (group.first(), centre(tree, &frames, links))
            else {
                continue;
            };
            let weight = m * gravity;
            let above = tree.joints_above(tree.child_link(branch));
            for a in above.iter().filter_map(|&j| axis_of[j]) {
                let tau = if a.prismatic {
                    a.axis.dot(&weight)
                } else {
                    a.axis.dot(&(c - a.origin).cross(&weight))
                };
                if tau.abs() > load.torque {
                    (load.torque, load.joint) = (tau.abs(), Some(a.joint));
                }
            }
        }
    }
    loads
}

fn link_mass(tree: &Tree<'_>, link: usize) -> f64 {
    match &tree.link(link).inertial {
        Ok(Some(i)) => i.mass,
        _ => 0.0,
    }
}

/// Every joint's position: moving ones sampled within their limits (0 when
/// `rng` is None), held ones at their hold, mimic joints following.
fn positions(
    tree: &Tree<'_>,
    s: &Selection,
    locks: &Locks,
    mut rng: Option<&mut ChaCha8Rng>,
) -> BTreeMap<usize, f64> {
    let mut q = BTreeMap::new();
    for (&j, role) in &s.roles {
        if *role == Role::Moving {
            let (lower, upper) = range(tree, j);
            let value = rng.as_mut().map_or(0.0, |r| r.random_range(lower..=upper));
            q.insert(j, value);
        }
    }
    for j in 0..tree.urdf.joints.len() {
        if q.contains_key(&j) {
            continue;
        }
        let value = match (s.roles.get(&j), &tree.joint(j).mimic) {
            (Some(Role::Locked(v)), _) => *v,
            (_, Some(m)) => match tree.joint_index.get(m.joint.as_str()) {
                Some(master) if q.contains_key(master) => m.multiplier * q[master] + m.offset,
                _ => held_position(tree, locks, j, 0),
            },
            _ => held_position(tree, locks, j, 0),
        };
        q.insert(j, value);
    }
    q
}

fn range(tree: &Tree<'_>, joint: usize) -> (f64, f64) {
    let limit = tree.joint(joint).data.as_ref().map(|d| d.limit).ok();
    let given = limit.and_then(|l| Some((l.lower?, l.upper?)));
    match (tree.kind(joint), given) {
        (Kind::Revolute | Kind::Prismatic, Some((lower, upper))) if lower < upper => (lower, upper),
        (Kind::Prismatic, _) => (0.0, 0.0),
        _ => (-PI, PI),
    }
}

/// Frames of the kept links and axes of the moving joints, in the base frame.
fn forward(
    tree: &Tree<'_>,
    s: &Selection,
    q: &BTreeMap<usize, f64>,
) -> (BTreeMap<usize, Frame>, Vec<Axis>) {
    let identity = Frame {
        rotation: Matrix3::identity(),
        origin: Vector3::zeros(),
    };
    let mut frames = BTreeMap::from([(s.base, identity)]);
    let mut axes = Vec::new();
    let mut stack = vec![s.base];
    while let Some(link) = stack.pop() {
        let parent = frames[&link];
        for &j in tree.child_joints(link) {
            let Ok(data) = &tree.joint(j).data else {
                continue;
            };
            let rotation = parent.rotation * rpy_matrix(&data.rpy);
            let origin = parent.origin + parent.rotation * Vector3::from(data.xyz);
            let axis = Unit::try_new(Vector3::from(data.axis), 1e-12);
            let value = q.get(&j).copied().unwrap_or(0.0);
            let mut child = Frame { rotation, origin };
            match (tree.kind(j), axis) {
                (Kind::Revolute | Kind::Continuous, Some(axis)) => {
                    child.rotation = rotation * Rotation3::from_axis_angle(&axis, value);
                }
                (Kind::Prismatic, Some(axis)) => {
                    child.origin += rotation * axis.into_inner() * value
                }
                _ => {}
            }
            if s.roles.get(&j) == Some(&Role::Moving)
                && let Some(axis) = axis
            {
                axes.push(Axis {
                    joint: j,
                    prismatic: tree.kind(j) == Kind::Prismatic,
                    axis: rotation * axis.into_inner(),
                    origin,
                });
            }
            frames.insert(tree.child_link(j), child);
            stack.push(tree.child_link(j));
        }
    }
    (frames, axes)
}

/// Mass and centre of mass (base frame) of `links`; None when massless.
fn centre(
    tree: &Tree<'_>,
    frames: &BTreeMap<usize, Frame>,
    links: &[usize],
) -> Option<(f64, Vector3<f64>)> {
    let mut mass = 0.0;
    let mut moment = Vector3::zeros();
    for &l in links {
        let (Some(frame), Ok(Some(inertial))) = (frames.get(&l), &tree.link(l).inertial) else {
            continue;
        };
        let c = frame.origin + frame.rotation * Vector3::from(inertial.xyz);
        mass += inertial.mass;
        moment += inertial.mass * c;
    }
    (mass > 0.0).then(|| (mass, moment / mass))
}
