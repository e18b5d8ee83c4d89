//! `sdnn import-urdf`: converts a URDF into an sdnn TOML robot description.
//!
//! The URDF tree is cut to the serial chain from `base` to `tip`. Links
//! hanging off that chain are kept when every joint below them is rigid
//! (fixed, or revolute and `--lock`ed), because the generator lumps them;
//! branches that still move are dropped with a warning. Links above the base
//! are dropped and gravity is expressed in the base frame. Inertias are
//! rotated from the URDF `<inertial><origin rpy>` into the link frame, which
//! is what the description expects.
//!
//! Command-line syntax of the options (see [`Attachment`] and [`parse_lock`]):
//! `--lock JOINT=ANGLE` (radians) and
//! `--attach 'LINK:mass=KG[,com=X;Y;Z][,inertia=IXX;IYY;IZZ[;IXY;IXZ;IYZ]]'`.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::fmt;
use std::str::FromStr;

use codegen::reduce::rpy_matrix;
use nalgebra::{Matrix3, Rotation3, Unit, Vector3};
use toml_edit::{Array, ArrayOfTables, DocumentMut, InlineTable, Item, Table, Value};
use urdf_rs::{JointType, Robot};

/// Gravity in the URDF root frame (z up), m/s^2.
const WORLD_GRAVITY: [f64; 3] = [0.0, 0.0, -9.81];

/// Radius of the solid sphere that stands in for a point-mass attachment:
/// the description needs a positive-definite inertia, and at 1 mm its
/// inertia (2/5 m r^2) is negligible next to any arm link.
const POINT_MASS_RADIUS: f64 = 1e-3;

/// What to import and what to change on the way.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ImportOptions {
    /// The link fixed to the world; default: the URDF root link.
    pub base: Option<String>,
    /// The last link of the chain; default: the end of the only moving branch.
    pub tip: Option<String>,
    /// Revolute joints held at an angle (rad): `locked = ANGLE`.
    pub lock: Vec<(String, f64)>,
    /// Rigid payloads added as fixed child links.
    pub attach: Vec<Attachment>,
    /// The description's `name`; default: the URDF robot name.
    pub name: Option<String>,
}

/// A rigid payload fixed to `link`: mass (kg), centre of mass in the link
/// frame (m) and, optionally, the inertia about that centre of mass in link
/// axes (kg m^2, order ixx iyy izz ixy ixz iyz). Without an inertia it is a
/// point mass.
///
/// Syntax: `LINK:mass=KG[,com=X;Y;Z][,inertia=IXX;IYY;IZZ[;IXY;IXZ;IYZ]]`,
/// e.g. `END_EFFECTOR:mass=0.2018,com=0;0;0.05` (quote it in a shell).
#[derive(Debug, Clone, PartialEq)]
pub struct Attachment {
    pub link: String,
    pub mass: f64,
    pub com: [f64; 3],
    pub inertia: Option<[f64; 6]>,
}

/// The description text and what the import changed or ignored.
#[derive(Debug, Clone, PartialEq)]
pub struct Imported {
    pub toml: String,
    pub warnings: Vec<String>,
}

/// Why a URDF cannot be imported. Messages name the element at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ImportError {
    #[error("cannot parse the URDF: {0}")]
    Parse(String),
    /// The links and joints do not form one tree.
    #[error("URDF structure: {0}")]
    Structure(String),
    /// A joint the description cannot represent, on the imported chain.
    #[error("joint '{joint}' ({kind}): {message}")]
    Unsupported {
        joint: String,
        kind: String,
        message: String,
    },
    /// A value that is not a finite, physical number.
    #[error("{element}: {message}")]
    Invalid { element: String, message: String },
    /// A command-line option that does not fit the URDF.
    #[error("{option}: {message}")]
    Option {
        option: &'static str,
        message: String,
    },
}

fn option_error(option: &'static str, message: impl Into<String>) -> ImportError {
    ImportError::Option {
        option,
        message: message.into(),
    }
}

fn invalid(element: impl Into<String>, message: impl Into<String>) -> ImportError {
    ImportError::Invalid {
        element: element.into(),
        message: message.into(),
    }
}

/// Parses `--lock JOINT=ANGLE` (radians).
pub fn parse_lock(s: &str) -> Result<(String, f64), String> {
    let (joint, angle) = s
        .rsplit_once('=')
        .ok_or_else(|| format!("expected JOINT=ANGLE (radians), found '{s}'"))?;
    let joint = joint.trim();
    if joint.is_empty() {
        return Err(format!(
            "missing joint name in '{s}' (expected JOINT=ANGLE)"
        ));
    }
    let angle = parse_number(angle, "angle")?;
    Ok((joint.to_string(), angle))
}

fn parse_number(text: &str, what: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(format!("{what} must be a finite number, found '{text}'")),
    }
}

fn parse_numbers(text: &str, what: &str) -> Result<Vec<f64>, String> {
    text.split(';').map(|v| parse_number(v, what)).collect()
}

impl FromStr for Attachment {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        const SYNTAX: &str = "LINK:mass=KG[,com=X;Y;Z][,inertia=IXX;IYY;IZZ[;IXY;IXZ;IYZ]]";
        // Split at the last ':' so namespaced link names (`a:b`) still work.
        let (link, fields) = s
            .rsplit_once(':')
            .ok_or_else(|| format!("expected {SYNTAX}, found '{s}'"))?;
        let link = link.trim();
        if link.is_empty() {
            return Err(format!("missing link name in '{s}' (expected {SYNTAX})"));
        }
        let (mut mass, mut com, mut inertia) = (None, None, None);
        for field in fields.split(',') {
            let (key, value) = field
                .split_once('=')
                .ok_or_else(|| format!("expected KEY=VALUE in '{field}' (syntax {SYNTAX})"))?;
            let duplicate = match key.trim() {
                "mass" => mass.replace(parse_number(value, "mass")?).is_some(),
                "com" => com.replace(parse_com(value)?).is_some(),
                "inertia" => inertia.replace(parse_inertia(value)?).is_some(),
                other => {
                    return Err(format!(
                        "unknown key '{other}' (expected mass, com or inertia)"
                    ));
                }
            };
            if duplicate {
                return Err(format!("key '{}' given twice in '{s}'", key.trim()));
            }
        }
        let mass = mass.ok_or_else(|| format!("missing mass=KG in '{s}'"))?;
        if mass <= 0.0 {
            return Err(format!("mass must be > 0 kg, found {mass}"));
        }
        Ok(Attachment {
            link: link.to_string(),
            mass,
            com: com.unwrap_or_default(),
            inertia,
        })
    }
}

fn parse_com(value: &str) -> Result<[f64; 3], String> {
    let v = parse_numbers(value, "com")?;
    <[f64; 3]>::try_from(v).map_err(|_| format!("com needs 3 numbers X;Y;Z (m), found '{value}'"))
}

fn parse_inertia(value: &str) -> Result<[f64; 6], String> {
    let v = parse_numbers(value, "inertia")?;
    let six = match v.as_slice() {
        [xx, yy, zz] => [*xx, *yy, *zz, 0.0, 0.0, 0.0],
        [xx, yy, zz, xy, xz, yz] => [*xx, *yy, *zz, *xy, *xz, *yz],
        _ => {
            return Err(format!(
                "inertia needs 3 (IXX;IYY;IZZ) or 6 (IXX;IYY;IZZ;IXY;IXZ;IYZ) numbers, found '{value}'"
            ));
        }
    };
    let matrix = inertia_matrix(&six);
    let eigen = crate::kernels::symmetric_eigenvalues(nalgebra::DMatrix::from_column_slice(
        3,
        3,
        matrix.as_slice(),
    ))
    .ok_or_else(|| format!("inertia '{value}' has no principal moments (entries too large?)"))?;
    if eigen.min() <= 0.0 {
        return Err(format!(
            "inertia '{value}' is not positive definite (smallest principal moment {:e})",
            eigen.min()
        ));
    }
    Ok(six)
}

