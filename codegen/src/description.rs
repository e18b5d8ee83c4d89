//! The robot description file (TOML): parsing and validation (the types
//! are in `schema.rs`, the name rules in `names.rs`).
//!
//! A description is a tree of links connected by joints. Parsing checks the
//! syntax and the schema (serde, unknown keys rejected); validation checks
//! the physics (masses, inertias, axes) and the topology (one root, no cycles,
//! no link with two parents). Every error names the file, line and key.

use std::collections::{HashMap, HashSet};
use std::path::Path;

use serde::Deserialize;

use crate::error::{DescriptionError, KeyPath, Located, line_column};
pub use crate::names::{MAX_NAME_CHARS, check_model_name, check_name};
use crate::reduce::{Chain, reduce};
pub use crate::schema::{Inertia, Joint, JointEffects, JointKind, Limits, Link, Mimic, Origin};
pub use crate::validate::{
    INERTIA_FLOOR, INERTIA_ROUNDING, PLAUSIBLE_ANGLE, PLAUSIBLE_EFFECT, PLAUSIBLE_GRAVITY,
    PLAUSIBLE_INERTIA, PLAUSIBLE_LENGTH, PLAUSIBLE_MASS, PLAUSIBLE_RIPPLE_CYCLES,
    PLAUSIBLE_STRIBECK_VELOCITY,
};
use crate::validate::{norm, plausible, validate_joint, validate_link, validate_name};

/// Largest description file read (16 MiB, about 64,000 joints; a real
/// arm's is a few kB): beyond it a file is refused before it is read
/// whole, where a 2 GiB file aborted on a 15 GB allocation. Loading is
/// linear in the joints, about 0.9 s and 220 MB for 16,000.
pub const MAX_DESCRIPTION_BYTES: u64 = 16 << 20;

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
        let source = read_bounded(path).map_err(|e| DescriptionError::Io {
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
                message: with_key(e.message(), e.span().and_then(|s| source.get(s))),
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

    /// The tool frame, if the tip's link carries one (`tool.rs`).
    pub fn tool_frame(&self) -> Option<crate::tool::ToolFrame> {
        crate::tool::tool_frame(&self.chain, &self.joints)
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
        let mut joint_index: HashMap<&str, usize> = HashMap::new();
        let mut parent_of: HashMap<&str, &str> = HashMap::new();
        for (i, joint) in self.joints.iter().enumerate() {
            let at = KeyPath::root().key("joints").index(i);
            if joint_index.insert(joint.name.as_str(), i).is_some() {
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
        self.check_mimics(&joint_index)?;
        self.check_acyclic_single_root(&parent_of, &joint_index)
    }

    /// A mimic follows an existing joint with a position that is not itself
    /// a mimic.
    fn check_mimics(&self, joint_index: &HashMap<&str, usize>) -> Result<(), Located> {
        for (i, joint) in self.joints.iter().enumerate() {
            let Some(mimic) = &joint.mimic else { continue };
            let master = joint_index
                .get(mimic.joint.as_str())
                .map(|&m| &self.joints[m]);
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

    /// One root and no cycle, in time linear in the links: each link is
    /// walked up until a link already known to reach the root (a walk per
    /// link to the root was quadratic in a long chain, cubic with the
    /// joint look-ups).
    fn check_acyclic_single_root(
        &self,
        parent_joint: &HashMap<&str, &str>,
        joint_index: &HashMap<&str, usize>,
    ) -> Result<(), Located> {
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
        // Links whose walk up ends at a root.
        let mut rooted: HashSet<&str> = roots.iter().copied().collect();
        for link in &self.links {
            let mut path: HashSet<&str> = HashSet::new();
            let mut current = link.name.as_str();
            while !rooted.contains(current) {
                if !path.insert(current) {
                    let j = joint_index[parent_joint[current]];
                    return Err(Located::new(
                        KeyPath::root().key("joints").index(j).key("parent"),
                        format!("the joints form a cycle through link `{current}`"),
                    ));
                }
                // Not rooted, so not a root: it has a parent joint.
                current = &self.joints[joint_index[parent_joint[current]]].parent;
            }
            rooted.extend(path);
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
                    some_names(many)
                ),
            )),
        }
    }
}

/// At most ten names of a list, comma separated, then how many more: an
/// error about 100,000 unconnected links stays a readable line.
fn some_names(names: &[&str]) -> String {
    const SHOWN: usize = 10;
    let mut text = names[..names.len().min(SHOWN)].join(", ");
    if names.len() > SHOWN {
        text.push_str(&format!(" and {} more", names.len() - SHOWN));
    }
    text
}

/// The text of `path`, refused beyond [`MAX_DESCRIPTION_BYTES`].
fn read_bounded(path: &Path) -> std::io::Result<String> {
    use std::io::Read;
    let mut text = String::new();
    std::fs::File::open(path)?
        .take(MAX_DESCRIPTION_BYTES + 1)
        .read_to_string(&mut text)?;
    if text.len() as u64 > MAX_DESCRIPTION_BYTES {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!(
                "larger than {} MiB: not a robot description (a few kB for an arm)",
                MAX_DESCRIPTION_BYTES >> 20
            ),
        ));
    }
    Ok(text)
}

/// The parser's message, naming the key for a duplicate key (the message
/// alone says "duplicate key" and the span points at it).
fn with_key(message: &str, span: Option<&str>) -> String {
    match span.map(str::trim) {
        Some(key)
            if message.starts_with("duplicate key") && !key.is_empty() && key.len() <= 200 =>
        {
            format!("{} `{key}`", message.trim_end())
        }
        _ => message.to_string(),
    }
}
