//! The descent of the nonlinear candidates' parameters (a body's mass and
//! COM, a first moment, a tilt) on the least-squares problem of their
//! column coefficients: damped Newton steps (Levenberg-Marquardt), each
//! body's mass solved exactly for the COM the step reaches.

use nalgebra::{DMatrix, DVector, Vector3};

use super::candidate::{Candidate, Shape, width};
use super::shape::point_mass;
use super::solve::{SquareRoot, pseudo_solve};

/// Most steps of one descent. Converged descents take a handful; the cap
/// stops one that cannot settle (a flat valley of rounding).
const MAX_STEPS: usize = 200;

/// Where a descent ended.
pub(super) struct Descent {
    pub(super) theta: DVector<f64>,
    /// The column coefficients at `theta`.
    pub(super) coefficients: DVector<f64>,
    /// The residual sum of squares there.
    pub(super) sse: f64,
    /// Steps tried, accepted or not (what the tests hold the descent to).
    #[cfg_attr(not(test), expect(dead_code))]
    pub(super) steps: usize,
}

/// Levenberg-Marquardt from parameters `theta` (concatenated in `selected`
/// order) on `problem`, with the bodies' masses projected (see
/// [`project_masses`]) at the start and after every step.
pub(super) fn levenberg_marquardt(
    candidates: &[Candidate],
    selected: &[usize],
    problem: &SquareRoot,
    theta: &DVector<f64>,
) -> Descent {
    let mut theta = theta.clone();
    project_masses(candidates, selected, problem, &mut theta);
    let (mut coef, mut jacobian) = coefficients(candidates, selected, &theta);
    let mut value = problem.sse(&coef);
    // What no coefficient explains: the reference of the convergence test.
    let unexplained = problem.sse(&DVector::zeros(coef.len()));
    let mut lambda = 1e-3;
    let mut steps = 0;
    // The quadratic model at `theta`, kept while steps are refused (only
    // the damping changes then).
    let mut model: Option<Model> = None;
    while steps < MAX_STEPS {
        steps += 1;
        let local = model.get_or_insert_with(|| {
            Model::at(candidates, selected, problem, (&theta, &coef, &jacobian))
        });
        let step = local.step(lambda);
        let mut trial = &theta + &step;
        project_masses(candidates, selected, problem, &mut trial);
        let (trial_coef, trial_jacobian) = coefficients(candidates, selected, &trial);
        let trial_value = problem.sse(&trial_coef);
        // Converged when a step gains less than 1e-10 of what the
        // coefficients explain: far below the noise of any torque
        // measurement.
        let negligible = 1e-10 * (unexplained - value).abs().max(1e-300);
        if trial_value < value {
            let decrease = value - trial_value;
            (theta, coef, jacobian, value) = (trial, trial_coef, trial_jacobian, trial_value);
            model = None;
            lambda = (lambda / 3.0).max(1e-12);
            if decrease <= negligible {
                break;
            }
        } else {
            // Refused, and neither this step nor the model promise a
            // gain: the descent is at its optimum to rounding, where
            // raising the damping would only shorten the step (MINPACK's
            // relative-reduction test).
            if value - trial_value >= -negligible && local.predicted(&step) <= negligible {
                break;
            }
            lambda *= 4.0;
            if lambda > 1e12 {
                break;
            }
        }
    }
    Descent {
        theta,
        coefficients: coef,
        sse: value,
        steps,
    }
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
        if let Shape::Body { .. } = &candidates[c].shape {
            let com = Vector3::new(theta[col + 1], theta[col + 2], theta[col + 3]);
            // Everything but the mass term is held.
            let w = width(&candidates[c]);
            let held = candidates[c].shape.held(&theta.as_slice()[col..col + w]);
            bodies.push((row, col, point_mass(1.0, &com), held));
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
    for (k, (row, _, unit, held_terms)) in bodies.iter().enumerate() {
        for i in 0..10 {
            held[row + i] = held_terms[i];
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

/// The least-squares problem's quadratic model in the parameters at one
/// point: SSE(theta + s) ~ SSE - 2 gradient.s + s^T H s.
struct Model {
    /// Half the negative gradient of the sum of squares.
    gradient: DVector<f64>,
    /// J^T A J, the Gauss-Newton Hessian (half the sum's).
    gauss_newton: DMatrix<f64>,
    /// The Gauss-Newton Hessian plus the coefficients' curvature weighted
    /// by the residual's excess (A c - b): the exact Hessian.
    newton: DMatrix<f64>,
}

impl Model {
    /// The model at `theta`, whose coefficients and their Jacobian are
    /// `coef` and `jacobian`.
    fn at(
        candidates: &[Candidate],
        selected: &[usize],
        problem: &SquareRoot,
        (theta, coef, jacobian): (&DVector<f64>, &DVector<f64>, &DMatrix<f64>),
    ) -> Model {
        let excess = problem.excess(coef);
        let gauss_newton = jacobian.transpose() * &problem.a * jacobian;
        let newton = &gauss_newton + curvature(candidates, selected, theta, &excess);
        Model {
            gradient: -(jacobian.transpose() * &excess),
            gauss_newton,
            newton,
        }
    }

    /// The decrease of the sum of squares the Gauss-Newton model predicts
    /// for `step`.
    fn predicted(&self, step: &DVector<f64>) -> f64 {
        2.0 * self.gradient.dot(step) - step.dot(&(&self.gauss_newton * step))
    }

    /// A damped Newton step: the exact Hessian with Marquardt's damping
    /// `lambda`; where that is not positive definite (far from a minimum),
    /// the damped Gauss-Newton step, which always descends.
    fn step(&self, lambda: f64) -> DVector<f64> {
        // A parameter nothing depends on (a held COM axis) has no gradient:
        // a unit diagonal keeps its step zero and the Hessian invertible.
        let damping = DMatrix::from_diagonal(&self.gauss_newton.diagonal().map(|d| match d {
            0.0 => 1.0,
            d => d * lambda,
        }));
        if let Some(cholesky) = (&self.newton + &damping).cholesky() {
            return cholesky.solve(&self.gradient);
        }
        pseudo_solve(&(&self.gauss_newton + damping), &self.gradient)
    }
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

#[cfg(test)]
mod tests {
    use super::super::kind::Kind;
    use super::*;

    /// A link's ten columns over 400 samples in which the mass column is
    /// nearly the first moment's x column (the origin barely accelerates
    /// apart from along the lever): the data fix m c far better than m, the
    /// valley along which a body trades mass for lever arm.
    fn valley_columns() -> Vec<DVector<f64>> {
        let wave = |k: usize, i: usize| ((i * (2 * k + 3)) as f64 * 0.0137 + k as f64).sin();
        let mut columns: Vec<DVector<f64>> = (0..10)
            .map(|k| DVector::from_fn(400, |i, _| wave(k, i)))
            .collect();
        columns[0] = &columns[1] * 0.2 + DVector::from_fn(400, |i, _| 1e-3 * wave(11, i));
        columns
    }

    #[test]
    fn a_body_in_the_mass_lever_valley_reaches_its_optimum_in_a_few_steps() {
        let columns = valley_columns();
        let (m0, c0) = (1.0, Vector3::new(0.0, 0.0, 0.1));
        let offset = point_mass(-m0, &c0);
        let truth = (2.5, Vector3::new(0.12, -0.04, 0.05));
        let change = point_mass(truth.0, &truth.1);
        let x = DMatrix::from_columns(&columns);
        // Torque no body explains, as real residuals have: the objective's
        // curvature in (m, c) is then not the Gauss-Newton one.
        let unexplained = DVector::from_fn(400, |i, _| 3.0 * ((i * 29) as f64 * 0.0071).cos());
        let r = &x * DVector::from_fn(10, |k, _| change[k] + offset[k]) + unexplained;
        let problem = SquareRoot::new(x.transpose() * &x, x.transpose() * &r, r.dot(&r)).unwrap();
        let body = Candidate {
            shape: Shape::Body {
                offset,
                base_mass: m0,
                base_moment: c0 * m0,
                own_inertia: false,
                held_com: None,
            },
            names: vec!["mass", "cx", "cy", "cz"],
            columns,
            ..super::super::candidate::linear(Kind::InertialError, DVector::zeros(400))
        };
        let start = DVector::from_vec(vec![m0, c0.x, c0.y, c0.z]);
        let candidates = [body];
        let end = levenberg_marquardt(&candidates, &[0], &problem, &start);
        // At the least-squares optimum: no parameter's gradient is left
        // beyond rounding of what the body explains.
        let (_, jacobian) = coefficients(&candidates, &[0], &end.theta);
        let gradient = jacobian.transpose() * problem.excess(&end.coefficients);
        let scale = (jacobian.transpose() * &problem.b).amax();
        assert!(gradient.amax() < 1e-8 * scale, "{gradient} {scale}");
        assert!(end.sse >= 0.0);
        // Without the masses' projection the same descent takes 15 steps.
        assert!(end.steps <= 10, "{} steps", end.steps);
    }
}
