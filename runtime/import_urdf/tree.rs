//! The URDF's links and joints as a tree, with its structure checked.

use std::collections::{HashMap, HashSet};

use super::parse::{Joint, Kind, Link, Urdf};
use super::{ImportError, option_error};

pub(super) struct Tree<'a> {
    pub urdf: &'a Urdf,
    link_index: HashMap<&'a str, usize>,
    pub joint_index: HashMap<&'a str, usize>,
    /// The joint whose child is this link, by link index.
    parent_joint: Vec<Option<usize>>,
    /// Joints whose parent is this link, in file order, by link index.
    children: Vec<Vec<usize>>,
    /// Each joint's parent and child link, by joint index (looked up once:
    /// a lookup by name per call dominated imports of large trees).
    links_of: Vec<(usize, usize)>,
    pub root: usize,
}

fn structure(message: String) -> ImportError {
    ImportError::Structure(message)
}

/// At most ten names, then how many more: an error about 10,000 links
/// stays one readable line (100,000 names made a 789 KB message).
fn some_names(names: &[&str]) -> String {
    const SHOWN: usize = 10;
    let mut text = names[..names.len().min(SHOWN)].join(", ");
    if names.len() > SHOWN {
        text.push_str(&format!(" and {} more", names.len() - SHOWN));
    }
    text
}

impl<'a> Tree<'a> {
    pub fn new(urdf: &'a Urdf) -> Result<Tree<'a>, ImportError> {
        let mut link_index = HashMap::new();
        for (i, link) in urdf.links.iter().enumerate() {
            if link_index.insert(link.name.as_str(), i).is_some() {
                return Err(structure(format!(
                    "link '{}' is defined twice (line {})",
                    link.name, link.line
                )));
            }
        }
        let mut joint_index = HashMap::new();
        let mut parent_joint = vec![None; urdf.links.len()];
        let mut children = vec![Vec::new(); urdf.links.len()];
        let mut links_of = Vec::with_capacity(urdf.joints.len());
        for (j, joint) in urdf.joints.iter().enumerate() {
            if joint_index.insert(joint.name.as_str(), j).is_some() {
                return Err(structure(format!(
                    "joint '{}' is defined twice (line {})",
                    joint.name, joint.line
                )));
            }
            let find = |role: &str, link: &str| {
                link_index.get(link).copied().ok_or_else(|| {
                    structure(format!(
                        "joint '{}' (line {}): {role} link '{link}' is not defined",
                        joint.name, joint.line
                    ))
                })
            };
            let (parent, child) = (find("parent", &joint.parent)?, find("child", &joint.child)?);
            if let Some(other) = parent_joint[child].replace(j) {
                return Err(structure(format!(
                    "link '{}' is the child of two joints, '{}' and '{}' (line {})",
                    joint.child, urdf.joints[other].name, joint.name, joint.line
                )));
            }
            children[parent].push(j);
            links_of.push((parent, child));
        }
        let root = single_root(urdf, &parent_joint)?;
        let tree = Tree {
            urdf,
            link_index,
            joint_index,
            parent_joint,
            children,
            links_of,
            root,
        };
        tree.check_connected()?;
        Ok(tree)
    }

    /// With one parent per link, links unreachable from the root sit on a cycle.
    fn check_connected(&self) -> Result<(), ImportError> {
        let reached: HashSet<usize> = self.subtree_links(self.root).into_iter().collect();
        let lost: Vec<&str> = (0..self.urdf.links.len())
            .filter(|l| !reached.contains(l))
            .map(|l| self.link_name(l))
            .collect();
        if lost.is_empty() {
            Ok(())
        } else {
            Err(structure(format!(
                "the joints form a cycle through links {}",
                some_names(&lost)
            )))
        }
    }

    pub fn link(&self, link: usize) -> &'a Link {
        &self.urdf.links[link]
    }

    pub fn joint(&self, joint: usize) -> &'a Joint {
        &self.urdf.joints[joint]
    }

    pub fn link_name(&self, link: usize) -> &'a str {
        &self.urdf.links[link].name
    }

    pub fn joint_name(&self, joint: usize) -> &'a str {
        &self.urdf.joints[joint].name
    }

    pub fn kind(&self, joint: usize) -> Kind {
        self.urdf.joints[joint].kind
    }

    pub fn joint_count(&self) -> usize {
        self.urdf.joints.len()
    }

    pub fn link_count(&self) -> usize {
        self.urdf.links.len()
    }

    pub fn child_joints(&self, link: usize) -> &[usize] {
        &self.children[link]
    }

    pub fn parent_joint(&self, link: usize) -> Option<usize> {
        self.parent_joint[link]
    }

    pub fn child_link(&self, joint: usize) -> usize {
        self.links_of[joint].1
    }

    pub fn parent_link(&self, joint: usize) -> usize {
        self.links_of[joint].0
    }

    /// The link named by a command-line option.
    pub fn find_link(&self, option: &'static str, name: &str) -> Result<usize, ImportError> {
        self.link_index
            .get(name)
            .copied()
            .ok_or_else(|| option_error(option, format!("no link named '{name}' in the URDF")))
    }

    pub fn find_joint(&self, option: &'static str, name: &str) -> Result<usize, ImportError> {
        self.joint_index
            .get(name)
            .copied()
            .ok_or_else(|| option_error(option, format!("no joint named '{name}' in the URDF")))
    }

    /// Links of the subtree at `link` (itself first), depth first, file order.
    pub fn subtree_links(&self, link: usize) -> Vec<usize> {
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
    pub fn subtree_joints(&self, joint: usize) -> Vec<usize> {
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
    pub fn joints_above(&self, link: usize) -> Vec<usize> {
        let mut joints = Vec::new();
        let mut current = link;
        while let Some(j) = self.parent_joint[current] {
            joints.push(j);
            current = self.parent_link(j);
        }
        joints.reverse();
        joints
    }

    /// Leaves (links without children) of the subtree at `link`.
    pub fn leaves(&self, link: usize) -> Vec<&'a str> {
        self.subtree_links(link)
            .into_iter()
            .filter(|&l| self.child_joints(l).is_empty())
            .map(|l| self.link_name(l))
            .collect()
    }
}

fn single_root(urdf: &Urdf, parent_joint: &[Option<usize>]) -> Result<usize, ImportError> {
    let roots: Vec<usize> = (0..urdf.links.len())
        .filter(|&l| parent_joint[l].is_none())
        .collect();
    match roots.as_slice() {
        [root] => Ok(*root),
        [] if urdf.links.is_empty() => Err(structure("the URDF has no links".into())),
        [] => Err(structure(
            "every link has a parent: the joints form a cycle".into(),
        )),
        many => {
            let names: Vec<&str> = many.iter().map(|&l| urdf.links[l].name.as_str()).collect();
            Err(structure(format!(
                "{} links have no parent ({}): a URDF must be one tree",
                many.len(),
                some_names(&names)
            )))
        }
    }
}
