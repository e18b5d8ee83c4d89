//! A payload is a body, not a point: where the data determine its own
//! moment of inertia about its centre of mass (a tool or an object turned
//! by the wrist), the payload named as a point mass is given one. One
//! moment, the same about every axis (a compact body's, a sphere's 2/5 m
//! r^2): a tool's six inertia entries are rarely determined by torques
//! their size, and fitted freely they trade with the noise of the joints
//! near it. Without it the wrist's armatures, or a neighbouring link's
//! inertial error, stand in for it.

use super::admit::admits;
use super::alternatives::NEAR;
use super::candidate::{Candidate, Shape, label};
use super::heldout::{Scoring, cv_mse};
use super::kind::Kind;
use super::moments::Moments;
use super::settings::Settings;

/// Gives the point-mass payload its own inertia where, judged at the step
/// that named it (beside the effects named before it), the inertia is
/// significant and physical and lowers the summed held-out MSE without
/// raising any joint's beyond [`NEAR`]; or where the step named the last
/// link's inertial error instead and the payload with its inertia does as
/// well on every joint (within [`NEAR`]: the payload is then named in the
/// link error's place, see `alternatives::payload_over_link_error`).
/// Returns the note to give when it did: the selection is then run again
/// with the payload a body, so that nothing stands in for its inertia.
pub(super) fn give_inertia(
    m: &Moments,
    dof: usize,
    candidates: &mut [Candidate],
    selected: &[usize],
    settings: Settings,
) -> Option<String> {
    let payload = candidates.iter().position(|c| {
        c.kind == Kind::Payload
            && matches!(c.shape, Shape::Body { own_inertia, .. } if !own_inertia)
    })?;
    let at = selected.iter().position(|&c| {
        c == payload
            || (candidates[c].kind == Kind::InertialError
                && candidates[c].link == candidates[payload].link)
    })?;
    let before = cv_mse(m, dof, candidates, &selected[..=at], Scoring::Fitted);
    let point = candidates[payload].clone();
    if let Shape::Body { own_inertia, .. } = &mut candidates[payload].shape {
        *own_inertia = true;
    }
    candidates[payload].names.push("inertia");
    let mut step = selected[..at].to_vec();
    step.push(payload);
    let after = cv_mse(m, dof, candidates, &step, Scoring::Fitted);
    let (sum_before, sum_after) = (before.iter().sum::<f64>(), after.iter().sum::<f64>());
    let near = after.iter().zip(&before).all(|(a, b)| *a <= NEAR * b);
    let better = sum_after < sum_before || selected[at] != payload;
    if better && near && admits(m, candidates, &step, settings) {
        return Some(format!(
            "{}: the data determine the payload's own moment of inertia about its centre of mass \
             (one moment about every axis): a body, not a point mass; at the step that named \
             {}, summed held-out MSE {sum_before:.4e}, with this body {sum_after:.4e} N m^2",
            label(&candidates[payload]),
            label(&candidates[selected[at]]),
        ));
    }
    candidates[payload] = point;
    None
}
