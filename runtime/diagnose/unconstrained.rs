//! The unconstrained fit of a named inertial effect, reported beside the
//! physical one: the link's ten standard parameters fitted freely by least
//! squares (the other named effects with them). The physical fit moves only
//! the mass and the centre of mass, so it is a realizable body by
//! construction; where the free fit is not realizable, or explains
//! held-out data clearly better (the inertia about the COM is wrong too),
//! the report shows both.

use serde::Serialize;

use nalgebra::DMatrix;

use super::candidate::{Candidate, Shape, label, width};
use super::fit::fit;
use super::heldout::cv_mse_per_joint;
use super::moments::Moments;
use super::settings::{COLLINEAR, Settings};
use super::shape::{physically_consistent, pseudo_inertia_margin};
use super::solve::ROUNDING;
use super::whole::{combinations, combine};

/// The free least-squares fit of a link's ten inertial parameters.
#[derive(Debug, Clone, Serialize)]
pub struct Unconstrained {
    /// Corrected standard parameters about the link origin, in the link
    /// frame: the model's plus the free fit's change, which keeps the
    /// model's values in the directions the data do not determine, or moves
    /// along them as far as needed to reach a physical body when one exists.
    pub mass: f64,
    pub first_moment: [f64; 3],
    /// [ixx, ixy, ixz, iyy, iyz, izz] about the link origin, kg m^2.
    pub inertia: [f64; 6],
    /// How many combinations of the ten parameters these data determine
    /// (base parameters): the rest are the model's.
    pub identifiable_combinations: usize,
    /// Whether a physical body (pseudo-inertia positive semi-definite) fits
    /// the data as the free fit does; `None` when that cannot be computed.
    pub physically_consistent: Option<bool>,
    /// Held-out MSE summed over the joints (N m^2) with the free fit, and
    /// with the physical fit the report names.
    pub heldout_mse: f64,
    pub physical_heldout_mse: f64,
}

/// The free fit of named inertial effect `c` (a payload's or a link's ten
/// columns, linear) with the other `selected` effects, when it differs from
/// the physical fit (held-out MSE per joint `physical_mse`): not
/// realizable, or some joint's held-out MSE lower by at least
/// `settings.min_gain`. A note says which and what it means.
pub(super) fn unconstrained(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
    physical_mse: &[f64],
    c: usize,
    settings: Settings,
    notes: &mut Vec<String>,
) -> Option<Unconstrained> {
    if !matches!(
        candidates[c].shape,
        Shape::Body { .. } | Shape::Moment { .. }
    ) || candidates[c].columns.len() != 10
    {
        return None;
    }
    let (reduced, free, basis, null) = base_parameters(m, candidates, c)?;
    let dof = m.xx.first().map_or(0, Vec::len);
    let fitted = fit(&reduced, &free, selected, |_| true)?;
    let at: usize = selected
        .iter()
        .take_while(|&&s| s != c)
        .map(|&s| width(&free[s]))
        .sum();
    let change = &basis * fitted.theta.rows(at, basis.ncols());
    let fitted_body: [f64; 10] = std::array::from_fn(|k| free[c].modelled[k] + change[k]);
    let (corrected, consistent) = nearest_physical(&fitted_body, &null);
    // A model link that is no body (a lumped tensor breaking the triangle
    // inequality) makes the free fit's realizability say nothing about data.
    let model_physical = physically_consistent(&free[c].modelled) != Some(false);
    let free_mse = cv_mse_per_joint(&reduced, dof, &free, selected);
    let better = free_mse
        .iter()
        .zip(physical_mse)
        .any(|(f, p)| *p > 0.0 && (p - f) / p >= settings.min_gain);
    let unrealizable = model_physical && consistent == Some(false);
    if !unrealizable && !better {
        return None;
    }
    let [mass, hx, hy, hz, ixx, ixy, iyy, ixz, iyz, izz] = corrected;
    let report = Unconstrained {
        mass,
        first_moment: [hx, hy, hz],
        inertia: [ixx, ixy, ixz, iyy, iyz, izz],
        identifiable_combinations: basis.ncols(),
        physically_consistent: consistent,
        heldout_mse: free_mse.iter().sum(),
        physical_heldout_mse: physical_mse.iter().sum(),
    };
    notes.push(note(&candidates[c], &report, model_physical, better));
    Some(report)
}

/// Moments and candidates in the base-parameter basis, the map from its
/// coefficients to the ten parameters' change, and the directions unseen.
type BaseParameters = (Moments, Vec<Candidate>, DMatrix<f64>, Vec<[f64; 10]>);

