//! Which part of the URDF is imported, and what each kept joint becomes.
//!
//! The chain runs from the base to the tip. Everything that hangs from the
//! moving part of the chain is kept, whatever its joints: a hand with
//! fingers is lumped into the link it hangs from, its joints held at 0 or at
//! their `--lock` value, mimic joints following their master. Branches that
//! hang from the fixed base change no torque; those that would move are left
//! out. Links above the base are dropped (they only set the direction of
//! gravity). A free (floating, planar) joint between base and tip moves the
//! base below it: the robot is taken as fixed there.

use std::collections::{BTreeMap, HashSet};

use super::parse::{Kind, Mimic};
use super::tree::Tree;
use super::{ImportError, ImportOptions, option_error};

/// What the description does with a kept joint.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Role {
    Fixed,
    Moving,
    /// Held at this position (rad or m): `--lock`, or a branch joint at 0.
    Locked(f64),
    /// Follows a written joint: q = multiplier * q_master + offset.
    Mimic(Mimic),
}

/// The part of the URDF that is imported.
pub(super) struct Selection {
    pub base: usize,
    pub tip: usize,
    /// Joints from base to tip.
    pub path: Vec<usize>,
    /// Kept links and joints, depth first from the base, file order.
    pub links: Vec<usize>,
    pub joints: Vec<usize>,
    /// The role of every kept joint, by joint index.
    pub roles: BTreeMap<usize, Role>,
    /// Joints from the URDF root to the base (dropped).
    pub above: Vec<usize>,
    /// Branches hanging from the moving chain whose joints are held, by
    /// the joint that attaches them.
    pub held: Vec<usize>,
    /// Branches hanging from the moving chain that are left out (below a
    /// free joint), by the joint that attaches them.
    pub dropped: Vec<usize>,
    /// Links left out because they hang from the fixed base by joints that
    /// would move.
    pub base_branches: Vec<usize>,
    pub warnings: Vec<String>,
}

/// The `--lock` positions by joint index.
pub(super) struct Locks {
    pub positions: BTreeMap<usize, f64>,
    /// By joint: whether its subtree (itself included) holds a joint that
    /// is neither fixed nor locked. Computed once: asking each joint's
    /// subtree in turn made a long chain's import quadratic (9,000 links
    /// took 2.8 s).
    moving_below: Vec<bool>,
}

impl Locks {
    pub fn new(tree: &Tree<'_>, locks: &[(String, f64)]) -> Result<Locks, ImportError> {
        let mut positions = BTreeMap::new();
        for (name, value) in locks {
            let j = tree.find_joint("--lock", name)?;
            let kind = tree.kind(j);
            if !kind.is_single_dof() {
                return Err(option_error(
                    "--lock",
                    format!(
                        "joint '{name}' is {}: only revolute, continuous and prismatic joints \
                         can be locked",
                        kind.name()
                    ),
                ));
            }
            if !value.is_finite() {
                return Err(option_error(
                    "--lock",
                    format!("position of '{name}' must be finite"),
                ));
            }
            if positions.insert(j, *value).is_some() {
                return Err(option_error(
                    "--lock",
                    format!("joint '{name}' is locked twice"),
                ));
            }
        }
        Ok(Locks::at(tree, positions))
    }

    /// The joints locked at `positions`.
    fn at(tree: &Tree<'_>, positions: BTreeMap<usize, f64>) -> Locks {
        let mut moving_below = vec![false; tree.joint_count()];
        // Depth first from the root, reversed: a link's child joints are
        // settled before the joint above it.
        for &link in tree.subtree_links(tree.root).iter().rev() {
            if let Some(j) = tree.parent_joint(link) {
                let rigid = tree.kind(j) == Kind::Fixed || positions.contains_key(&j);
                moving_below[j] =
                    !rigid || tree.child_joints(link).iter().any(|&k| moving_below[k]);
            }
        }
        Locks {
            positions,
            moving_below,
        }
    }

    pub fn get(&self, joint: usize) -> Option<f64> {
        self.positions.get(&joint).copied()
    }

    /// Fixed, or held by `--lock`.
    fn is_rigid(&self, tree: &Tree<'_>, joint: usize) -> bool {
        tree.kind(joint) == Kind::Fixed || self.positions.contains_key(&joint)
    }