impl fmt::Display for Attachment {
    /// The command-line syntax, so `to_string().parse()` round-trips.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let join = |v: &[f64]| {
            v.iter()
                .map(|x| format!("{x:?}"))
                .collect::<Vec<_>>()
                .join(";")
        };
        write!(
            f,
            "{}:mass={:?},com={}",
            self.link,
            self.mass,
            join(&self.com)
        )?;
        if let Some(inertia) = &self.inertia {
            write!(f, ",inertia={}", join(inertia))?;
        }
        Ok(())
    }
}

/// Converts `urdf_text` to description TOML. `source_label` is only written
/// into the header comment (give a relative path, not a machine path).
pub fn import_urdf(
    urdf_text: &str,
    source_label: &str,
    options: &ImportOptions,
) -> Result<Imported, ImportError> {
    check_nesting(urdf_text)?;
    let robot =
        urdf_rs::read_from_string(urdf_text).map_err(|e| ImportError::Parse(e.to_string()))?;
    let tree = Tree::new(&robot)?;
    let mut warnings = Vec::new();
    let locks = Locks::new(&tree, &options.lock)?;
    let chain = select(&tree, options, &locks, &mut warnings)?;
    check_chain(&tree, &chain, &locks, &mut warnings)?;
    warnings.extend(transmission_warnings(urdf_text));
    let gravity = base_gravity(&tree, &chain, &locks, &mut warnings)?;
    let mut links = chain
        .links
        .iter()
        .map(|&l| convert_link(&robot.links[l], &mut warnings))
        .collect::<Result<Vec<_>, _>>()?;
    let mut joints = chain
        .joints
        .iter()
        .map(|&j| convert_joint(&robot.joints[j], locks.angle(j), &mut warnings))
        .collect::<Result<Vec<_>, _>>()?;
    attach_payloads(&tree, &chain, &options.attach, &mut links, &mut joints)?;
    let name = options.name.clone().unwrap_or_else(|| robot.name.clone());
    check_names(&name, options.name.is_some(), &links, &joints)?;
    if links.iter().all(|l| l.body.is_none()) {
        return Err(ImportError::Structure(
            "no link on the imported chain has an <inertial> with a mass: the arm would be \
             massless and every torque zero; add the links' <inertial> elements"
                .into(),
        ));
    }
    let header = header(source_label, &robot.name, &tree, &chain, options);
    let body = render(&name, gravity, &links, &joints);
    Ok(Imported {
        toml: format!("{header}\n{body}"),
        warnings,
    })
}

/// The URDF as a tree, with its structure checked.
struct Tree<'a> {
    robot: &'a Robot,
    link_index: HashMap<&'a str, usize>,
    joint_index: HashMap<&'a str, usize>,
    /// The joint whose child is this link.
    parent_joint: HashMap<&'a str, usize>,
    /// Joints whose parent is this link, in file order.
    children: HashMap<&'a str, Vec<usize>>,
    root: usize,
}

impl<'a> Tree<'a> {
    fn new(robot: &'a Robot) -> Result<Tree<'a>, ImportError> {
        let structure = |m: String| ImportError::Structure(m);
        let mut link_index = HashMap::new();
        for (i, link) in robot.links.iter().enumerate() {
            if link_index.insert(link.name.as_str(), i).is_some() {
                return Err(structure(format!("link '{}' is defined twice", link.name)));
            }
        }
        let mut joint_index = HashMap::new();
        let mut parent_joint = HashMap::new();
        let mut children: HashMap<&str, Vec<usize>> = HashMap::new();
        for (j, joint) in robot.joints.iter().enumerate() {
            if joint_index.insert(joint.name.as_str(), j).is_some() {
                return Err(structure(format!(
                    "joint '{}' is defined twice",
                    joint.name
                )));
            }
            for (role, link) in [("parent", &joint.parent.link), ("child", &joint.child.link)] {
                if !link_index.contains_key(link.as_str()) {
                    return Err(structure(format!(
                        "joint '{}': {role} link '{link}' is not defined",
                        joint.name
                    )));
                }
            }
            if let Some(other) = parent_joint.insert(joint.child.link.as_str(), j) {
                return Err(structure(format!(
                    "link '{}' is the child of two joints, '{}' and '{}'",
                    joint.child.link, robot.joints[other].name, joint.name
                )));
            }
            children
                .entry(joint.parent.link.as_str())
                .or_default()
                .push(j);
        }
        let roots: Vec<usize> = (0..robot.links.len())
            .filter(|&l| !parent_joint.contains_key(robot.links[l].name.as_str()))
            .collect();
        let root = match roots.as_slice() {
            [root] => *root,
            [] if robot.links.is_empty() => return Err(structure("the URDF has no links".into())),
            [] => {
                return Err(structure(
                    "every link has a parent: the joints form a cycle".into(),
                ));
            }
            many => {
                let names: Vec<&str> = many.iter().map(|&l| robot.links[l].name.as_str()).collect();
                return Err(structure(format!(
                    "{} links have no parent ({}): a URDF must be one tree",
                    many.len(),
                    names.join(", ")
                )));
            }
        };
        let tree = Tree {
            robot,
            link_index,
            joint_index,
            parent_joint,
            children,
            root,
        };
        tree.check_connected()?;
        Ok(tree)
    }

    /// With one parent per link, links unreachable from the root sit on a cycle.
    fn check_connected(&self) -> Result<(), ImportError> {
        let reached: HashSet<usize> = self.subtree_links(self.root).into_iter().collect();
        let lost: Vec<&str> = (0..self.robot.links.len())
            .filter(|l| !reached.contains(l))
            .map(|l| self.link_name(l))
            .collect();
        if lost.is_empty() {
            Ok(())
        } else {
            Err(ImportError::Structure(format!(
                "the joints form a cycle through links {}",
                lost.join(", ")
            )))
        }
    }

    fn link_name(&self, link: usize) -> &'a str {
        &self.robot.links[link].name
    }

    fn child_joints(&self, link: usize) -> &[usize] {
        self.children
            .get(self.link_name(link))
            .map_or(&[], Vec::as_slice)
    }

    fn child_link(&self, joint: usize) -> usize {
        self.link_index[self.robot.joints[joint].child.link.as_str()]
    }

    fn parent_link(&self, joint: usize) -> usize {
        self.link_index[self.robot.joints[joint].parent.link.as_str()]
    }

    /// The link named by a command-line option.
    fn find_link(&self, option: &'static str, name: &str) -> Result<usize, ImportError> {
        self.link_index
            .get(name)
            .copied()
            .ok_or_else(|| option_error(option, format!("no link named '{name}' in the URDF")))
    }

    /// Links of the subtree at `link` (itself first), depth first, file order.
    fn subtree_links(&self, link: usize) -> Vec<usize> {
        let mut order = Vec::new();
        let mut stack = vec![link];
        while let Some(l) = stack.pop() {
            order.push(l);
            stack.extend(
                self.child_joints(l)
                    .iter()
                    .rev()
                    .map(|&j| self.child_link(j)),
            );
        }
        order
    }

    /// Joints of the subtree hanging from `joint` (itself first).
    fn subtree_joints(&self, joint: usize) -> Vec<usize> {
        let below = self.subtree_links(self.child_link(joint));
        std::iter::once(joint)
            .chain(
                below
                    .iter()
                    .flat_map(|&l| self.child_joints(l).iter().copied()),
            )
            .collect()
    }

    /// Joints from the root down to `link`, root first.
    fn joints_above(&self, link: usize) -> Vec<usize> {
        let mut joints = Vec::new();
        let mut current = self.link_name(link);
        while let Some(&j) = self.parent_joint.get(current) {
            joints.push(j);
            current = &self.robot.joints[j].parent.link;
        }
        joints.reverse();
        joints
    }

    fn kind(&self, joint: usize) -> &'static str {
        kind_name(&self.robot.joints[joint].joint_type)
    }
}