/// Candidate `c`'s ten inertial columns replaced by the combinations the
/// data determine (base parameters): eigenvectors of their unit-diagonal
/// Gram matrix with eigenvalues at least [`COLLINEAR`] times the largest.
/// Returns the moments and candidates in that basis (`c` linear) and the
/// 10 x k map from the combinations' coefficients to the parameters'
/// change, which is zero in the directions the data do not see.
fn base_parameters(m: &Moments, candidates: &[Candidate], c: usize) -> Option<BaseParameters> {
    let offset: usize = candidates[..c].iter().map(|x| x.columns.len()).sum();
    let mut gram = DMatrix::<f64>::zeros(10, 10);
    for xx in m.xx.iter().flatten() {
        gram += xx.view((offset, offset), (10, 10));
    }
    // A column at rounding level (a first moment along the only axis that
    // moves the link) is no information: it must not become a unit column.
    let (basis, null) = combinations(&gram, COLLINEAR, ROUNDING)?;
    // Old moment columns -> new: the ten replaced by the k combinations.
    let p = m.xx.first()?.first()?.nrows();
    let k = basis.ncols();
    let mut t = DMatrix::<f64>::zeros(p, p - 10 + k);
    for old in 0..p {
        match old {
            _ if old < offset => t[(old, old)] = 1.0,
            _ if old < offset + 10 => {
                for l in 0..k {
                    t[(old, offset + l)] = basis[(old - offset, l)];
                }
            }
            _ => t[(old, old - 10 + k)] = 1.0,
        }
    }
    let moved = |old: usize| match old {
        _ if old < offset => old,
        _ => old - 10 + k,
    };
    let mut applied: Vec<usize> = m.applied[..offset].iter().map(|&a| moved(a)).collect();
    applied.extend(offset..offset + k);
    applied.extend(m.applied[offset + 10..].iter().map(|&a| moved(a)));
    let reduced = Moments::from_parts(
        m.xx.iter()
            .map(|g| g.iter().map(|xx| t.transpose() * xx * &t).collect())
            .collect(),
        m.xr.iter()
            .map(|g| g.iter().map(|xr| t.transpose() * xr).collect())
            .collect(),
        m.rr.clone(),
        m.rows.clone(),
        applied,
    )
    .weighted(m.weights.clone());
    let mut free = candidates.to_vec();
    let columns = &candidates[c].columns;
    free[c].shape = Shape::Linear;
    free[c].columns = combine(columns, &basis);
    Some((reduced, free, basis, null))
}

/// The body closest to `fitted` along the `null` directions (changes the
/// data do not see) that is physical, and whether one was found: the
/// pseudo-inertia's smallest eigenvalue is concave in the parameters, so a
/// compass search climbs towards its maximum over those directions.
fn nearest_physical(fitted: &[f64; 10], null: &[[f64; 10]]) -> ([f64; 10], Option<bool>) {
    let Some(mut margin) = pseudo_inertia_margin(fitted) else {
        return (*fitted, None);
    };
    let mut body = *fitted;
    let start = fitted[0].abs().max(1.0);
    let mut step = start;
    let mut evaluations = 0;
    while margin < 0.0 && step > 1e-9 * start && evaluations < 20_000 {
        let mut moved = false;
        for direction in null {
            for sign in [1.0, -1.0] {
                let trial = std::array::from_fn(|k| body[k] + sign * step * direction[k]);
                evaluations += 1;
                if let Some(value) = pseudo_inertia_margin(&trial)
                    && value > margin
                {
                    (body, margin, moved) = (trial, value, true);
                }
            }
        }
        if !moved {
            step *= 0.5;
        }
    }
    (body, Some(margin >= 0.0))
}

fn note(candidate: &Candidate, free: &Unconstrained, model_physical: bool, better: bool) -> String {
    let realizable = match free.physically_consistent {
        Some(false) if !model_physical => {
            "is not a physical body, nor is the model's link it starts from (correct the \
             model's inertia first)"
        }
        Some(false) => {
            "is not a physical body (its pseudo-inertia is not positive semi-definite: the data \
             pull the link's parameters where no body is, so read its numbers as the trace of \
             another error)"
        }
        _ => "is a physical body",
    };
    let explains = if better {
        format!(
            "and explains held-out data better ({:.4} against {:.4} N m^2 summed over the \
             joints): the link's inertia about its COM, which the physical fit holds as \
             modelled, differs too",
            free.heldout_mse, free.physical_heldout_mse
        )
    } else {
        "but explains held-out data no better".to_string()
    };
    format!(
        "{}: the free least-squares fit of the link's ten inertial parameters ({} combinations \
         identifiable in these data, the rest kept as modelled) {realizable}, {explains}; \
         reported as `unconstrained` beside the physical fit",
        label(candidate),
        free.identifiable_combinations,
    )
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::super::shape::point_mass;
    use super::*;

    const MASS: [f64; 10] = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];

    /// A point mass at (0, 0.1, 0.3) whose mass the data do not see: a fit
    /// that left it at -0.2 kg has a physical body among its equals, one
    /// with a positive mass and the same first and second moments.
    #[test]
    fn a_physical_body_is_found_along_what_the_data_do_not_see() {
        let mut fitted = point_mass(0.5, &Vector3::new(0.0, 0.1, 0.3));
        fitted[0] = -0.2;
        assert_eq!(physically_consistent(&fitted), Some(false));
        let (body, found) = nearest_physical(&fitted, &[MASS]);
        assert_eq!(found, Some(true));
        assert!(body[0] > 0.0 && body[1..] == fitted[1..], "{body:?}");
        // Nowhere to move: the fit is what it is.
        assert_eq!(nearest_physical(&fitted, &[]).1, Some(false));
    }

    /// Principal moments 1, 1, 3 about the COM break the triangle
    /// inequality whatever the mass: no physical body along the mass.
    #[test]
    fn an_impossible_inertia_stays_impossible_along_the_mass() {
        let mut fitted = point_mass(1.0, &Vector3::zeros());
        (fitted[4], fitted[6], fitted[9]) = (1.0, 1.0, 3.0);
        assert_eq!(nearest_physical(&fitted, &[MASS]).1, Some(false));
    }
}
