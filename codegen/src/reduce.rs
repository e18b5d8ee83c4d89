//! DOF reduction: fixed and held joints (locked, or mimics of a locked
//! joint) are lumped into the moving body they hang from (thesis Eq.
//! 2.1-2.9, with the full parallel-axis term), leaving a serial chain of
//! revolute and prismatic joints.

use std::collections::{HashMap, HashSet};

use nalgebra::{Matrix3, Rotation3, Unit, Vector3};

use crate::error::{KeyPath, Located};
use crate::schema::{Inertia, Joint, JointEffects, JointKind, Limits, Link};

/// A serial chain of moving bodies, base first.
#[derive(Debug, Clone, PartialEq)]
pub struct Chain {
    /// Gravity acceleration in the base frame, m/s^2.
    pub gravity: Vector3<f64>,
    pub bodies: Vec<Body>,
}

impl Chain {
    /// Degrees of freedom: the bodies whose joints move alone (a coupled
    /// body follows one of them).
    pub fn dof(&self) -> usize {
        self.bodies.iter().filter(|b| b.coupling.is_none()).count()
    }

    /// The body of each degree of freedom, base first.
    pub fn dof_bodies(&self) -> Vec<usize> {
        (0..self.bodies.len())
            .filter(|&b| self.bodies[b].coupling.is_none())
            .collect()
    }

    /// The bodies of the degrees of freedom, base first.
    pub fn free_bodies(&self) -> impl Iterator<Item = &Body> {
        self.bodies.iter().filter(|b| b.coupling.is_none())
    }

    /// Whether any joint on the chain follows another.
    pub fn is_coupled(&self) -> bool {
        self.bodies.iter().any(|b| b.coupling.is_some())
    }

    /// Body `b`'s degree of freedom and its position's multiplier and
    /// offset: q_b = multiplier * q_dof + offset.
    pub fn driver(&self, b: usize) -> (usize, f64, f64) {
        match &self.bodies[b].coupling {
            Some(c) => (c.dof, c.multiplier, c.offset),
            None => (
                self.bodies[..b]
                    .iter()
                    .filter(|x| x.coupling.is_none())
                    .count(),
                1.0,
                0.0,
            ),
        }
    }
}

/// A body whose joint follows another joint on the chain (a mimic):
/// q = multiplier * q_dof + offset.
#[derive(Debug, Clone, PartialEq)]
pub struct Coupling {
    /// The name of the joint it follows.
    pub master: String,
    /// That joint's degree of freedom (0-based).
    pub dof: usize,
    pub multiplier: f64,
    pub offset: f64,
}

/// A moving body: everything rigidly attached after one moving joint.
///
/// Its frame is the joint frame rotated by q about `axis` (revolute) or
/// moved by q along it (prismatic). The joint frame is
/// `rotation`/`translation` away from the previous body's frame (the base
/// frame for the first body).
#[derive(Debug, Clone, PartialEq)]
pub struct Body {
    /// Name of the moving joint.
    pub joint: String,
    /// Name of the link whose frame is the body frame.
    pub link: String,
    pub rotation: Matrix3<f64>,
    pub translation: Vector3<f64>,
    /// Revolute or prismatic.
    pub kind: JointKind,
    /// Unit rotation axis or direction of travel in the joint frame.
    pub axis: Vector3<f64>,
    pub inertial: Inertial,
    pub effects: JointEffects,
    pub limits: Option<Limits>,
    /// Set when the joint follows another one on the chain.
    pub coupling: Option<Coupling>,
    /// The moving body it hangs from (an index into `Chain::bodies`, always
    /// smaller); `None` for the base. Coupled bodies may branch.
    pub parent: Option<usize>,
}

/// Mass, centre of mass and inertia about the centre of mass, in body axes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Inertial {
    pub mass: f64,
    pub com: Vector3<f64>,
    pub inertia: Matrix3<f64>,
}

impl Inertial {
    pub const ZERO: Inertial = Inertial {
        mass: 0.0,
        com: Vector3::new(0.0, 0.0, 0.0),
        inertia: Matrix3::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    };