fn kind_name(kind: &JointType) -> &'static str {
    match kind {
        JointType::Revolute => "revolute",
        JointType::Continuous => "continuous",
        JointType::Prismatic => "prismatic",
        JointType::Fixed => "fixed",
        JointType::Floating => "floating",
        JointType::Planar => "planar",
        JointType::Spherical => "spherical",
    }
}

fn is_rotary(kind: &JointType) -> bool {
    matches!(kind, JointType::Revolute | JointType::Continuous)
}

/// The `--lock` angles by joint index.
struct Locks(BTreeMap<usize, f64>);

impl Locks {
    fn new(tree: &Tree<'_>, locks: &[(String, f64)]) -> Result<Locks, ImportError> {
        let mut angles = BTreeMap::new();
        for (name, angle) in locks {
            let &j = tree.joint_index.get(name.as_str()).ok_or_else(|| {
                option_error("--lock", format!("no joint named '{name}' in the URDF"))
            })?;
            let kind = &tree.robot.joints[j].joint_type;
            if !is_rotary(kind) {
                return Err(option_error(
                    "--lock",
                    format!(
                        "joint '{name}' is {}: only revolute and continuous joints can be locked",
                        kind_name(kind)
                    ),
                ));
            }
            if !angle.is_finite() {
                return Err(option_error(
                    "--lock",
                    format!("angle of '{name}' must be finite"),
                ));
            }
            if angles.insert(j, *angle).is_some() {
                return Err(option_error(
                    "--lock",
                    format!("joint '{name}' is locked twice"),
                ));
            }
        }
        Ok(Locks(angles))
    }

    fn angle(&self, joint: usize) -> Option<f64> {
        self.0.get(&joint).copied()
    }

    /// Fixed, or a rotary joint held by `--lock`: lumped by the generator.
    fn is_rigid(&self, tree: &Tree<'_>, joint: usize) -> bool {
        tree.robot.joints[joint].joint_type == JointType::Fixed || self.0.contains_key(&joint)
    }

    fn subtree_rigid(&self, tree: &Tree<'_>, joint: usize) -> bool {
        tree.subtree_joints(joint)
            .iter()
            .all(|&j| self.is_rigid(tree, j))
    }
}

/// The part of the URDF that is imported.
struct Selection {
    base: usize,
    tip: usize,
    /// Joints from base to tip.
    path: Vec<usize>,
    /// Kept links and joints, depth first from the base, file order.
    links: Vec<usize>,
    joints: Vec<usize>,
    /// Joints from the URDF root to the base (dropped).
    above: Vec<usize>,
}

fn select(
    tree: &Tree<'_>,
    options: &ImportOptions,
    locks: &Locks,
    warnings: &mut Vec<String>,
) -> Result<Selection, ImportError> {
    let base = match &options.base {
        Some(name) => tree.find_link("--base", name)?,
        None => tree.root,
    };
    let tip = match &options.tip {
        Some(name) => tree.find_link("--tip", name)?,
        None => default_tip(tree, base, locks)?,
    };
    let path = path_between(tree, base, tip)?;
    let on_path: HashSet<usize> = path.iter().copied().collect();
    let mut links = Vec::new();
    let mut stack = vec![base];
    while let Some(link) = stack.pop() {
        links.push(link);
        let mut kept = Vec::new();
        for &j in tree.child_joints(link) {
            if on_path.contains(&j) || locks.subtree_rigid(tree, j) {
                kept.push(tree.child_link(j));
            } else {
                warnings.push(dropped_branch(tree, j, locks));
            }
        }
        // Reversed so the stack visits children in file order.
        stack.extend(kept.into_iter().rev());
    }
    // Every kept link but the base is reached through its parent joint.
    let joints = links[1..]
        .iter()
        .filter_map(|&l| tree.parent_joint.get(tree.link_name(l)).copied())
        .collect();
    let above = tree.joints_above(base);
    if !above.is_empty() {
        let dropped = tree.robot.links.len() - tree.subtree_links(base).len();
        warnings.push(format!(
            "link '{}' is the base: {dropped} link(s) above it are dropped (from root '{}'), \
             and the base is taken as fixed in the world",
            tree.link_name(base),
            tree.link_name(tree.root)
        ));
    }
    Ok(Selection {
        base,
        tip,
        path,
        links,
        joints,
        above,
    })
}

fn dropped_branch(tree: &Tree<'_>, joint: usize, locks: &Locks) -> String {
    let moving: Vec<String> = tree
        .subtree_joints(joint)
        .into_iter()
        .filter(|&j| !locks.is_rigid(tree, j))
        .map(|j| format!("'{}' ({})", tree.robot.joints[j].name, tree.kind(j)))
        .collect();
    let links = tree.subtree_links(tree.child_link(joint)).len();
    format!(
        "dropped the branch at joint '{}' ({links} link(s) from '{}'): it is off the base-tip chain \
         and has non-rigid joints {}; --lock them to keep it lumped",
        tree.robot.joints[joint].name,
        tree.robot.joints[joint].child.link,
        moving.join(", ")
    )
}

/// Follows the only moving branch from `base`; branches that are rigid are
/// kept anyway. Stops at the end of that branch's rigid tail if it is a
/// simple chain, else where the moving joints end.
fn default_tip(tree: &Tree<'_>, base: usize, locks: &Locks) -> Result<usize, ImportError> {
    let mut link = base;
    loop {
        let moving: Vec<usize> = tree
            .child_joints(link)
            .iter()
            .copied()
            .filter(|&j| !locks.subtree_rigid(tree, j))
            .collect();
        match moving.as_slice() {
            [] => return Ok(single_leaf(tree, link).unwrap_or(link)),
            [j] => link = tree.child_link(*j),
            _ => {
                let leaves: Vec<&str> = tree
                    .subtree_links(link)
                    .into_iter()
                    .filter(|&l| tree.child_joints(l).is_empty())
                    .map(|l| tree.link_name(l))
                    .collect();
                return Err(option_error(
                    "--tip",
                    format!(
                        "the URDF branches at link '{}' into several moving branches; choose the tip \
                         with --tip (leaves: {})",
                        tree.link_name(link),
                        leaves.join(", ")
                    ),
                ));
            }
        }
    }
}

/// The leaf below `link` if the subtree is a simple chain.
fn single_leaf(tree: &Tree<'_>, mut link: usize) -> Option<usize> {
    loop {
        match tree.child_joints(link) {
            [] => return Some(link),
            [j] => link = tree.child_link(*j),
            _ => return None,
        }
    }
}

fn path_between(tree: &Tree<'_>, base: usize, tip: usize) -> Result<Vec<usize>, ImportError> {
    let above_tip = tree.joints_above(tip);
    if base == tip {
        return Ok(Vec::new());
    }
    let start = above_tip
        .iter()
        .position(|&j| tree.parent_link(j) == base)
        .ok_or_else(|| {
            option_error(
                "--tip",
                format!(
                    "link '{}' is not below the base '{}'",
                    tree.link_name(tip),
                    tree.link_name(base)
                ),
            )
        })?;
    Ok(above_tip[start..].to_vec())
}

/// Rejects joints the description cannot hold on the imported part, and
/// checks that something still moves.
fn check_chain(
    tree: &Tree<'_>,
    chain: &Selection,
    locks: &Locks,
    warnings: &mut Vec<String>,
) -> Result<(), ImportError> {
    for &j in &chain.joints {
        let joint = &tree.robot.joints[j];
        let unsupported = |message: String| ImportError::Unsupported {
            joint: joint.name.clone(),
            kind: tree.kind(j).to_string(),
            message,
        };
        if !is_rotary(&joint.joint_type) && joint.joint_type != JointType::Fixed {
            return Err(unsupported(format!(
                "{} joints are not supported (only revolute, continuous and fixed); \
                 choose a --base/--tip that leaves it out",
                tree.kind(j)
            )));
        }
        if let Some(mimic) = &joint.mimic {
            if !locks.is_rigid(tree, j) {
                return Err(unsupported(format!(
                    "<mimic joint='{}'> couples it to another joint, which the description cannot \
                     express; --lock it or leave it out with --tip",
                    mimic.joint
                )));
            }
            warnings.push(format!(
                "joint '{}': <mimic joint='{}'> ignored, the joint is held rigid",
                joint.name, mimic.joint
            ));
        }
    }
    let moving = chain.path.iter().any(|&j| !locks.is_rigid(tree, j));
    if !moving {
        return Err(option_error(
            "--tip",
            format!(
                "no joint moves between base '{}' and tip '{}'",
                tree.link_name(chain.base),
                tree.link_name(chain.tip)
            ),
        ));
    }
    let kept: HashSet<usize> = chain.joints.iter().chain(&chain.above).copied().collect();
    if let Some(&j) = locks.0.keys().find(|j| !kept.contains(j)) {
        return Err(option_error(
            "--lock",
            format!(
                "joint '{}' is not in the imported chain (its branch is dropped)",
                tree.robot.joints[j].name
            ),
        ));
    }
    Ok(())
}