    fn subtree_rigid(&self, joint: usize) -> bool {
        !self.moving_below[joint]
    }
}

pub(super) fn select(
    tree: &Tree<'_>,
    options: &ImportOptions,
    locks: &Locks,
    notes: &mut Vec<String>,
) -> Result<Selection, ImportError> {
    let given_base = match &options.base {
        Some(name) => tree.find_link("--base", name)?,
        None => tree.root,
    };
    let tip = match &options.tip {
        Some(name) => tree.find_link("--tip", name)?,
        None => default_tip(tree, below_free_joints(tree, given_base), locks)?,
    };
    let mut path = path_between(tree, given_base, tip)?;
    let base = match path.iter().rposition(|&j| is_free(tree.kind(j))) {
        Some(k) => {
            let free = path[k];
            path.drain(..=k);
            tree.child_link(free)
        }
        None => given_base,
    };
    base_notes(tree, base, notes);
    let mut selection = Selection {
        base,
        tip,
        path,
        links: Vec::new(),
        joints: Vec::new(),
        roles: BTreeMap::new(),
        above: tree.joints_above(base),
        held: Vec::new(),
        dropped: Vec::new(),
        base_branches: Vec::new(),
        warnings: Vec::new(),
    };
    keep(tree, locks, &mut selection)?;
    check_moves(tree, &selection)?;
    check_locks(tree, locks, &selection)?;
    Ok(selection)
}

/// Says where the robot is taken as fixed when that is not a plain mount:
/// below a free joint, below dropped links, or at a root that holds
/// several moving limbs (a humanoid's pelvis).
fn base_notes(tree: &Tree<'_>, base: usize, notes: &mut Vec<String>) {
    let name = tree.link_name(base);
    if let Some(j) = tree.parent_joint(base)
        && is_free(tree.kind(j))
    {
        notes.push(format!(
            "link '{name}' hangs from '{}' by the {} joint '{}': taken as fixed at {name}",
            tree.joint(j).parent,
            tree.kind(j).name(),
            tree.joint_name(j)
        ));
    }
    if base != tree.root {
        let dropped = tree.link_count() - tree.subtree_links(base).len();
        notes.push(format!(
            "link '{name}' is the base: {dropped} link(s) above it are dropped (from root '{}'), \
             and the base is taken as fixed in the world",
            tree.link_name(tree.root)
        ));
    } else if moving_children(tree, base, &Locks::at(tree, BTreeMap::new())).len() > 1 {
        notes.push(format!(
            "the URDF root '{name}' holds several moving branches: taken as fixed at {name} \
             (if it floats, as a humanoid's pelvis does, the torques are those of a robot \
             fixed there)"
        ));
    }
}

/// Keeps the chain and what hangs from it; gives every kept joint its role.
fn keep(tree: &Tree<'_>, locks: &Locks, s: &mut Selection) -> Result<(), ImportError> {
    let on_path: HashSet<usize> = s.path.iter().copied().collect();
    let chain_links: HashSet<usize> = std::iter::once(s.base)
        .chain(s.path.iter().map(|&j| tree.child_link(j)))
        .collect();
    // Links reached from the base through no joint that moves: the fixed base.
    let mut fixed: HashSet<usize> = HashSet::from([s.base]);
    let mut stack = vec![s.base];
    while let Some(link) = stack.pop() {
        s.links.push(link);
        let mut kept = Vec::new();
        for &j in tree.child_joints(link) {
            let child = tree.child_link(j);
            let from_base = fixed.contains(&link);
            if on_path.contains(&j) {
                if from_base && locks.is_rigid(tree, j) {
                    fixed.insert(child);
                }
            } else if from_base {
                if follows_the_chain(tree, j, &on_path) {
                    // A finger that mimics a chain joint moves with it:
                    // kept, its mimics coupled, its other joints held.
                } else if !locks.subtree_rigid(j) {
                    s.base_branches.push(j);
                    continue;
                } else {
                    fixed.insert(child);
                }
            } else if is_free(tree.kind(j)) {
                s.dropped.push(j);
                continue;
            } else if chain_links.contains(&link)
                && tree
                    .subtree_joints(j)
                    .iter()
                    .any(|&b| tree.kind(b) != Kind::Fixed)
            {
                s.held.push(j);
            }
            s.warnings.extend(unknown_master(tree, j));
            s.roles
                .insert(j, role(tree, locks, j, on_path.contains(&j)));
            kept.push(child);
        }
        // Reversed so the stack visits children in file order.
        stack.extend(kept.into_iter().rev());
    }
    // Every kept link but the base is reached through its parent joint.
    s.joints = s.links[1..]
        .iter()
        .filter_map(|&l| tree.parent_joint(l))
        .collect();
    let kept: HashSet<usize> = s.joints.iter().copied().collect();
    resolve_mimics(tree, locks, &kept, &mut s.roles);
    Ok(())
}

