//! Whether a fitted candidate's parameters are significant: |t| against
//! the larger of the least-squares and jackknife standard errors, with a
//! higher bar for shapes chosen among many.

use nalgebra::{DVector, Vector3};

use super::candidate::{Candidate, Shape, width};
use super::fit::Fit;
use super::kind::Kind;
use super::moments::Moments;
use super::uncertainty::{fit_robust, robust_quantity};

/// The fitted parameters of the last candidate of `trial` when it is
/// significant: every parameter of a joint effect; a payload's mass (its COM
/// components may be zero); for an inertial error, a change of the mass or
/// of some COM component from the model's. Each |t| uses the larger of the
/// least-squares and the jackknife standard error, so a parameter that
/// swings from trajectory to trajectory is not significant however many
/// correlated samples pin it down within each.
pub(super) fn significant(
    m: &Moments,
    candidates: &[Candidate],
    trial: &[usize],
    full: &Fit,
    min_t: f64,
) -> Option<Vec<f64>> {
    let (_, se) = fit_robust(m, candidates, trial)?;
    let theta = &full.theta;
    let added = *trial.last()?;
    let offset: usize = trial[..trial.len() - 1]
        .iter()
        .map(|&c| width(&candidates[c]))
        .sum();
    let w = width(&candidates[added]);
    let candidate = &candidates[added];
    let min_t = searched_threshold(min_t, candidate.searched);
    let t = |k: usize, reference: f64| (theta[offset + k] - reference).abs() / se[offset + k];
    let ok = match (&candidate.kind, &candidate.shape) {
        // A payload's mass, and its own moment of inertia where it has one.
        (
            Kind::Payload,
            Shape::Body {
                own_inertia: true, ..
            },
        ) => t(0, 0.0) > min_t && t(4, 0.0) > min_t,
        (Kind::Payload, _) => t(0, 0.0) > min_t,
        // A tilt may be about one axis only, a ripple's phase anything; a
        // spring's constant (its rest angle times its stiffness) may well
        // be zero.
        (Kind::GravityDirection | Kind::TorqueRipple, _) => (0..w).any(|k| t(k, 0.0) > min_t),
        (Kind::JointSpring, _) => t(0, 0.0) > min_t,
        (
            Kind::InertialError,
            Shape::Body {
                base_mass,
                base_moment,
                ..
            },
        ) => {
            let com = if *base_mass > 0.0 {
                base_moment / *base_mass
            } else {
                Vector3::zeros()
            };
            let nominal = [*base_mass, com.x, com.y, com.z];
            // Mass and COM may trade against each other (a link whose mass
            // acts only through second moments) while their product, the
            // first moment, is well determined: a change of either counts.
            let moment = |p: &DVector<f64>| {
                let at = p.rows(offset, 4);
                DVector::from_fn(3, |i, _| at[0] * at[i + 1] - base_moment[i])
            };
            let (change, change_se) = robust_quantity(m, candidates, trial, full, moment);
            (0..4).any(|k| t(k, nominal[k]) > min_t)
                || (0..3).any(|i| change[i].abs() > min_t * change_se[i])
        }
        // Some combination of the link's parameters changed.
        (Kind::InertialError, Shape::Whole { .. }) => (0..w).any(|k| t(k, 0.0) > min_t),
        (Kind::InertialError, Shape::Moment { base_moment, .. }) => {
            (0..3).any(|k| t(k, base_moment[k]) > min_t)
        }
        _ => (0..w).all(|k| t(k, 0.0) > min_t),
    };
    ok.then(|| theta.rows(offset, w).iter().copied().collect())
}

/// The |t| a candidate chosen among `searched` column shapes must pass:
/// sqrt(min_t^2 + 2 ln searched), close to a Bonferroni correction of the
/// normal tail (3 -> 4.0 for 50 shapes), so the best of many shapes fitted
/// to noise is not named.
pub(super) fn searched_threshold(min_t: f64, searched: usize) -> f64 {
    (min_t * min_t + 2.0 * (searched.max(1) as f64).ln()).sqrt()
}
