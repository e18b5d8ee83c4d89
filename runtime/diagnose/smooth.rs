//! Whether a named effect that is not friction holds when the friction of
//! the joints whose dry friction is named may follow a smoother law than
//! the model's sign(qd) and viscous terms. A plant's friction that rounds
//! off near zero speed (a sigmoid law: the Panda's, as Gaz et al. identify
//! it) leaves a velocity-shaped residual that a 0.4% torque scale, a 0.04
//! degree tilt or a link's mass fits significantly. Fitted beside a few
//! smooth functions of each such joint's velocity and the rate of its
//! Coulomb column (the flip's timing), a real tilt, scale, payload, offset
//! or delay keeps its significance (none of them is a function of the
//! velocity alone; a delay shifts the rigid-body torque too); such a trace
//! does not.

use nalgebra::DVector;

use super::candidate::{Candidate, label, on_joint};
use super::fit::fit;
use super::gain::relative_gain;
use super::heldout::{Scoring, cv_mse, worst_rise};
use super::kind::Kind;
use super::moments::Moments;
use super::settings::Settings;
use super::significance::significant;
use super::stacked::Stacked;

/// The generic features ([`super::stacked::GENERIC_FEATURES`]) that shape a
/// smoother friction law: qd |qd| and sign(qd) exp(-|qd| / 0.1 rad/s).
const SMOOTH_FEATURES: [usize; 2] = [1, 3];

/// An effect without which some joint's held-out MSE at least doubles is
/// named whatever its significance beside the smooth friction: the model
/// needs it, whatever part of it the friction's shape may be (as the held
/// check's rule, `super::held`).
const INDISPENSABLE: f64 = 2.0;

/// Drops each named effect other than friction that is no longer
/// significant beside the smooth friction columns of every joint with
/// named dry friction, with a note.
pub(super) fn drop_friction_traces(
    data: &Stacked,
    moments: &Moments,
    candidates: &[Candidate],
    selected: &mut Vec<usize>,
    notes: &mut Vec<String>,
    settings: Settings,
) {
    let joints = friction_joints(data.dof, candidates, selected);
    let checked: Vec<usize> = (0..selected.len())
        .filter(|&p| !is_friction(candidates[selected[p]].kind))
        .collect();
    if joints.is_empty() || checked.is_empty() {
        return;
    }
    // The named effects, then the smooth friction: one list the moments hold.
    let mut list: Vec<Candidate> = selected.iter().map(|&c| candidates[c].clone()).collect();
    let named = list.len();
    list.extend(smooth_friction(data, candidates, selected, &joints));
    let m = Moments::new(data, &list).weighted(moments.weights.clone());
    let smooth: Vec<usize> = (named..list.len()).collect();
    let mut traces = Vec::new();
    for p in checked {
        if holds(&m, &list, named, &smooth, p, settings) {
            continue;
        }
        let rise = worst_rise(moments, candidates, selected, p);
        if rise < INDISPENSABLE {
            traces.push(p);
            continue;
        }
        notes.push(format!(
            "{}: not significant beside a smoother friction law on the joints with dry friction, \
             but without it a joint's held-out MSE would be {rise:.1} times as large: named; part \
             of what it explains may be how the friction rounds off near zero speed",
            label(&candidates[selected[p]])
        ));
    }
    for &p in traces.iter().rev() {
        let dropped = selected.remove(p);
        notes.push(format!(
            "{}: significant in the fit, but not beside a smoother friction law on the joints \
             with dry friction (qd |qd|, sign(qd) exp(-|qd| / 0.1 rad/s), the friction's flip \
             a moment earlier or later): what it explains is how the friction changes near zero \
             speed, which the model's sign(qd) cannot follow; not named",
            label(&candidates[dropped])
        ));
    }
}

/// The joints whose Coulomb friction is named.
fn friction_joints(dof: usize, candidates: &[Candidate], selected: &[usize]) -> Vec<usize> {
    (0..dof)
        .filter(|&j| {
            selected.iter().any(|&c| {
                candidates[c].kind == Kind::CoulombFriction && candidates[c].joint == Some(j)
            })
        })
        .collect()
}

