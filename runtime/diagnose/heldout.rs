//! Held-out (leave-one-segment-out) MSE of the residual after effects.

use nalgebra::DVector;

use super::candidate::{Candidate, columns_of};
use super::fit::{fit, fit_near, is_nonlinear};
use super::moments::Moments;
use crate::parallel::map_in_order;

/// Leave-one-trajectory-out MSE per joint of the residual after the effects.
pub(super) fn cv_mse_per_joint(
    m: &Moments,
    dof: usize,
    candidates: &[Candidate],
    selected: &[usize],
) -> Vec<f64> {
    cv_mse(m, dof, candidates, selected, Scoring::Applied)
}

/// How held-out residuals are scored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Scoring {
    /// As the generated model computes the effects once applied (Coulomb
    /// friction with the plain sign(qd), also at rest): what `evaluate`
    /// will show; the reported MSEs.
    Applied,
    /// With the fitted columns (Coulomb friction zero at rest, where the
    /// friction is static and unknown): how well each effect's physics
    /// explains the data, which decides what is named. A joint that sticks
    /// half the time would otherwise make the right kind look worse than a
    /// wrong one.
    Fitted,
}

/// Leave-one-group-out MSE per joint of the residual after the effects.
pub(super) fn cv_mse(
    m: &Moments,
    dof: usize,
    candidates: &[Candidate],
    selected: &[usize],
    scoring: Scoring,
) -> Vec<f64> {
    let Some(by_group) = cv_sse_by_group(m, dof, candidates, selected, scoring) else {
        return vec![f64::INFINITY; dof];
    };
    (0..dof)
        .map(|j| {
            let sse = by_group.iter().fold(0.0, |s, g| s + g[j]);
            let count: usize = m.rows.iter().map(|r| r[j]).sum();
            sse / count.max(1) as f64
        })
        .collect()
}

/// Each held-out group's squared residual per joint (group, joint) after
/// the effects fitted on the other groups; `None` when a fit fails.
pub(super) fn cv_sse_by_group(
    m: &Moments,
    dof: usize,
    candidates: &[Candidate],
    selected: &[usize],
    scoring: Scoring,
) -> Option<Vec<Vec<f64>>> {
    let fitted = columns_of(candidates, selected);
    let columns = match scoring {
        Scoring::Applied => m.applied(&fitted),
        Scoring::Fitted => fitted,
    };
    // Bodies descend in each fold from the whole data's fit.
    let near = match is_nonlinear(candidates, selected) {
        true => Some(fit(m, candidates, selected, |_| true)?.theta),
        false => None,
    };
    let groups: Vec<usize> = (0..m.xx.len()).collect();
    map_in_order(&groups, |&g| {
        let coefficients = match (selected.is_empty(), &near) {
            (true, _) => DVector::zeros(0),
            (false, Some(near)) => {
                fit_near(m, candidates, selected, |h| h != g, near)?.coefficients
            }
            (false, None) => fit(m, candidates, selected, |h| h != g)?.coefficients,
        };
        Some(
            (0..dof)
                .map(|j| m.sse(g, j, &columns, &coefficients))
                .collect(),
        )
    })
    .into_iter()
    .collect()
}

/// The held-out MSE (generated model's columns) of the joints of the
/// effect at `position` of `selected` (all joints for a link or data
/// effect), summed: with the whole selection, and with that effect left
/// out.
pub(super) fn with_and_without(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
    position: usize,
) -> (f64, f64) {
    let (joints, with, without) = per_joint_with_and_without(m, candidates, selected, position);
    let total = |mse: &[f64]| joints.iter().map(|&j| mse[j]).sum::<f64>();
    (total(&with), total(&without))
}

/// The largest factor by which leaving the effect at `position` out of
/// `selected` raises the held-out MSE (generated model's columns) of one
/// of its joints (all joints for a link or data effect).
pub(super) fn worst_rise(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
    position: usize,
) -> f64 {
    let (joints, with, without) = per_joint_with_and_without(m, candidates, selected, position);
    joints
        .iter()
        .map(|&j| without[j] / with[j])
        .fold(0.0, f64::max)
}

/// The joints of the effect at `position` of `selected`, and every joint's
/// held-out MSE with the whole selection and with that effect left out.
fn per_joint_with_and_without(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
    position: usize,
) -> (Vec<usize>, Vec<f64>, Vec<f64>) {
    let dof = m.xx.first().map_or(0, Vec::len);
    let mut rest = selected.to_vec();
    rest.remove(position);
    let joints: Vec<usize> = match candidates[selected[position]].joint {
        Some(j) => vec![j],
        None => (0..dof).collect(),
    };
    (
        joints,
        cv_mse_per_joint(m, dof, candidates, selected),
        cv_mse_per_joint(m, dof, candidates, &rest),
    )
}
