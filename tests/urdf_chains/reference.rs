//! An independent rigid-body computation straight from a URDF, for issue
//! 22's acceptance check. It shares nothing with the product: the URDF is
//! read with `roxmltree` (not `urdf-rs`), the whole tree is kept (every
//! branch, every finger), and the torques come from a textbook recursive
//! Newton-Euler (Luh, Walker, Paul; Craig ch. 6) about each link frame's
//! origin, with world gravity rotated into the base frame.
//!
//! The chain contract it implements: the moving joints on the path
//! base -> tip are the degrees of freedom, in that order; a `locked` joint
//! is held at its value wherever it is; a mimic joint follows its master
//! (q = multiplier * q_master + offset), so a mimic joint on the chain is
//! driven by its master's DOF and adds its torque times the multiplier to
//! it; every other moving joint is held at 0. Links that are not below the
//! base never move and exert nothing on the chain. URDF `<dynamics damping
//! friction>` adds damping * qd + friction * sign(qd) at its joint (the
//! importer's documented viscous and Coulomb effects).

use std::collections::HashMap;

use nalgebra::{Matrix3, Rotation3, Unit, Vector3};

type V3 = Vector3<f64>;
type M3 = Matrix3<f64>;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    Rigid,
    Revolute,
    Prismatic,
}

#[derive(Debug, Clone)]
struct Link {
    mass: f64,
    /// Centre of mass in the link frame.
    com: V3,
    /// Inertia about the centre of mass, link axes.
    inertia: M3,
}

#[derive(Debug, Clone)]
struct Joint {
    name: String,
    kind: Kind,
    parent: usize,
    child: usize,
    rotation: M3,
    translation: V3,
    axis: V3,
    mimic: Option<(String, f64, f64)>,
    damping: f64,
    friction: f64,
}

/// How a joint moves: not at all, held at a value, or with DOF `k` as
/// `a * q_k + b`.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Drive {
    Fixed,
    Held(f64),
    Dof { k: usize, a: f64, b: f64 },
}

/// A URDF cut to the chain `base -> tip`, ready for torques.
pub struct Reference {
    links: Vec<Link>,
    joints: Vec<Joint>,
    drives: Vec<Drive>,
    /// Joints below the base, parents before children.
    order: Vec<usize>,
    base: usize,
    /// World gravity in the base frame.
    gravity: V3,
    /// Joint names of the degrees of freedom, base to tip.
    pub dofs: Vec<String>,
}

fn numbers(text: Option<&str>, default: [f64; 3]) -> V3 {
    match text {
        None => V3::from(default),
        Some(t) => {
            let v: Vec<f64> = t.split_whitespace().map(|x| x.parse().unwrap()).collect();
            assert_eq!(v.len(), 3, "three numbers expected in '{t}'");
            V3::new(v[0], v[1], v[2])
        }
    }
}

/// URDF origin: translation, then R = Rz(yaw) Ry(pitch) Rx(roll).
fn origin(node: Option<roxmltree::Node>) -> (M3, V3) {
    let xyz = numbers(node.and_then(|n| n.attribute("xyz")), [0.0; 3]);
    let rpy = numbers(node.and_then(|n| n.attribute("rpy")), [0.0; 3]);
    (rpy_matrix(rpy), xyz)
}

fn rpy_matrix(rpy: V3) -> M3 {
    let about = |axis: V3, angle: f64| {
        *Rotation3::from_axis_angle(&Unit::new_normalize(axis), angle).matrix()
    };
    about(V3::z(), rpy.z) * about(V3::y(), rpy.y) * about(V3::x(), rpy.x)
}

fn child<'a>(node: roxmltree::Node<'a, 'a>, tag: &str) -> Option<roxmltree::Node<'a, 'a>> {
    node.children().find(|c| c.has_tag_name(tag))
}

fn number(node: Option<roxmltree::Node>, attribute: &str, default: f64) -> f64 {
    node.and_then(|n| n.attribute(attribute))
        .map(|t| t.trim().parse().unwrap())
        .unwrap_or(default)
}