/// URDF `<transmission>` elements (urdf-rs drops them): a warning each.
fn transmission_warnings(urdf_text: &str) -> Vec<String> {
    let text = strip_xml_comments(urdf_text);
    text.split("<transmission")
        .skip(1)
        .filter(|rest| rest.starts_with(|c: char| c.is_whitespace() || c == '>' || c == '/'))
        .map(|rest| {
            let tag = &rest[..rest.find('>').unwrap_or(rest.len())];
            let name = attribute(tag, "name").unwrap_or("(unnamed)");
            format!("<transmission name='{name}'> ignored: gear ratios and actuators carry no dynamics the description uses")
        })
        .collect()
}

fn strip_xml_comments(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(start) = rest.find("<!--") {
        out.push_str(&rest[..start]);
        rest = rest[start..]
            .find("-->")
            .map_or("", |end| &rest[start + end + 3..]);
    }
    out.push_str(rest);
    out
}

fn attribute<'t>(tag: &'t str, name: &str) -> Option<&'t str> {
    let value = tag
        .split_whitespace()
        .find_map(|token| token.strip_prefix(name)?.strip_prefix('='))?;
    Some(value.trim_end_matches(['>', '/']).trim_matches(['"', '\'']))
}

/// Gravity in the base frame: the URDF root is taken as z up, and joints
/// above the base at their `--lock` angle (0 if not locked).
fn base_gravity(
    tree: &Tree<'_>,
    chain: &Selection,
    locks: &Locks,
    warnings: &mut Vec<String>,
) -> Result<[f64; 3], ImportError> {
    let mut rotation = Matrix3::identity();
    for &j in &chain.above {
        let joint = &tree.robot.joints[j];
        let element = format!("joint '{}' <origin>", joint.name);
        rotation *= rpy_matrix(&finite3(joint.origin.rpy.0, &element, "rpy")?);
        if is_rotary(&joint.joint_type) {
            let angle = locks.angle(j).unwrap_or_else(|| {
                warnings.push(format!(
                    "joint '{}' above the base is taken at 0 rad for the direction of gravity; \
                     --lock it to choose another angle",
                    joint.name
                ));
                0.0
            });
            let axis = finite3(
                joint.axis.xyz.0,
                &format!("joint '{}' <axis>", joint.name),
                "xyz",
            )?;
            rotation *= axis_rotation(&axis, angle);
        } else if joint.joint_type != JointType::Fixed && joint.joint_type != JointType::Prismatic {
            warnings.push(format!(
                "joint '{}' ({}) above the base is taken at its origin pose",
                joint.name,
                tree.kind(j)
            ));
        }
    }
    let g = rotation.transpose() * Vector3::from(WORLD_GRAVITY);
    // Exact right angles leave ~1e-16 residues; print them as zero.
    Ok(g.map(|x| if x.abs() < 1e-12 { 0.0 } else { x }).into())
}

fn axis_rotation(axis: &[f64; 3], angle: f64) -> Matrix3<f64> {
    Unit::try_new(Vector3::from(*axis), 1e-12).map_or_else(Matrix3::identity, |axis| {
        Rotation3::from_axis_angle(&axis, angle).into_inner()
    })
}

fn inertia_matrix(i: &[f64; 6]) -> Matrix3<f64> {
    let [xx, yy, zz, xy, xz, yz] = *i;
    Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz)
}

fn finite3(v: [f64; 3], element: &str, what: &str) -> Result<[f64; 3], ImportError> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(v)
    } else {
        Err(invalid(
            element,
            format!("{what} must be finite numbers, found {v:?}"),
        ))
    }
}

/// A description link: a massless frame or a rigid body.
#[derive(Debug, Clone, PartialEq)]
struct LinkOut {
    name: String,
    body: Option<Body>,
    comment: Option<String>,
}

/// Mass (kg), COM in the link frame (m), inertia about the COM in link axes
/// (kg m^2; ixx iyy izz ixy ixz iyz).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Body {
    mass: f64,
    com: [f64; 3],
    inertia: [f64; 6],
}

fn convert_link(link: &urdf_rs::Link, warnings: &mut Vec<String>) -> Result<LinkOut, ImportError> {
    let element = format!("link '{}' <inertial>", link.name);
    let inertial = &link.inertial;
    let mass = inertial.mass.value;
    if !mass.is_finite() || mass < 0.0 {
        return Err(invalid(
            element,
            format!("mass must be a finite number >= 0 kg, found {mass}"),
        ));
    }
    let i = &inertial.inertia;
    let inertia = [i.ixx, i.iyy, i.izz, i.ixy, i.ixz, i.iyz];
    if !inertia.iter().all(|x| x.is_finite()) {
        return Err(invalid(element, "inertia entries must be finite numbers"));
    }
    // urdf-rs reads a missing <inertial> as mass 0: both are massless frames.
    if mass == 0.0 {
        if inertia.iter().any(|&x| x != 0.0) {
            warnings.push(format!(
                "{element}: mass 0 with a non-zero inertia; imported as a massless frame"
            ));
        }
        return Ok(LinkOut {
            name: link.name.clone(),
            body: None,
            comment: None,
        });
    }
    let com = finite3(inertial.origin.xyz.0, &element, "origin xyz")?;
    let rpy = finite3(inertial.origin.rpy.0, &element, "origin rpy")?;
    Ok(LinkOut {
        name: link.name.clone(),
        body: Some(Body {
            mass,
            com,
            inertia: rotate_inertia(&inertia, &rpy),
        }),
        comment: None,
    })
}

/// The inertia given in the `<inertial><origin rpy>` frame, in link axes:
/// R I R^T. Left untouched when rpy is zero so the values stay exact.
fn rotate_inertia(inertia: &[f64; 6], rpy: &[f64; 3]) -> [f64; 6] {
    if rpy.iter().all(|&a| a == 0.0) {
        return *inertia;
    }
    let r = rpy_matrix(rpy);
    let m = r * inertia_matrix(inertia) * r.transpose();
    [
        m[(0, 0)],
        m[(1, 1)],
        m[(2, 2)],
        m[(0, 1)],
        m[(0, 2)],
        m[(1, 2)],
    ]
}

/// lower, upper, velocity, effort.
type LimitsOut = (f64, f64, Option<f64>, Option<f64>);

/// A description joint.
#[derive(Debug, Clone, PartialEq)]
struct JointOut {
    name: String,
    revolute: bool,
    parent: String,
    child: String,
    xyz: [f64; 3],
    rpy: [f64; 3],
    axis: [f64; 3],
    limits: Option<LimitsOut>,
    locked: Option<f64>,
    /// viscous, coulomb.
    effects: Option<(f64, f64)>,
}