/// Floating, planar (and spherical): no single degree of freedom.
pub(super) fn is_free(kind: Kind) -> bool {
    !kind.is_single_dof() && kind != Kind::Fixed
}

/// Whether a joint below `joint` (or `joint` itself) follows a joint of the
/// chain, directly or through other mimics.
fn follows_the_chain(tree: &Tree<'_>, joint: usize, on_path: &HashSet<usize>) -> bool {
    tree.subtree_joints(joint).into_iter().any(|b| {
        let mut current = b;
        // A mimic chain is at most as long as the URDF has joints.
        for _ in 0..=tree.joint_index.len() {
            let Some(m) = mimic(tree, current) else {
                return false;
            };
            current = tree.joint_index[m.joint.as_str()];
            if on_path.contains(&current) {
                return true;
            }
        }
        false
    })
}

/// A joint's `<mimic>` when it names a joint of the URDF (a mimic of a
/// joint that does not exist is ignored, with a warning when kept).
fn mimic<'a>(tree: &Tree<'a>, joint: usize) -> Option<&'a Mimic> {
    let mimic = tree.joint(joint).mimic.as_ref()?;
    tree.joint_index
        .contains_key(mimic.joint.as_str())
        .then_some(mimic)
}

fn unknown_master(tree: &Tree<'_>, joint: usize) -> Option<String> {
    let j = tree.joint(joint);
    let m = j.mimic.as_ref()?;
    (mimic(tree, joint).is_none() && j.kind != Kind::Fixed).then(|| {
        format!(
            "joint '{}' <mimic> (line {}): joint='{}' names no joint of the URDF; the mimic is \
             ignored and the joint taken as an ordinary {} joint",
            j.name,
            j.line,
            m.joint,
            j.kind.name()
        )
    })
}

/// The role of a kept joint before mimic masters are checked.
fn role(tree: &Tree<'_>, locks: &Locks, joint: usize, on_path: bool) -> Role {
    let j = tree.joint(joint);
    if j.kind == Kind::Fixed {
        Role::Fixed
    } else if let Some(value) = locks.get(joint) {
        Role::Locked(value)
    } else if let Some(mimic) = mimic(tree, joint) {
        Role::Mimic(mimic.clone())
    } else if on_path {
        Role::Moving
    } else {
        Role::Locked(0.0)
    }
}

/// A mimic joint follows the joint at the end of its `<mimic>` chain (the
/// description wants a master that is not a mimic itself), with the
/// multipliers and offsets composed. Where that master is not written, the
/// joint is held where the master's own hold puts it (its `--lock`, else 0).
fn resolve_mimics(
    tree: &Tree<'_>,
    locks: &Locks,
    kept: &HashSet<usize>,
    roles: &mut BTreeMap<usize, Role>,
) {
    let mimics: Vec<usize> = roles
        .iter()
        .filter(|(_, r)| matches!(r, Role::Mimic(_)))
        .map(|(&j, _)| j)
        .collect();
    for j in mimics {
        let role = match ultimate_master(tree, locks, j) {
            Some((master, mimic)) if kept.contains(&master) => Role::Mimic(mimic),
            _ => Role::Locked(held_position(tree, locks, j, 0)),
        };
        roles.insert(j, role);
    }
}

