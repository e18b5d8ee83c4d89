//! The robot description file (TOML): schema, parsing and validation.
//!
//! A description is a tree of links connected by joints. Parsing checks the
//! syntax and the schema (serde, unknown keys rejected); validation checks
//! the physics (masses, inertias, axes) and the topology (one root, no cycles,
//! no link with two parents). Every error names the file, line and key.

use std::collections::{HashMap, HashSet};
use std::path::Path;

use nalgebra::{Matrix3, SymmetricEigen};
use serde::Deserialize;

use crate::error::{DescriptionError, KeyPath, Located};
use crate::reduce::{Chain, reduce};

/// Standard gravity pointing down the base frame's z axis.
pub const DEFAULT_GRAVITY: [f64; 3] = [0.0, 0.0, -9.81];

/// Relative tolerance for inertia symmetry and the triangle inequality.
const INERTIA_RTOL: f64 = 1e-9;

/// A parsed and validated robot description.
#[derive(Debug, Clone, PartialEq)]
pub struct Description {
    /// Model name: the TOML file stem (`models/panda.toml` is `panda`).
    pub name: String,
    /// Human-readable robot name (`name` key); the model name if absent.
    pub robot: String,
    /// Gravity acceleration in the base frame, m/s^2.
    pub gravity: [f64; 3],
    pub links: Vec<Link>,
    pub joints: Vec<Joint>,
    chain: Chain,
}

/// A rigid body. A link without `mass` is a massless frame.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Link {
    pub name: String,
    /// Mass in kg; absent for a massless frame.
    pub mass: Option<f64>,
    /// Centre of mass in the link frame, m.
    #[serde(default)]
    pub com: [f64; 3],
    /// Inertia about the centre of mass, in link-frame axes, kg m^2.
    #[serde(default)]
    pub inertia: Option<Inertia>,
    /// Opt-in to keep an inertia tensor that is not physically realisable
    /// (violates the triangle inequality). The value says why.
    #[serde(default)]
    pub nonphysical_inertia: Option<String>,
}

/// The six independent entries of a symmetric inertia tensor, or a full
/// 3x3 matrix (checked for symmetry).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Inertia {
    pub ixx: f64,
    pub iyy: f64,
    pub izz: f64,
    pub ixy: f64,
    pub ixz: f64,
    pub iyz: f64,
}

/// The joint kinds a description may use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JointKind {
    Revolute,
    Fixed,
}

/// A joint connecting `parent` to `child`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Joint {
    pub name: String,
    #[serde(rename = "type")]
    pub kind: JointKind,
    pub parent: String,
    pub child: String,
    /// Joint frame in the parent link frame.
    #[serde(default)]
    pub origin: Origin,
    /// Rotation axis in the joint frame; normalized on load.
    #[serde(default = "default_axis")]
    pub axis: [f64; 3],
    #[serde(default)]
    pub limits: Option<Limits>,
    /// A revolute joint held at this angle (rad): lumped like a fixed joint.
    #[serde(default)]
    pub locked: Option<f64>,
    #[serde(default)]
    pub effects: JointEffects,
}

/// A frame offset: translation, then roll-pitch-yaw (fixed axes x, y, z).
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Origin {
    #[serde(default)]
    pub xyz: [f64; 3],
    #[serde(default)]
    pub rpy: [f64; 3],
}

/// Joint limits; informative for the generator, used by trajectory tools.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Limits {
    pub lower: f64,
    pub upper: f64,
    #[serde(default)]
    pub velocity: Option<f64>,
    #[serde(default)]
    pub effort: Option<f64>,
}

/// Per-joint effects added to the rigid-body torque:
/// `armature*qdd + viscous*qd + coulomb*sign(qd) + offset`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointEffects {
    /// Reflected rotor inertia, kg m^2.
    #[serde(default)]
    pub armature: f64,
    /// Viscous friction, N m s/rad.
    #[serde(default)]
    pub viscous: f64,
    /// Coulomb friction level, N m (sign(0) = 0).
    #[serde(default)]
    pub coulomb: f64,
    /// Constant torque offset, N m.
    #[serde(default)]
    pub offset: f64,
}