fn convert_joint(
    joint: &urdf_rs::Joint,
    locked: Option<f64>,
    warnings: &mut Vec<String>,
) -> Result<JointOut, ImportError> {
    let element = |part: &str| format!("joint '{}' {part}", joint.name);
    let revolute = is_rotary(&joint.joint_type);
    let axis = finite3(joint.axis.xyz.0, &element("<axis>"), "xyz")?;
    if revolute && axis.iter().all(|&a| a == 0.0) {
        return Err(invalid(element("<axis>"), "the rotation axis is zero"));
    }
    let limits = if joint.joint_type == JointType::Revolute {
        convert_limits(joint, locked, warnings)?
    } else {
        None
    };
    Ok(JointOut {
        name: joint.name.clone(),
        revolute,
        parent: joint.parent.link.clone(),
        child: joint.child.link.clone(),
        xyz: finite3(joint.origin.xyz.0, &element("<origin>"), "xyz")?,
        rpy: finite3(joint.origin.rpy.0, &element("<origin>"), "rpy")?,
        axis,
        limits,
        locked,
        effects: convert_dynamics(joint, revolute && locked.is_none(), warnings)?,
    })
}

fn convert_limits(
    joint: &urdf_rs::Joint,
    locked: Option<f64>,
    warnings: &mut Vec<String>,
) -> Result<Option<LimitsOut>, ImportError> {
    let l = &joint.limit;
    // urdf-rs fills a missing <limit> with zeros (URDF < 1.2) or infinities.
    let absent = [l.lower, l.upper, l.effort, l.velocity]
        .iter()
        .all(|&v| v == 0.0);
    if absent || !l.lower.is_finite() || !l.upper.is_finite() {
        warnings.push(format!(
            "joint '{}' (revolute) has no finite <limit lower upper>; imported without limits",
            joint.name
        ));
        return Ok(None);
    }
    if l.lower > l.upper {
        return Err(invalid(
            format!("joint '{}' <limit>", joint.name),
            format!("lower {} > upper {}", l.lower, l.upper),
        ));
    }
    if let Some(angle) = locked.filter(|a| *a < l.lower || *a > l.upper) {
        warnings.push(format!(
            "joint '{}' is locked at {angle} rad, outside its limits [{}, {}]",
            joint.name, l.lower, l.upper
        ));
    }
    let positive = |v: f64| (v.is_finite() && v > 0.0).then_some(v);
    Ok(Some((
        l.lower,
        l.upper,
        positive(l.velocity),
        positive(l.effort),
    )))
}

/// URDF `<dynamics damping friction>` as viscous and Coulomb friction; only
/// a moving joint may carry them in the description.
fn convert_dynamics(
    joint: &urdf_rs::Joint,
    moving: bool,
    warnings: &mut Vec<String>,
) -> Result<Option<(f64, f64)>, ImportError> {
    let Some(d) = &joint.dynamics else {
        return Ok(None);
    };
    for (what, v) in [("damping", d.damping), ("friction", d.friction)] {
        if !v.is_finite() || v < 0.0 {
            return Err(invalid(
                format!("joint '{}' <dynamics>", joint.name),
                format!("{what} must be a finite number >= 0, found {v}"),
            ));
        }
    }
    if d.damping == 0.0 && d.friction == 0.0 {
        return Ok(None);
    }
    if !moving {
        warnings.push(format!(
            "joint '{}': <dynamics damping={} friction={}> dropped, the joint does not move",
            joint.name, d.damping, d.friction
        ));
        return Ok(None);
    }
    Ok(Some((d.damping, d.friction)))
}

fn attach_payloads(
    tree: &Tree<'_>,
    chain: &Selection,
    attachments: &[Attachment],
    links: &mut Vec<LinkOut>,
    joints: &mut Vec<JointOut>,
) -> Result<(), ImportError> {
    let mut taken: HashSet<String> = tree
        .link_index
        .keys()
        .chain(tree.joint_index.keys())
        .map(|s| s.to_string())
        .collect();
    for a in attachments {
        let link = tree.find_link("--attach", &a.link)?;
        if !chain.links.contains(&link) {
            return Err(option_error(
                "--attach",
                format!("link '{}' is not in the imported chain", a.link),
            ));
        }
        let body = payload_body(a)?;
        let name = unique_name(&format!("{}_payload", a.link), &mut taken);
        let joint = unique_name(&format!("{name}_joint"), &mut taken);
        let comment = match a.inertia {
            Some(_) => format!("Attached payload: --attach '{a}'"),
            None => format!(
                "Attached point mass: --attach '{a}'\n(inertia of a solid sphere of radius {POINT_MASS_RADIUS} m: \
                 the description needs a positive-definite one)"
            ),
        };
        links.push(LinkOut {
            name: name.clone(),
            body: Some(body),
            comment: Some(comment),
        });
        joints.push(JointOut {
            name: joint,
            revolute: false,
            parent: a.link.clone(),
            child: name,
            xyz: [0.0; 3],
            rpy: [0.0; 3],
            axis: [0.0, 0.0, 1.0],
            limits: None,
            locked: None,
            effects: None,
        });
    }
    Ok(())
}

fn payload_body(a: &Attachment) -> Result<Body, ImportError> {
    let finite = a.mass.is_finite()
        && a.com.iter().all(|x| x.is_finite())
        && a.inertia.iter().flatten().all(|x| x.is_finite());
    if !finite || a.mass <= 0.0 {
        return Err(option_error(
            "--attach",
            format!("'{a}' needs a finite mass > 0 and finite com/inertia"),
        ));
    }
    // 2/5 m r^2, to 6 digits so the file does not show rounding noise.
    let sphere = 0.4 * a.mass * POINT_MASS_RADIUS * POINT_MASS_RADIUS;
    let sphere = format!("{sphere:.5e}").parse().unwrap_or(sphere);
    Ok(Body {
        mass: a.mass,
        com: a.com,
        inertia: a.inertia.unwrap_or([sphere, sphere, sphere, 0.0, 0.0, 0.0]),
    })
}

/// Deepest element nesting accepted; a URDF is a few levels deep, and the
/// XML parser recurses per level (30,000 levels overflowed its stack).
const MAX_NESTING: usize = 64;

/// Refuses absurdly nested XML before the recursive parser sees it (one
/// pass: an opening tag counts when its `>` is not preceded by `/`).
fn check_nesting(text: &str) -> Result<(), ImportError> {
    let (mut depth, mut deepest) = (0usize, 0usize);
    // Inside an opening tag, a closing tag, or neither.
    let (mut opening, mut closing) = (false, false);
    let mut previous = b' ';
    for (i, pair) in text.as_bytes().windows(2).enumerate() {
        let (b, next) = (pair[0], pair[1]);
        match b {
            b'<' if next == b'/' => closing = true,
            b'<' if next != b'?' && next != b'!' => opening = true,
            b'>' if closing => {
                closing = false;
                depth = depth.saturating_sub(1);
            }
            b'>' if opening => {
                opening = false;
                if previous != b'/' {
                    depth += 1;
                    deepest = deepest.max(depth);
                }
            }
            _ => {}
        }
        previous = b;
        if deepest > MAX_NESTING {
            return Err(ImportError::Parse(format!(
                "elements nested more than {MAX_NESTING} deep (near byte {i}); a URDF is a few \
                 levels deep"
            )));
        }
    }
    Ok(())
}

/// Refuses names a description would refuse (control characters, such as
/// a newline written `&#10;` in the URDF), naming the element to rename.
fn check_names(
    name: &str,
    from_option: bool,
    links: &[LinkOut],
    joints: &[JointOut],
) -> Result<(), ImportError> {
    let invalid = |element: String, message: String| ImportError::Invalid { element, message };
    codegen::names::check_name(name).map_err(|m| {
        if from_option {
            invalid("--name".into(), m)
        } else {
            invalid(
                "<robot name>".into(),
                format!("{m}; pass --name to choose another"),
            )
        }
    })?;
    for link in links {
        codegen::names::check_name(&link.name)
            .map_err(|m| invalid(format!("<link name={:?}>", link.name), m))?;
    }
    for joint in joints {
        codegen::names::check_name(&joint.name)
            .map_err(|m| invalid(format!("<joint name={:?}>", joint.name), m))?;
    }
    Ok(())
}

fn unique_name(wanted: &str, taken: &mut HashSet<String>) -> String {
    let name = std::iter::once(wanted.to_string())
        .chain((2..).map(|n| format!("{wanted}_{n}")))
        .find(|n| !taken.contains(n))
        .unwrap_or_default();
    taken.insert(name.clone());
    name
}

