//! Reads what rigid-body dynamics need from URDF text: the robot name, each
//! link's `<inertial>` and each joint. Nothing else is interpreted (visual,
//! collision, materials, textures, transmissions, gazebo), so a malformed
//! colour or a texture without a file cannot stop an import. Errors name the
//! element and its line.
//!
//! A value error inside a link or joint is kept with it and raised only when
//! that element is imported: a bad number in the other arm of a humanoid
//! does not stop the import of this one.

use std::collections::BTreeMap;

use roxmltree::{Document, Node, ParsingOptions};

use super::ImportError;

/// Deepest element nesting accepted; a URDF is a few levels deep.
const MAX_NESTING: usize = 64;

/// Most XML nodes accepted: a bound on memory for hostile input (the
/// largest humanoid URDFs have tens of thousands).
const MAX_NODES: u32 = 2_000_000;

/// Most links, and most joints, accepted: a robot has tens to hundreds;
/// the import's chain analysis grows faster than linearly (10,000 links
/// take about 6 s and 230 MB), and 10^6 links exhausted 12 GB.
pub(super) const MAX_LINKS: usize = 10_000;

/// The parts of a URDF the import uses.
#[derive(Debug)]
pub(super) struct Urdf {
    pub name: String,
    pub links: Vec<Link>,
    pub joints: Vec<Joint>,
    /// Top-level elements that carry no rigid-body dynamics, by tag, counted.
    pub skipped: BTreeMap<String, usize>,
}

#[derive(Debug)]
pub(super) struct Link {
    pub name: String,
    pub line: usize,
    pub inertial: Result<Option<Inertial>, ImportError>,
}

/// Mass (kg), COM and inertia frame in the link frame, inertia about the
/// COM in that frame (ixx iyy izz ixy ixz iyz, kg m^2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Inertial {
    pub xyz: [f64; 3],
    pub rpy: [f64; 3],
    pub mass: f64,
    pub inertia: [f64; 6],
    pub line: usize,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Kind {
    Revolute,
    Continuous,
    Prismatic,
    Fixed,
    Floating,
    Planar,
    Spherical,
}

impl Kind {
    fn parse(text: &str) -> Option<Kind> {
        Some(match text {
            "revolute" => Kind::Revolute,
            "continuous" => Kind::Continuous,
            "prismatic" => Kind::Prismatic,
            "fixed" => Kind::Fixed,
            "floating" => Kind::Floating,
            "planar" => Kind::Planar,
            "spherical" => Kind::Spherical,
            _ => return None,
        })
    }

    pub fn name(self) -> &'static str {
        match self {
            Kind::Revolute => "revolute",
            Kind::Continuous => "continuous",
            Kind::Prismatic => "prismatic",
            Kind::Fixed => "fixed",
            Kind::Floating => "floating",
            Kind::Planar => "planar",
            Kind::Spherical => "spherical",
        }
    }

    /// One degree of freedom the description can hold (moving or locked).
    pub fn is_single_dof(self) -> bool {
        matches!(self, Kind::Revolute | Kind::Continuous | Kind::Prismatic)
    }

    pub fn is_rotary(self) -> bool {
        matches!(self, Kind::Revolute | Kind::Continuous)
    }
}

#[derive(Debug)]
pub(super) struct Joint {
    pub name: String,
    pub line: usize,
    pub kind: Kind,
    pub parent: String,
    pub child: String,
    pub mimic: Option<Mimic>,
    pub data: Result<JointData, ImportError>,
}

/// A joint's numbers (URDF defaults filled in).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct JointData {
    pub xyz: [f64; 3],
    pub rpy: [f64; 3],
    pub axis: [f64; 3],
    pub limit: Limit,
    /// `<dynamics damping friction>`.
    pub damping: f64,
    pub friction: f64,
}

/// `<limit>` attributes that are present.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct Limit {
    pub lower: Option<f64>,
    pub upper: Option<f64>,
    pub velocity: Option<f64>,
    pub effort: Option<f64>,
}

