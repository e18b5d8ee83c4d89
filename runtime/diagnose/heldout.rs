//! Held-out (leave-one-segment-out) MSE of the residual after effects.

use nalgebra::DVector;

use super::candidate::{Candidate, columns_of};
use super::fit::fit;
use super::moments::Moments;

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
    let fitted = columns_of(candidates, selected);
    let columns = match scoring {
        Scoring::Applied => m.applied(&fitted),
        Scoring::Fitted => fitted,
    };
    let mut sse = vec![0.0; dof];
    let mut count = vec![0usize; dof];
    for g in 0..m.xx.len() {
        let coefficients = if selected.is_empty() {
            DVector::zeros(0)
        } else {
            match fit(m, candidates, selected, |h| h != g) {
                Some(f) => f.coefficients,
                None => return vec![f64::INFINITY; dof],
            }
        };
        for j in 0..dof {
            sse[j] += m.sse(g, j, &columns, &coefficients);
            count[j] += m.rows[g][j];
        }
    }
    sse.iter()
        .zip(&count)
        .map(|(s, &c)| s / c.max(1) as f64)
        .collect()
}