fn header(
    source: &str,
    robot: &str,
    tree: &Tree<'_>,
    chain: &Selection,
    options: &ImportOptions,
) -> String {
    // Every name is written escaped ({:?}): a comment line cannot be ended
    // by the URDF's text.
    let mut flags = vec![
        format!("--base {:?}", tree.link_name(chain.base)),
        format!("--tip {:?}", tree.link_name(chain.tip)),
    ];
    flags.extend(
        options
            .lock
            .iter()
            .map(|(j, a)| format!("--lock {:?}", format!("{j}={a:?}"))),
    );
    flags.extend(
        options
            .attach
            .iter()
            .map(|a| format!("--attach {:?}", a.to_string())),
    );
    if let Some(name) = &options.name {
        flags.push(format!("--name {name:?}"));
    }
    format!(
        "# Imported by `sdnn import-urdf` from {source:?}\n# URDF robot {robot:?}, options: {}\n",
        flags.join(" ")
    )
}

fn render(name: &str, gravity: [f64; 3], links: &[LinkOut], joints: &[JointOut]) -> String {
    let mut doc = DocumentMut::new();
    doc["name"] = toml_edit::value(name);
    doc["gravity"] = toml_edit::value(float_array(&gravity));
    let mut link_tables = ArrayOfTables::new();
    for link in links {
        link_tables.push(link_table(link));
    }
    let mut joint_tables = ArrayOfTables::new();
    for joint in joints {
        joint_tables.push(joint_table(joint));
    }
    doc["links"] = Item::ArrayOfTables(link_tables);
    doc["joints"] = Item::ArrayOfTables(joint_tables);
    doc.to_string()
}

fn link_table(link: &LinkOut) -> Table {
    let mut t = Table::new();
    let comment: String = link
        .comment
        .iter()
        .flat_map(|c| c.lines())
        .map(|line| format!("# {line}\n"))
        .collect();
    t.decor_mut().set_prefix(format!("\n{comment}"));
    t["name"] = toml_edit::value(&link.name);
    if let Some(b) = &link.body {
        t["mass"] = toml_edit::value(float(b.mass));
        t["com"] = toml_edit::value(float_array(&b.com));
        let keys = ["ixx", "iyy", "izz", "ixy", "ixz", "iyz"];
        t["inertia"] = toml_edit::value(inline(
            keys.iter().zip(b.inertia).map(|(k, v)| (*k, float(v))),
        ));
    }
    t
}

fn joint_table(joint: &JointOut) -> Table {
    let mut t = Table::new();
    t.decor_mut().set_prefix("\n");
    t["name"] = toml_edit::value(&joint.name);
    t["type"] = toml_edit::value(if joint.revolute { "revolute" } else { "fixed" });
    t["parent"] = toml_edit::value(&joint.parent);
    t["child"] = toml_edit::value(&joint.child);
    let mut origin = vec![("xyz", Value::Array(float_array(&joint.xyz)))];
    if joint.rpy != [0.0; 3] {
        origin.push(("rpy", Value::Array(float_array(&joint.rpy))));
    }
    t["origin"] = toml_edit::value(inline(origin));
    if joint.revolute {
        t["axis"] = toml_edit::value(float_array(&joint.axis));
    }
    if let Some((lower, upper, velocity, effort)) = joint.limits {
        let entries = [
            ("lower", Some(lower)),
            ("upper", Some(upper)),
            ("velocity", velocity),
            ("effort", effort),
        ];
        let present = entries
            .into_iter()
            .filter_map(|(k, v)| Some((k, float(v?))));
        t["limits"] = toml_edit::value(inline(present));
    }
    if let Some(angle) = joint.locked {
        t["locked"] = toml_edit::value(float(angle));
    }
    if let Some((viscous, coulomb)) = joint.effects {
        t["effects"] = toml_edit::value(inline([
            ("viscous", float(viscous)),
            ("coulomb", float(coulomb)),
        ]));
    }
    t
}

fn inline<'k>(entries: impl IntoIterator<Item = (&'k str, Value)>) -> InlineTable {
    let mut table = InlineTable::new();
    for (k, v) in entries {
        table.insert(k, v);
    }
    table.fmt();
    table
}

/// A float in Rust's shortest round-trip form (`{:?}`: `0.35`, `3.9e-7`),
/// with -0.0 printed as 0.0.
fn float(x: f64) -> Value {
    let x = x + 0.0;
    format!("{x:?}").parse().unwrap_or_else(|_| Value::from(x))
}

fn float_array(v: &[f64]) -> Array {
    let mut array: Array = v.iter().map(|&x| float(x)).collect();
    array.fmt();
    array
}

#[cfg(test)]
mod tests {
    use super::*;

    fn link(name: &str) -> String {
        format!("<link name='{name}'/>")
    }

    fn body(name: &str, mass: f64, rpy: &str) -> String {
        format!(
            "<link name='{name}'><inertial><origin xyz='0.1 0 0' rpy='{rpy}'/><mass value='{mass}'/>\
             <inertia ixx='1' iyy='2' izz='3' ixy='0' ixz='0' iyz='0'/></inertial></link>"
        )
    }

    fn joint(name: &str, kind: &str, parent: &str, child: &str) -> String {
        format!(
            "<joint name='{name}' type='{kind}'><parent link='{parent}'/><child link='{child}'/>\
             <axis xyz='0 0 1'/><limit lower='-1' upper='1' effort='5' velocity='2'/></joint>"
        )
    }

    fn robot(parts: &[String]) -> String {
        format!("<robot name='test'>{}</robot>", parts.concat())
    }

    /// base -J1-> a -J2-> b, the smallest valid arm.
    fn arm(extra: &[String]) -> String {
        let mut parts = vec![
            link("base"),
            body("a", 1.0, "0 0 0"),
            body("b", 1.0, "0 0 0"),
            joint("J1", "revolute", "base", "a"),
            joint("J2", "revolute", "a", "b"),
        ];
        parts.extend_from_slice(extra);
        robot(&parts)
    }

    fn run(urdf: &str, options: &ImportOptions) -> Result<Imported, ImportError> {
        import_urdf(urdf, "test.urdf", options)
    }

    fn error(urdf: &str, options: &ImportOptions) -> String {
        run(urdf, options)
            .expect_err("import should fail")
            .to_string()
    }

    fn options(tip: &str) -> ImportOptions {
        ImportOptions {
            tip: Some(tip.into()),
            ..Default::default()
        }
    }

    fn parse(toml: &str) -> codegen::Description {
        codegen::Description::parse(toml, "test", std::path::Path::new("test.toml"))
            .unwrap_or_else(|e| panic!("{e}\n{toml}"))
    }

    #[test]
    fn prismatic_joint_on_the_chain_is_an_error() {
        let urdf = arm(&[body("c", 1.0, "0 0 0"), joint("J7", "prismatic", "b", "c")]);
        assert_eq!(
            error(&urdf, &ImportOptions::default()),
            "joint 'J7' (prismatic): prismatic joints are not supported (only revolute, continuous \
             and fixed); choose a --base/--tip that leaves it out"
        );
        // Off the chain it is only dropped with a warning.
        let imported = run(&urdf, &options("b")).expect("tip before J7");
        assert!(
            imported
                .warnings
                .iter()
                .any(|w| w.contains("'J7' (prismatic)"))
        );
        assert!(!imported.toml.contains("J7"));
    }

    #[test]
    fn mimic_joint_on_the_chain_is_an_error_unless_locked() {
        let mimic = "<joint name='J3' type='revolute'><parent link='b'/><child link='c'/>\
                     <limit lower='-1' upper='1' effort='1' velocity='1'/><mimic joint='J2'/></joint>";
        let urdf = arm(&[body("c", 1.0, "0 0 0"), mimic.to_string()]);
        let message = error(&urdf, &ImportOptions::default());
        assert!(
            message.starts_with("joint 'J3' (revolute): <mimic joint='J2'>"),
            "{message}"
        );
        let locked = ImportOptions {
            lock: vec![("J3".into(), 0.0)],
            ..Default::default()
        };
        let imported = run(&urdf, &locked).expect("locked mimic joint");
        assert!(
            imported
                .warnings
                .iter()
                .any(|w| w.contains("<mimic joint='J2'> ignored"))
        );
        assert_eq!(parse(&imported.toml).dof(), 2);
    }