/// The smooth friction of `joints`: their [`SMOOTH_FEATURES`] columns,
/// where it is not named their direction-dependent dry friction (the
/// round-off of a law whose levels differ by direction), and the rate of
/// their Coulomb column (its flip a moment earlier or later than the
/// measured velocity's sign says, which a torque delay would otherwise
/// fit: a real delay shifts the rigid-body torque too).
fn smooth_friction<'a>(
    data: &'a Stacked,
    candidates: &'a [Candidate],
    selected: &'a [usize],
    joints: &'a [usize],
) -> impl Iterator<Item = Candidate> + 'a {
    let named = move |c: &Candidate| {
        selected
            .iter()
            .any(|&s| candidates[s].kind == c.kind && candidates[s].joint == c.joint)
    };
    let asymmetries = candidates.iter().filter(move |c| {
        c.kind == Kind::CoulombAsymmetry
            && c.joint.is_some_and(|j| joints.contains(&j))
            && !named(c)
    });
    let timing = joints.iter().filter_map(move |&j| {
        let coulomb = candidates
            .iter()
            .find(|c| c.kind == Kind::CoulombFriction && c.joint == Some(j))?;
        Some(nuisance(j, rate_within_groups(data, &coulomb.columns[0])))
    });
    joints
        .iter()
        .flat_map(move |&j| smooth_columns(data, j))
        .chain(asymmetries.cloned())
        .chain(timing)
}

/// The rate of `column` along each joint's samples (central differences
/// within a segment, zero at its ends), per sample period.
fn rate_within_groups(data: &Stacked, column: &DVector<f64>) -> DVector<f64> {
    let (n, len) = (data.dof, column.len());
    DVector::from_fn(len, |r, _| {
        if r < n || r + n >= len || data.group[r - n] != data.group[r + n] {
            return 0.0;
        }
        (column[r + n] - column[r - n]) / 2.0
    })
}

/// Whether the named effect at `position`, fitted after the other named
/// effects and the smooth friction columns, passes selection's bars:
/// significant, and some joint's held-out MSE lower by `min_gain`.
fn holds(
    m: &Moments,
    list: &[Candidate],
    named: usize,
    smooth: &[usize],
    position: usize,
    settings: Settings,
) -> bool {
    // An offset and direction-dependent friction on its own joint are the
    // same torque while the joint moves: an ambiguity reported as one.
    let checked = &list[position];
    let same_torque = |c: &Candidate| {
        checked.kind == Kind::TorqueOffset
            && c.kind == Kind::CoulombAsymmetry
            && c.joint == checked.joint
    };
    let trial: Vec<usize> = (0..named)
        .filter(|&p| p != position)
        .chain(smooth.iter().copied().filter(|&s| !same_torque(&list[s])))
        .chain([position])
        .collect();
    // A fit that fails says nothing against the effect.
    let Some(full) = fit(m, list, &trial, |_| true) else {
        return true;
    };
    if significant(m, list, &trial, &full, settings.min_t).is_none() {
        return false;
    }
    // Selection's other bar, beside the smooth friction: some joint's
    // held-out MSE (fitted columns) lower by `min_gain` with the effect.
    let dof = m.xx.first().map_or(0, Vec::len);
    let with = cv_mse(m, dof, list, &trial, Scoring::Fitted);
    let without = cv_mse(m, dof, list, &trial[..trial.len() - 1], Scoring::Fitted);
    relative_gain(&without, &with, &without).share >= settings.min_gain
}

fn is_friction(kind: Kind) -> bool {
    matches!(
        kind,
        Kind::ViscousFriction
            | Kind::CoulombFriction
            | Kind::CoulombAsymmetry
            | Kind::StribeckFriction
    )
}

/// The smooth friction columns of joint `j`: linear candidates on its rows.
fn smooth_columns(data: &Stacked, j: usize) -> impl Iterator<Item = Candidate> + '_ {
    SMOOTH_FEATURES.into_iter().map(move |f| {
        let column =
            data.generic[f].map_with_location(|r, _, v| if r % data.dof == j { v } else { 0.0 });
        nuisance(j, column)
    })
}

