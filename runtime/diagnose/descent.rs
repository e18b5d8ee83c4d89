//! The descent of the nonlinear candidates' parameters (a body's mass and
//! COM, a first moment, a tilt) on the least-squares problem of their
//! column coefficients: damped Newton steps (Levenberg-Marquardt), each
//! body's mass solved exactly for the COM the step reaches.

use nalgebra::{DMatrix, DVector};

use super::candidate::{Candidate, Shape, width};
use super::shape::point_mass;
use super::solve::{SquareRoot, pseudo_solve};

/// Most steps of one descent. Converged descents take a handful; the cap
/// stops one that cannot settle (a flat valley of rounding).
const MAX_STEPS: usize = 200;

/// Levenberg-Marquardt from parameters `theta` (concatenated in `selected`
/// order) on `problem`, with the bodies' masses projected (see
/// [`project_masses`]) at the start and after every step. Returns the
/// parameters, the column coefficients and the residual sum of squares.
pub(super) fn levenberg_marquardt(
    candidates: &[Candidate],
    selected: &[usize],
    problem: &SquareRoot,
    theta: &DVector<f64>,
) -> (DVector<f64>, DVector<f64>, f64) {
    let mut theta = theta.clone();
    project_masses(candidates, selected, problem, &mut theta);
    let (mut coef, mut jacobian) = coefficients(candidates, selected, &theta);
    let mut value = problem.sse(&coef);
    // What no coefficient explains: the reference of the convergence test.
    let unexplained = problem.sse(&DVector::zeros(coef.len()));
    let mut lambda = 1e-3;
    for _ in 0..MAX_STEPS {
        let excess = problem.excess(&coef);
        let gradient = -(jacobian.transpose() * &excess);
        let hessian = jacobian.transpose() * &problem.a * &jacobian;
        let step = newton_step(
            candidates, selected, &theta, &excess, &hessian, &gradient, lambda,
        );
        let mut trial = &theta + &step;
        project_masses(candidates, selected, problem, &mut trial);
        let (trial_coef, trial_jacobian) = coefficients(candidates, selected, &trial);
        let trial_value = problem.sse(&trial_coef);
        if trial_value < value {
            let decrease = value - trial_value;
            (theta, coef, jacobian, value) = (trial, trial_coef, trial_jacobian, trial_value);
            lambda = (lambda / 3.0).max(1e-12);
            // Converged when a step gains less than 1e-10 of what the
            // coefficients explain: far below the noise of any torque
            // measurement.
            if decrease <= 1e-10 * (unexplained - value).abs().max(1e-300) {
                break;
            }
        } else {
            lambda *= 4.0;
            if lambda > 1e12 {
                break;
            }
        }
    }
    (theta, coef, value)
}

/// Sets each body's mass to the one that minimizes the sum of squares with
/// everything else held: at a fixed COM a body's coefficients are linear in
/// its mass (m point_mass(1, c) + offset), so the masses solve a small
/// linear system exactly and the descent moves the COMs (and the other
/// nonlinear parameters) alone. Along the valley in which a body trades
/// mass for lever arm the mass then follows the COM at once, where damped
/// steps in both crawled.
fn project_masses(
    candidates: &[Candidate],
    selected: &[usize],
    problem: &SquareRoot,
    theta: &mut DVector<f64>,
) {
    let mut bodies = Vec::new();
    let (mut row, mut col) = (0, 0);
    for &c in selected {
        if let Shape::Body { offset, .. } = &candidates[c].shape {
            let com = nalgebra::Vector3::new(theta[col + 1], theta[col + 2], theta[col + 3]);
            bodies.push((row, col, point_mass(1.0, &com), *offset));
        }
        row += candidates[c].columns.len();
        col += width(&candidates[c]);
    }
    if bodies.is_empty() {
        return;
    }
    let (coefficients, _) = coefficients(candidates, selected, theta);
    let mut held = coefficients;
    let mut units = DMatrix::zeros(held.len(), bodies.len());
    for (k, (row, _, unit, offset)) in bodies.iter().enumerate() {
        for i in 0..10 {
            held[row + i] = offset[i];
            units[(row + i, k)] = unit[i];
        }
    }
    let lhs = units.transpose() * &problem.a * &units;
    let rhs = units.transpose() * problem.excess(&held);
    let masses = pseudo_solve(&lhs, &(-rhs));
    if masses.iter().all(|m| m.is_finite()) {
        for (k, (_, col, _, _)) in bodies.iter().enumerate() {
            theta[*col] = masses[k];
        }
    }
}

/// Column coefficients ([`super::candidate::columns_of`] order) and their
/// Jacobian for the `selected` candidates' concatenated parameters.
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
        let w = width(&candidates[c]);
        let (values, d) = candidates[c].shape.map(&theta.as_slice()[col..col + w]);
        coefficients
            .rows_mut(row, values.len())
            .copy_from_slice(&values);
        jacobian
            .view_mut((row, col), (values.len(), w))
            .copy_from(&d);
        row += values.len();
        col += w;
    }
    (coefficients, jacobian)
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

/// Block-diagonal sum of each coefficient's Hessian in the parameters
/// weighted by `weights` (one per coefficient, in column order).
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
        let (w, n) = (width(candidate), candidate.columns.len());
        let block = candidate.shape.curvature(
            &theta.as_slice()[col..col + w],
            &weights.as_slice()[row..row + n],
        );
        total.view_mut((col, col), (w, w)).copy_from(&block);
        row += n;
        col += w;
    }
    total
}
