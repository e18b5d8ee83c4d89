//! Least-squares fits of candidate effects from per-group second moments:
//! linear candidates exactly, bodies by Levenberg-Marquardt; held-out MSE,
//! least-squares and jackknife standard errors.

use nalgebra::{DMatrix, DVector, Vector3};

use super::COLLINEAR;
use super::candidate::{Candidate, Shape, columns_of, width};
use super::data::Stacked;

/// Second moments of all candidate columns and the residual, per
/// trajectory and joint: every least-squares fit and cross-validation fold
/// is then a small solve, independent of the number of samples.
pub(super) struct Moments {
    /// `[group][joint]`: X^T X, X^T r, r^T r and the row count.
    pub(super) xx: Vec<Vec<DMatrix<f64>>>,
    pub(super) xr: Vec<Vec<DVector<f64>>>,
    pub(super) rr: Vec<Vec<f64>>,
    pub(super) rows: Vec<Vec<usize>>,
    /// For each candidate column, the moment column that scores it (itself,
    /// or its `applied` column stored after all candidate columns).
    pub(super) applied: Vec<usize>,
    /// X^T X and X^T r per group summed over the joints, and over
    /// everything: a fold's normal equations are the total less one group,
    /// not a sum over every other group and joint.
    group_xx: Vec<DMatrix<f64>>,
    group_xr: Vec<DVector<f64>>,
    total_xx: DMatrix<f64>,
    total_xr: DVector<f64>,
}

impl Moments {
    pub(super) fn new(data: &Stacked, candidates: &[Candidate]) -> Moments {
        let mut columns: Vec<&DVector<f64>> =
            candidates.iter().flat_map(|c| c.columns.iter()).collect();
        let mut applied: Vec<usize> = (0..columns.len()).collect();
        let mut at = 0;
        for c in candidates {
            if let Some(column) = &c.applied {
                applied[at] = columns.len();
                columns.push(column);
            }
            at += c.columns.len();
        }
        let p = columns.len();
        let groups = data.group.iter().max().map_or(0, |g| g + 1);
        let mut xx = vec![vec![DMatrix::zeros(p, p); data.dof]; groups];
        let mut xr = vec![vec![DVector::zeros(p); data.dof]; groups];
        let mut rr = vec![vec![0.0; data.dof]; groups];
        let mut rows = vec![vec![0; data.dof]; groups];
        for (r, (&g, &y)) in data.group.iter().zip(data.residual.iter()).enumerate() {
            let j = r % data.dof;
            let x = DVector::from_fn(p, |k, _| columns[k][r]);
            xx[g][j].ger(1.0, &x, &x, 1.0);
            xr[g][j].axpy(y, &x, 1.0);
            rr[g][j] += y * y;
            rows[g][j] += 1;
        }
        Moments::from_parts(xx, xr, rr, rows, applied)
    }

    /// Moments from their per-group, per-joint parts, with the sums over
    /// joints and groups that the normal equations use.
    pub(super) fn from_parts(
        xx: Vec<Vec<DMatrix<f64>>>,
        xr: Vec<Vec<DVector<f64>>>,
        rr: Vec<Vec<f64>>,
        rows: Vec<Vec<usize>>,
        applied: Vec<usize>,
    ) -> Moments {
        let p = xx.first().and_then(|g| g.first()).map_or(0, DMatrix::nrows);
        let sum_m = |parts: &[DMatrix<f64>]| parts.iter().fold(DMatrix::zeros(p, p), |a, x| a + x);
        let sum_v = |parts: &[DVector<f64>]| parts.iter().fold(DVector::zeros(p), |a, x| a + x);
        let group_xx: Vec<DMatrix<f64>> = xx.iter().map(|g| sum_m(g)).collect();
        let group_xr: Vec<DVector<f64>> = xr.iter().map(|g| sum_v(g)).collect();
        Moments {
            total_xx: sum_m(&group_xx),
            total_xr: sum_v(&group_xr),
            group_xx,
            group_xr,
            xx,
            xr,
            rr,
            rows,
            applied,
        }
    }