/// `<mimic joint multiplier offset>`: q = multiplier * q_joint + offset.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Mimic {
    pub joint: String,
    pub multiplier: f64,
    pub offset: f64,
}

/// Parses URDF text into the parts the import uses.
pub(super) fn parse(text: &str) -> Result<Urdf, ImportError> {
    check_nesting(text)?;
    let options = ParsingOptions {
        allow_dtd: true,
        nodes_limit: MAX_NODES,
        ..ParsingOptions::default()
    };
    let doc = Document::parse_with_options(text, options)
        .map_err(|e| ImportError::Parse(format!("not well-formed XML: {e}")))?;
    let root = doc.root_element();
    let reader = Reader::new(text);
    if root.tag_name().name() != "robot" {
        return Err(ImportError::Parse(format!(
            "the root element is <{}> (line {}), not <robot>: not a URDF",
            root.tag_name().name(),
            reader.line(root)
        )));
    }
    check_counts(root)?;
    let mut urdf = Urdf {
        name: root.attribute("name").unwrap_or_default().to_string(),
        links: Vec::new(),
        joints: Vec::new(),
        skipped: BTreeMap::new(),
    };
    for node in root.children().filter(Node::is_element) {
        match node.tag_name().name() {
            "link" => urdf.links.push(reader.link(node)?),
            "joint" => urdf.joints.push(reader.joint(node)?),
            // Colours of visuals: standard URDF, and no dynamics.
            "material" => {}
            other => *urdf.skipped.entry(other.to_string()).or_default() += 1,
        }
    }
    Ok(urdf)
}

/// Refuses more than [`MAX_LINKS`] links or joints, before any is read.
fn check_counts(root: Node<'_, '_>) -> Result<(), ImportError> {
    for tag in ["link", "joint"] {
        let count = root
            .children()
            .filter(|n| n.is_element() && n.tag_name().name() == tag)
            .count();
        if count > MAX_LINKS {
            return Err(ImportError::Parse(format!(
                "{count} <{tag}> elements, more than this importer takes ({MAX_LINKS}; a robot \
                 has tens to hundreds)"
            )));
        }
    }
    Ok(())
}

/// 1-based line of a byte offset.
fn line_at(text: &str, offset: usize) -> usize {
    line_ends(text).take_while(|&i| i < offset).count() + 1
}

/// Byte offsets of the line ends: `\n`, or a `\r` not followed by one
/// (a classic Mac file; Windows' `\r\n` is one line end, at its `\n`).
fn line_ends(text: &str) -> impl Iterator<Item = usize> + '_ {
    let bytes = text.as_bytes();
    bytes.iter().enumerate().filter_map(move |(i, &b)| {
        let lone_cr = b == b'\r' && bytes.get(i + 1) != Some(&b'\n');
        (b == b'\n' || lone_cr).then_some(i)
    })
}

fn element<'a, 'i>(node: Node<'a, 'i>, tag: &str) -> Option<Node<'a, 'i>> {
    node.children()
        .find(|n| n.is_element() && n.tag_name().name() == tag)
}

/// Builds elements from nodes; knows the text for line numbers (counted
/// only when a message needs one).
struct Reader<'t> {
    text: &'t str,
    /// Byte offsets of the text's line ends: a line is found by binary
    /// search (counting from the start for every element was quadratic).
    newlines: Vec<usize>,
}

