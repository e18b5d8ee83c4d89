//! `sdnn import-urdf`: converts a URDF into an sdnn TOML robot description.
//!
//! By job: `parse` reads the dynamics out of the XML, `tree` checks its
//! structure, `chain` chooses what is imported and what each joint becomes,
//! `convert` turns links and joints into description ones, `inertia` judges
//! inertias, `statics` weighs the branches held or dropped for the report,
//! `write` renders the TOML. Command-line syntax is in `options`.

mod chain;
mod convert;
mod inertia;
mod options;
mod parse;
mod statics;
mod tree;
mod write;

#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_quirks;

use std::collections::{BTreeMap, HashSet};

use codegen::reduce::rpy_matrix;
use nalgebra::{Matrix3, Rotation3, Unit, Vector3};

pub use options::{Attachment, parse_lock};

use chain::{Locks, Role, Selection};
use convert::{JointOut, LinkOut};
use tree::Tree;

/// Gravity in the URDF root frame (z up), m/s^2.
const WORLD_GRAVITY: [f64; 3] = [0.0, 0.0, -9.81];

/// What to import and what to change on the way.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ImportOptions {
    /// The link fixed to the world; default: the URDF root link.
    pub base: Option<String>,
    /// The last link of the chain; default: where the only moving branch
    /// ends or splits (a hand's fingers).
    pub tip: Option<String>,
    /// Joints held at a position (rad or m): `locked = VALUE`.
    pub lock: Vec<(String, f64)>,
    /// Rigid payloads added as fixed child links.
    pub attach: Vec<Attachment>,
    /// Links whose non-physical inertia is kept on purpose.
    pub nonphysical_inertia: Vec<String>,
    /// The description's `name`; default: the URDF robot name.
    pub name: Option<String>,
}

/// The description text and what the import changed or ignored.
#[derive(Debug, Clone, PartialEq)]
pub struct Imported {
    pub toml: String,
    /// What the user should look at: values changed or taken on trust.
    pub warnings: Vec<String>,
    /// What the import did: held branches and their weight, the base,
    /// skipped elements.
    pub notes: Vec<String>,
}

/// Why a URDF cannot be imported. Messages name the element at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ImportError {
    #[error("cannot parse the URDF: {0}")]
    Parse(String),
    /// The links and joints do not form one tree.
    #[error("URDF structure: {0}")]
    Structure(String),
    /// A value that is not a finite, physical number.
    #[error("{element}: {message}")]
    Invalid { element: String, message: String },
    /// A command-line option that does not fit the URDF.
    #[error("{option}: {message}")]
    Option {
        option: &'static str,
        message: String,
    },
    /// The description the URDF became is refused by the generator.
    #[error("the description imported from this URDF is refused: {0}")]
    Refused(String),
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

/// Messages gathered on the way.
#[derive(Debug, Default)]
struct Messages {
    warnings: Vec<String>,
    notes: Vec<String>,
    /// Held or mimic joints whose `<dynamics>` is left out.
    idle_dynamics: Vec<String>,
    /// Joints whose `<dynamics>` became their friction.
    friction: Vec<String>,
}

/// Converts `urdf_text` to description TOML. `source_label` is only written
/// into the header comment (give a relative path, not a machine path).
pub fn import_urdf(
    urdf_text: &str,
    source_label: &str,
    options: &ImportOptions,
) -> Result<Imported, ImportError> {
    let urdf = parse::parse(urdf_text)?;
    let tree = Tree::new(&urdf)?;
    let mut messages = Messages::default();
    let locks = Locks::new(&tree, &options.lock)?;
    let mut selection = chain::select(&tree, options, &locks, &mut messages.notes)?;
    messages.warnings.append(&mut selection.warnings);
    let gravity = base_gravity(&tree, &selection, &locks, &mut messages)?;
    let (mut links, mut joints) = convert_all(&tree, &selection, &locks, options, &mut messages)?;
    let mut taken: HashSet<String> = urdf
        .links
        .iter()
        .map(|l| l.name.clone())
        .chain(urdf.joints.iter().map(|j| j.name.clone()))
        .collect();
    for a in &options.attach {
        tree.find_link("--attach", &a.link)?;
    }
    convert::attach_payloads(&options.attach, &mut taken, &mut links, &mut joints)?;
    let name = options.name.clone().unwrap_or_else(|| urdf.name.clone());
    convert::check_names(&name, options.name.is_some(), &links, &joints)?;
    if links.iter().all(|l| l.body.is_none()) {
        return Err(ImportError::Structure(
            "no link on the imported chain has an <inertial> with a mass: the arm would be \
             massless and every torque zero; add the links' <inertial> elements"
                .into(),
        ));
    }
    branch_reports(&tree, &selection, &locks, gravity, &mut messages);
    summary_notes(&tree, &selection, &urdf.skipped, &mut messages);
    let header = write::header(
        source_label,
        &urdf.name,
        tree.link_name(selection.base),
        tree.link_name(selection.tip),
        options,
    );
    let toml = format!(
        "{header}\n{}",
        write::render(&name, gravity.into(), &links, &joints)
    );
    check_description(&toml)?;
    Ok(Imported {
        toml,
        warnings: messages.warnings,
        notes: messages.notes,
    })
}