    /// Sums of X^T X and X^T r over the groups `keep` accepts, restricted to `columns`.
    pub(super) fn normal_equations(
        &self,
        columns: &[usize],
        keep: impl Fn(usize) -> bool,
    ) -> (DMatrix<f64>, DVector<f64>) {
        let gather = |xx: &DMatrix<f64>, xr: &DVector<f64>| {
            let k = columns.len();
            let a = DMatrix::from_fn(k, k, |r, c| xx[(columns[r], columns[c])]);
            (a, DVector::from_fn(k, |r, _| xr[columns[r]]))
        };
        let left_out: Vec<usize> = (0..self.group_xx.len()).filter(|&g| !keep(g)).collect();
        match left_out[..] {
            [] => gather(&self.total_xx, &self.total_xr),
            // A cross-validation fold: everything but one group.
            [g] => {
                let (a, b) = gather(&self.total_xx, &self.total_xr);
                let (ag, bg) = gather(&self.group_xx[g], &self.group_xr[g]);
                (a - ag, b - bg)
            }
            _ => {
                let kept = (0..self.group_xx.len()).filter(|&g| keep(g));
                let parts: Vec<_> = kept
                    .map(|g| gather(&self.group_xx[g], &self.group_xr[g]))
                    .collect();
                let k = columns.len();
                parts.into_iter().fold(
                    (DMatrix::zeros(k, k), DVector::zeros(k)),
                    |(a, b), (ag, bg)| (a + ag, b + bg),
                )
            }
        }
    }

    /// The scoring columns of fitted `columns` (see `Candidate::applied`).
    pub(super) fn applied(&self, columns: &[usize]) -> Vec<usize> {
        columns.iter().map(|&c| self.applied[c]).collect()
    }

    /// Residual sum of squares of group g, joint j after subtracting X theta.
    pub(super) fn sse(&self, g: usize, j: usize, columns: &[usize], theta: &DVector<f64>) -> f64 {
        // Gathered directly: selecting rows first copies whole rows of the
        // moment matrix (hundreds of columns for a 7-joint arm).
        let (xx, xr) = (&self.xx[g][j], &self.xr[g][j]);
        let a = DMatrix::from_fn(columns.len(), columns.len(), |r, c| {
            xx[(columns[r], columns[c])]
        });
        let b = DVector::from_fn(columns.len(), |r, _| xr[columns[r]]);
        // Clamped: rounding can push a near-perfect fit's sum below zero.
        (self.rr[g][j] - 2.0 * theta.dot(&b) + theta.dot(&(a * theta))).max(0.0)
    }
}

/// Smallest squared Cholesky pivot of a unit-diagonal matrix that
/// [`pseudo_solve`] trusts; below it the SVD decides what is singular.
pub(super) const CHOLESKY_PIVOT: f64 = 1e-8;

/// A least-squares fit of some candidates.
pub(super) struct Fit {
    /// The candidates' parameters, concatenated in selection order.
    pub(super) theta: DVector<f64>,
    /// Coefficients of their columns ([`columns_of`] order).
    pub(super) coefficients: DVector<f64>,
    /// Information matrix J^T J at `theta`, J the residual's Jacobian.
    pub(super) information: DMatrix<f64>,
}