    /// The ten standard inertial parameters, Pinocchio's order:
    /// m, m*cx, m*cy, m*cz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz, with the inertia
    /// taken about the body frame origin.
    pub fn standard_parameters(&self) -> [f64; 10] {
        let m = self.mass;
        let c = self.com;
        let i = self.inertia + m * (c.norm_squared() * Matrix3::identity() - c * c.transpose());
        [
            m,
            m * c.x,
            m * c.y,
            m * c.z,
            i[(0, 0)],
            i[(0, 1)],
            i[(1, 1)],
            i[(0, 2)],
            i[(1, 2)],
            i[(2, 2)],
        ]
    }

    /// The same body seen from a frame in which this one sits at
    /// `translation` with orientation `rotation`.
    pub fn transformed(&self, rotation: &Matrix3<f64>, translation: &Vector3<f64>) -> Inertial {
        Inertial {
            mass: self.mass,
            com: rotation * self.com + translation,
            inertia: rotation * self.inertia * rotation.transpose(),
        }
    }

    /// Lumps rigidly attached bodies given in one frame: mass sum,
    /// mass-weighted COM, parallel-axis theorem about the combined COM.
    pub fn combine(parts: &[Inertial]) -> Inertial {
        // One part stays bit for bit what the description says.
        if let [single] = parts {
            return *single;
        }
        let mass: f64 = parts.iter().map(|p| p.mass).sum();
        if mass == 0.0 {
            return Inertial::ZERO;
        }
        let com = parts.iter().map(|p| p.mass * p.com).sum::<Vector3<f64>>() / mass;
        let inertia = parts
            .iter()
            .map(|p| {
                let d = p.com - com;
                p.inertia + p.mass * (d.norm_squared() * Matrix3::identity() - d * d.transpose())
            })
            .sum();
        Inertial { mass, com, inertia }
    }
}

/// Rotation of a URDF-style roll-pitch-yaw: Rz(yaw) * Ry(pitch) * Rx(roll).
pub fn rpy_matrix(rpy: &[f64; 3]) -> Matrix3<f64> {
    Rotation3::from_euler_angles(rpy[0], rpy[1], rpy[2]).into_inner()
}

/// Rotation by `angle` about the unit `axis`.
pub fn axis_angle(axis: &Vector3<f64>, angle: f64) -> Matrix3<f64> {
    Rotation3::from_axis_angle(&Unit::new_normalize(*axis), angle).into_inner()
}

/// Where a link sits relative to the moving body that carries it.
struct Placement {
    body: Option<usize>,
    rotation: Matrix3<f64>,
    translation: Vector3<f64>,
}

/// The links and joints of a validated description, with name indexes
/// (look-ups by scanning made loading quadratic in the chain).
struct Tree<'a> {
    links: &'a [Link],
    joints: &'a [Joint],
    gravity: [f64; 3],
    link_index: HashMap<&'a str, usize>,
    joint_index: HashMap<&'a str, usize>,
}

impl<'a> Tree<'a> {
    fn new(links: &'a [Link], joints: &'a [Joint], gravity: [f64; 3]) -> Tree<'a> {
        let index =
            |names: Vec<&'a str>| names.into_iter().enumerate().map(|(i, n)| (n, i)).collect();
        Tree {
            links,
            joints,
            gravity,
            link_index: index(links.iter().map(|l| l.name.as_str()).collect()),
            joint_index: index(joints.iter().map(|j| j.name.as_str()).collect()),
        }
    }

    /// The link no joint has as its child.
    fn root(&self) -> &Link {
        let children: HashSet<&str> = self.joints.iter().map(|j| j.child.as_str()).collect();
        self.links
            .iter()
            .find(|l| !children.contains(l.name.as_str()))
            .expect("validated description has a root")
    }

    fn link(&self, name: &str) -> Option<&Link> {
        self.link_index.get(name).map(|&i| &self.links[i])
    }

    fn joint(&self, name: &str) -> Option<&Joint> {
        self.joint_index.get(name).map(|&j| &self.joints[j])
    }
}

