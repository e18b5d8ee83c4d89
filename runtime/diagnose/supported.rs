//! Effects the data support beside the named ones that were not named, and
//! what each would change in the named effects' parameters were it fitted
//! with them. That change is a bias the named fit cannot rule out (the
//! named parameters absorb part of a small unnamed effect), so the reported
//! intervals include it (docs/diagnosis.md, "How far the intervals hold").

use nalgebra::DVector;

use super::admit::{levels_hold, physical};
use super::candidate::{Candidate, width};
use super::diagnosis::{Effect, HeldoutLeft};
use super::fit::{fit, identifiability};
use super::gain::Gain;
use super::heldout::{Scoring, cv_mse};
use super::moments::Moments;
use super::report::effect;
use super::select::admissible;
use super::settings::{COLLINEAR, Settings};
use super::significance::significant;
use super::uncertainty::fit_robust;
use crate::parallel::map_in_order;

/// The |t| (with the larger of the least-squares and the jackknife
/// standard error) above which an unnamed effect counts as supported: its
/// 95% interval excludes zero.
const SUPPORT_T: f64 = 1.96;

/// A candidate the data support that was not named.
pub(super) struct Supported {
    pub(super) candidate: usize,
    /// Its parameters fitted with the named effects, with their 95%
    /// half-widths.
    pub(super) values: Vec<(f64, f64)>,
    /// The change of the named effects' parameters (concatenated in
    /// selection order) when it is fitted with them.
    pub(super) shift: DVector<f64>,
    /// The held-out MSE it removes from the joint it helps most, that
    /// joint's held-out MSE before the diagnosis and after the named
    /// effects, and the joint (0-based).
    pub(super) removed: f64,
    pub(super) of: f64,
    pub(super) left: f64,
    pub(super) joint: usize,
}

/// Every candidate not in `selected` that, added to it, lowers the
/// held-out MSE (fitted columns; the sum over joints of each joint's
/// relative change), with parameters identifiable beside the named ones,
/// significant at [`SUPPORT_T`] and physical: the data support it, although
/// it was not named (below the naming |t|, below the minimum gain or the
/// gain floor, or dropped). The `untried` candidates are left out.
pub(super) fn supported(
    m: &Moments,
    dof: usize,
    candidates: &[Candidate],
    selected: &[usize],
    (settings, untried): (Settings, &[usize]),
) -> Vec<Supported> {
    let initial = cv_mse(m, dof, candidates, &[], Scoring::Fitted);
    let current = cv_mse(m, dof, candidates, selected, Scoring::Fitted);
    let named = if selected.is_empty() {
        DVector::zeros(0)
    } else {
        match fit(m, candidates, selected, |_| true) {
            Some(f) => f.theta,
            None => return Vec::new(),
        }
    };
    let open: Vec<usize> = (0..candidates.len())
        .filter(|c| {
            !selected.contains(c) && !untried.contains(c) && admissible(candidates, *c, selected)
        })
        .collect();
    // Each candidate's cross-validation is independent of the others'.
    map_in_order(&open, |&c| {
        let mut trial = selected.to_vec();
        trial.push(c);
        let mse = cv_mse(m, dof, candidates, &trial, Scoring::Fitted);
        if relative_drop(&current, &mse) <= 0.0 {
            return None;
        }
        let gain = largest_drop(&current, &mse);
        let full = fit(m, candidates, &trial, |_| true)?;
        let (at, w) = (named.len(), width(&candidates[c]));
        if identifiability(&full.information, at..at + w) < COLLINEAR {
            return None;
        }
        significant(m, candidates, &trial, &full, SUPPORT_T)?;
        let (_, se) = fit_robust(m, candidates, &trial)?;
        let own: Vec<f64> = full.theta.rows(at, w).iter().copied().collect();
        physical(&candidates[c], &own, gain, settings.reach).ok()?;
        levels_hold(candidates, &trial, full.theta.as_slice()).ok()?;
        Some(Supported {
            candidate: c,
            values: (0..w).map(|k| (own[k], 1.96 * se[at + k])).collect(),
            shift: full.theta.rows(0, at) - &named,
            removed: current[gain.joint] - mse[gain.joint],
            of: initial[gain.joint],
            left: current[gain.joint],
            joint: gain.joint,
        })
    })
    .into_iter()
    .flatten()
    .collect()
}