    #[test]
    fn names_with_newlines_are_refused_and_never_reach_the_toml() {
        let crafted = arm(&[]).replace("name='test'", "name='Arm&#10;pub fn injected() {}&#10;#'");
        let message = error(&crafted, &ImportOptions::default());
        assert!(
            message.contains("<robot name>") && message.contains("U+000A"),
            "{message}"
        );
        assert!(message.contains("--name"), "{message}");
        // With --name the robot name is not used, and the header escapes it.
        let options = ImportOptions {
            name: Some("arm".into()),
            ..ImportOptions::default()
        };
        let imported = run(&crafted, &options).expect("imports with --name");
        assert!(!imported.toml.contains("\npub fn"), "{}", imported.toml);
        assert!(
            imported.toml.contains("\\npub fn injected"),
            "{}",
            imported.toml
        );
        let link = arm(&[])
            .replace("body(\"b\"", "")
            .replace("name='b'", "name='b&#10;x'");
        let link = link.replace("link='b'", "link='b&#10;x'");
        let message = error(&link, &ImportOptions::default());
        assert!(
            message.contains("<link name=") && message.contains("U+000A"),
            "{message}"
        );
        let bad = ImportOptions {
            name: Some("two\nlines".into()),
            ..ImportOptions::default()
        };
        assert!(error(&arm(&[]), &bad).starts_with("--name"));
    }

    #[test]
    fn deep_nesting_and_massless_arms_are_refused() {
        let deep = format!(
            "<robot name='r'>{}{}</robot>",
            "<x>".repeat(30_000),
            "</x>".repeat(30_000)
        );
        assert!(error(&deep, &ImportOptions::default()).contains("nested more than"));
        let shallow = arm(&["<gazebo><plugin><a/></plugin></gazebo>".to_string()]);
        assert!(run(&shallow, &ImportOptions::default()).is_ok());
        let massless = robot(&[
            link("base"),
            link("a"),
            link("b"),
            joint("J1", "revolute", "base", "a"),
            joint("J2", "revolute", "a", "b"),
        ]);
        let message = error(&massless, &ImportOptions::default());
        assert!(message.contains("massless"), "{message}");
    }

    #[test]
    fn unknown_names_in_options_are_errors() {
        let urdf = arm(&[]);
        let with = |f: fn(&mut ImportOptions)| {
            let mut o = ImportOptions::default();
            f(&mut o);
            error(&urdf, &o)
        };
        assert_eq!(
            with(|o| o.base = Some("nope".into())),
            "--base: no link named 'nope' in the URDF"
        );
        assert_eq!(
            with(|o| o.tip = Some("nope".into())),
            "--tip: no link named 'nope' in the URDF"
        );
        assert_eq!(
            with(|o| o.lock = vec![("nope".into(), 0.0)]),
            "--lock: no joint named 'nope' in the URDF"
        );
        assert_eq!(
            with(|o| o.attach = vec!["nope:mass=1".parse().unwrap()]),
            "--attach: no link named 'nope' in the URDF"
        );
        assert_eq!(
            with(|o| o.tip = Some("base".into())),
            "--tip: no joint moves between base 'base' and tip 'base'"
        );
        assert_eq!(
            with(|o| {
                o.base = Some("b".into());
                o.tip = Some("a".into());
            }),
            "--tip: link 'a' is not below the base 'b'"
        );
    }

    #[test]
    fn branching_tree_needs_a_tip_and_drops_moving_branches() {
        let urdf = arm(&[body("c", 1.0, "0 0 0"), joint("J3", "revolute", "a", "c")]);
        assert_eq!(
            error(&urdf, &ImportOptions::default()),
            "--tip: the URDF branches at link 'a' into several moving branches; choose the tip \
             with --tip (leaves: b, c)"
        );
        let imported = run(&urdf, &options("b")).expect("tip given");
        assert!(imported.warnings[0].starts_with("dropped the branch at joint 'J3'"));
        // Locking the other branch keeps it, lumped into body 1.
        let lock = ImportOptions {
            lock: vec![("J3".into(), 0.5)],
            ..options("b")
        };
        let imported = run(&urdf, &lock).expect("branch locked");
        assert!(imported.toml.contains("locked = 0.5"));
        assert!((parse(&imported.toml).chain().bodies[0].inertial.mass - 2.0).abs() < 1e-15);
    }

    #[test]
    fn rigid_branches_are_kept_and_links_above_the_base_dropped() {
        let urdf = robot(&[
            link("world"),
            link("base"),
            body("a", 1.0, "0 0 0"),
            body("gripper", 0.5, "0 0 0"),
            link("camera"),
            joint("mount", "fixed", "world", "base"),
            joint("J1", "continuous", "base", "a"),
            joint("grip", "fixed", "a", "gripper"),
            joint("cam", "fixed", "base", "camera"),
        ]);
        let all = run(&urdf, &ImportOptions::default()).expect("default chain");
        assert!(all.toml.contains("name = \"gripper\""), "{}", all.toml);
        let d = parse(&all.toml);
        assert_eq!((d.dof(), d.chain().bodies[0].inertial.mass), (1, 1.5));
        assert!(d.joints[1].limits.is_none(), "continuous has no limits");
        let base = ImportOptions {
            base: Some("base".into()),
            ..Default::default()
        };
        let cut = run(&urdf, &base).expect("base below the root");
        assert!(!cut.toml.contains("world"));
        assert!(cut.toml.contains("camera"));
        assert!(cut.warnings[0].contains("1 link(s) above it are dropped"));
    }

    #[test]
    fn gravity_is_expressed_in_a_rotated_base() {
        let mount = "<joint name='mount' type='fixed'><parent link='world'/><child link='base'/>\
                     <origin rpy='1.5707963267948966 0 0'/></joint>";
        let urdf = arm(&[link("world"), mount.to_string()]);
        let base = ImportOptions {
            base: Some("base".into()),
            ..Default::default()
        };
        let imported = run(&urdf, &base).expect("rotated base");
        assert_eq!(parse(&imported.toml).gravity, [0.0, -9.81, 0.0]);
    }

    /// Hand computation: roll 90 deg then yaw 90 deg (fixed axes) is
    /// R = Rz(90) Rx(90) = [[0,0,1],[1,0,0],[0,1,0]]: link x is the inertial
    /// frame's z, link y its x, link z its y, so diag(1, 2, 3) becomes
    /// diag(3, 1, 2). The other order, Rx Rz, would give diag(2, 3, 1).
    #[test]
    fn inertia_is_rotated_from_the_inertial_origin_into_the_link_frame() {
        let half_pi = std::f64::consts::FRAC_PI_2;
        let rotated = rotate_inertia(&[1.0, 2.0, 3.0, 0.0, 0.0, 0.0], &[half_pi, 0.0, half_pi]);
        let expected = [3.0, 1.0, 2.0, 0.0, 0.0, 0.0];
        assert!(
            rotated
                .iter()
                .zip(expected)
                .all(|(a, b)| (a - b).abs() < 1e-15),
            "{rotated:?}"
        );
        // Roll 90 deg maps a product of inertia ixy to ixz: R I R^T with
        // R = [[1,0,0],[0,0,-1],[0,1,0]] on [[a,d,0],[d,b,0],[0,0,c]] is
        // [[a,0,d],[0,c,0],[d,0,b]].
        let rotated = rotate_inertia(&[1.0, 2.0, 3.0, 0.5, 0.0, 0.0], &[half_pi, 0.0, 0.0]);
        let expected = [1.0, 3.0, 2.0, 0.0, 0.5, 0.0];
        assert!(
            rotated
                .iter()
                .zip(expected)
                .all(|(a, b)| (a - b).abs() < 1e-15),
            "{rotated:?}"
        );
        // And through the whole import.
        let urdf = arm(&[]).replace(
            &body("b", 1.0, "0 0 0"),
            &body("b", 1.0, "1.5707963267948966 0 1.5707963267948966"),
        );
        let d = parse(&run(&urdf, &ImportOptions::default()).expect("import").toml);
        let i = d.link("b").and_then(|l| l.inertia).expect("inertia");
        assert!(
            (i.ixx - 3.0).abs() < 1e-15
                && (i.iyy - 1.0).abs() < 1e-15
                && (i.izz - 2.0).abs() < 1e-15
        );
    }