/// The first joint up the `<mimic>` chain of `joint` that is not a mimic
/// (or is locked), and the composed coupling to it; None for a cycle or a
/// master that cannot move.
fn ultimate_master(tree: &Tree<'_>, locks: &Locks, joint: usize) -> Option<(usize, Mimic)> {
    let (mut multiplier, mut offset) = (1.0, 0.0);
    let mut current = joint;
    for _ in 0..16 {
        let Some(m) = mimic(tree, current).filter(|_| locks.get(current).is_none()) else {
            let master = Mimic {
                joint: tree.joint_name(current).to_string(),
                multiplier,
                offset,
            };
            return tree
                .kind(current)
                .is_single_dof()
                .then_some((current, master));
        };
        // q_current = m q_next + o, and q_joint = M q_current + O.
        offset += multiplier * m.offset;
        multiplier *= m.multiplier;
        current = tree.joint_index[m.joint.as_str()];
    }
    None
}

/// Where a joint is held when nothing written drives it: its `--lock`
/// value, its master's through `<mimic>`, else 0 (rad or m).
pub(super) fn held_position(tree: &Tree<'_>, locks: &Locks, joint: usize, depth: usize) -> f64 {
    if let Some(value) = locks.get(joint) {
        return value;
    }
    let Some(m) = mimic(tree, joint) else {
        return 0.0;
    };
    // A cycle of mimic joints (invalid URDF) ends instead of looping.
    let master = tree.joint_index[m.joint.as_str()];
    let master_position = match depth {
        0..16 => held_position(tree, locks, master, depth + 1),
        _ => 0.0,
    };
    m.multiplier * master_position + m.offset
}

fn check_moves(tree: &Tree<'_>, s: &Selection) -> Result<(), ImportError> {
    let moving = s.path.iter().any(|j| s.roles.get(j) == Some(&Role::Moving));
    if moving {
        return Ok(());
    }
    Err(option_error(
        "--tip",
        format!(
            "no joint moves between base '{}' and tip '{}'",
            tree.link_name(s.base),
            tree.link_name(s.tip)
        ),
    ))
}

fn check_locks(tree: &Tree<'_>, locks: &Locks, s: &Selection) -> Result<(), ImportError> {
    let kept: HashSet<usize> = s.joints.iter().chain(&s.above).copied().collect();
    match locks.positions.keys().find(|j| !kept.contains(j)) {
        None => Ok(()),
        Some(&j) => Err(option_error(
            "--lock",
            format!(
                "joint '{}' is not imported (it hangs from the fixed base or below a free \
                 joint, where it changes no torque of the chain)",
                tree.joint_name(j)
            ),
        )),
    }
}

/// Child joints of `link` whose subtrees hold a joint that moves (a free
/// joint holds an object, not a limb).
fn moving_children(tree: &Tree<'_>, link: usize, locks: &Locks) -> Vec<usize> {
    tree.child_joints(link)
        .iter()
        .copied()
        .filter(|&j| !is_free(tree.kind(j)) && !locks.subtree_rigid(j))
        .collect()
}

/// Below the last free joint of the single line of joints that starts at
/// `base` (`world` -floating-> `pelvis`), else `base`.
fn below_free_joints(tree: &Tree<'_>, base: usize) -> usize {
    let (mut link, mut below) = (base, base);
    while let [j] = tree.child_joints(link) {
        if tree.kind(*j).is_single_dof() {
            break;
        }
        link = tree.child_link(*j);
        if is_free(tree.kind(*j)) {
            below = link;
        }
    }
    below
}

/// Follows the only moving branch from `base` to where it ends or splits
/// (a hand's fingers): the split's branches are held. Past the last moving
/// joint, the tip is the end of a simple rigid tail.
fn default_tip(tree: &Tree<'_>, base: usize, locks: &Locks) -> Result<usize, ImportError> {
    let mut link = base;
    let mut moved = false;
    loop {
        match moving_children(tree, link, locks).as_slice() {
            [] => return Ok(single_leaf(tree, link).unwrap_or(link)),
            [j] => {
                moved |= tree.kind(*j) != Kind::Fixed && locks.get(*j).is_none();
                link = tree.child_link(*j);
            }
            _ if moved => return Ok(link),
            _ => {
                return Err(option_error(
                    "--tip",
                    format!(
                        "the URDF branches at link '{}' into several moving branches; choose \
                         the tip with --tip (leaves: {})",
                        tree.link_name(link),
                        tree.leaves(link).join(", ")
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
    if base == tip {
        return Ok(Vec::new());
    }
    let above_tip = tree.joints_above(tip);
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
