//! Least-squares fits of candidate effects from the moments: linear
//! candidates exactly, bodies by Levenberg-Marquardt, and how well the
//! data determine the fitted parameters.

use nalgebra::{DMatrix, DVector, Vector3};

use super::candidate::{Candidate, Shape, columns_of, width};
use super::moments::Moments;
use super::settings::COLLINEAR;

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
    let x = pseudo_solve_columns(h, &DMatrix::from_column_slice(g.len(), 1, g.as_slice()));
    DVector::from_column_slice(x.as_slice())
}

/// [`pseudo_solve`] for each column of `g`, with one factorization.
pub(super) fn pseudo_solve_columns(h: &DMatrix<f64>, g: &DMatrix<f64>) -> DMatrix<f64> {
    let k = h.nrows();
    if k == 0 {
        return DMatrix::zeros(0, g.ncols());
    }
    let d = DVector::from_fn(k, |i, _| {
        let v = h[(i, i)];
        if v > 0.0 { v.sqrt() } else { 1.0 }
    });
    let scaled = DMatrix::from_fn(k, k, |i, j| h[(i, j)] / (d[i] * d[j]));
    let rhs = DMatrix::from_fn(k, g.ncols(), |i, j| g[(i, j)] / d[i]);
    let unscale = |x: DMatrix<f64>| DMatrix::from_fn(k, x.ncols(), |i, j| x[(i, j)] / d[i]);
    if let Some(cholesky) = scaled.clone().cholesky() {
        let l = cholesky.l_dirty();
        if (0..k).all(|i| l[(i, i)] * l[(i, i)] > CHOLESKY_PIVOT) {
            return unscale(cholesky.solve(&rhs));
        }
    }
    // Non-finite or non-converging: no solution (the callers check their
    // data for finiteness first, so this is a guard, not a path).
    let Some(svd) = crate::kernels::svd(scaled) else {
        return DMatrix::zeros(k, g.ncols());
    };
    let tolerance = 1e-12 * svd.singular_values.max().max(f64::MIN_POSITIVE);
    svd.solve(&rhs, tolerance)
        .map(unscale)
        .unwrap_or_else(|_| DMatrix::zeros(k, g.ncols()))
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
            Shape::Linear | Shape::Delay { .. } | Shape::Asymmetry { .. } | Shape::Whole { .. } => {
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
            Shape::Linear | Shape::Delay { .. } | Shape::Asymmetry { .. } | Shape::Whole { .. } => {
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

/// The least-squares fit from `theta` on the normal equations (a, b): the
/// linear candidates' coefficients eliminated exactly (variable
/// projection: for given nonlinear coefficients the best linear ones solve
/// a linear system, which leaves normal equations in the nonlinear
/// coefficients alone, their Schur complement), Levenberg-Marquardt on
/// what is left. Linear parameters collinear with a body's columns (a
/// neighbouring link's whole-body error) made the joint descent crawl.
/// Returns the parameters, the column coefficients, their Jacobian and the
/// objective.
fn descend(
    candidates: &[Candidate],
    selected: &[usize],
    a: &DMatrix<f64>,
    b: &DVector<f64>,
    theta: DVector<f64>,
) -> (DVector<f64>, DVector<f64>, DMatrix<f64>, f64) {
    let (mut linear_columns, mut nonlinear_columns) = (Vec::new(), Vec::new());
    let mut nonlinear_parameters = Vec::new();
    let (mut column, mut parameter) = (0, 0);
    for &c in selected {
        let (n, w) = (candidates[c].columns.len(), width(&candidates[c]));
        if candidates[c].shape.is_linear() {
            linear_columns.extend(column..column + n);
        } else {
            nonlinear_columns.extend(column..column + n);
            nonlinear_parameters.extend(parameter..parameter + w);
        }
        (column, parameter) = (column + n, parameter + w);
    }
    if nonlinear_columns.is_empty() || linear_columns.is_empty() {
        return levenberg_marquardt(candidates, selected, a, b, theta);
    }
    let block = |rows: &[usize], columns: &[usize]| a.select_rows(rows).select_columns(columns);
    let a_ll = block(&linear_columns, &linear_columns);
    let a_ln = block(&linear_columns, &nonlinear_columns);
    let mut rhs = a_ln.clone().insert_column(a_ln.ncols(), 0.0);
    rhs.set_column(a_ln.ncols(), &b.select_rows(&linear_columns));
    // A_ll^+ [A_ln, b_l]: the best linear coefficients are y - X c_n.
    let solved = pseudo_solve_columns(&a_ll, &rhs);
    let x = solved.columns(0, a_ln.ncols()).into_owned();
    let y = solved.column(a_ln.ncols()).into_owned();
    let a_nl = a_ln.transpose();
    let reduced_a = block(&nonlinear_columns, &nonlinear_columns) - &a_nl * &x;
    let reduced_b = b.select_rows(&nonlinear_columns) - &a_nl * &y;
    let bodies: Vec<usize> = selected
        .iter()
        .copied()
        .filter(|&c| !candidates[c].shape.is_linear())
        .collect();
    let (body_theta, body_coefficients, _, _) = levenberg_marquardt(
        candidates,
        &bodies,
        &reduced_a,
        &reduced_b,
        theta.select_rows(&nonlinear_parameters),
    );
    let linear = y - x * body_coefficients;
    let mut theta = theta;
    let (mut at_linear, mut at_body, mut parameter) = (0, 0, 0);
    for &c in selected {
        let w = width(&candidates[c]);
        for k in parameter..parameter + w {
            if candidates[c].shape.is_linear() {
                theta[k] = linear[at_linear];
                at_linear += 1;
            } else {
                theta[k] = body_theta[at_body];
                at_body += 1;
            }
        }
        parameter += w;
    }
    let (coefficients, jacobian) = coefficients(candidates, selected, &theta);
    let value = coefficients.dot(&(a * &coefficients)) - 2.0 * coefficients.dot(b);
    (theta, coefficients, jacobian, value)
}

/// Levenberg-Marquardt from `theta` on the normal equations (a, b); one
/// exact step when every candidate is linear.
fn levenberg_marquardt(
    candidates: &[Candidate],
    selected: &[usize],
    a: &DMatrix<f64>,
    b: &DVector<f64>,
    mut theta: DVector<f64>,
) -> (DVector<f64>, DVector<f64>, DMatrix<f64>, f64) {
    let objective = |coefficients: &DVector<f64>| {
        coefficients.dot(&(a * coefficients)) - 2.0 * coefficients.dot(b)
    };
    let nonlinear = selected.iter().any(|&c| !candidates[c].shape.is_linear());
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
