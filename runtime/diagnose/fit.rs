//! Least-squares fits of candidate effects from the moments: linear
//! candidates exactly, bodies by Levenberg-Marquardt on what the linear
//! ones leave (see [`super::descent`]), and how well the data determine the
//! fitted parameters.

use nalgebra::{DMatrix, DVector, Vector3};

use super::candidate::{Candidate, Shape, columns_of, width};
use super::descent::{coefficients, levenberg_marquardt};
use super::moments::Moments;
use super::settings::COLLINEAR;
use super::shape::holds;
use super::solve::{SquareRoot, pseudo_solve, pseudo_solve_columns};
use crate::parallel::map_in_order;

/// A least-squares fit of some candidates.
pub(super) struct Fit {
    /// The candidates' parameters, concatenated in selection order.
    pub(super) theta: DVector<f64>,
    /// Coefficients of their columns ([`columns_of`] order).
    pub(super) coefficients: DVector<f64>,
    /// Information matrix J^T J at `theta`, J the residual's Jacobian.
    pub(super) information: DMatrix<f64>,
    /// d coefficients / d theta at `theta`.
    pub(super) jacobian: DMatrix<f64>,
}

/// Fits the `selected` candidates on the groups `keep` accepts: linear
/// candidates exactly, bodies by Levenberg-Marquardt from the linear fit of
/// their mass and first-moment columns and from the model's body, the
/// better end kept. `None` when there are no data.
pub(super) fn fit(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
    keep: impl Fn(usize) -> bool,
) -> Option<Fit> {
    fit_with(m, candidates, selected, keep, None)
}

/// [`fit`] on a part of the data (a cross-validation fold) whose bodies
/// descend from `near`, the parameters fitted on all of it: the fold's
/// optimum lies close to the whole data's, which more data determine
/// better than either cold start, and the descent from there takes a few
/// steps where the two cold ones took tens. Linear candidates are solved
/// exactly as in [`fit`].
pub(super) fn fit_near(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
    keep: impl Fn(usize) -> bool,
    near: &DVector<f64>,
) -> Option<Fit> {
    fit_with(m, candidates, selected, keep, Some(near))
}

/// Whether a fit of `selected` descends (some candidate is not linear in
/// its parameters).
pub(super) fn is_nonlinear(candidates: &[Candidate], selected: &[usize]) -> bool {
    selected.iter().any(|&c| !candidates[c].shape.is_linear())
}

fn fit_with(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
    keep: impl Fn(usize) -> bool,
    near: Option<&DVector<f64>>,
) -> Option<Fit> {
    let columns = columns_of(candidates, selected);
    let (a, b) = m.normal_equations(&columns, &keep);
    let rr = m.residual_sum(&keep);
    if a.nrows() > 0 && a.diagonal().iter().all(|v| *v == 0.0) {
        return None;
    }
    let nonlinear = is_nonlinear(candidates, selected);
    let starts = match near {
        Some(near) if nonlinear => vec![near.clone()],
        _ => starts(candidates, selected, &a, &b),
    };
    let (theta, coef, jacobian) = if nonlinear {
        let reduced = reduce(candidates, selected, (&a, &b, rr))?;
        map_in_order(&starts, |start| {
            descend(candidates, selected, &reduced, start.clone())
        })
        .into_iter()
        .min_by(|x, y| x.3.total_cmp(&y.3))
        .map(|(t, c, j, _)| (t, c, j))?
    } else {
        let start = starts.into_iter().next()?;
        linear(candidates, selected, &a, &b, start)
    };
    let information = jacobian.transpose() * &a * &jacobian;
    Some(Fit {
        theta,
        coefficients: coef,
        information,
        jacobian,
    })
}

/// The cold starts of a fit: the linear fit of every linear column and of
/// each body's mass and first-moment columns; and, where some body has a
/// modelled mass, every body as modelled.
fn starts(
    candidates: &[Candidate],
    selected: &[usize],
    a: &DMatrix<f64>,
    b: &DVector<f64>,
) -> Vec<DVector<f64>> {
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
                own_inertia,
                held_com,
                ..
            } => {
                let mass = base_mass + x0[at];
                let moment = base_moment + Vector3::new(x0[at + 1], x0[at + 2], x0[at + 3]);
                let mut com = if mass.abs() > 1e-9 {
                    moment / mass
                } else {
                    Vector3::zeros()
                };
                // A held axis stays where the model has it (the descent
                // never moves it).
                for a in (0..3).filter(|&a| holds(held_com, a)) {
                    com[a] = base_moment[a] / base_mass;
                }
                theta.extend([mass, com.x, com.y, com.z]);
                if *own_inertia {
                    theta.push(0.0);
                }
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
    starts
}