/// Kept links and joints in description form.
fn convert_all(
    tree: &Tree<'_>,
    s: &Selection,
    locks: &Locks,
    options: &ImportOptions,
    messages: &mut Messages,
) -> Result<(Vec<LinkOut>, Vec<JointOut>), ImportError> {
    let allowed: HashSet<&str> = options
        .nonphysical_inertia
        .iter()
        .map(String::as_str)
        .collect();
    for link in &allowed {
        if !s.links.iter().any(|&l| tree.link_name(l) == *link) {
            return Err(option_error(
                "--nonphysical-inertia",
                format!("no imported link named '{link}'"),
            ));
        }
    }
    let fixed_base = fixed_base_links(tree, s);
    let links = s
        .links
        .iter()
        .map(|&l| {
            let link = tree.link(l);
            let allowed = allowed.contains(link.name.as_str());
            convert::convert_link(link, fixed_base.contains(&l), allowed, messages)
        })
        .collect::<Result<Vec<_>, _>>()?;
    let joints = s
        .joints
        .iter()
        .map(|&j| {
            let user_lock = locks.get(j).is_some();
            convert::convert_joint(tree.joint(j), &s.roles[&j], user_lock, messages)
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok((links, joints))
}

/// Links that never move: reached from the base through no moving joint.
fn fixed_base_links(tree: &Tree<'_>, s: &Selection) -> HashSet<usize> {
    let mut fixed = HashSet::from([s.base]);
    for &j in &s.joints {
        let rigid = matches!(s.roles[&j], Role::Fixed | Role::Locked(_));
        if rigid && fixed.contains(&tree.parent_link(j)) {
            fixed.insert(tree.child_link(j));
        }
    }
    fixed
}

/// Gravity in the base frame: the URDF root is taken as z up, and joints
/// above the base at their `--lock` position (0 if not locked).
fn base_gravity(
    tree: &Tree<'_>,
    s: &Selection,
    locks: &Locks,
    messages: &mut Messages,
) -> Result<Vector3<f64>, ImportError> {
    let mut rotation = Matrix3::identity();
    let mut at_zero = Vec::new();
    for &j in &s.above {
        let joint = tree.joint(j);
        let data = joint.data.clone()?;
        rotation *= rpy_matrix(&data.rpy);
        if joint.kind.is_rotary() {
            let angle = locks.get(j).unwrap_or_else(|| {
                at_zero.push(joint.name.as_str());
                0.0
            });
            rotation *= Unit::try_new(Vector3::from(data.axis), 1e-12)
                .map_or_else(Matrix3::identity, |axis| {
                    Rotation3::from_axis_angle(&axis, angle).into_inner()
                });
        }
    }
    if !at_zero.is_empty() {
        messages.notes.push(format!(
            "joint(s) above the base taken at 0 rad for the direction of gravity ({}); --lock \
             them to choose other angles",
            names(&at_zero)
        ));
    }
    let g = rotation.transpose() * Vector3::from(WORLD_GRAVITY);
    // Exact right angles leave ~1e-16 residues; print them as zero.
    Ok(g.map(|x| if x.abs() < 1e-12 { 0.0 } else { x }))
}

/// One note per chain link that holds branches with held joints: their
/// mass, what holds them, and the largest gravity torque they put on the
/// chain, so the user can judge; one warning per dropped branch.
fn branch_reports(
    tree: &Tree<'_>,
    s: &Selection,
    locks: &Locks,
    gravity: Vector3<f64>,
    messages: &mut Messages,
) {
    let mut by_link: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for &b in &s.held {
        by_link.entry(tree.parent_link(b)).or_default().push(b);
    }
    let groups: Vec<Vec<usize>> = by_link
        .values()
        .cloned()
        .chain(s.dropped.iter().map(|&b| vec![b]))
        .collect();
    let loads = statics::branches_loads(tree, s, locks, gravity, &groups);
    let (held, dropped) = loads.split_at(by_link.len());
    for ((link, branches), load) in by_link.iter().zip(held) {
        let at: Vec<&str> = branches.iter().map(|&b| tree.joint_name(b)).collect();
        let held: Vec<usize> = branches
            .iter()
            .flat_map(|&b| tree.subtree_joints(b))
            .collect();
        let count = match at.len() {
            1 => "a branch".to_string(),
            n => format!("{n} branches"),
        };
        messages.notes.push(format!(
            "kept {count} at link '{}' ({}; {:.4} kg{}), joints held: {}",
            tree.link_name(*link),
            names(&at),
            load.mass,
            lever(tree, load),
            holds(tree, s, &held)
        ));
    }
    for (&b, load) in s.dropped.iter().zip(dropped) {
        messages.warnings.push(format!(
            "dropped the branch below the {} joint '{}' ({:.4} kg{}): a free body is not part \
             of the arm",
            tree.kind(b).name(),
            tree.joint_name(b),
            load.mass,
            lever(tree, load),
        ));
    }
}

/// The held joints of a branch: those at 0 and the mimic joints counted
/// (a hand has dozens), other positions listed.
fn holds(tree: &Tree<'_>, s: &Selection, joints: &[usize]) -> String {
    let (mut zero, mut mimics, mut others) = (Vec::new(), 0, Vec::new());
    for &j in joints {
        match s.roles.get(&j) {
            Some(Role::Locked(v)) if *v == 0.0 => zero.push(tree.joint_name(j)),
            Some(Role::Locked(v)) => others.push(format!("'{}' at {v:?}", tree.joint_name(j))),
            Some(Role::Mimic(_)) => mimics += 1,
            _ => {}
        }
    }
    if !zero.is_empty() {
        others.insert(0, format!("{} at 0 ({})", zero.len(), names(&zero)));
    }
    if mimics > 0 {
        others.push(format!("{mimics} mimic joint(s) following their master"));
    }
    others.join(", ")
}

/// At most four names, then how many more.
fn names(list: &[&str]) -> String {
    match list.len() {
        0..=4 => list.join(", "),
        n => format!("{}, and {} more", list[..3].join(", "), n - 3),
    }
}

fn lever(tree: &Tree<'_>, load: &statics::Load) -> String {
    let Some(j) = load.joint else {
        return String::new();
    };
    let torque = load.torque;
    let (unit, what) = match tree.kind(j) {
        parse::Kind::Prismatic => ("N", "force"),
        _ => ("N m", "torque"),
    };
    format!(
        "; up to {torque:.3} {unit} of gravity {what} on '{}'",
        tree.joint_name(j)
    )
}

/// One line each for what was left out without consequence.
fn summary_notes(
    tree: &Tree<'_>,
    s: &Selection,
    skipped: &BTreeMap<String, usize>,
    messages: &mut Messages,
) {
    if !s.base_branches.is_empty() {
        let at: Vec<&str> = s
            .base_branches
            .iter()
            .map(|&j| tree.joint_name(j))
            .collect();
        messages.notes.push(format!(
            "left out {} branch(es) on the fixed base (at {}): they change no torque of the chain",
            at.len(),
            names(&at)
        ));
    }
    if !messages.idle_dynamics.is_empty() {
        let idle: Vec<&str> = messages.idle_dynamics.iter().map(String::as_str).collect();
        messages.notes.push(format!(
            "<dynamics> of {} joint(s) that do not move left out: {}",
            idle.len(),
            names(&idle)
        ));
    }
    if !messages.friction.is_empty() {
        let joints: Vec<&str> = messages.friction.iter().map(String::as_str).collect();
        messages.notes.push(format!(
            "<dynamics> of {} joint(s) imported as their friction (damping as viscous, friction \
             as Coulomb): {}; simulator values are often placeholders: check them against the \
             robot's, or let `sdnn diagnose` measure them",
            joints.len(),
            names(&joints)
        ));
    }
    if !skipped.is_empty() {
        let counts: Vec<String> = skipped
            .iter()
            .map(|(tag, n)| format!("{n} <{tag}>"))
            .collect();
        messages.notes.push(format!(
            "skipped {}: no rigid-body dynamics in them",
            counts.join(", ")
        ));
    }
}

/// What this tool writes it must also read: a value the description
/// refuses (a mass beyond any arm) is reported by key, not by a line of a
/// file that was never written.
fn check_description(toml: &str) -> Result<(), ImportError> {
    let path = std::path::Path::new("imported.toml");
    match codegen::Description::parse(toml, "imported", path) {
        Ok(_) => Ok(()),
        Err(codegen::DescriptionError::Invalid { key, message, .. }) => {
            Err(ImportError::Refused(format!("`{key}`: {message}")))
        }
        Err(codegen::DescriptionError::Syntax { message, .. }) => {
            Err(ImportError::Refused(message))
        }
        Err(e) => Err(ImportError::Refused(e.to_string())),
    }
}
