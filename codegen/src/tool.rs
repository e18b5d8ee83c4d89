//! The tool frame: a link fixed to the tip's link with nothing after it (a
//! flange, a tool centre point), where a description has one. The
//! generated `tool_pose` and `tool_jacobian` place it.

use nalgebra::{Matrix3, Vector3};

use crate::reduce::{Chain, rpy_matrix};
use crate::schema::{Joint, JointKind};

/// A frame rigidly attached to the tip body: its link and its placement in
/// the tip link's frame.
#[derive(Debug, Clone, PartialEq)]
pub struct ToolFrame {
    pub link: String,
    pub rotation: Matrix3<f64>,
    pub translation: Vector3<f64>,
}

/// The leaf link reached from the tip link through fixed joints only (at
/// least one); with several, the one whose last joint is listed last.
/// `None` when there is none (the tip link is a leaf, or everything after
/// it moves).
pub fn tool_frame(chain: &Chain, joints: &[Joint]) -> Option<ToolFrame> {
    let tip = chain.bodies.iter().rposition(|b| b.coupling.is_none())?;
    let start = (
        chain.bodies[tip].link.as_str(),
        Matrix3::identity(),
        Vector3::zeros(),
    );
    let mut stack = vec![(start, None)];
    let mut best: Option<(usize, ToolFrame)> = None;
    while let Some(((link, rotation, translation), via)) = stack.pop() {
        let children: Vec<(usize, &Joint)> = joints
            .iter()
            .enumerate()
            .filter(|(_, j)| j.parent == link)
            .collect();
        if children.is_empty() {
            if let Some(index) = via
                && best.as_ref().is_none_or(|(k, _)| index > *k)
            {
                let frame = ToolFrame {
                    link: link.to_string(),
                    rotation,
                    translation,
                };
                best = Some((index, frame));
            }
            continue;
        }
        for (index, joint) in children {
            if joint.kind != JointKind::Fixed {
                continue;
            }
            let r = rotation * rpy_matrix(&joint.origin.rpy);
            let p = translation + rotation * Vector3::from(joint.origin.xyz);
            stack.push(((joint.child.as_str(), r, p), Some(index)));
        }
    }
    best.map(|(_, frame)| frame)
}
