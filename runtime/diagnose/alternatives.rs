//! Confusable effects: another candidate that explains the structure a
//! named effect explains almost as well on held-out data (a torque scale
//! and a link's inertial error, a payload and the last link's mass, a
//! torque offset and direction-dependent dry friction). The data cannot
//! tell such pairs apart; the report says so instead of hiding the
//! runner-up.

use super::admit::admits;
use super::candidate::{Candidate, label};
use super::gain::{Gain, relative_gain};
use super::heldout::{Scoring, cv_mse};
use super::kind::Kind;
use super::moments::Moments;
use super::settings::Settings;

/// A runner-up whose held-out MSE is within this factor of the named
/// effect's on every joint explains the data almost as well.
pub const NEAR: f64 = 1.1;

/// A named effect and a runner-up the data barely tell from it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Alternative {
    pub(super) named: usize,
    pub(super) runner_up: usize,
    /// Held-out MSE (N m^2) of the joint the named effect acts on most,
    /// with the named effect and with the runner-up instead.
    pub(super) joint: usize,
    pub(super) named_mse: f64,
    pub(super) runner_up_mse: f64,
}

/// The runners-up of step `named` (added to `before`, leaving held-out
/// MSEs `after`): candidates of another kind or place whose own held-out
/// MSEs (`scored`) are within [`NEAR`] of `after` on every joint, that are
/// significant and physical in place of the named effect, and that add no
/// gain once it is named (they explain the same structure).
#[allow(clippy::too_many_arguments)]
pub(super) fn runners_up(
    m: &Moments,
    candidates: &[Candidate],
    before: &[usize],
    named: usize,
    gain: Gain,
    after: &[f64],
    initial: &[f64],
    scored: &[(usize, Gain, Vec<f64>)],
    settings: Settings,
) -> Vec<Alternative> {
    let dof = after.len();
    let floor = initial.iter().fold(0.0_f64, |a, &b| a.max(b)) * 1e-12;
    scored
        .iter()
        .filter(|(r, _, mse)| {
            *r != named
                && !same_effect(&candidates[named], &candidates[*r])
                && mse.iter().zip(after).all(|(r, n)| *r <= NEAR * n + floor)
        })
        .filter(|(r, _, _)| {
            let mut trial = before.to_vec();
            trial.push(*r);
            admits(m, candidates, &trial, settings)
        })
        .filter(|(r, _, _)| {
            let mut both = before.to_vec();
            both.extend([named, *r]);
            let mse = cv_mse(m, dof, candidates, &both, Scoring::Fitted);
            relative_gain(after, &mse, after).share < settings.min_gain
        })
        .map(|(r, _, mse)| Alternative {
            named,
            runner_up: *r,
            joint: gain.joint,
            named_mse: after[gain.joint],
            runner_up_mse: mse[gain.joint],
        })
        .collect()
}

/// Among the candidates that leave the step's joint (the best one's) with a
/// held-out MSE within [`NEAR`] of the best's, the one that cuts the most
/// error over all joints (summed relative drops from `current`). A torque
/// scale and a heavier tip scale the same gravity torques on one joint;
/// the body also explains the other joints it loads, the scale does not.
/// A body that explains no other joint (less than [`ELSEWHERE`]) is no
/// broader than the joint's own effect, and has more parameters: there the
/// best joint-level candidate of the near ones is taken (a constant force
/// on a vertical lift is an offset, not mass on an axis no other joint
/// feels). `is_link(c)`: whether candidate c is a body (payload or link
/// error).
pub(super) fn broadest<'a>(
    scored: &'a [(usize, Gain, Vec<f64>)],
    best: &'a (usize, Gain, Vec<f64>),
    current: &[f64],
    is_link: &dyn Fn(usize) -> bool,
) -> &'a (usize, Gain, Vec<f64>) {
    let joint = best.1.joint;
    let drops = |mse: &[f64]| -> Vec<f64> {
        mse.iter()
            .zip(current)
            .map(|(a, b)| {
                if *b > 0.0 {
                    ((b - a) / b).max(0.0)
                } else {
                    0.0
                }
            })
            .collect()
    };
    let cut = |mse: &[f64]| -> f64 { drops(mse).iter().sum() };
    let elsewhere = |mse: &[f64]| -> f64 { cut(mse) - drops(mse)[joint] };
    let near: Vec<&(usize, Gain, Vec<f64>)> = scored
        .iter()
        .filter(|(_, _, mse)| mse[joint] <= NEAR * best.2[joint])
        .collect();
    let broadest = near
        .iter()
        .copied()
        .max_by(|a, b| cut(&a.2).total_cmp(&cut(&b.2)))
        .unwrap_or(best);
    if !is_link(broadest.0) || elsewhere(&broadest.2) >= ELSEWHERE {
        return broadest;
    }
    near.into_iter()
        .filter(|(c, _, _)| !is_link(*c))
        .min_by(|a, b| a.2[joint].total_cmp(&b.2[joint]))
        .unwrap_or(broadest)
}

/// Summed relative drop of the other joints' held-out MSE below which a
/// body explains nothing beyond the step's joint.
pub const ELSEWHERE: f64 = 0.05;