    #[test]
    fn dynamics_become_effects_and_are_dropped_when_locked() {
        let urdf = arm(&[]).replace(
            "</joint></robot>",
            "<dynamics damping='0.3' friction='0.1'/></joint></robot>",
        );
        let imported = run(&urdf, &ImportOptions::default()).expect("import");
        assert!(
            imported
                .toml
                .contains("effects = { viscous = 0.3, coulomb = 0.1 }")
        );
        let lock = ImportOptions {
            lock: vec![("J2".into(), 0.0)],
            ..Default::default()
        };
        let imported = run(&urdf, &lock).expect("import");
        assert!(!imported.toml.contains("effects"));
        assert!(imported.warnings[0].contains("<dynamics damping=0.3 friction=0.1> dropped"));
        assert_eq!(parse(&imported.toml).dof(), 1);
    }

    #[test]
    fn transmissions_are_reported() {
        let urdf = arm(&[
            "<transmission name='t1'><type>x</type></transmission>".into(),
            "<!-- <transmission name='hidden'/> -->".into(),
        ]);
        let imported = run(&urdf, &ImportOptions::default()).expect("import");
        assert_eq!(imported.warnings.len(), 1);
        assert!(imported.warnings[0].starts_with("<transmission name='t1'> ignored"));
    }

    #[test]
    fn bad_urdf_values_and_structure_are_errors() {
        let cases = [
            (
                arm(&[]).replace("value='1'", "value='-1'"),
                "link 'a' <inertial>: mass must be",
            ),
            (
                arm(&[]).replace("lower='-1' upper='1'", "lower='1' upper='-1'"),
                "joint 'J1' <limit>: lower 1 > upper -1",
            ),
            (
                arm(&[]).replace("<axis xyz='0 0 1'/>", "<axis xyz='0 0 0'/>"),
                "joint 'J1' <axis>: the rotation axis is zero",
            ),
            (
                arm(&[joint("J9", "fixed", "b", "a")]),
                "URDF structure: link 'a' is the child of two joints",
            ),
            (
                arm(&[link("island")]),
                "URDF structure: 2 links have no parent (base, island)",
            ),
            (
                arm(&[link("a")]),
                "URDF structure: link 'a' is defined twice",
            ),
            (
                arm(&[joint("J3", "fixed", "b", "ghost")]),
                "URDF structure: joint 'J3': child link 'ghost'",
            ),
            (
                "<robot name='x'><link name='a'>".to_string(),
                "cannot parse the URDF",
            ),
            (String::new(), "cannot parse the URDF"),
        ];
        for (urdf, expected) in cases {
            let message = error(&urdf, &ImportOptions::default());
            assert!(message.starts_with(expected), "{message}");
        }
    }

    #[test]
    fn attachment_syntax() {
        let a: Attachment = "tool:mass=0.2018,com=0;0;0.05".parse().expect("valid");
        assert_eq!(
            (a.link.as_str(), a.mass, a.com, a.inertia),
            ("tool", 0.2018, [0.0, 0.0, 0.05], None)
        );
        assert_eq!(a.to_string().parse::<Attachment>(), Ok(a));
        let b: Attachment = "ns:tool:mass=1,inertia=1;2;2".parse().expect("valid");
        assert_eq!(
            (b.link.as_str(), b.com, b.inertia),
            ("ns:tool", [0.0; 3], Some([1.0, 2.0, 2.0, 0.0, 0.0, 0.0]))
        );
        let bad = [
            ("tool", "expected LINK:mass=KG"),
            (":mass=1", "missing link name"),
            ("tool:com=0;0;0", "missing mass=KG"),
            ("tool:mass=0", "mass must be > 0 kg"),
            ("tool:mass=x", "mass must be a finite number, found 'x'"),
            ("tool:mass=1,com=0;0", "com needs 3 numbers"),
            ("tool:mass=1,size=2", "unknown key 'size'"),
            ("tool:mass=1,mass=2", "key 'mass' given twice"),
            ("tool:mass=1,inertia=1;1", "inertia needs 3"),
            (
                "tool:mass=1,inertia=1;1;-1",
                "inertia '1;1;-1' is not positive definite",
            ),
            ("tool:mass=1;com=0;0;0", "mass must be a finite number"),
        ];
        for (text, expected) in bad {
            let message = text.parse::<Attachment>().expect_err(text);
            assert!(message.contains(expected), "{text}: {message}");
        }
    }

    #[test]
    fn lock_syntax() {
        assert_eq!(parse_lock("J3=0.5"), Ok(("J3".to_string(), 0.5)));
        assert_eq!(parse_lock(" J3 = -1e-1 "), Ok(("J3".to_string(), -0.1)));
        assert!(
            parse_lock("J3")
                .unwrap_err()
                .contains("expected JOINT=ANGLE")
        );
        assert!(parse_lock("=1").unwrap_err().contains("missing joint name"));
        assert!(parse_lock("J3=inf").unwrap_err().contains("finite number"));
    }

    #[test]
    fn attachment_adds_a_fixed_payload_link() {
        let attach = ImportOptions {
            attach: vec![
                "b:mass=0.5,com=0;0;0.1".parse().unwrap(),
                "b:mass=0.25".parse().unwrap(),
            ],
            ..Default::default()
        };
        let imported = run(&arm(&[]), &attach).expect("import");
        let d = parse(&imported.toml);
        assert!(d.link("b_payload").is_some() && d.link("b_payload_2").is_some());
        assert!((d.chain().bodies[1].inertial.mass - 1.75).abs() < 1e-15);
        assert!(
            imported
                .toml
                .contains("inertia = { ixx = 2e-7, iyy = 2e-7, izz = 2e-7")
        );
    }

    /// Kinova's URDF, vendored with its licence in data/gen3_lite/.
    const GEN3_LITE: &str = "data/gen3_lite/GEN3-LITE.urdf";

    fn gen3_lite() -> String {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(GEN3_LITE);
        std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
    }

    #[test]
    fn gen3_lite_round_trips_through_the_description_parser() {
        let urdf = gen3_lite();
        let label = GEN3_LITE;
        let imported = import_urdf(&urdf, label, &ImportOptions::default()).expect("import");
        assert!(imported.warnings.is_empty(), "{:?}", imported.warnings);
        assert!(imported.toml.starts_with(&format!(
            "# Imported by `sdnn import-urdf` from {label:?}\n"
        )));
        let d = parse(&imported.toml);
        assert_eq!(d.dof(), 6);
        assert_eq!(d.links.len(), 8);
        let again = import_urdf(&urdf, label, &ImportOptions::default()).expect("import");
        assert_eq!(again, imported, "deterministic");
        let locked = ImportOptions {
            lock: ["J3", "J4", "J5"]
                .iter()
                .map(|j| (j.to_string(), 0.0))
                .collect(),
            attach: vec!["END_EFFECTOR:mass=0.2018,com=0;0;0.05".parse().unwrap()],
            ..Default::default()
        };
        let three = parse(&import_urdf(&urdf, label, &locked).expect("import").toml);
        assert_eq!(three.dof(), 3);
        let mass: f64 = three.chain().bodies[2].inertial.mass;
        assert!((mass - (0.59767669 + 0.52693412 + 0.58097325 + 0.2018)).abs() < 1e-12);
    }
}