impl<'t> Reader<'t> {
    fn new(text: &'t str) -> Reader<'t> {
        let newlines = line_ends(text).collect();
        Reader { text, newlines }
    }

    fn line(&self, node: Node<'_, '_>) -> usize {
        let offset = node.range().start.min(self.text.len());
        self.newlines.partition_point(|&n| n < offset) + 1
    }

    /// `owner <tag> (line N)`, e.g. `link 'a' <inertial> (line 12)`.
    fn at(&self, node: Node<'_, '_>, owner: &str) -> String {
        format!(
            "{owner} <{}> (line {})",
            node.tag_name().name(),
            self.line(node)
        )
    }

    fn invalid(&self, node: Node<'_, '_>, owner: &str, message: String) -> ImportError {
        ImportError::Invalid {
            element: self.at(node, owner),
            message,
        }
    }

    fn attribute<'n>(
        &self,
        node: Node<'n, '_>,
        name: &str,
        owner: &str,
    ) -> Result<&'n str, ImportError> {
        node.attribute(name)
            .ok_or_else(|| self.invalid(node, owner, format!("missing attribute '{name}'")))
    }

    fn name(&self, node: Node<'_, '_>, tag: &str) -> Result<String, ImportError> {
        let name = node.attribute("name").ok_or_else(|| ImportError::Invalid {
            element: format!("<{tag}> (line {})", self.line(node)),
            message: "missing attribute 'name'".into(),
        })?;
        Ok(name.to_string())
    }

    fn number(
        &self,
        node: Node<'_, '_>,
        name: &str,
        owner: &str,
    ) -> Result<Option<f64>, ImportError> {
        let Some(text) = node.attribute(name) else {
            return Ok(None);
        };
        parse_float(text)
            .map(Some)
            .ok_or_else(|| self.invalid(node, owner, not_a_number(name, text, "a finite number")))
    }

    fn vector(
        &self,
        node: Node<'_, '_>,
        name: &str,
        owner: &str,
    ) -> Result<Option<[f64; 3]>, ImportError> {
        let Some(text) = node.attribute(name) else {
            return Ok(None);
        };
        let values: Option<Vec<f64>> = text.split_whitespace().map(parse_float).collect();
        values
            .and_then(|v| <[f64; 3]>::try_from(v).ok())
            .map(Some)
            .ok_or_else(|| self.invalid(node, owner, not_a_number(name, text, "3 finite numbers")))
    }

    /// `<origin xyz rpy>` of `node`, zero when absent.
    fn origin(&self, node: Node<'_, '_>, owner: &str) -> Result<([f64; 3], [f64; 3]), ImportError> {
        let Some(origin) = element(node, "origin") else {
            return Ok(([0.0; 3], [0.0; 3]));
        };
        Ok((
            self.vector(origin, "xyz", owner)?.unwrap_or_default(),
            self.vector(origin, "rpy", owner)?.unwrap_or_default(),
        ))
    }

    fn link(&self, node: Node<'_, '_>) -> Result<Link, ImportError> {
        let name = self.name(node, "link")?;
        let owner = format!("link '{name}'");
        let inertial = element(node, "inertial")
            .map(|n| self.inertial(n, &owner))
            .transpose();
        Ok(Link {
            name,
            line: self.line(node),
            inertial,
        })
    }

    fn inertial(&self, node: Node<'_, '_>, owner: &str) -> Result<Inertial, ImportError> {
        let (xyz, rpy) = self.origin(node, owner)?;
        let mass_node = element(node, "mass")
            .ok_or_else(|| self.invalid(node, owner, "missing <mass value>".into()))?;
        let mass = self
            .number(mass_node, "value", owner)?
            .ok_or_else(|| self.invalid(mass_node, owner, "missing attribute 'value'".into()))?;
        if mass < 0.0 {
            return Err(self.invalid(
                mass_node,
                owner,
                format!("mass must be a finite number >= 0 kg, found {mass}"),
            ));
        }
        // A missing <inertia> (or entry) is zero: a point mass.
        let mut inertia = [0.0; 6];
        if let Some(i) = element(node, "inertia") {
            for (value, key) in inertia
                .iter_mut()
                .zip(["ixx", "iyy", "izz", "ixy", "ixz", "iyz"])
            {
                *value = self.number(i, key, owner)?.unwrap_or(0.0);
            }
        }
        Ok(Inertial {
            xyz,
            rpy,
            mass,
            inertia,
            line: self.line(node),
        })
    }

    fn joint(&self, node: Node<'_, '_>) -> Result<Joint, ImportError> {
        let name = self.name(node, "joint")?;
        let owner = format!("joint '{name}'");
        let kind_text = self.attribute(node, "type", &owner)?;
        let kind = Kind::parse(kind_text).ok_or_else(|| {
            self.invalid(
                node,
                &owner,
                format!(
                    "type '{kind_text}' is not a URDF joint type (revolute, continuous, \
                     prismatic, fixed, floating, planar)"
                ),
            )
        })?;
        let link_of = |tag: &str| -> Result<String, ImportError> {
            let n = element(node, tag)
                .ok_or_else(|| self.invalid(node, &owner, format!("missing <{tag} link>")))?;
            Ok(self.attribute(n, "link", &owner)?.to_string())
        };
        let (parent, child) = (link_of("parent")?, link_of("child")?);
        let mimic = element(node, "mimic")
            .map(|n| self.mimic(n, &owner))
            .transpose()?;
        Ok(Joint {
            line: self.line(node),
            kind,
            parent,
            child,
            mimic,
            data: self.joint_data(node, &owner),
            name,
        })
    }

    fn joint_data(&self, node: Node<'_, '_>, owner: &str) -> Result<JointData, ImportError> {
        let (xyz, rpy) = self.origin(node, owner)?;
        // URDF's default axis is x.
        let axis = match element(node, "axis") {
            Some(a) => self.vector(a, "xyz", owner)?.unwrap_or([1.0, 0.0, 0.0]),
            None => [1.0, 0.0, 0.0],
        };
        let limit = match element(node, "limit") {
            Some(l) => self.limit(l, owner)?,
            None => Limit::default(),
        };
        let (mut damping, mut friction) = (0.0, 0.0);
        if let Some(d) = element(node, "dynamics") {
            damping = self.number(d, "damping", owner)?.unwrap_or(0.0);
            friction = self.number(d, "friction", owner)?.unwrap_or(0.0);
            if damping < 0.0 || friction < 0.0 {
                return Err(self.invalid(
                    d,
                    owner,
                    format!("damping {damping} and friction {friction} must be >= 0"),
                ));
            }
        }
        Ok(JointData {
            xyz,
            rpy,
            axis,
            limit,
            damping,
            friction,
        })
    }

    fn limit(&self, node: Node<'_, '_>, owner: &str) -> Result<Limit, ImportError> {
        let limit = Limit {
            lower: self.number(node, "lower", owner)?,
            upper: self.number(node, "upper", owner)?,
            velocity: self.number(node, "velocity", owner)?,
            effort: self.number(node, "effort", owner)?,
        };
        if let (Some(lower), Some(upper)) = (limit.lower, limit.upper)
            && lower > upper
        {
            return Err(self.invalid(node, owner, format!("lower {lower} > upper {upper}")));
        }
        Ok(limit)
    }

    fn mimic(&self, node: Node<'_, '_>, owner: &str) -> Result<Mimic, ImportError> {
        Ok(Mimic {
            joint: self.attribute(node, "joint", owner)?.to_string(),
            multiplier: self.number(node, "multiplier", owner)?.unwrap_or(1.0),
            offset: self.number(node, "offset", owner)?.unwrap_or(0.0),
        })
    }
}

fn parse_float(text: &str) -> Option<f64> {
    text.trim().parse::<f64>().ok().filter(|v| v.is_finite())
}

fn not_a_number(name: &str, text: &str, expected: &str) -> String {
    let hint = if text.contains("${") || text.contains("$(") {
        " (an unexpanded xacro expression: run xacro on the file to get the URDF)"
    } else {
        ""
    };
    format!("{name}='{text}': expected {expected}{hint}")
}

/// Refuses absurdly nested XML before the parser sees it (one pass: an
/// opening tag counts when its `>` is not preceded by `/`).
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
                "elements nested more than {MAX_NESTING} deep (line {}); a URDF is a few \
                 levels deep",
                line_at(text, i)
            )));
        }
    }
    Ok(())
}
