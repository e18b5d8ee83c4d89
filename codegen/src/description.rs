//! The robot description file (TOML): parsing and validation (the types
//! are in `schema.rs`, the name rules in `names.rs`).
//!
//! A description is a tree of links connected by joints. Parsing checks the
//! syntax and the schema (serde, unknown keys rejected); validation checks
//! the physics (masses, inertias, axes) and the topology (one root, no cycles,
//! no link with two parents). Every error names the file, line and key.

use std::collections::{HashMap, HashSet};
use std::path::Path;

use nalgebra::SymmetricEigen;
use serde::Deserialize;

use crate::error::{DescriptionError, KeyPath, Located, line_column};
pub use crate::names::{MAX_NAME_CHARS, check_model_name, check_name};
use crate::reduce::{Chain, reduce};
pub use crate::schema::{Inertia, Joint, JointEffects, JointKind, Limits, Link, Mimic, Origin};

/// Standard gravity pointing down the base frame's z axis.
pub const DEFAULT_GRAVITY: [f64; 3] = [0.0, 0.0, -9.81];

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
        description.chain =
            reduce(&description.links, &description.joints, description.gravity).map_err(locate)?;
        Ok(description)
    }

    /// The serial chain of moving bodies, fixed and locked joints lumped.
    pub fn chain(&self) -> &Chain {
        &self.chain
    }

    /// Degrees of freedom: the moving joints that do not follow another.
    pub fn dof(&self) -> usize {
        self.chain.dof()
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
        let gravity = KeyPath::root().key("gravity");
        plausible(
            &self.gravity,
            PLAUSIBLE_GRAVITY,
            gravity,
            "gravity component (m/s^2)",
        )?;
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

    /// The link with this name.
    pub fn link(&self, name: &str) -> Option<&Link> {
        self.links.iter().find(|l| l.name == name)
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
        self.check_mimics()?;
        self.check_acyclic_single_root(&parent_of)
    }

    /// A mimic follows an existing joint with a position that is not itself
    /// a mimic.
    fn check_mimics(&self) -> Result<(), Located> {
        for (i, joint) in self.joints.iter().enumerate() {
            let Some(mimic) = &joint.mimic else { continue };
            let master = self.joints.iter().find(|j| j.name == mimic.joint);
            let problem = match master {
                None => Some("which is not defined in [[joints]]"),
                Some(m) if m.name == joint.name => Some("itself"),
                Some(m) if !m.kind.has_position() => Some("which is fixed"),
                Some(m) if m.mimic.is_some() => {
                    Some("which is a mimic itself; follow its master instead")
                }
                Some(_) => None,
            };
            if let Some(problem) = problem {
                return Err(Located::new(
                    KeyPath::root()
                        .key("joints")
                        .index(i)
                        .key("mimic")
                        .key("joint"),
                    format!(
                        "joint `{}` follows `{}`, {problem}",
                        joint.name, mimic.joint
                    ),
                ));
            }
        }
        Ok(())
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
    plausible(&[mass], PLAUSIBLE_MASS, at.key("mass"), "mass (kg)")?;
    plausible(
        &link.com,
        PLAUSIBLE_LENGTH,
        at.key("com"),
        "com component (m)",
    )?;
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
    let entries = inertia.values();
    plausible(
        &entries,
        PLAUSIBLE_INERTIA,
        at.clone(),
        "inertia entry (kg m^2)",
    )?;
    let eig = SymmetricEigen::new(inertia.matrix()).eigenvalues;
    let mut p = [eig[0], eig[1], eig[2]];
    p.sort_by(f64::total_cmp);
    if link.nonphysical_inertia.is_some() {
        return Ok(());
    }
    // A point mass (zero inertia) and a thin rod (one moment zero) are
    // physical; files round their numbers, so both checks allow for it.
    let rounding = INERTIA_ROUNDING * p[2] + INERTIA_FLOOR;
    if p[0] < -rounding {
        return Err(Located::new(
            at,
            format!(
                "inertia of link `{}` is not positive semi-definite: principal moments {:.6e}, {:.6e}, {:.6e} kg m^2, \
                 so no rigid body has it; fix the tensor, or keep it on purpose with `nonphysical_inertia = \"<why>\"`",
                link.name, p[0], p[1], p[2]
            ),
        ));
    }
    if p[0] + p[1] < p[2] - rounding {
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

/// Rounding allowed in the inertia checks: relative to the largest principal
/// moment (files print five or six digits) plus an absolute floor, far below
/// any link of an arm (kg m^2).
pub const INERTIA_ROUNDING: f64 = 1e-5;
pub const INERTIA_FLOOR: f64 = 1e-12;

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
    let origin = at.key("origin");
    plausible(
        &joint.origin.xyz,
        PLAUSIBLE_LENGTH,
        origin.key("xyz"),
        "origin component (m)",
    )?;
    plausible(
        &joint.origin.rpy,
        PLAUSIBLE_ANGLE,
        origin.key("rpy"),
        "rpy angle (rad)",
    )?;
    let (position_limit, unit) = match joint.kind {
        JointKind::Prismatic => (PLAUSIBLE_LENGTH, "position (m)"),
        _ => (PLAUSIBLE_ANGLE, "angle (rad)"),
    };
    if let Some(position) = joint.locked {
        plausible(
            &[position],
            position_limit,
            at.key("locked"),
            &format!("locked {unit}"),
        )?;
    }
    if joint.kind.has_position() && norm(&joint.axis) < 1e-12 {
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
    let effects = e.parameters();
    if !finite(&effects) || !finite(&e.shapes()) {
        return Err(Located::new(
            at.key("effects"),
            "effects must be finite numbers",
        ));
    }
    plausible(
        &[e.spring_rest],
        PLAUSIBLE_ANGLE,
        at.key("effects").key("spring_rest"),
        "spring rest angle (rad)",
    )?;
    plausible(
        &effects,
        PLAUSIBLE_EFFECT,
        at.key("effects"),
        "effect coefficient",
    )?;
    shaping_numbers(e, &joint.name, &at.key("effects"))?;
    if e.coulomb_asymmetry.abs() > e.coulomb {
        return Err(Located::new(
            at.key("effects").key("coulomb_asymmetry"),
            format!(
                "coulomb_asymmetry of joint `{}` is {}, beyond coulomb ({}): one direction's \
                 friction level (coulomb - |coulomb_asymmetry|) would be negative",
                joint.name, e.coulomb_asymmetry, e.coulomb
            ),
        ));
    }
    for (key, value) in [
        ("armature", e.armature),
        ("viscous", e.viscous),
        ("coulomb", e.coulomb),
        ("spring", e.spring),
        ("stribeck", e.stribeck),
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
    validate_hold(joint, &at)?;
    if !joint.is_free() && *e != JointEffects::default() {
        return Err(Located::new(
            at.key("effects"),
            format!(
                "joint `{}` does not move alone (fixed, locked or a mimic), so it cannot have effects",
                joint.name
            ),
        ));
    }
    if let Some(l) = joint.limits {
        validate_limits(&l, &at.key("limits"))?;
    }
    Ok(())
}

/// `locked` and `mimic`: only on joints with a position, not both, finite.
fn validate_hold(joint: &Joint, at: &KeyPath) -> Result<(), Located> {
    if joint.locked.is_some() && !joint.kind.has_position() {
        return Err(Located::new(
            at.key("locked"),
            "only a revolute or prismatic joint can be locked",
        ));
    }
    let Some(mimic) = &joint.mimic else {
        return Ok(());
    };
    let at = at.key("mimic");
    if !joint.kind.has_position() {
        return Err(Located::new(
            at,
            "only a revolute or prismatic joint can follow another",
        ));
    }
    if joint.locked.is_some() {
        return Err(Located::new(
            at,
            format!(
                "joint `{}` is locked and a mimic: remove one (a mimic is held when its master is locked)",
                joint.name
            ),
        ));
    }
    if !mimic.multiplier.is_finite() || !mimic.offset.is_finite() {
        return Err(Located::new(
            at,
            "mimic multiplier and offset must be finite numbers",
        ));
    }
    plausible(
        &[mimic.multiplier, mimic.offset],
        PLAUSIBLE_EFFECT,
        at,
        "mimic multiplier or offset",
    )
}

/// Both position limits or neither, finite, lower <= upper; speeds and
/// efforts finite and >= 0.
fn validate_limits(l: &Limits, at: &KeyPath) -> Result<(), Located> {
    match (l.lower, l.upper) {
        (Some(lower), Some(upper))
            if !(lower.is_finite() && upper.is_finite() && lower <= upper) =>
        {
            return Err(Located::new(
                at.clone(),
                format!("limits need finite lower <= upper, found {lower} > {upper}"),
            ));
        }
        (Some(_), None) | (None, Some(_)) => {
            return Err(Located::new(
                at.clone(),
                "give both `lower` and `upper`, or neither (a continuous joint)",
            ));
        }
        _ => {}
    }
    for (key, value) in [("velocity", l.velocity), ("effort", l.effort)] {
        if let Some(v) = value
            && !(v.is_finite() && v >= 0.0)
        {
            return Err(Located::new(
                at.key(key),
                format!("{key} limit must be a finite number >= 0, found {v}"),
            ));
        }
    }
    Ok(())
}

/// Euclidean length without overflow (components are scaled by the
/// largest first: an axis of [1e200, 0, 0] has length 1e200, not inf).
fn norm(v: &[f64; 3]) -> f64 {
    let largest = v.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
    if largest == 0.0 || !largest.is_finite() {
        return largest;
    }
    let s = v.map(|x| x / largest);
    largest * (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt()
}

/// Largest magnitudes accepted, far outside any arm: a value past them is
/// a typo or a unit slip, and squared in the dynamics it would overflow.
pub const PLAUSIBLE_MASS: f64 = 1e5; // kg
pub const PLAUSIBLE_LENGTH: f64 = 1e2; // m (origins, centres of mass)
pub const PLAUSIBLE_INERTIA: f64 = 1e5; // kg m^2
pub const PLAUSIBLE_ANGLE: f64 = 1e2; // rad (rpy, locked angles)
pub const PLAUSIBLE_EFFECT: f64 = 1e6; // armature, friction, offset, spring
pub const PLAUSIBLE_GRAVITY: f64 = 1e3; // m/s^2

/// A located error when a value exceeds `limit`.
fn plausible(values: &[f64], limit: f64, at: KeyPath, what: &str) -> Result<(), Located> {
    match values.iter().find(|v| v.abs() > limit) {
        Some(v) => Err(Located::new(
            at,
            format!("{what} {v:e} is beyond any arm (at most {limit:e}); a typo or a unit slip?"),
        )),
        None => Ok(()),
    }
}

/// Fastest Stribeck velocity, rad/s, and most ripple periods per revolution.
pub const PLAUSIBLE_STRIBECK_VELOCITY: f64 = 1e2;
pub const PLAUSIBLE_RIPPLE_CYCLES: f64 = 1e4;

/// The Stribeck velocity and the ripple's cycles: within range, and
/// positive where their effect is present (a zero would divide or vanish).
fn shaping_numbers(e: &JointEffects, joint: &str, at: &KeyPath) -> Result<(), Located> {
    let checks = [
        (
            "stribeck_velocity",
            e.stribeck_velocity,
            PLAUSIBLE_STRIBECK_VELOCITY,
            e.stribeck != 0.0,
            "rad/s, the speed past which the breakaway excess `stribeck` fades",
        ),
        (
            "ripple_cycles",
            e.ripple_cycles,
            PLAUSIBLE_RIPPLE_CYCLES,
            e.ripple_sin != 0.0 || e.ripple_cos != 0.0,
            "periods of the ripple per joint revolution",
        ),
    ];
    for (key, value, limit, needed, meaning) in checks {
        plausible(&[value], limit, at.key(key), key)?;
        if value < 0.0 || (needed && value == 0.0) {
            let requirement = if needed { "> 0" } else { ">= 0" };
            return Err(Located::new(
                at.key(key),
                format!(
                    "{key} of joint `{joint}` must be {requirement} ({meaning}), found {value}"
                ),
            ));
        }
    }
    Ok(())
}