/// The change of the named effects' parameters when a torque delay is
/// fitted with them, whatever the data say of the delay itself: how the
/// torque's timing against the states (a logging offset, the controller's
/// hold) moves them. Zero when a delay is named or cannot be fitted.
pub(super) fn timing_shift(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
) -> Option<DVector<f64>> {
    let delay = candidates
        .iter()
        .position(|c| c.kind == super::kind::Kind::TorqueDelay)?;
    if selected.contains(&delay) || selected.is_empty() {
        return None;
    }
    let named = fit(m, candidates, selected, |_| true)?.theta;
    let mut trial = selected.to_vec();
    trial.push(delay);
    let full = fit(m, candidates, &trial, |_| true)?;
    let at = named.len();
    if identifiability(&full.information, at..at + 1) < COLLINEAR {
        return None;
    }
    Some(full.theta.rows(0, at) - named)
}

/// The sum over joints of each joint's relative drop of held-out MSE from
/// `before` to `after`: relative, so a joint with a large torque does not
/// outweigh the others (a link effect can help one joint and hurt another).
fn relative_drop(before: &[f64], after: &[f64]) -> f64 {
    before
        .iter()
        .zip(after)
        .filter(|(b, _)| **b > 0.0)
        .map(|(b, a)| (b - a) / b)
        .sum()
}

/// The joint whose held-out MSE drops the most (relative to its MSE) from
/// `before` to `after`.
fn largest_drop(before: &[f64], after: &[f64]) -> Gain {
    let share = |j: usize| {
        if before[j] > 0.0 {
            (before[j] - after[j]) / before[j]
        } else {
            0.0
        }
    };
    let joint = (0..before.len())
        .max_by(|&a, &b| share(a).total_cmp(&share(b)))
        .unwrap_or(0);
    Gain {
        share: share(joint),
        joint,
    }
}

/// Per named parameter, the bias the data cannot rule out: the largest
/// change any supported effect makes to it (the strongest alternative the
/// data support) plus the change a fitted torque delay makes (`timing`).
/// Added, not in quadrature: they are two looks at the same unmodelled
/// structure, not independent errors.
pub(super) fn bias(
    supported: &[Supported],
    timing: Option<DVector<f64>>,
    parameters: usize,
) -> DVector<f64> {
    DVector::from_fn(parameters, |k, _| {
        let strongest = supported
            .iter()
            .map(|s| s.shift[k].abs())
            .fold(0.0, f64::max);
        strongest + timing.as_ref().map_or(0.0, |t| t[k].abs())
    })
}

/// The supported effects as the report lists them, most held-out error
/// removed first: value, 95% interval, held-out MSE removed from its joint.
/// Their own notes (a poorly determined COM) are left out: they are not
/// named, the interval says it.
pub(super) fn listed(
    candidates: &[Candidate],
    supported: &[Supported],
    resolution: f64,
) -> Vec<Effect> {
    let mut order: Vec<&Supported> = supported.iter().collect();
    order.sort_by(|a, b| b.removed.total_cmp(&a.removed));
    order
        .into_iter()
        .map(|s| {
            let candidate = &candidates[s.candidate];
            let mut effect = effect(candidate, &s.values, resolution, &mut Vec::new());
            // Only named effects print a ready-made `--torque-scale` or
            // `--torque-delay`: an unnamed one, applied alone beside a model
            // fitted without it, can raise the held-out error (a UR10e's
            // joint 1: a supported scale of 1.26 took it from 18 to 58 N m^2).
            effect.parameters.remove("correction");
            effect.heldout_mse_removed = s.removed;
            effect.heldout_share = (s.removed / s.of.max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
            effect.heldout_left = Some(HeldoutLeft {
                joint: s.joint + 1,
                mse: s.left,
                share: (s.removed / s.left.max(f64::MIN_POSITIVE)).clamp(0.0, 1.0),
            });
            effect
        })
        .collect()
}