/// Solves H x = g for a symmetric positive semi-definite H by the
/// pseudo-inverse of its unit-diagonal scaling (minimum-norm in scaled
/// parameters when H is singular). A Cholesky factor whose pivots all stay
/// above [`CHOLESKY_PIVOT`] (a well-conditioned H, nearly every call) solves
/// it at a fraction of the SVD's cost, with the same solution.
pub(super) fn pseudo_solve(h: &DMatrix<f64>, g: &DVector<f64>) -> DVector<f64> {
    let k = h.nrows();
    if k == 0 {
        return DVector::zeros(0);
    }
    let d = DVector::from_fn(k, |i, _| {
        let v = h[(i, i)];
        if v > 0.0 { v.sqrt() } else { 1.0 }
    });
    let scaled = DMatrix::from_fn(k, k, |i, j| h[(i, j)] / (d[i] * d[j]));
    let rhs = DVector::from_fn(k, |i, _| g[i] / d[i]);
    if let Some(cholesky) = scaled.clone().cholesky() {
        let l = cholesky.l_dirty();
        if (0..k).all(|i| l[(i, i)] * l[(i, i)] > CHOLESKY_PIVOT) {
            let x = cholesky.solve(&rhs);
            return DVector::from_fn(k, |i, _| x[i] / d[i]);
        }
    }
    // Non-finite or non-converging: no solution (the callers check their
    // data for finiteness first, so this is a guard, not a path).
    let Some(svd) = crate::kernels::svd(scaled) else {
        return DVector::zeros(k);
    };
    let tolerance = 1e-12 * svd.singular_values.max().max(f64::MIN_POSITIVE);
    let x = svd
        .solve(&rhs, tolerance)
        .unwrap_or_else(|_| DVector::zeros(k));
    DVector::from_fn(k, |i, _| x[i] / d[i])
}

/// Whether a shape's coefficients are its parameters.
fn linear(shape: &Shape) -> bool {
    matches!(
        shape,
        Shape::Linear | Shape::Delay { .. } | Shape::Asymmetry { .. }
    )
}

/// Column coefficients and their Jacobian for concatenated parameters.
pub(super) fn coefficients(
    candidates: &[Candidate],
    selected: &[usize],
    theta: &DVector<f64>,
) -> (DVector<f64>, DMatrix<f64>) {
    let columns: usize = selected.iter().map(|&c| candidates[c].columns.len()).sum();
    let mut coefficients = DVector::zeros(columns);
    let mut jacobian = DMatrix::zeros(columns, theta.len());
    let (mut row, mut col) = (0, 0);
    for &c in selected {
        let candidate = &candidates[c];
        let w = width(candidate);
        let parameters: Vec<f64> = theta.rows(col, w).iter().copied().collect();
        let (values, d) = candidate.shape.map(&parameters);
        for (k, v) in values.iter().enumerate() {
            coefficients[row + k] = *v;
        }
        jacobian
            .view_mut((row, col), (values.len(), w))
            .copy_from(&d);
        row += values.len();
        col += w;
    }
    (coefficients, jacobian)
}