/// Reduces a validated description (its links, joints and gravity) to its
/// serial chain of moving bodies.
pub(crate) fn reduce(
    links: &[Link],
    joints: &[Joint],
    gravity: [f64; 3],
) -> Result<Chain, Located> {
    let description = &Tree::new(links, joints, gravity);
    let mut bodies: Vec<Body> = Vec::new();
    let mut parts: Vec<Vec<Inertial>> = Vec::new();
    let mut parent_body: Vec<Option<usize>> = Vec::new();
    let children = children_by_parent(description);
    let root = description.root().name.clone();
    let mut stack = vec![(
        root,
        Placement {
            body: None,
            rotation: Matrix3::identity(),
            translation: Vector3::zeros(),
        },
    )];
    while let Some((link_name, placement)) = stack.pop() {
        let link = description
            .link(&link_name)
            .ok_or_else(|| missing(&link_name))?;
        if let (Some(b), Some(inertial)) = (placement.body, link_inertial(link)) {
            parts[b].push(inertial.transformed(&placement.rotation, &placement.translation));
        }
        for &j in children
            .get(link_name.as_str())
            .map_or(&[][..], Vec::as_slice)
        {
            let joint = &description.joints[j];
            let origin_rotation = placement.rotation * rpy_matrix(&joint.origin.rpy);
            let origin_translation =
                placement.rotation * Vector3::from(joint.origin.xyz) + placement.translation;
            let coupling = coupling_of(description, joint);
            let child = if joint.is_free() || coupling.is_some() {
                bodies.push(Body {
                    joint: joint.name.clone(),
                    link: joint.child.clone(),
                    rotation: origin_rotation,
                    translation: origin_translation,
                    kind: joint.kind,
                    axis: Vector3::from(joint.axis).normalize(),
                    inertial: Inertial::ZERO,
                    effects: joint.effects,
                    limits: joint.limits,
                    coupling,
                    parent: None,
                });
                parts.push(Vec::new());
                parent_body.push(placement.body);
                Placement {
                    body: Some(bodies.len() - 1),
                    rotation: Matrix3::identity(),
                    translation: Vector3::zeros(),
                }
            } else {
                let (turn, shift) = held_motion(description, joint)?;
                Placement {
                    body: placement.body,
                    rotation: origin_rotation * turn,
                    translation: origin_translation + origin_rotation * shift,
                }
            };
            stack.push((joint.child.clone(), child));
        }
    }
    for (body, parts) in bodies.iter_mut().zip(&parts) {
        body.inertial = Inertial::combine(parts);
    }
    order_tree(description, bodies, parent_body)
}

fn children_by_parent<'a>(description: &Tree<'a>) -> HashMap<&'a str, Vec<usize>> {
    let mut children: HashMap<&str, Vec<usize>> = HashMap::new();
    for (j, joint) in description.joints.iter().enumerate() {
        children.entry(joint.parent.as_str()).or_default().push(j);
    }
    // Reverse so the depth-first stack visits joints in file order.
    for list in children.values_mut() {
        list.reverse();
    }
    children
}

/// The rotation and the shift (joint axes) of a joint that does not move
/// alone: fixed, locked, or a mimic of a locked joint.
fn held_motion(
    description: &Tree<'_>,
    joint: &Joint,
) -> Result<(Matrix3<f64>, Vector3<f64>), Located> {
    let position = held_position(description, joint)?;
    let axis = Vector3::from(joint.axis);
    Ok(match joint.kind {
        JointKind::Revolute => (axis_angle(&axis, position), Vector3::zeros()),
        JointKind::Prismatic => (Matrix3::identity(), axis.normalize() * position),
        JointKind::Fixed => (Matrix3::identity(), Vector3::zeros()),
    })
}

/// A mimic of a joint that moves: coupled to it (its degree of freedom is
/// found once the chain is ordered).
fn coupling_of(description: &Tree<'_>, joint: &Joint) -> Option<Coupling> {
    let mimic = joint.mimic.as_ref()?;
    let master = description.joint(&mimic.joint)?;
    master.is_free().then(|| Coupling {
        master: master.name.clone(),
        dof: 0,
        multiplier: mimic.multiplier,
        offset: mimic.offset,
    })
}

/// The position of a held joint: its lock, or its master's times the
/// multiplier plus the offset.
fn held_position(description: &Tree<'_>, joint: &Joint) -> Result<f64, Located> {
    let Some(mimic) = &joint.mimic else {
        return Ok(joint.locked.unwrap_or(0.0));
    };
    let master = description
        .joint(&mimic.joint)
        .expect("validated mimic master");
    Ok(mimic.multiplier * master.locked.unwrap_or(0.0) + mimic.offset)
}

fn link_inertial(link: &Link) -> Option<Inertial> {
    let mass = link.mass?;
    let inertia = link
        .inertia
        .unwrap_or(Inertia::from_matrix(&Matrix3::zeros()));
    Some(Inertial {
        mass,
        com: Vector3::from(link.com),
        inertia: inertia.matrix(),
    })
}