/// The least-squares problem of the nonlinear candidates' coefficients
/// alone: the linear candidates' coefficients eliminated exactly (variable
/// projection: for given nonlinear coefficients the best linear ones solve
/// a linear system, which leaves a least-squares problem in the nonlinear
/// coefficients alone, their Schur complement). Linear parameters collinear
/// with a body's columns (a neighbouring link's whole-body error) made a
/// joint descent crawl. The same for every start of a fit.
struct Reduced {
    /// The nonlinear candidates, in selection order, and where their
    /// parameters sit among all of them.
    bodies: Vec<usize>,
    nonlinear_parameters: Vec<usize>,
    /// The best linear coefficients are y - x c for nonlinear coefficients c.
    x: DMatrix<f64>,
    y: DVector<f64>,
    problem: SquareRoot,
}

/// The [`Reduced`] problem of normal equations (a, b) with the residual's
/// sum of squares `rr`; `None` when every candidate is linear or the
/// problem is not finite.
fn reduce(
    candidates: &[Candidate],
    selected: &[usize],
    (a, b, rr): (&DMatrix<f64>, &DVector<f64>, f64),
) -> Option<Reduced> {
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
    if nonlinear_columns.is_empty() {
        return None;
    }
    let block = |rows: &[usize], columns: &[usize]| a.select_rows(rows).select_columns(columns);
    let a_ll = block(&linear_columns, &linear_columns);
    let a_ln = block(&linear_columns, &nonlinear_columns);
    let mut rhs = a_ln.clone().insert_column(a_ln.ncols(), 0.0);
    let b_l = b.select_rows(&linear_columns);
    rhs.set_column(a_ln.ncols(), &b_l);
    // A_ll^+ [A_ln, b_l]: the best linear coefficients are y - X c_n.
    let solved = pseudo_solve_columns(&a_ll, &rhs);
    let x = solved.columns(0, a_ln.ncols()).into_owned();
    let y = solved.column(a_ln.ncols()).into_owned();
    let a_nl = a_ln.transpose();
    let problem = SquareRoot::new(
        block(&nonlinear_columns, &nonlinear_columns) - &a_nl * &x,
        b.select_rows(&nonlinear_columns) - &a_nl * &y,
        rr - b_l.dot(&y),
    )?;
    let bodies = selected
        .iter()
        .copied()
        .filter(|&c| !candidates[c].shape.is_linear())
        .collect();
    Some(Reduced {
        bodies,
        nonlinear_parameters,
        x,
        y,
        problem,
    })
}

/// The least-squares fit from `theta`: Levenberg-Marquardt on the reduced
/// problem, then the linear coefficients that go with it. Returns the
/// parameters, the column coefficients, their Jacobian and the residual
/// sum of squares.
fn descend(
    candidates: &[Candidate],
    selected: &[usize],
    reduced: &Reduced,
    theta: DVector<f64>,
) -> (DVector<f64>, DVector<f64>, DMatrix<f64>, f64) {
    let end = levenberg_marquardt(
        candidates,
        &reduced.bodies,
        &reduced.problem,
        &theta.select_rows(&reduced.nonlinear_parameters),
    );
    let linear = &reduced.y - &reduced.x * end.coefficients;
    let mut theta = theta;
    let (mut at_linear, mut at_body, mut parameter) = (0, 0, 0);
    for &c in selected {
        let w = width(&candidates[c]);
        for k in parameter..parameter + w {
            if candidates[c].shape.is_linear() {
                theta[k] = linear[at_linear];
                at_linear += 1;
            } else {
                theta[k] = end.theta[at_body];
                at_body += 1;
            }
        }
        parameter += w;
    }
    let (coefficients, jacobian) = coefficients(candidates, selected, &theta);
    (theta, coefficients, jacobian, end.sse)
}

/// The exact least-squares step from `theta` when every candidate is
/// linear (the parameters are the coefficients).
fn linear(
    candidates: &[Candidate],
    selected: &[usize],
    a: &DMatrix<f64>,
    b: &DVector<f64>,
    theta: DVector<f64>,
) -> (DVector<f64>, DVector<f64>, DMatrix<f64>) {
    let (coef, jacobian) = coefficients(candidates, selected, &theta);
    let gradient = -(jacobian.transpose() * (a * &coef - b));
    let hessian = jacobian.transpose() * a * &jacobian;
    let trial = &theta + pseudo_solve(&hessian, &gradient);
    let (coef, jacobian) = coefficients(candidates, selected, &trial);
    (trial, coef, jacobian)
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