fn default_axis() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawDescription {
    #[serde(default)]
    name: Option<String>,
    #[serde(default)]
    gravity: Option<[f64; 3]>,
    #[serde(default)]
    links: Vec<Link>,
    #[serde(default)]
    joints: Vec<Joint>,
}

impl Inertia {
    /// The tensor as a symmetric matrix.
    pub fn matrix(&self) -> Matrix3<f64> {
        Matrix3::new(
            self.ixx, self.ixy, self.ixz, self.ixy, self.iyy, self.iyz, self.ixz, self.iyz,
            self.izz,
        )
    }

    /// The six entries of a symmetric matrix (its upper triangle).
    pub fn from_matrix(m: &Matrix3<f64>) -> Inertia {
        Inertia {
            ixx: m[(0, 0)],
            iyy: m[(1, 1)],
            izz: m[(2, 2)],
            ixy: m[(0, 1)],
            ixz: m[(0, 2)],
            iyz: m[(1, 2)],
        }
    }

    fn values(&self) -> [f64; 6] {
        [self.ixx, self.iyy, self.izz, self.ixy, self.ixz, self.iyz]
    }
}

impl<'de> Deserialize<'de> for Inertia {
    fn deserialize<D: serde::Deserializer<'de>>(de: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct Entries {
            ixx: f64,
            iyy: f64,
            izz: f64,
            #[serde(default)]
            ixy: f64,
            #[serde(default)]
            ixz: f64,
            #[serde(default)]
            iyz: f64,
        }
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Form {
            Entries(Entries),
            Matrix([[f64; 3]; 3]),
        }
        let form = Form::deserialize(de).map_err(|_| {
            serde::de::Error::custom(
                "expected `inertia = { ixx = .., iyy = .., izz = .., ixy = .., ixz = .., iyz = .. }` \
                 or a symmetric 3x3 matrix `[[..], [..], [..]]` of numbers",
            )
        })?;
        Ok(match form {
            Form::Entries(e) => Inertia {
                ixx: e.ixx,
                iyy: e.iyy,
                izz: e.izz,
                ixy: e.ixy,
                ixz: e.ixz,
                iyz: e.iyz,
            },
            Form::Matrix(m) => {
                let (sym, skew) = symmetric_parts(&m);
                if skew > INERTIA_RTOL * sym.max(f64::MIN_POSITIVE) {
                    return Err(serde::de::Error::custom(format!(
                        "inertia matrix is not symmetric (largest asymmetry {skew:e} kg m^2)"
                    )));
                }
                Inertia::from_matrix(&Matrix3::from_fn(|r, c| m[r][c]))
            }
        })
    }
}

/// Largest absolute entry and largest asymmetry |m_rc - m_cr| of a matrix.
fn symmetric_parts(m: &[[f64; 3]; 3]) -> (f64, f64) {
    let cells = (0..3).flat_map(|r| (0..3).map(move |c| (r, c)));
    cells.fold((0.0, 0.0), |(largest, skew): (f64, f64), (r, c)| {
        (
            largest.max(m[r][c].abs()),
            skew.max((m[r][c] - m[c][r]).abs()),
        )
    })
}

