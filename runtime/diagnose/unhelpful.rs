//! Named effects that make the applied model no better: selection scores
//! the fitted columns, and an effect at the noise floor can pass it yet
//! remove no held-out error once applied.

use super::candidate::{Candidate, label};
use super::heldout::cv_mse_per_joint;
use super::moments::Moments;
use super::report;

/// Drops, one at a time, a named effect that removes no held-out error
/// from its joints once applied (the generated model's columns, counted in
/// selection order): selection scores the fitted columns, and an effect at
/// the noise floor can pass it yet make the applied model no better.
pub(super) fn drop_unhelpful(
    m: &Moments,
    candidates: &[Candidate],
    selected: &mut Vec<usize>,
    notes: &mut Vec<String>,
) {
    while let Some(position) = report::heldout_removals(m, candidates, selected)
        .iter()
        .enumerate()
        .position(|(k, &(removed, _))| {
            removed <= 0.0 && !helps_the_rest(m, candidates, selected, k)
        })
    {
        let dropped = selected.remove(position);
        notes.push(format!(
            "{}: significant in the fit, but once applied it removes no held-out error from its \
             joints; dropped",
            label(&candidates[dropped])
        ));
    }
}

/// Whether the effect at `position` of `selected` lowers its joints' held-out
/// MSE (applied columns) beside all the others: counted in the order named
/// an effect can seem to remove nothing because a later one (a payload that
/// replaced an early link error) did the work it needed (viscous friction
/// on three Panda joints beside a payload, 12 of 12 segments better with
/// it in the final model).
fn helps_the_rest(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
    position: usize,
) -> bool {
    let dof = m.xx.first().map_or(0, Vec::len);
    let rest: Vec<usize> = selected
        .iter()
        .enumerate()
        .filter_map(|(k, &c)| (k != position).then_some(c))
        .collect();
    let (with, without) = (
        cv_mse_per_joint(m, dof, candidates, selected),
        cv_mse_per_joint(m, dof, candidates, &rest),
    );
    let joints: Vec<usize> = match candidates[selected[position]].joint {
        Some(j) => vec![j],
        None => (0..dof).collect(),
    };
    joints.iter().map(|&j| without[j] - with[j]).sum::<f64>() > 0.0
}

#[cfg(test)]
mod tests {
    use nalgebra::DVector;

    use super::*;
    use crate::diagnose::candidate::Shape;
    use crate::diagnose::kind::Kind;
    use crate::diagnose::stacked::Stacked;

    fn candidate(kind: Kind, column: DVector<f64>) -> Candidate {
        Candidate {
            kind,
            joint: Some(0),
            link: None,
            modelled: [0.0; 10],
            extent: f64::INFINITY,
            names: vec!["value"],
            columns: vec![column],
            applied: None,
            shape: Shape::Linear,
            settings: Vec::new(),
            searched: 1,
        }
    }

    /// The residual is x - y (plus noise) for columns x = u and y = u + w,
    /// u and w orthogonal in every segment: named first, x alone fits only
    /// noise (in the order named it removes nothing), but beside y it
    /// removes all of the structure. It stays; the order-only rule dropped it.
    #[test]
    fn an_effect_that_needs_a_later_one_is_kept() {
        let (segments, per) = (4, 1000);
        let n = segments * per;
        let phase = |s: usize, k: f64| {
            (2.0 * std::f64::consts::PI * k * (s % per) as f64 / per as f64).sin()
        };
        let u = DVector::from_fn(n, |s, _| phase(s, 5.0));
        let w = DVector::from_fn(n, |s, _| phase(s, 7.0));
        let noise = DVector::from_fn(n, |s, _| {
            0.05 * ((s as f64 * 12.9898).sin() * 43758.5453).fract()
        });
        let residual = -&w + noise;
        let data = Stacked {
            measured: residual.clone(),
            residual,
            qd: DVector::zeros(n),
            qdd: DVector::zeros(n),
            gravity: DVector::zeros(n),
            generic: Vec::new(),
            group: (0..n).map(|s| s / per).collect(),
            dof: 1,
            levers: vec![1.0],
            rest: vec![0.02],
        };
        let candidates = vec![
            candidate(Kind::ViscousFriction, u.clone()),
            candidate(Kind::CoulombFriction, &u + &w),
        ];
        let m = Moments::new(&data, &candidates);
        let removals = report::heldout_removals(&m, &candidates, &[0, 1]);
        assert!(removals[0].0 <= 0.0, "{removals:?}");
        let (mut selected, mut notes) = (vec![0, 1], Vec::new());
        drop_unhelpful(&m, &candidates, &mut selected, &mut notes);
        assert_eq!(selected, vec![0, 1], "{notes:?}");
    }
}
