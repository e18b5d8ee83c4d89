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
use super::candidate::{Candidate, Shape, label, width};
use super::fit::fit;
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
    let payload = candidates.iter().position(point_payload)?;
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

/// Notes on the armatures named beside a point-mass payload (its own
/// moment not determined by these data) that are no larger than a ball's
/// of the payload's mass reaching its COM: on the joints that turn it, a
/// carried body's inertia about its COM acts much like an armature, so
/// such an armature may be that inertia.
pub(super) fn stand_ins(m: &Moments, candidates: &[Candidate], selected: &[usize]) -> Vec<String> {
    if !selected.iter().any(|&c| point_payload(&candidates[c])) {
        return Vec::new();
    }
    let Some(full) = fit(m, candidates, selected, |_| true) else {
        return Vec::new();
    };
    let mut at = 0;
    let mut payload = None;
    let mut armatures = Vec::new();
    for &c in selected {
        if point_payload(&candidates[c]) {
            payload = Some(&full.theta.as_slice()[at..at + 4]);
        } else if candidates[c].kind == Kind::Armature {
            armatures.push((c, full.theta[at]));
        }
        at += width(&candidates[c]);
    }
    let Some(&[mass, x, y, z]) = payload else {
        return Vec::new();
    };
    let distance = (x * x + y * y + z * z).sqrt();
    let ball = 0.4 * mass * distance * distance;
    armatures
        .into_iter()
        .filter(|&(_, inertia)| inertia > 0.0 && inertia <= ball)
        .map(|(c, inertia)| {
            format!(
                "{}: {inertia:.2e} kg m^2, named beside a point-mass payload of {mass:.3} kg: a \
                 carried body's own inertia about its centre of mass acts on the joints that turn \
                 it much like an armature (a ball of that mass reaching the payload's COM, \
                 {distance:.3} m out, has up to {ball:.2e} kg m^2), and these data do not \
                 determine a moment of the payload's own; if the arm carries a body rather than a \
                 point, this armature may be that inertia",
                label(&candidates[c])
            )
        })
        .collect()
}

/// Whether `selected` holds a payload with a moment of its own (one
/// [`give_inertia`] made a body).
pub(super) fn body_named(candidates: &[Candidate], selected: &[usize]) -> bool {
    selected.iter().any(|&c| body_payload(&candidates[c]))
}

/// Makes the payload [`give_inertia`] made a body a point mass again; the
/// note that says so.
pub(super) fn withdraw_inertia(candidates: &mut [Candidate]) -> Option<String> {
    let payload = candidates.iter_mut().find(|c| body_payload(c))?;
    if let Shape::Body { own_inertia, .. } = &mut payload.shape {
        *own_inertia = false;
    }
    payload.names.retain(|&n| n != "inertia");
    Some(format!(
        "{}: its own moment of inertia, determined at the step that named it, did not hold \
         once the effects named after it were fitted with it (the selection with it a body \
         dropped it): kept a point mass",
        label(payload)
    ))
}

/// Whether a candidate is a payload without a moment of its own.
fn point_payload(c: &Candidate) -> bool {
    payload_with_moment(c, false)
}

/// Whether a candidate is a payload with a moment of its own.
fn body_payload(c: &Candidate) -> bool {
    payload_with_moment(c, true)
}

fn payload_with_moment(c: &Candidate, own: bool) -> bool {
    c.kind == Kind::Payload
        && matches!(c.shape, Shape::Body { own_inertia, .. } if own_inertia == own)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::candidate::payload_candidate;
    use crate::diagnose::stacked::Link;
    use nalgebra::DVector;

    /// A point-mass payload of the last of three links, as `candidates`
    /// builds it.
    fn point() -> Candidate {
        let link = Link {
            name: "tool".to_string(),
            parameters: [0.0; 10],
            extent: f64::INFINITY,
        };
        payload_candidate(2, &link, vec![DVector::zeros(3); 10])
    }

    /// On an independent UR10e (one recording: friction on every joint, a
    /// 1.09 kg payload, an offset), the payload made a body at its step lost
    /// its moment beside the friction named later; the backward check then
    /// dropped the payload and ten friction terms with it, leaving joint 2's
    /// held-out error where it began. The payload is a point mass again,
    /// as first fitted, and nothing else is.
    #[test]
    fn a_withdrawn_moment_leaves_the_point_mass_it_was() {
        let mut candidates = vec![point(), point()];
        candidates[1].kind = Kind::InertialError;
        let before = candidates[0].names.clone();
        if let Shape::Body { own_inertia, .. } = &mut candidates[0].shape {
            *own_inertia = true;
        }
        candidates[0].names.push("inertia");
        assert!(body_named(&candidates, &[0, 1]));
        assert!(!body_named(&candidates, &[1]));
        let note = withdraw_inertia(&mut candidates).unwrap();
        assert!(note.contains("kept a point mass"), "{note}");
        assert!(point_payload(&candidates[0]));
        assert_eq!(candidates[0].names, before);
        assert!(!body_named(&candidates, &[0, 1]));
        assert!(withdraw_inertia(&mut candidates).is_none());
    }
}