impl Reference {
    /// Reads `urdf`, cuts it at `base` and `tip`, holds `locks` (joint,
    /// value) and every other joint off the chain at 0.
    pub fn new(urdf: &str, base: &str, tip: &str, locks: &[(&str, f64)]) -> Reference {
        let document = roxmltree::Document::parse(urdf).expect("URDF is XML");
        let robot = document.root_element();
        let mut link_index = HashMap::new();
        let mut links = Vec::new();
        for node in robot.children().filter(|n| n.has_tag_name("link")) {
            link_index.insert(node.attribute("name").unwrap().to_string(), links.len());
            links.push(read_link(node));
        }
        let joints: Vec<Joint> = robot
            .children()
            .filter(|n| n.has_tag_name("joint"))
            .map(|n| read_joint(n, &link_index))
            .collect();
        let (base, tip) = (link_index[base], link_index[tip]);
        let parent_joint: HashMap<usize, usize> = joints
            .iter()
            .enumerate()
            .map(|(j, jt)| (jt.child, j))
            .collect();
        // The path, tip up to base, then reversed.
        let mut path = Vec::new();
        let mut link = tip;
        while link != base {
            let j = *parent_joint.get(&link).expect("tip is below base");
            path.push(j);
            link = joints[j].parent;
        }
        path.reverse();
        let by_name: HashMap<&str, usize> = joints
            .iter()
            .enumerate()
            .map(|(j, jt)| (jt.name.as_str(), j))
            .collect();
        let lock: HashMap<usize, f64> = locks.iter().map(|&(n, v)| (by_name[n], v)).collect();
        let mut drives: Vec<Option<Drive>> = vec![None; joints.len()];
        let mut dofs = Vec::new();
        for &j in &path {
            let jt = &joints[j];
            if jt.kind != Kind::Rigid && jt.mimic.is_none() && !lock.contains_key(&j) {
                drives[j] = Some(Drive::Dof {
                    k: dofs.len(),
                    a: 1.0,
                    b: 0.0,
                });
                dofs.push(jt.name.clone());
            }
        }
        let drives: Vec<Drive> = (0..joints.len())
            .map(|j| resolve(j, &joints, &by_name, &lock, &mut drives, 0))
            .collect();
        // Gravity: the base's orientation in the root frame, every joint
        // above it at its held value.
        let mut rotation = M3::identity();
        let mut link = base;
        while let Some(&j) = parent_joint.get(&link) {
            let q = match drives[j] {
                Drive::Fixed => 0.0,
                Drive::Held(v) => v,
                Drive::Dof { .. } => panic!("a joint above the base follows the chain"),
            };
            rotation = placement(&joints[j], q).0 * rotation;
            link = joints[j].parent;
        }
        let gravity = rotation.transpose() * V3::new(0.0, 0.0, -9.81);
        let mut order = Vec::new();
        let mut frontier = vec![base];
        while let Some(l) = frontier.pop() {
            for (j, jt) in joints.iter().enumerate().filter(|(_, jt)| jt.parent == l) {
                order.push(j);
                frontier.push(jt.child);
            }
        }
        Reference {
            links,
            joints,
            drives,
            order,
            base,
            gravity,
            dofs,
        }
    }

    /// Torques of the degrees of freedom (`self.dofs`' order).
    pub fn torques(&self, q: &[f64], qd: &[f64], qdd: &[f64]) -> Vec<f64> {
        let n = self.links.len();
        // Per link: angular velocity, angular acceleration, linear
        // acceleration of the frame origin, all in link axes.
        let mut w = vec![V3::zeros(); n];
        let mut wd = vec![V3::zeros(); n];
        let mut a = vec![V3::zeros(); n];
        a[self.base] = -self.gravity;
        let motion = |d: Drive| match d {
            Drive::Fixed => (0.0, 0.0, 0.0),
            Drive::Held(v) => (v, 0.0, 0.0),
            Drive::Dof { k, a, b } => (a * q[k] + b, a * qd[k], a * qdd[k]),
        };
        for &j in &self.order {
            let jt = &self.joints[j];
            let (p, c) = (jt.parent, jt.child);
            let (pos, vel, acc) = motion(self.drives[j]);
            let (r, t) = placement(jt, pos);
            let rt = r.transpose();
            let z = jt.axis;
            let a_origin = rt * (a[p] + wd[p].cross(&t) + w[p].cross(&w[p].cross(&t)));
            let w_in = rt * w[p];
            match jt.kind {
                Kind::Revolute => {
                    w[c] = w_in + z * vel;
                    wd[c] = rt * wd[p] + w_in.cross(&(z * vel)) + z * acc;
                    a[c] = a_origin;
                }
                Kind::Prismatic => {
                    w[c] = w_in;
                    wd[c] = rt * wd[p];
                    a[c] = a_origin + 2.0 * w[c].cross(&(z * vel)) + z * acc;
                }
                Kind::Rigid => {
                    w[c] = w_in;
                    wd[c] = rt * wd[p];
                    a[c] = a_origin;
                }
            }
        }
        // Force and moment (about the frame origin) each link exerts on its
        // subtree's inboard joint, link axes.
        let mut f = vec![V3::zeros(); n];
        let mut m = vec![V3::zeros(); n];
        for (l, link) in self.links.iter().enumerate() {
            let c = link.com;
            let a_com = a[l] + wd[l].cross(&c) + w[l].cross(&w[l].cross(&c));
            let force = link.mass * a_com;
            let moment = link.inertia * wd[l] + w[l].cross(&(link.inertia * w[l]));
            f[l] = force;
            m[l] = moment + c.cross(&force);
        }
        let mut tau = vec![0.0; self.dofs.len()];
        for &j in self.order.iter().rev() {
            let jt = &self.joints[j];
            let (p, c) = (jt.parent, jt.child);
            let (pos, vel, _) = motion(self.drives[j]);
            let (r, t) = placement(jt, pos);
            let (fc, mc) = (r * f[c], r * m[c]);
            f[p] += fc;
            m[p] += mc + t.cross(&fc);
            if let Drive::Dof { k, a, .. } = self.drives[j] {
                let generalized = match jt.kind {
                    Kind::Revolute => jt.axis.dot(&m[c]),
                    Kind::Prismatic => jt.axis.dot(&f[c]),
                    Kind::Rigid => 0.0,
                };
                let effects = jt.damping * vel + jt.friction * sign(vel);
                tau[k] += a * (generalized + effects);
            }
        }
        tau
    }
}

fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// The child frame in the parent frame at joint position `q`.
fn placement(jt: &Joint, q: f64) -> (M3, V3) {
    match jt.kind {
        Kind::Revolute => {
            let turn = Rotation3::from_axis_angle(&Unit::new_normalize(jt.axis), q);
            (jt.rotation * turn.matrix(), jt.translation)
        }
        Kind::Prismatic => (jt.rotation, jt.translation + jt.rotation * jt.axis * q),
        Kind::Rigid => (jt.rotation, jt.translation),
    }
}

fn resolve(
    j: usize,
    joints: &[Joint],
    by_name: &HashMap<&str, usize>,
    lock: &HashMap<usize, f64>,
    drives: &mut Vec<Option<Drive>>,
    depth: usize,
) -> Drive {
    assert!(depth < 100, "mimic cycle at '{}'", joints[j].name);
    if let Some(d) = drives[j] {
        return d;
    }
    let jt = &joints[j];
    let d = if jt.kind == Kind::Rigid {
        Drive::Fixed
    } else if let Some(&v) = lock.get(&j) {
        Drive::Held(v)
    } else if let Some((master, mul, off)) = &jt.mimic {
        match resolve(
            by_name[master.as_str()],
            joints,
            by_name,
            lock,
            drives,
            depth + 1,
        ) {
            Drive::Fixed => Drive::Held(*off),
            Drive::Held(v) => Drive::Held(mul * v + off),
            Drive::Dof { k, a, b } => Drive::Dof {
                k,
                a: mul * a,
                b: mul * b + off,
            },
        }
    } else {
        Drive::Held(0.0)
    };
    drives[j] = Some(d);
    d
}

fn read_link(node: roxmltree::Node) -> Link {
    let Some(inertial) = child(node, "inertial") else {
        return Link {
            mass: 0.0,
            com: V3::zeros(),
            inertia: M3::zeros(),
        };
    };
    let (rotation, com) = origin(child(inertial, "origin"));
    let i = child(inertial, "inertia");
    let get = |name: &str| number(i, name, 0.0);
    let (ixy, ixz, iyz) = (get("ixy"), get("ixz"), get("iyz"));
    let about_com = M3::new(
        get("ixx"),
        ixy,
        ixz,
        ixy,
        get("iyy"),
        iyz,
        ixz,
        iyz,
        get("izz"),
    );
    Link {
        mass: number(child(inertial, "mass"), "value", 0.0),
        com,
        inertia: rotation * about_com * rotation.transpose(),
    }
}

fn read_joint(node: roxmltree::Node, link_index: &HashMap<String, usize>) -> Joint {
    let kind = match node.attribute("type").unwrap() {
        "revolute" | "continuous" => Kind::Revolute,
        "prismatic" => Kind::Prismatic,
        // fixed; floating and planar held at their zero pose
        _ => Kind::Rigid,
    };
    let (rotation, translation) = origin(child(node, "origin"));
    let link = |tag: &str| link_index[child(node, tag).unwrap().attribute("link").unwrap()];
    let axis = numbers(
        child(node, "axis").and_then(|a| a.attribute("xyz")),
        [1.0, 0.0, 0.0],
    );
    let mimic = child(node, "mimic").map(|m| {
        (
            m.attribute("joint").unwrap().to_string(),
            number(Some(m), "multiplier", 1.0),
            number(Some(m), "offset", 0.0),
        )
    });
    let dynamics = child(node, "dynamics");
    Joint {
        name: node.attribute("name").unwrap().to_string(),
        kind,
        parent: link("parent"),
        child: link("child"),
        rotation,
        translation,
        axis: axis.normalize(),
        mimic,
        damping: number(dynamics, "damping", 0.0),
        friction: number(dynamics, "friction", 0.0),
    }
}