fn missing(link: &str) -> Located {
    Located::new(
        KeyPath::root().key("links"),
        format!("link `{link}` is not defined"),
    )
}

/// Orders the moving bodies parents first (depth first, in file order) and
/// checks that the joints that move alone form one serial chain: the
/// other moving bodies are coupled ones (mimics of a chain joint), which
/// may branch off it (a gripper's second finger).
fn order_tree(
    description: &Tree<'_>,
    mut bodies: Vec<Body>,
    parent_body: Vec<Option<usize>>,
) -> Result<Chain, Located> {
    if bodies.is_empty() {
        return Err(Located::new(
            KeyPath::root().key("joints"),
            "the description has no moving joint: add a revolute or prismatic joint that is not locked",
        ));
    }
    let n = bodies.len();
    let order = depth_first(&parent_body);
    if let Some((a, b)) = branching(&order, &bodies, &parent_body) {
        let j = description
            .joint_index
            .get(bodies[b].joint.as_str())
            .copied()
            .unwrap_or(0);
        return Err(Located::new(
            KeyPath::root().key("joints").index(j),
            format!(
                "joints `{}` and `{}` both move, on different branches: only serial chains are \
                 supported (lock or fix one of them)",
                bodies[a].joint, bodies[b].joint
            ),
        ));
    }
    let mut position = vec![0; n];
    for (k, &b) in order.iter().enumerate() {
        position[b] = k;
    }
    for (b, body) in bodies.iter_mut().enumerate() {
        body.parent = parent_body[b].map(|p| position[p]);
    }
    let mut slots: Vec<Option<Body>> = bodies.into_iter().map(Some).collect();
    let mut ordered: Vec<Body> = order.iter().filter_map(|&b| slots[b].take()).collect();
    let dof_of: HashMap<String, usize> = ordered
        .iter()
        .filter(|b| b.coupling.is_none())
        .enumerate()
        .map(|(d, b)| (b.joint.clone(), d))
        .collect();
    for body in &mut ordered {
        if let Some(c) = &mut body.coupling {
            c.dof = dof_of[&c.master];
        }
    }
    Ok(Chain {
        gravity: Vector3::from(description.gravity),
        bodies: ordered,
    })
}

/// The bodies parents first, depth first, siblings in file order.
fn depth_first(parent_body: &[Option<usize>]) -> Vec<usize> {
    let n = parent_body.len();
    let mut roots = Vec::new();
    let mut children = vec![Vec::new(); n];
    // Reversed so that the stack pops siblings in file order.
    for b in (0..n).rev() {
        match parent_body[b] {
            Some(p) => children[p].push(b),
            None => roots.push(b),
        }
    }
    let mut order = Vec::with_capacity(n);
    let mut stack = roots;
    while let Some(b) = stack.pop() {
        order.push(b);
        stack.extend_from_slice(&children[b]);
    }
    order
}

/// Two bodies that move alone on different branches, if any (the earlier
/// in `order` first). The free bodies form one chain exactly when each
/// one's nearest free ancestor is the free body before it in depth-first
/// order, which is checked in one pass (a check of every pair was cubic).
fn branching(
    order: &[usize],
    bodies: &[Body],
    parent_body: &[Option<usize>],
) -> Option<(usize, usize)> {
    let free = |b: usize| bodies[b].coupling.is_none();
    // Parents come first in `order`, so each parent's entry is ready.
    let mut nearest_free: Vec<Option<usize>> = vec![None; bodies.len()];
    for &b in order {
        nearest_free[b] =
            parent_body[b].and_then(|p| if free(p) { Some(p) } else { nearest_free[p] });
    }
    let chain: Vec<usize> = order.iter().copied().filter(|&b| free(b)).collect();
    let k = chain
        .windows(2)
        .position(|w| nearest_free[w[1]] != Some(w[0]))?;
    let b = chain[k + 1];
    // Name the first chain body that is not an ancestor of `b`.
    let ancestors =
        std::iter::successors(parent_body[b], |&p| parent_body[p]).collect::<HashSet<_>>();
    let a = chain[..=k]
        .iter()
        .copied()
        .find(|a| !ancestors.contains(a))?;
    Some((a, b))
}