/// Fits the `selected` candidates on the groups `keep` accepts: linear
/// candidates exactly, bodies by Levenberg-Marquardt from the linear fit of
/// their mass and first-moment columns. `None` when there are no data.
pub(super) fn fit(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
    keep: impl Fn(usize) -> bool,
) -> Option<Fit> {
    let columns = columns_of(candidates, selected);
    let (a, b) = m.normal_equations(&columns, keep);
    if a.nrows() > 0 && a.diagonal().iter().all(|v| *v == 0.0) {
        return None;
    }
    // Start: linear fit of every linear column and each body's first four.
    let mut start_columns = Vec::new();
    let mut at = 0;
    for &c in selected {
        match candidates[c].shape {
            Shape::Linear | Shape::Delay { .. } | Shape::Asymmetry { .. } => {
                start_columns.extend(at..at + candidates[c].columns.len())
            }
            // A small tilt barely changes the gravity along the model's.
            Shape::Tilt { .. } => start_columns.extend(at..at + 2),
            Shape::Body { .. } => start_columns.extend(at..at + 4),
            // The mass column carries no information (that is why the shape
            // was chosen): start from the first-moment columns alone.
            Shape::Moment { .. } => start_columns.extend(at + 1..at + 4),
        }
        at += candidates[c].columns.len();
    }
    let a0 = a.select_rows(&start_columns).select_columns(&start_columns);
    let x0 = pseudo_solve(&a0, &b.select_rows(&start_columns));
    let mut theta = Vec::new();
    let mut at = 0;
    for &c in selected {
        match &candidates[c].shape {
            Shape::Tilt { .. } => {
                theta.extend(x0.rows(at, 2).iter());
                at += 2;
            }
            Shape::Linear | Shape::Delay { .. } | Shape::Asymmetry { .. } => {
                let count = candidates[c].columns.len();
                theta.extend(x0.rows(at, count).iter());
                at += count;
            }
            Shape::Body {
                base_mass,
                base_moment,
                ..
            } => {
                let mass = base_mass + x0[at];
                let moment = base_moment + Vector3::new(x0[at + 1], x0[at + 2], x0[at + 3]);
                let com = if mass.abs() > 1e-9 {
                    moment / mass
                } else {
                    Vector3::zeros()
                };
                theta.extend([mass, com.x, com.y, com.z]);
                at += 4;
            }
            Shape::Moment { base_moment, .. } => {
                theta.extend((base_moment + Vector3::new(x0[at], x0[at + 1], x0[at + 2])).iter());
                at += 3;
            }
        }
    }
    // Second start: every body as modelled (a link's change can be far from
    // what its first-moment columns alone suggest, which then absorb inertia).
    let mut modelled = theta.clone();
    let mut at = 0;
    let mut other_start = false;
    for &c in selected {
        let w = width(&candidates[c]);
        if let Shape::Body {
            base_mass,
            base_moment,
            ..
        } = &candidates[c].shape
            && *base_mass > 0.0
        {
            let com = base_moment / *base_mass;
            modelled[at..at + 4].copy_from_slice(&[*base_mass, com.x, com.y, com.z]);
            other_start = true;
        }
        if let Shape::Moment { base_moment, .. } = &candidates[c].shape {
            modelled[at..at + 3].copy_from_slice(base_moment.as_slice());
            other_start = true;
        }
        at += w;
    }
    let mut starts = vec![DVector::from_vec(theta)];
    if other_start {
        starts.push(DVector::from_vec(modelled));
    }
    let (theta, coef, jacobian) = starts
        .into_iter()
        .map(|start| descend(candidates, selected, &a, &b, start))
        .min_by(|x, y| x.3.total_cmp(&y.3))
        .map(|(t, c, j, _)| (t, c, j))?;
    let information = jacobian.transpose() * &a * &jacobian;
    Some(Fit {
        theta,
        coefficients: coef,
        information,
    })
}

/// Levenberg-Marquardt from `theta` on the normal equations (a, b); one
/// exact step when every candidate is linear. Returns the parameters, the
/// column coefficients, their Jacobian and the objective.
pub(super) fn descend(
    candidates: &[Candidate],
    selected: &[usize],
    a: &DMatrix<f64>,
    b: &DVector<f64>,
    mut theta: DVector<f64>,
) -> (DVector<f64>, DVector<f64>, DMatrix<f64>, f64) {
    let objective = |coefficients: &DVector<f64>| {
        coefficients.dot(&(a * coefficients)) - 2.0 * coefficients.dot(b)
    };
    let nonlinear = selected.iter().any(|&c| !linear(&candidates[c].shape));
    let (mut coef, mut jacobian) = coefficients(candidates, selected, &theta);
    let mut value = objective(&coef);
    let mut lambda = 1e-3;
    for _ in 0..200 {
        let excess = a * &coef - b;
        let gradient = -(jacobian.transpose() * &excess);
        let hessian = jacobian.transpose() * a * &jacobian;
        let step = if nonlinear {
            newton_step(
                candidates, selected, &theta, &excess, &hessian, &gradient, lambda,
            )
        } else {
            pseudo_solve(&hessian, &gradient)
        };
        let trial = &theta + &step;
        let (trial_coef, trial_jacobian) = coefficients(candidates, selected, &trial);
        let trial_value = objective(&trial_coef);
        if !nonlinear {
            return (trial, trial_coef, trial_jacobian, trial_value);
        }
        if trial_value < value {
            let decrease = value - trial_value;
            theta = trial;
            coef = trial_coef;
            jacobian = trial_jacobian;
            value = trial_value;
            lambda = (lambda / 3.0).max(1e-12);
            // Converged when a step gains less than 1e-10 of the objective:
            // far below the noise of any torque measurement.
            if decrease <= 1e-10 * value.abs().max(1e-300) {
                break;
            }
        } else {
            lambda *= 4.0;
            if lambda > 1e12 {
                break;
            }
        }
    }
    (theta, coef, jacobian, value)
}