impl Description {
    /// Reads, parses and validates a description file. The model name is the
    /// file stem.
    pub fn load(path: impl AsRef<Path>) -> Result<Description, DescriptionError> {
        let path = path.as_ref();
        let source = std::fs::read_to_string(path).map_err(|e| DescriptionError::Io {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        let stem = path
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("model")
            .to_string();
        Description::parse(&source, &stem, path)
    }

    /// Parses and validates description text; `path` is used in messages only.
    pub fn parse(source: &str, name: &str, path: &Path) -> Result<Description, DescriptionError> {
        let raw: RawDescription = toml::from_str(source).map_err(|e| {
            let (line, column) = e
                .span()
                .map(|s| line_column(source, s.start))
                .unwrap_or((0, 0));
            DescriptionError::Syntax {
                path: path.to_path_buf(),
                line,
                column,
                message: e.message().to_string(),
            }
        })?;
        let mut description = Description {
            name: name.to_string(),
            robot: raw.name.unwrap_or_else(|| name.to_string()),
            gravity: raw.gravity.unwrap_or(DEFAULT_GRAVITY),
            links: raw.links,
            joints: raw.joints,
            chain: Chain {
                gravity: Default::default(),
                bodies: Vec::new(),
            },
        };
        let locate = |e: Located| e.locate(source, path.to_path_buf());
        description.validate().map_err(locate)?;
        description.normalize_axes();
        description.chain = reduce(&description).map_err(locate)?;
        Ok(description)
    }

    /// The serial chain of moving bodies, fixed and locked joints lumped.
    pub fn chain(&self) -> &Chain {
        &self.chain
    }

    /// Number of moving joints.
    pub fn dof(&self) -> usize {
        self.chain.bodies.len()
    }

    fn normalize_axes(&mut self) {
        for joint in &mut self.joints {
            let n = norm(&joint.axis);
            joint.axis = joint.axis.map(|a| a / n);
        }
    }

    /// Checks values and topology; errors carry a key path, not yet a line.
    fn validate(&self) -> Result<(), Located> {
        if !self.gravity.iter().all(|g| g.is_finite()) {
            return Err(Located::new(
                KeyPath::root().key("gravity"),
                "gravity must be finite numbers",
            ));
        }
        validate_name(&self.robot, KeyPath::root().key("name"))?;
        for (i, link) in self.links.iter().enumerate() {
            let at = KeyPath::root().key("links").index(i);
            validate_name(&link.name, at.key("name"))?;
            validate_link(link, at)?;
        }
        for (i, joint) in self.joints.iter().enumerate() {
            let at = KeyPath::root().key("joints").index(i);
            validate_name(&joint.name, at.key("name"))?;
            validate_joint(joint, at)?;
        }
        self.validate_topology()
    }

    fn validate_topology(&self) -> Result<(), Located> {
        let mut link_index = HashMap::new();
        for (i, link) in self.links.iter().enumerate() {
            if link_index.insert(link.name.as_str(), i).is_some() {
                return Err(Located::new(
                    KeyPath::root().key("links").index(i).key("name"),
                    format!("duplicate link name `{}`", link.name),
                ));
            }
        }
        let mut joint_names = HashSet::new();
        let mut parent_of: HashMap<&str, &str> = HashMap::new();
        for (i, joint) in self.joints.iter().enumerate() {
            let at = KeyPath::root().key("joints").index(i);
            if !joint_names.insert(joint.name.as_str()) {
                return Err(Located::new(
                    at.key("name"),
                    format!("duplicate joint name `{}`", joint.name),
                ));
            }
            for (key, link) in [("parent", &joint.parent), ("child", &joint.child)] {
                if !link_index.contains_key(link.as_str()) {
                    return Err(Located::new(
                        at.key(key),
                        format!(
                            "joint `{}` refers to link `{link}`, which is not defined in [[links]]",
                            joint.name
                        ),
                    ));
                }
            }
            if let Some(previous) = parent_of.insert(&joint.child, &joint.name) {
                return Err(Located::new(
                    at.key("child"),
                    format!(
                        "link `{}` has two parents: joints `{previous}` and `{}` both name it as child",
                        joint.child, joint.name
                    ),
                ));
            }
        }
        self.check_acyclic_single_root(&parent_of)
    }

    fn check_acyclic_single_root(&self, parent_joint: &HashMap<&str, &str>) -> Result<(), Located> {
        if self.links.is_empty() {
            return Err(Located::new(
                KeyPath::root(),
                "the description has no [[links]]",
            ));
        }
        let roots: Vec<&str> = self
            .links
            .iter()
            .map(|l| l.name.as_str())
            .filter(|name| !parent_joint.contains_key(name))
            .collect();
        let joint_of = |name: &str| self.joints.iter().position(|j| j.name == name);
        // Walk up from every link; a walk longer than the link count is a cycle.
        for link in &self.links {
            let mut current = link.name.as_str();
            for _ in 0..=self.links.len() {
                match parent_joint.get(current) {
                    Some(joint) => current = &self.joints[joint_of(joint).unwrap_or(0)].parent,
                    None => break,
                }
            }
            if parent_joint.contains_key(current) {
                let j = joint_of(parent_joint[current]).unwrap_or(0);
                return Err(Located::new(
                    KeyPath::root().key("joints").index(j).key("parent"),
                    format!("the joints form a cycle through link `{current}`"),
                ));
            }
        }
        match roots.as_slice() {
            [_] => Ok(()),
            [] => Err(Located::new(
                KeyPath::root().key("joints"),
                "every link has a parent: the joints form a cycle",
            )),
            many => Err(Located::new(
                KeyPath::root().key("links"),
                format!(
                    "the links do not form one tree: {} links have no parent ({}); connect them with joints",
                    many.len(),
                    many.join(", ")
                ),
            )),
        }
    }

    /// The root link: the only link that is no joint's child.
    pub fn root(&self) -> &Link {
        self.links
            .iter()
            .find(|l| self.joints.iter().all(|j| j.child != l.name))
            .expect("validated description has a root")
    }

    /// The link with this name.
    pub fn link(&self, name: &str) -> Option<&Link> {
        self.links.iter().find(|l| l.name == name)
    }
}

/// Rust keywords (strict and reserved, all editions): a model is a module
/// named by its file stem, so these cannot be model names.
const KEYWORDS: [&str; 52] = [
    "abstract", "as", "async", "await", "become", "box", "break", "const", "continue", "crate",
    "do", "dyn", "else", "enum", "extern", "false", "final", "fn", "for", "gen", "if", "impl",
    "in", "let", "loop", "macro", "match", "mod", "move", "mut", "override", "priv", "pub", "ref",
    "return", "self", "static", "struct", "super", "trait", "true", "try", "type", "typeof",
    "union", "unsafe", "unsized", "use", "virtual", "where", "while", "yield",
];

/// A model is a module named by its description's file stem: a snake_case
/// Rust identifier that is not a keyword.
pub fn check_model_name(name: &str, toml: &Path) -> Result<(), String> {
    if KEYWORDS.contains(&name) || name == "_" {
        return Err(format!(
            "{}: the model is named by its file stem, which becomes a Rust module name;              `{name}` is a Rust keyword, rename the file (for example `{name}_arm.toml`)",
            toml.display()
        ));
    }
    let mut chars = name.chars();
    let valid = chars
        .next()
        .is_some_and(|c| c.is_ascii_lowercase() || c == '_')
        && chars.all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_');
    if valid {
        Ok(())
    } else {
        Err(format!(
            "{}: the model is named by its file stem, which must be a snake_case Rust identifier \
             (lowercase letters, digits, `_`); found `{name}`",
            toml.display()
        ))
    }
}

/// Longest robot, link or joint name accepted, in characters.
pub const MAX_NAME_CHARS: usize = 200;

/// Names are data shown in generated comments, reports and files: one line
/// of printable text. Control characters (a newline could end a comment in
/// generated code) are refused, not escaped, so every output shows the name
/// as written.
pub fn check_name(name: &str) -> Result<(), String> {
    if let Some(c) = name.chars().find(|c| c.is_control()) {
        return Err(format!(
            "name {name:?} contains the control character U+{:04X}; names must be one line of printable text",
            u32::from(c)
        ));
    }
    if name.chars().count() > MAX_NAME_CHARS {
        return Err(format!(
            "name is {} characters long; at most {MAX_NAME_CHARS} are accepted",
            name.chars().count()
        ));
    }
    Ok(())
}

fn validate_name(name: &str, at: KeyPath) -> Result<(), Located> {
    check_name(name).map_err(|message| Located::new(at, message))
}

fn validate_link(link: &Link, at: KeyPath) -> Result<(), Located> {
    let Some(mass) = link.mass else {
        if link.inertia.is_some() || link.com != [0.0; 3] {
            return Err(Located::new(
                at.key("mass"),
                format!(
                    "link `{}` has `com` or `inertia` but no `mass`; give a mass > 0 or remove them for a massless frame",
                    link.name
                ),
            ));
        }
        return Ok(());
    };
    if !mass.is_finite() || mass <= 0.0 {
        return Err(Located::new(
            at.key("mass"),
            format!(
                "mass of link `{}` must be a finite number > 0 kg, found {mass}",
                link.name
            ),
        ));
    }
    if !link.com.iter().all(|c| c.is_finite()) {
        return Err(Located::new(
            at.key("com"),
            "com must be finite numbers (m)",
        ));
    }
    let Some(inertia) = link.inertia else {
        return Err(Located::new(
            at.key("inertia"),
            format!(
                "link `{}` has a mass but no `inertia` about its centre of mass",
                link.name
            ),
        ));
    };
    validate_inertia(&inertia, link, at.key("inertia"))
}

fn validate_inertia(inertia: &Inertia, link: &Link, at: KeyPath) -> Result<(), Located> {
    if !inertia.values().iter().all(|v| v.is_finite()) {
        return Err(Located::new(
            at,
            "inertia entries must be finite numbers (kg m^2)",
        ));
    }
    let eig = SymmetricEigen::new(inertia.matrix()).eigenvalues;
    let mut p = [eig[0], eig[1], eig[2]];
    p.sort_by(f64::total_cmp);
    if p[0] <= 0.0 {
        return Err(Located::new(
            at,
            format!(
                "inertia of link `{}` is not positive definite: principal moments {:.6e}, {:.6e}, {:.6e} kg m^2",
                link.name, p[0], p[1], p[2]
            ),
        ));
    }
    if p[0] + p[1] < p[2] * (1.0 - INERTIA_RTOL) && link.nonphysical_inertia.is_none() {
        return Err(Located::new(
            at,
            format!(
                "inertia of link `{}` violates the triangle inequality: principal moments {:.6e} + {:.6e} < {:.6e} kg m^2, \
                 so no rigid body has it; fix the tensor, or keep it on purpose with `nonphysical_inertia = \"<why>\"`",
                link.name, p[0], p[1], p[2]
            ),
        ));
    }
    Ok(())
}

fn validate_joint(joint: &Joint, at: KeyPath) -> Result<(), Located> {
    let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
    if !finite(&joint.origin.xyz) || !finite(&joint.origin.rpy) {
        return Err(Located::new(
            at.key("origin"),
            "origin xyz and rpy must be finite numbers",
        ));
    }
    if !finite(&joint.axis) {
        return Err(Located::new(at.key("axis"), "axis must be finite numbers"));
    }
    if joint.kind == JointKind::Revolute && norm(&joint.axis) < 1e-12 {
        return Err(Located::new(
            at.key("axis"),
            format!(
                "axis of joint `{}` is zero; give a non-zero direction",
                joint.name
            ),
        ));
    }
    if joint.child == joint.parent {
        return Err(Located::new(
            at.key("child"),
            format!(
                "joint `{}` connects link `{}` to itself",
                joint.name, joint.child
            ),
        ));
    }
    let e = &joint.effects;
    if !finite(&[e.armature, e.viscous, e.coulomb, e.offset]) {
        return Err(Located::new(
            at.key("effects"),
            "effects must be finite numbers",
        ));
    }
    for (key, value) in [
        ("armature", e.armature),
        ("viscous", e.viscous),
        ("coulomb", e.coulomb),
    ] {
        if value < 0.0 {
            return Err(Located::new(
                at.key("effects").key(key),
                format!(
                    "{key} of joint `{}` must be >= 0, found {value}",
                    joint.name
                ),
            ));
        }
    }
    if let Some(angle) = joint.locked {
        if joint.kind != JointKind::Revolute {
            return Err(Located::new(
                at.key("locked"),
                "only a revolute joint can be locked",
            ));
        }
        if !angle.is_finite() {
            return Err(Located::new(
                at.key("locked"),
                "locked angle must be a finite number (rad)",
            ));
        }
    }
    let moving = joint.kind == JointKind::Revolute && joint.locked.is_none();
    if !moving && *e != JointEffects::default() {
        return Err(Located::new(
            at.key("effects"),
            format!(
                "joint `{}` does not move (fixed or locked), so it cannot have effects",
                joint.name
            ),
        ));
    }
    if let Some(l) = joint.limits
        && (!finite(&[l.lower, l.upper]) || l.lower > l.upper)
    {
        return Err(Located::new(
            at.key("limits"),
            format!(
                "limits need finite lower <= upper, found {} > {}",
                l.lower, l.upper
            ),
        ));
    }
    Ok(())
}

fn norm(v: &[f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// 1-based line and column of a byte offset.
pub(crate) fn line_column(source: &str, offset: usize) -> (usize, usize) {
    let before = &source[..offset.min(source.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}
