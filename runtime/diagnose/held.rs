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
/// called last for the final one.
pub(super) fn drop_unheld(
    m: &Moments,
    candidates: &[Candidate],
    selected: &mut Vec<usize>,
    notes: &mut Vec<String>,
    mut bias: impl FnMut(&[usize]) -> DVector<f64>,
) {
    while let Some((theta, half)) = half_widths(m, candidates, selected, &bias(selected)) {
        let mut offset = 0;
        let mut failing = None;
        for (position, &c) in selected.iter().enumerate() {
            let w = width(&candidates[c]);
            let values: Vec<(f64, f64)> =
                (offset..offset + w).map(|k| (theta[k], half[k])).collect();
            offset += w;
            if !excludes_none(&candidates[c], &values) {
                failing = Some(position);
            }
        }
        let Some(position) = failing else {
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
