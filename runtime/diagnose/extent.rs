//! Named first moments held within their links: where the final fit puts
//! a link's centre of mass (at its modelled mass) beyond the link's extent,
//! the report and `--apply` carry the nearest fit that keeps it there.

use nalgebra::{DMatrix, DVector, Matrix3};

use super::candidate::{Candidate, Shape, label, width};
use super::nearest::moment_within;
use super::solve::pseudo_solve_columns;
use super::stacked::EXTENT_MARGIN;

/// The named effects' parameters `theta` (selection order) with every
/// first moment (a [`Shape::Moment`]) whose COM lies beyond its link's
/// extent moved to the nearest one within it, and the other parameters
/// refitted to it: for the quadratic model of the fit (its `information`,
/// J^T J), the constrained optimum. The first moment minimizes its
/// distance in the precision it has with the others refitted (the inverse
/// of its covariance block), and the others move as they are correlated
/// with it (their conditional optimum). A note gives both fits.
pub(super) fn moments_within(
    candidates: &[Candidate],
    selected: &[usize],
    information: &DMatrix<f64>,
    mut theta: DVector<f64>,
    notes: &mut Vec<String>,
) -> DVector<f64> {
    let mut offset = 0;
    for &c in selected {
        let candidate = &candidates[c];
        let at = offset;
        offset += width(candidate);
        let Shape::Moment { base_mass, .. } = candidate.shape else {
            continue;
        };
        let radius = candidate.extent * base_mass;
        let fitted = [theta[at], theta[at + 1], theta[at + 2]];
        if !(radius.is_finite() && norm(&fitted) > radius) {
            continue;
        }
        let picks = DMatrix::from_fn(theta.len(), 3, |i, a| f64::from(i == at + a));
        let covariance = pseudo_solve_columns(information, &picks);
        let block = Matrix3::from_fn(|a, b| covariance[(at + a, b)]);
        let Some(precision) = block.try_inverse() else {
            continue;
        };
        let kept = moment_within(fitted, &precision, radius);
        let step = nalgebra::Vector3::from_fn(|a, _| kept[a] - fitted[a]);
        theta += &covariance * (precision * step);
        for a in 0..3 {
            theta[at + a] = kept[a];
        }
        notes.push(format!(
            "{}: the fitted first moment [{:.4}, {:.4}, {:.4}] kg m puts the centre of mass \
             {:.3} m from the link origin at the modelled mass, beyond the link's extent ({:.3} \
             m: its farthest child joint or modelled COM plus {EXTENT_MARGIN} m); reported and \
             applied: the nearest fit that keeps it within, first moment [{:.4}, {:.4}, {:.4}] \
             kg m, the other named effects refitted to it (the intervals are the free fit's)",
            label(candidate),
            fitted[0],
            fitted[1],
            fitted[2],
            norm(&fitted) / base_mass,
            candidate.extent,
            kept[0],
            kept[1],
            kept[2]
        ));
    }
    theta
}

fn norm(h: &[f64; 3]) -> f64 {
    h.iter().map(|x| x * x).sum::<f64>().sqrt()
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::*;
    use crate::diagnose::kind::Kind;

    fn candidate(kind: Kind, shape: Shape, extent: f64) -> Candidate {
        Candidate {
            kind,
            joint: None,
            link: Some((1, "upper_arm".into())),
            modelled: [0.0; 10],
            extent,
            names: vec![],
            columns: vec![],
            applied: None,
            shape,
            settings: Vec::new(),
            searched: 1,
            neighbours: Vec::new(),
        }
    }

    /// A first moment fitted 0.70 m out (12.93 kg, extent 0.68 m) beside an
    /// armature correlated with it: the kept fit is the constrained optimum
    /// of the quadratic model (Karush-Kuhn-Tucker: the armature's gradient
    /// zero, the moment's pointing inward along it, the COM on the sphere).
    #[test]
    fn a_first_moment_beyond_its_link_is_held_within_with_the_rest_refitted() {
        let moment = Shape::Moment {
            offset: [0.0; 10],
            base_mass: 12.93,
            base_moment: Vector3::new(0.0, 0.0, 12.93 * 0.3),
        };
        let candidates = [
            candidate(Kind::InertialError, moment, 0.68),
            candidate(Kind::Armature, Shape::Linear, f64::INFINITY),
        ];
        let columns = DMatrix::from_fn(40, 4, |i, j| {
            let t = i as f64 * 0.37;
            let own = [t.sin(), (1.3 * t).cos(), (0.7 * t).sin() * t.cos(), t.cos()][j];
            own + if j == 3 { 0.8 * (1.3 * t).cos() } else { 0.0 }
        });
        let information = columns.transpose() * &columns;
        let fitted = DVector::from_vec(vec![-0.02, 8.54, 2.91, 4.0]);
        let mut notes = Vec::new();
        let kept = moments_within(
            &candidates,
            &[0, 1],
            &information,
            fitted.clone(),
            &mut notes,
        );
        let radius = 0.68 * 12.93;
        let h = Vector3::new(kept[0], kept[1], kept[2]);
        assert!((h.norm() - radius).abs() < 1e-9 * radius, "{kept}");
        let gradient = &information * (&kept - &fitted);
        assert!(gradient[3].abs() < 1e-9 * gradient.amax(), "{gradient}");
        let along = Vector3::new(gradient[0], gradient[1], gradient[2]);
        assert!(
            (along.normalize() + h.normalize()).norm() < 1e-6,
            "{along} {h}"
        );
        assert!(
            notes[0].contains("0.698 m") && notes[0].contains("refitted"),
            "{notes:?}"
        );
        let within = DVector::from_vec(vec![-0.02, 8.0, 2.0, 4.0]);
        let same = moments_within(
            &candidates,
            &[0, 1],
            &information,
            within.clone(),
            &mut notes,
        );
        assert_eq!(same, within);
    }
}