/// A damped Newton step: the Gauss-Newton Hessian plus the coefficients'
/// curvature weighted by the residual's excess (A c - b), with Marquardt's
/// damping; where that is not positive definite (far from a minimum), the
/// damped Gauss-Newton step, which always descends.
fn newton_step(
    candidates: &[Candidate],
    selected: &[usize],
    theta: &DVector<f64>,
    excess: &DVector<f64>,
    gauss_newton: &DMatrix<f64>,
    gradient: &DVector<f64>,
    lambda: f64,
) -> DVector<f64> {
    let damping = DMatrix::from_diagonal(&(gauss_newton.diagonal() * lambda));
    let exact = gauss_newton + curvature(candidates, selected, theta, excess) + &damping;
    if let Some(cholesky) = exact.cholesky() {
        return cholesky.solve(gradient);
    }
    pseudo_solve(&(gauss_newton + damping), gradient)
}

/// Block-diagonal sum of each coefficient's Hessian in theta weighted by
/// `weights` (one per coefficient, [`columns_of`] order).
fn curvature(
    candidates: &[Candidate],
    selected: &[usize],
    theta: &DVector<f64>,
    weights: &DVector<f64>,
) -> DMatrix<f64> {
    let mut total = DMatrix::zeros(theta.len(), theta.len());
    let (mut row, mut col) = (0, 0);
    for &c in selected {
        let candidate = &candidates[c];
        let w = width(candidate);
        let n = candidate.columns.len();
        let parameters: Vec<f64> = theta.rows(col, w).iter().copied().collect();
        let weights: Vec<f64> = weights.rows(row, n).iter().copied().collect();
        let block = candidate.shape.curvature(&parameters, &weights);
        total.view_mut((col, col), (w, w)).copy_from(&block);
        row += n;
        col += w;
    }
    total
}

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

/// Smallest eigenvalue of the unit-diagonal scaling of the information
/// about the parameters at `range` once the others are projected out
/// (the Schur complement); 0 when some parameter has no information.
pub(super) fn identifiability(information: &DMatrix<f64>, range: std::ops::Range<usize>) -> f64 {
    let k = information.nrows();
    let inside: Vec<usize> = range.clone().collect();
    let outside: Vec<usize> = (0..k).filter(|i| !range.contains(i)).collect();
    let icc = information.select_rows(&inside).select_columns(&inside);
    let schur = if outside.is_empty() {
        icc.clone()
    } else {
        let ioo = information.select_rows(&outside).select_columns(&outside);
        let ioc = information.select_rows(&outside).select_columns(&inside);
        let solved = DMatrix::from_columns(
            &(0..inside.len())
                .map(|c| pseudo_solve(&ioo, &ioc.column(c).into_owned()))
                .collect::<Vec<_>>(),
        );
        &icc - ioc.transpose() * solved
    };
    let w = inside.len();
    let mut least: f64 = 1.0;
    let d: Vec<f64> = (0..w).map(|i| schur[(i, i)]).collect();
    for i in 0..w {
        // A parameter whose own information vanishes after projection.
        if icc[(i, i)] <= 0.0 || d[i] <= COLLINEAR * icc[(i, i)] {
            return 0.0;
        }
    }
    let scaled = DMatrix::from_fn(w, w, |i, j| schur[(i, j)] / (d[i] * d[j]).sqrt());
    let Some(eigenvalues) = crate::kernels::symmetric_eigenvalues(scaled) else {
        return 0.0;
    };
    for v in eigenvalues.iter() {
        least = least.min(*v);
    }
    least
}

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

/// Residual SSE per joint over all samples with `columns` fitted as `coefficients`.
pub(super) fn sse_per_joint(
    m: &Moments,
    columns: &[usize],
    coefficients: &DVector<f64>,
) -> Vec<f64> {
    let joints = m.xx.first().map_or(0, Vec::len);
    (0..joints)
        .map(|j| {
            (0..m.xx.len())
                .map(|g| m.sse(g, j, columns, coefficients))
                .sum()
        })
        .collect()
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
