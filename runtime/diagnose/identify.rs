//! Identifiability of the named effects' parameters in these data: the
//! condition number of their scaled information matrix and the pairs of
//! parameters the data can barely tell apart.

use nalgebra::DMatrix;
use serde::Serialize;

use super::candidate::{Candidate, Shape, label, width};
use super::fit::fit;
use super::moments::Moments;
use super::solve::pseudo_solve;

/// |correlation| of two parameter estimates above which they are reported
/// as confounded.
pub const CONFOUNDED: f64 = 0.9;

/// What the JSON report says about identifiability.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Identifiability {
    /// Condition number of the named parameters' information matrix scaled
    /// to unit diagonal (1: orthogonal effects; above about 1e3 the data
    /// barely separate some combination); `None` when nothing is named.
    pub condition_number: Option<f64>,
    /// Pairs of named parameters whose estimates correlate beyond
    /// 0.9 (`CONFOUNDED`): the data trade one for the other.
    pub confounded: Vec<Confounded>,
}

/// Two parameters the data can barely tell apart.
#[derive(Debug, Clone, Serialize)]
pub struct Confounded {
    pub first: String,
    pub second: String,
    pub correlation: f64,
}

pub(super) fn identifiability(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
) -> Identifiability {
    let Some(fit) = (!selected.is_empty())
        .then(|| fit(m, candidates, selected, |_| true))
        .flatten()
    else {
        return Identifiability::default();
    };
    // Each fitted parameter (a held COM axis is not one: no information),
    // its candidate and its index among the candidate's.
    let fitted: Vec<(usize, usize)> = selected
        .iter()
        .flat_map(|&c| (0..width(&candidates[c])).map(move |k| (c, k)))
        .collect();
    let kept: Vec<usize> = (0..fitted.len())
        .filter(|&i| candidates[fitted[i].0].shape.fitted(fitted[i].1))
        .collect();
    // A whole body's combinations correlate among themselves by
    // construction of the other effects' fit; only their link is a name.
    let owner: Vec<Option<usize>> = kept
        .iter()
        .map(|&i| {
            let c = fitted[i].0;
            matches!(candidates[c].shape, Shape::Whole { .. }).then_some(c)
        })
        .collect();
    let names: Vec<String> = kept
        .iter()
        .map(|&i| {
            let (c, k) = fitted[i];
            format!(
                "{}: {}",
                label(&candidates[c]),
                parameter_names(&candidates[c])[k]
            )
        })
        .collect();
    let info = fit.information.select_rows(&kept).select_columns(&kept);
    let info = &info;
    let k = info.nrows();
    let d: Vec<f64> = (0..k)
        .map(|i| info[(i, i)].max(f64::MIN_POSITIVE).sqrt())
        .collect();
    let scaled = DMatrix::from_fn(k, k, |i, j| info[(i, j)] / (d[i] * d[j]));
    let Some(eigen) = crate::kernels::symmetric_eigenvalues(scaled.clone()) else {
        return Identifiability::default();
    };
    let (low, high) = (eigen.min().max(0.0), eigen.max());
    let covariance = DMatrix::from_columns(
        &(0..k)
            .map(|c| {
                pseudo_solve(
                    &scaled,
                    &nalgebra::DVector::from_fn(k, |r, _| f64::from(r == c)),
                )
            })
            .collect::<Vec<_>>(),
    );
    let mut confounded = Vec::new();
    for i in 0..k {
        for j in i + 1..k {
            let denominator = (covariance[(i, i)] * covariance[(j, j)]).sqrt();
            let correlation = covariance[(i, j)] / denominator;
            let same_body = owner[i].is_some() && owner[i] == owner[j];
            if denominator > 0.0 && correlation.abs() > CONFOUNDED && !same_body {
                confounded.push(Confounded {
                    first: names[i].clone(),
                    second: names[j].clone(),
                    correlation,
                });
            }
        }
    }
    Identifiability {
        condition_number: Some(if low > 0.0 { high / low } else { f64::INFINITY }),
        confounded,
    }
}

/// The names of a candidate's fitted parameters (a body's mass and COM, or
/// its first moment when the mass is held).
fn parameter_names(candidate: &Candidate) -> Vec<&'static str> {
    match width(candidate) {
        3 if candidate.joint.is_none() => vec!["mx", "my", "mz"],
        _ => candidate.names.clone(),
    }
}