/// A payload and the last link's inertial error change the same ten
/// columns and differ only in second moments. Where a named link error can
/// be replaced by the payload on its link with every joint's held-out MSE
/// within [`NEAR`], the payload significant and physical in its place, the
/// payload is named (the usual case: the arm carries something) and the
/// link error is listed as ambiguous with it.
pub(super) fn payload_over_link_error(
    m: &Moments,
    candidates: &[Candidate],
    selected: &mut [usize],
    alternatives: &mut Vec<Alternative>,
    settings: Settings,
) {
    let dof = m.xx.first().map_or(0, Vec::len);
    let Some(payload) = candidates.iter().position(|p| p.kind == Kind::Payload) else {
        return;
    };
    let Some(at) = selected.iter().position(|&c| {
        candidates[c].kind == Kind::InertialError && candidates[c].link == candidates[payload].link
    }) else {
        return;
    };
    let named = selected[at];
    let mse = cv_mse(m, dof, candidates, selected, Scoring::Fitted);
    // The payload last: `significant` tests the last candidate.
    let mut trial: Vec<usize> = selected.iter().copied().filter(|&c| c != named).collect();
    trial.push(payload);
    let swapped = cv_mse(m, dof, candidates, &trial, Scoring::Fitted);
    let close = swapped.iter().zip(&mse).all(|(s, n)| *s <= NEAR * n);
    let admissible = admits(m, candidates, &trial, settings);
    if !(close && admissible) {
        return;
    }
    selected[at] = payload;
    alternatives.retain(|a| a.named != named);
    let joint = (0..dof)
        .max_by(|&a, &b| mse[a].total_cmp(&mse[b]))
        .unwrap_or(0);
    alternatives.push(Alternative {
        named: payload,
        runner_up: named,
        joint,
        named_mse: swapped[joint],
        runner_up_mse: mse[joint],
    });
}

/// Two candidates of one kind at one place (a ripple's harmonics, a
/// Stribeck velocity's grid) are one effect, not an ambiguity.
fn same_effect(a: &Candidate, b: &Candidate) -> bool {
    a.kind == b.kind && a.joint == b.joint && a.link == b.link
}

/// The note for a named effect's runner-up.
pub(super) fn note(candidates: &[Candidate], alternative: &Alternative) -> String {
    let (named, other) = (
        &candidates[alternative.named],
        &candidates[alternative.runner_up],
    );
    let (runner_up, named_mse) =
        crate::digits::apart(alternative.runner_up_mse, alternative.named_mse);
    format!(
        "{} is ambiguous with {}: in its place the other leaves joint {}'s held-out MSE at \
         {runner_up} N m^2 instead of {named_mse} and explains the same structure, so these data \
         barely tell them apart{}",
        label(named),
        label(other),
        alternative.joint + 1,
        hint(named.kind, other.kind)
    )
}

/// What would tell a confusable pair apart.
fn hint(a: Kind, b: Kind) -> &'static str {
    use Kind::*;
    match (a, b) {
        (TorqueScale, InertialError | Payload) | (InertialError | Payload, TorqueScale) => {
            ": a torque sensor's scale multiplies friction and armature torques too, an inertial \
             error does not; motions with more friction torque (slower, or reversing often), or \
             a torque-sensor calibration, would tell"
        }
        (Payload, InertialError) | (InertialError, Payload) => {
            ": a point mass and a link's mass change act through the same first moments; \
             motions that rotate the last link fast about its own axes would tell"
        }
        (TorqueOffset, CoulombAsymmetry) | (CoulombAsymmetry, TorqueOffset) => {
            ": only samples at rest tell a constant torque from friction that depends on the \
             direction of motion"
        }
        _ => ": motions that excite them differently would tell",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Step 1 of a payload hidden with friction (independent simulator):
    /// a scale on joint 3 cuts that joint 94%, the payload 94% too and
    /// joints 1 and 2 by 89% and 82%: the payload is the step's effect. A
    /// body that leaves the joint clearly worse is not.
    #[test]
    fn the_effect_that_explains_more_joints_wins_a_near_tie() {
        let current = [0.0055, 0.84, 0.158];
        let gain = |share| Gain { share, joint: 2 };
        let scale = (0, gain(0.943), vec![0.0055, 0.84, 0.00907]);
        let payload = (1, gain(0.938), vec![0.00061, 0.1506, 0.00982]);
        let far = (2, gain(0.80), vec![0.00061, 0.1506, 0.0316]);
        let link = |c: usize| c != 0;
        let scored = [scale.clone(), payload, far.clone()];
        assert_eq!(broadest(&scored, &scored[0], &current, &link).0, 1);
        let scored = [scale, far];
        assert_eq!(broadest(&scored, &scored[0], &current, &link).0, 0);
    }

    /// A vertical lift's constant force: mass on an axis no other joint
    /// feels fits joint 0 a little better than the offset, and explains
    /// nothing else: the offset (joint-level, fewer parameters) is named.
    #[test]
    fn a_body_that_explains_only_the_step_joint_yields_to_the_joint_effect() {
        let current = [76.0, 0.0105, 0.0176];
        let gain = |share| Gain { share, joint: 0 };
        let body = (0, gain(0.83), vec![12.7, 0.0104, 0.0175]);
        let offset = (1, gain(0.82), vec![13.5, 0.0105, 0.0176]);
        let link = |c: usize| c == 0;
        let scored = [body, offset];
        assert_eq!(broadest(&scored, &scored[0], &current, &link).0, 1);
    }
}