/// A column on joint `j` fitted beside the named effects, never named.
fn nuisance(j: usize, column: DVector<f64>) -> Candidate {
    on_joint(Kind::ViscousFriction, j, "smooth", column)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::candidate::linear as candidate;

    /// One joint with friction 0.3 sign(qd) - 0.1 sign(qd) exp(-|qd| / 0.1)
    /// (a law that rounds off near rest) plus `real` sin(q) and noise;
    /// named: Coulomb friction and a torque scale whose column is sin(q)
    /// plus the round-off's shape. What stays named after the check.
    fn named_after_check(real: f64) -> Vec<Kind> {
        let noise =
            |q: f64, qd: f64| 0.01 * ((q * 12.9898 + qd * 78.233).sin() * 43758.5453).fract();
        let round_off = |qd: f64| qd.signum() * (-qd.abs() / 0.1).exp();
        let (mut data, q, qd) = crate::diagnose::search::sweep(|q, qd| {
            0.3 * qd.signum() - 0.1 * round_off(qd) + real * q.sin() + noise(q, qd)
        });
        data.generic = vec![DVector::zeros(qd.len()); 4];
        data.generic[1] = qd.map(|v| v * v.abs());
        data.generic[3] = qd.map(round_off);
        let candidates = vec![
            candidate(Kind::CoulombFriction, qd.map(f64::signum)),
            candidate(
                Kind::TorqueScale,
                DVector::from_fn(q.len(), |r, _| q[r].sin() + round_off(qd[r])),
            ),
        ];
        let mut selected = vec![0, 1];
        let mut notes = Vec::new();
        let settings = Settings::default();
        drop_friction_traces(
            &data,
            &Moments::new(&data, &candidates),
            &candidates,
            &mut selected,
            &mut notes,
            settings,
        );
        selected.iter().map(|&c| candidates[c].kind).collect()
    }

    /// One joint with Coulomb friction 0.3 whose flip the sign of the
    /// velocity places a moment late, plus `real` times a rigid-body
    /// torque's rate; named: Coulomb friction and a torque delay whose
    /// column holds both rates. What stays named after the check.
    fn timing_after_check(real: f64) -> Vec<Kind> {
        let (data, q, qd) = crate::diagnose::search::sweep(|_, _| 0.0);
        let sign = qd.map(f64::signum);
        let flip = rate_within_groups(&data, &sign);
        let rigid = DVector::from_fn(q.len(), |r, _| q[r].cos() * qd[r]);
        let mut data = data;
        data.residual = DVector::from_fn(q.len(), |r, _| {
            0.3 * sign[r] + 0.05 * flip[r] + real * rigid[r] + 1e-3 * (r as f64 * 0.7).sin()
        });
        data.generic = vec![DVector::zeros(q.len()); 4];
        data.generic[1] = qd.map(|v| v * v.abs());
        data.generic[3] = qd.map(|v| v.signum() * (-v.abs() / 0.1).exp());
        let candidates = vec![
            candidate(Kind::CoulombFriction, sign),
            candidate(Kind::TorqueDelay, flip + rigid),
        ];
        let (mut selected, mut notes) = (vec![0, 1], Vec::new());
        let m = Moments::new(&data, &candidates);
        drop_friction_traces(
            &data,
            &m,
            &candidates,
            &mut selected,
            &mut notes,
            Settings::default(),
        );
        selected.iter().map(|&c| candidates[c].kind).collect()
    }

    #[test]
    fn a_delay_that_fits_only_the_friction_flip_is_dropped() {
        assert_eq!(timing_after_check(0.0), vec![Kind::CoulombFriction]);
        assert_eq!(
            timing_after_check(0.05),
            vec![Kind::CoulombFriction, Kind::TorqueDelay]
        );
    }

    #[test]
    fn an_effect_that_fits_only_the_friction_round_off_is_dropped() {
        assert_eq!(named_after_check(0.0), vec![Kind::CoulombFriction]);
    }

    #[test]
    fn an_effect_with_its_own_signal_stays() {
        assert_eq!(
            named_after_check(0.05),
            vec![Kind::CoulombFriction, Kind::TorqueScale]
        );
    }
}
