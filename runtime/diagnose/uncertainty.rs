//! Standard errors of fitted parameters: least squares, and the
//! delete-one-segment jackknife that holds when samples are correlated.

use nalgebra::{DMatrix, DVector};

use super::candidate::{Candidate, Shape, columns_of};
use super::fit::{Fit, fit, fit_near};
use super::moments::{Moments, sse_per_joint};
use super::solve::{pseudo_solve, pseudo_solve_columns};

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

/// Least-squares covariance of the fitted parameters, each joint's
/// residual variance its own: I^-1 (J^T B J) I^-1 with I the information
/// and B = sum over joints of sigma_j^2 X_j^T X_j (a sandwich estimate).
/// An arm's joints differ in noise by orders of magnitude (a UR10e's
/// shoulder 0.9 N m, its wrist 0.02): a variance pooled over them gives a
/// wrist's friction the shoulder's noise. With equal variances this is
/// sigma^2 I^-1.
fn covariance(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
    fit: &Fit,
) -> DMatrix<f64> {
    let columns = columns_of(candidates, selected);
    let sse = sse_per_joint(m, &columns, &fit.coefficients);
    let rows_of = |j: usize| m.rows.iter().map(|g| g[j]).sum::<usize>();
    let rows: usize = (0..sse.len()).map(rows_of).sum();
    let k = fit.theta.len();
    // Degrees of freedom spent on the parameters, shared in proportion.
    let spent = rows as f64 / rows.saturating_sub(k).max(1) as f64;
    let c = columns.len();
    let mut meat = DMatrix::zeros(c, c);
    for (j, sse) in sse.iter().enumerate() {
        let n = rows_of(j);
        if n == 0 {
            continue;
        }
        // A weighted fit's meat: w_j^2 sigma_j^2 X_j^T X_j.
        let w = m.weights[j];
        let variance = sse.max(0.0) / n as f64 * spent * w * w;
        for group in &m.xx {
            let xx = &group[j];
            meat += DMatrix::from_fn(c, c, |r, s| xx[(columns[r], columns[s])]) * variance;
        }
    }
    let meat = fit.jacobian.transpose() * meat * &fit.jacobian;
    let bread = pseudo_solve_columns(&fit.information, &DMatrix::identity(k, k));
    &bread * meat * bread.transpose()
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
                .map(|g| fit_on(m, candidates, selected, g, &fit.theta).map(|t| f(&t)))
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

/// The parameters fitted without group `g`, bodies descending from
/// `near` (the parameters fitted on every group).
fn fit_on(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
    g: usize,
    near: &DVector<f64>,
) -> Option<DVector<f64>> {
    fit_near(m, candidates, selected, |h| h != g, near).map(|f| f.theta)
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

/// 95% half-widths from normal-equivalent standard errors `se` and a bias
/// `bias` the data cannot rule out (how far the parameters move when the
/// fit is given what the named model lacks, see `supported::bias` and
/// [`rest_shift`]): the bias-aware interval of Armstrong and Kolesar
/// (2020), which covers 95% for any bias up to that size: the half-width
/// c se with P(|Z + bias / se| <= c) = 0.95, Z standard normal (1.96 se
/// without bias, about bias + 1.645 se for a large one).
pub(super) fn widened(se: &DVector<f64>, bias: &DVector<f64>) -> DVector<f64> {
    DVector::from_fn(se.len(), |k, _| {
        let b = bias.get(k).copied().unwrap_or(0.0).abs();
        if se[k] > 0.0 {
            se[k] * bias_aware_critical(b / se[k])
        } else {
            b
        }
    })
}

/// The c with P(|Z + t| <= c) = 0.95 for a standard normal Z, by
/// bisection between 1.96 (t = 0) and t + 1.96.
fn bias_aware_critical(t: f64) -> f64 {
    let covered = |c: f64| normal_cdf(c - t) - normal_cdf(-c - t);
    let (mut low, mut high) = (1.96, t + 1.96);
    for _ in 0..60 {
        let mid = 0.5 * (low + high);
        if covered(mid) < 0.95 {
            low = mid;
        } else {
            high = mid;
        }
    }
    high
}

/// The standard normal CDF (Abramowitz and Stegun 7.1.26 for erf, within
/// 1.5e-7).
fn normal_cdf(x: f64) -> f64 {
    let z = x.abs() / std::f64::consts::SQRT_2;
    let t = 1.0 / (1.0 + 0.327_591_1 * z);
    let poly = t
        * (0.254_829_592
            + t * (-0.284_496_736
                + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    let erf = 1.0 - poly * (-z * z).exp();
    if x >= 0.0 {
        0.5 * (1.0 + erf)
    } else {
        0.5 * (1.0 - erf)
    }
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
        .map(|g| fit_on(m, candidates, selected, g, theta))
        .collect::<Option<Vec<_>>>()?;
    let mean = folds.iter().fold(DVector::zeros(theta.len()), |a, f| a + f) / groups as f64;
    let g = groups as f64;
    let t = student_t975(groups - 1);
    Some(DVector::from_fn(theta.len(), |k, _| {
        let spread: f64 = folds.iter().map(|f| (f[k] - mean[k]).powi(2)).sum();
        t * ((g - 1.0) / g * spread).sqrt()
    }))
}

/// Per parameter, how much the fit moves when the friction of a joint
/// that moves slower than its at-rest speed is left free: each column with
/// an applied version (Coulomb friction: the plain sign(qd), also in that
/// band, against the fitted column's zero there) gets that version as a
/// second column, so the band's torque has its own coefficient and the
/// level is the two coefficients' sum. Neither column knows how friction
/// behaves near zero speed (static, creeping, the simulator's or the arm's
/// own law); the move is what that ignorance can cost the fitted levels
/// and, through them, the viscous coefficients. Linear candidates are
/// refitted with the others' coefficients held; theirs count zero.
pub(super) fn rest_shift(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
    fit: &Fit,
) -> DVector<f64> {
    let columns = columns_of(candidates, selected);
    let mut linear = Vec::new();
    for &c in selected {
        let is_linear = matches!(
            candidates[c].shape,
            Shape::Linear | Shape::Delay { .. } | Shape::Asymmetry { .. }
        );
        linear.extend(std::iter::repeat_n(is_linear, candidates[c].columns.len()));
    }
    let free: Vec<usize> = (0..columns.len()).filter(|&k| linear[k]).collect();
    let held: Vec<usize> = (0..columns.len()).filter(|&k| !linear[k]).collect();
    let band: Vec<usize> = free
        .iter()
        .copied()
        .filter(|&k| m.applied[columns[k]] != columns[k])
        .collect();
    if band.is_empty() {
        return DVector::zeros(fit.theta.len());
    }
    // Free columns, then each banded column's applied version, then the
    // held ones.
    let all: Vec<usize> = free
        .iter()
        .map(|&k| columns[k])
        .chain(band.iter().map(|&k| m.applied[columns[k]]))
        .chain(held.iter().map(|&k| columns[k]))
        .collect();
    let (a, b) = m.normal_equations(&all, |_| true);
    let solved = free.len() + band.len();
    let inside: Vec<usize> = (0..solved).collect();
    let outside: Vec<usize> = (solved..all.len()).collect();
    let rhs = b.select_rows(&inside)
        - a.select_rows(&inside).select_columns(&outside) * fit.coefficients.select_rows(&held);
    let refit = pseudo_solve(&a.select_rows(&inside).select_columns(&inside), &rhs);
    let mut coefficient = fit.coefficients.clone();
    for (i, &k) in free.iter().enumerate() {
        coefficient[k] = refit[i];
    }
    for (i, &k) in band.iter().enumerate() {
        coefficient[k] += refit[free.len() + i];
    }
    // Linear candidates' parameters are their coefficients, in order.
    let mut shift = DVector::zeros(fit.theta.len());
    let (mut column, mut parameter) = (0, 0);
    for &c in selected {
        let count = candidates[c].columns.len();
        if linear[column] {
            for k in 0..count {
                shift[parameter + k] = coefficient[column + k] - fit.coefficients[column + k];
            }
        }
        column += count;
        parameter += super::candidate::width(&candidates[c]);
    }
    shift
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
    use crate::diagnose::kind::Kind;
    use crate::diagnose::stacked::Stacked;

    /// Two joints, one column each on its own joint's rows, noise 1.0 N m
    /// on joint 1 and 0.01 N m on joint 2: each coefficient's standard
    /// error follows its own joint's noise, sigma_j / |column|, not the
    /// pooled one (which gives joint 2 about 70 times its own).
    #[test]
    fn standard_errors_follow_each_joints_own_noise() {
        let samples = 4000;
        let mut noise = crate::diagnose::search::white_noise(12345);
        let shape = |s: usize| (0.003 * s as f64).sin();
        let mut residual = DVector::zeros(2 * samples);
        let mut columns = [DVector::zeros(2 * samples), DVector::zeros(2 * samples)];
        for s in 0..samples {
            for (j, sigma) in [1.0, 0.01].into_iter().enumerate() {
                columns[j][2 * s + j] = shape(s);
                residual[2 * s + j] = 0.5 * shape(s) + sigma * noise();
            }
        }
        let data = Stacked::of_residual(residual, 2);
        let candidates: Vec<Candidate> = (0..2)
            .map(|j| Candidate {
                kind: Kind::ViscousFriction,
                joint: Some(j),
                link: None,
                modelled: [0.0; 10],
                extent: f64::INFINITY,
                names: vec![],
                columns: vec![columns[j].clone()],
                applied: None,
                shape: Shape::Linear,
                settings: Vec::new(),
                searched: 1,
                neighbours: Vec::new(),
            })
            .collect();
        let m = Moments::new(&data, &candidates);
        let (_, se) = fit_all(&m, &candidates, &[0, 1]).unwrap();
        for (j, sigma) in [1.0, 0.01].into_iter().enumerate() {
            let expected = sigma / columns[j].norm();
            assert!(
                (se[j] / expected - 1.0).abs() < 0.1,
                "joint {j}: {} vs {expected}",
                se[j]
            );
        }
    }

    #[test]
    fn bias_aware_critical_values_span_normal_to_shifted() {
        assert!((normal_cdf(1.96) - 0.975_002).abs() < 1e-6);
        assert!((bias_aware_critical(0.0) - 1.96).abs() < 1e-4);
        // P(|Z + 1| <= c) = 0.95 at c = 2.65 (tables of the folded normal).
        assert!((bias_aware_critical(1.0) - 2.65).abs() < 0.01);
        let large = bias_aware_critical(10.0);
        assert!((large - 11.645).abs() < 0.01, "{large}");
    }

    #[test]
    fn student_quantiles_fall_towards_the_normal() {
        assert_eq!(student_t975(5), 2.571);
        assert_eq!(student_t975(30), 2.042);
        assert!((student_t975(60) - 2.000).abs() < 0.003);
        assert!((student_t975(1_000_000) - 1.96).abs() < 1e-5);
        assert!(student_t975(0).is_infinite());
    }
}
