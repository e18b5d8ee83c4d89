//! Standard errors of fitted parameters: least squares, and the
//! delete-one-segment jackknife that holds when samples are correlated.

use nalgebra::{DMatrix, DVector};

use super::candidate::{Candidate, columns_of};
use super::fit::{Fit, fit, pseudo_solve};
use super::moments::{Moments, sse_per_joint};

/// Full-data fit with the standard errors of its parameters.
pub(super) fn fit_all(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
) -> Option<(Fit, DVector<f64>)> {
    if selected.is_empty() {
        return None;
    }
    let fit = fit(m, candidates, selected, |_| true)?;
    let covariance = covariance(m, candidates, selected, &fit);
    let se = DVector::from_fn(fit.theta.len(), |i, _| covariance[(i, i)].max(0.0).sqrt());
    Some((fit, se))
}

/// Least-squares covariance of the fitted parameters (sigma^2 from the
/// residual, the information's pseudo-inverse).
fn covariance(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
    fit: &Fit,
) -> DMatrix<f64> {
    let columns = columns_of(candidates, selected);
    let sse: f64 = sse_per_joint(m, &columns, &fit.coefficients).iter().sum();
    let rows: usize = m.rows.iter().flatten().sum();
    let sigma2 = sse.max(0.0) / (rows.saturating_sub(fit.theta.len())).max(1) as f64;
    let k = fit.theta.len();
    sigma2
        * DMatrix::from_columns(
            &(0..k)
                .map(|c| {
                    pseudo_solve(
                        &fit.information,
                        &DVector::from_fn(k, |r, _| f64::from(r == c)),
                    )
                })
                .collect::<Vec<_>>(),
        )
}

/// A quantity `f` of the parameters (e.g. a body's first moment m*c) at the
/// full-data fit, with its standard errors: the larger of the least-squares
/// one (delta method, central differences) and the jackknife one, as for
/// the parameters themselves.
pub(super) fn robust_quantity(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
    fit: &Fit,
    f: impl Fn(&DVector<f64>) -> DVector<f64>,
) -> (DVector<f64>, DVector<f64>) {
    let value = f(&fit.theta);
    let k = fit.theta.len();
    let jacobian = DMatrix::from_columns(
        &(0..k)
            .map(|i| {
                let h = 1e-6 * fit.theta[i].abs().max(1e-3);
                let (mut up, mut down) = (fit.theta.clone(), fit.theta.clone());
                up[i] += h;
                down[i] -= h;
                (f(&up) - f(&down)) / (2.0 * h)
            })
            .collect::<Vec<_>>(),
    );
    let covariance = &jacobian * covariance(m, candidates, selected, fit) * jacobian.transpose();
    let mut se = DVector::from_fn(value.len(), |i, _| covariance[(i, i)].max(0.0).sqrt());
    let groups = m.xx.len();
    let folds: Option<Vec<DVector<f64>>> = (groups >= 3)
        .then(|| {
            (0..groups)
                .map(|g| fit_on(m, candidates, selected, g).map(|t| f(&t)))
                .collect()
        })
        .flatten();
    if let Some(folds) = folds {
        let g = groups as f64;
        let mean = folds.iter().fold(DVector::zeros(value.len()), |a, v| a + v) / g;
        let t = student_t975(groups - 1);
        for i in 0..value.len() {
            let spread: f64 = folds.iter().map(|v| (v[i] - mean[i]).powi(2)).sum();
            se[i] = se[i].max(t * ((g - 1.0) / g * spread).sqrt() / 1.96);
        }
    }
    (value, se)
}

/// The parameters fitted without group `g`.
fn fit_on(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
    g: usize,
) -> Option<DVector<f64>> {
    fit(m, candidates, selected, |h| h != g).map(|f| f.theta)
}

/// [`fit_all`] with each standard error the larger of the least-squares and
/// the jackknife one (as a normal-equivalent error: the jackknife's 95%
/// half-width over 1.96), which significance tests and reported intervals
/// use.
pub(super) fn fit_robust(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
) -> Option<(Fit, DVector<f64>)> {
    let (fit, se) = fit_all(m, candidates, selected)?;
    let se = match jackknife_half_widths(m, candidates, selected, &fit.theta) {
        Some(half) => se.zip_map(&half, |s, h| s.max(h / 1.96)),
        None => se,
    };
    Some((fit, se))
}

/// 95% half-widths of the parameters from the leave-one-trajectory-out
/// fits (delete-one jackknife over trajectories, Student t with G - 1
/// degrees of freedom): unlike the least-squares standard errors they hold
/// when the samples of a trajectory are correlated (filtered signals,
/// unmodelled structure), because trajectories are independent. `None`
/// below three trajectories or when a fold cannot be fitted.
pub(super) fn jackknife_half_widths(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
    theta: &DVector<f64>,
) -> Option<DVector<f64>> {
    let groups = m.xx.len();
    if groups < 3 {
        return None;
    }
    let folds = (0..groups)
        .map(|g| fit(m, candidates, selected, |h| h != g).map(|f| f.theta))
        .collect::<Option<Vec<_>>>()?;
    let mean = folds.iter().fold(DVector::zeros(theta.len()), |a, f| a + f) / groups as f64;
    let g = groups as f64;
    let t = student_t975(groups - 1);
    Some(DVector::from_fn(theta.len(), |k, _| {
        let spread: f64 = folds.iter().map(|f| (f[k] - mean[k]).powi(2)).sum();
        t * ((g - 1.0) / g * spread).sqrt()
    }))
}

/// The 97.5% quantile of Student's t with `dof` degrees of freedom.
pub(super) fn student_t975(dof: usize) -> f64 {
    const TABLE: [f64; 30] = [
        12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160,
        2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056,
        2.052, 2.048, 2.045, 2.042,
    ];
    match dof {
        0 => f64::INFINITY,
        1..=30 => TABLE[dof - 1],
        // Within 0.003 of the exact quantile beyond 30.
        _ => 1.96 + 2.4 / dof as f64,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn student_quantiles_fall_towards_the_normal() {
        assert_eq!(student_t975(5), 2.571);
        assert_eq!(student_t975(30), 2.042);
        assert!((student_t975(60) - 2.000).abs() < 0.003);
        assert!((student_t975(1_000_000) - 1.96).abs() < 1e-5);
        assert!(student_t975(0).is_infinite());
    }
}
