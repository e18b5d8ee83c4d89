//! Whether a named effect holds against what the fit leaves out: its 95%
//! interval, widened by the bias the data cannot rule out (a supported
//! effect left unnamed, a torque delay, friction below the at-rest speed;
//! see [`super::report::describe`]), must exclude "no effect". Selection
//! judges |t| with the sampling error only; an effect that explains a
//! leftover of another (a sigmoid friction law fitted as Coulomb and
//! viscous friction leaves structure a 0.4% torque scale or a 0.04 degree
//! tilt fits significantly) does not survive the widening.

use nalgebra::DVector;

use super::candidate::{Candidate, Shape, label, width};
use super::fit::Fit;
use super::heldout::with_and_without;
use super::kind::Kind;
use super::moments::Moments;
use super::report::half_widths;
use super::supported::Supported;

/// Whether `values` (parameter, 95% half-width) of `candidate` exclude its
/// "no effect": the rules of [`super::admit::significant`] with the
/// half-width in place of the |t| bar.
pub(super) fn excludes_none(candidate: &Candidate, values: &[(f64, f64)]) -> bool {
    let clear = |k: usize, none: f64| (values[k].0 - none).abs() > values[k].1;
    let w = values.len();
    match (&candidate.kind, &candidate.shape) {
        (Kind::Payload | Kind::JointSpring, _) => clear(0, 0.0),
        (Kind::GravityDirection | Kind::TorqueRipple, _) => (0..w).any(|k| clear(k, 0.0)),
        // Mass and COM trade against each other where their product, the
        // first moment, is what the data determine (a link whose origin
        // does not accelerate): neither interval alone says whether the
        // body changed, so a mass-and-COM error is judged by selection's
        // significance only.
        (Kind::InertialError, Shape::Body { .. }) => true,
        (Kind::InertialError, Shape::Moment { base_moment, .. }) => {
            (0..3).any(|k| clear(k, base_moment[k]))
        }
        (Kind::InertialError, _) => (0..w).any(|k| clear(k, 0.0)),
        _ => (0..w).all(|k| clear(k, 0.0)),
    }
}

/// Drops, one at a time (the last named first, as the backward check
/// does), each named effect whose widened interval includes no effect,
/// with a note; `bias` gives the bias per parameter of a selection and is
/// called last for the final one. Only an effect that fails beside the
/// whole selection can go: dropping one leaves a larger residual and more
/// supported alternatives, which widen the others' intervals, and judged
/// again every effect could fall in turn (a Panda from two recordings
/// lost its 0.8 kg payload and eight effects after three viscous terms;
/// held-out MSE 0.0029 -> 4.1 N m^2).
pub(super) fn drop_unheld(
    m: &Moments,
    candidates: &[Candidate],
    selected: &mut Vec<usize>,
    notes: &mut Vec<String>,
    mut bias: impl FnMut(&[usize]) -> DVector<f64>,
) {
    let mut suspects: Option<Vec<usize>> = None;
    while let Some((Fit { theta, .. }, half)) =
        half_widths(m, candidates, selected, &bias(selected))
    {
        let mut offset = 0;
        let mut failing = Vec::new();
        for (position, &c) in selected.iter().enumerate() {
            let w = width(&candidates[c]);
            let values: Vec<(f64, f64)> =
                (offset..offset + w).map(|k| (theta[k], half[k])).collect();
            offset += w;
            if !excludes_none(&candidates[c], &values) {
                failing.push(position);
            }
        }
        let suspects = suspects.get_or_insert_with(|| {
            failing
                .iter()
                .filter(|&&p| !indispensable(m, candidates, selected, p))
                .map(|&p| selected[p])
                .collect()
        });
        let Some(position) = failing
            .into_iter()
            .rfind(|&p| suspects.contains(&selected[p]))
        else {
            return;
        };
        let dropped = selected.remove(position);
        notes.push(format!(
            "{}: significant in the fit, but its 95% interval, widened by what the fit leaves \
             out (docs/diagnosis.md, \"How far the intervals hold\"), includes no effect; not \
             named (listed as supported where the data support it)",
            label(&candidates[dropped])
        ));
    }
}

/// Whether leaving the effect at `position` out of `selected` at least
/// doubles its joints' held-out MSE (the generated model's columns): no
/// allowance for bias makes such an effect a leftover's fit. A supported
/// alternative elsewhere that trades against it (a link error beside a
/// payload from two recordings) widens its interval, not its evidence.
fn indispensable(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
    position: usize,
) -> bool {
    let (with, without) = with_and_without(m, candidates, selected, position);
    without >= 2.0 * with
}

/// Per named parameter, the bias the held check allows for: the largest
/// change a supported effect *at another place* makes to it, plus
/// `timing`. An alternative at the effect's own joint or link (Coulomb
/// beside viscous friction on an axis that mostly moves one way) can move
/// it by more than its size: the two explain the same structure, which is
/// an ambiguity (reported as one), not evidence against either.
pub(super) fn bias_elsewhere(
    candidates: &[Candidate],
    selected: &[usize],
    supported: &[Supported],
    timing: Option<DVector<f64>>,
) -> DVector<f64> {
    let place = |c: usize| (candidates[c].joint, candidates[c].link.clone());
    let owners: Vec<usize> = selected
        .iter()
        .flat_map(|&c| std::iter::repeat_n(c, width(&candidates[c])))
        .collect();
    DVector::from_fn(owners.len(), |k, _| {
        let strongest = supported
            .iter()
            .filter(|s| place(s.candidate) != place(owners[k]))
            .map(|s| s.shift[k].abs())
            .fold(0.0, f64::max);
        strongest + timing.as_ref().map_or(0.0, |t| t[k].abs())
    })
}

#[cfg(test)]
mod tests {
    use nalgebra::DVector;

    use super::*;
    use crate::diagnose::candidate::linear as candidate;

    /// One joint whose residual is `offset` sin(q) + 0.3 qd plus noise,
    /// both named; what stays named after the held check with a bias that
    /// fails whichever effect comes first (sin(q), then qd alone).
    fn held(offset: f64) -> Vec<usize> {
        let noise =
            |q: f64, qd: f64| 0.05 * ((q * 12.9898 + qd * 78.233).sin() * 43758.5453).fract();
        let (data, q, qd) =
            super::super::search::sweep(|q, qd| offset * q.sin() + 0.3 * qd + noise(q, qd));
        let candidates = vec![
            candidate(Kind::TorqueOffset, q.map(f64::sin)),
            candidate(Kind::ViscousFriction, qd),
        ];
        let m = Moments::new(&data, &candidates);
        let mut selected = vec![0, 1];
        let mut notes = Vec::new();
        // A bias that fails whichever effect comes first in the selection.
        drop_unheld(&m, &candidates, &mut selected, &mut notes, |s| {
            DVector::from_fn(s.len(), |k, _| if k == 0 { 1e3 } else { 0.0 })
        });
        selected
    }

    #[test]
    fn dropping_one_effect_does_not_condemn_another_that_held() {
        // The small effect fails beside both and goes; the viscous term,
        // then alone and failing too, held beside the whole selection.
        assert_eq!(held(0.01), vec![1]);
    }

    #[test]
    fn an_effect_its_joint_cannot_do_without_is_never_dropped() {
        // Without sin(q) at 0.5 the joint's held-out MSE grows far beyond
        // twice: its failing interval is an allowance, not evidence.
        assert_eq!(held(0.5), vec![0, 1]);
    }
}
