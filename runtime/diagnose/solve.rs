//! Linear algebra of normal equations: solves by the pseudo-inverse, and a
//! least-squares problem in square-root form whose residual sum of squares
//! cannot go below zero.

use nalgebra::{DMatrix, DVector};

/// Under this share of the largest related column's size, a column is
/// rounding: the same description computed another way (compiled, or read
/// at run time) gives other digits there, never another value.
pub(super) const ROUNDING: f64 = 1e-9;

/// Smallest squared Cholesky pivot of a unit-diagonal matrix that
/// [`pseudo_solve`] trusts; below it the SVD decides what is singular.
pub(super) const CHOLESKY_PIVOT: f64 = 1e-8;

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

/// The least-squares problem SSE(c) = rr - 2 c^T b + c^T A c held as a
/// square-root factor F of its augmented matrix M = [[A, -b], [-b^T, rr]]
/// = F^T F: SSE(c) = |F [c; 1]|^2, a sum of squares, so never below zero.
///
/// M is a Gram matrix (of the columns and the residual), positive
/// semi-definite; but a cross-validation fold's moments are the total less
/// one group's, and eliminating the linear coefficients subtracts nearly
/// equal numbers again, so it can come out slightly indefinite. Expanded as
/// a quadratic, such an M gave sums of squares below zero and descent
/// directions that are rounding; here its factor drops the pivots that
/// are not positive (see [`semidefinite_cholesky`]), so F^T F is positive
/// semi-definite whatever M's rounding.
pub(super) struct SquareRoot {
    /// A and b as given when M was positive definite, else those of the
    /// repaired M (the descent's gradient and Hessian use them).
    pub(super) a: DMatrix<f64>,
    pub(super) b: DVector<f64>,
    factor: DMatrix<f64>,
}

impl SquareRoot {
    /// `None` when M holds a non-finite entry.
    pub(super) fn new(a: DMatrix<f64>, b: DVector<f64>, rr: f64) -> Option<SquareRoot> {
        let n = a.nrows();
        let augmented = DMatrix::from_fn(n + 1, n + 1, |i, j| match (i < n, j < n) {
            (true, true) => a[(i, j)],
            (true, false) => -b[i],
            (false, true) => -b[j],
            (false, false) => rr,
        });
        // Unit-diagonal scaling: the pivots are then relative to each
        // column's own size.
        let d: Vec<f64> = (0..=n)
            .map(|i| {
                let v = augmented[(i, i)];
                if v > 0.0 { v.sqrt() } else { 1.0 }
            })
            .collect();
        let scaled = DMatrix::from_fn(n + 1, n + 1, |i, j| augmented[(i, j)] / (d[i] * d[j]));
        if !scaled.iter().all(|x| x.is_finite()) {
            return None;
        }
        let (lower, dropped) = semidefinite_cholesky(&scaled);
        let factor = DMatrix::from_fn(n + 1, n + 1, |i, j| lower[(j, i)] * d[j]);
        if !dropped {
            return Some(SquareRoot { a, b, factor });
        }
        let repaired = factor.transpose() * &factor;
        Some(SquareRoot {
            a: repaired.view((0, 0), (n, n)).into_owned(),
            b: -repaired.view((0, n), (n, 1)).column(0).into_owned(),
            factor,
        })
    }

    /// The residual sum of squares at coefficients `c`.
    pub(super) fn sse(&self, c: &DVector<f64>) -> f64 {
        let n = c.len();
        let mut total = 0.0;
        for row in self.factor.row_iter() {
            let r = row.columns(0, n).dot(&c.transpose()) + row[n];
            total += r * r;
        }
        total
    }

    /// A c - b: the gradient of SSE / 2 in the coefficients.
    pub(super) fn excess(&self, c: &DVector<f64>) -> DVector<f64> {
        &self.a * c - &self.b
    }
}

/// The lower Cholesky factor L of the unit-diagonal symmetric `m`, each
/// pivot that is not positive taken as zero and its column left out (a
/// column that depends on the earlier ones in a positive semi-definite
/// matrix, or the negative part of one that rounding made indefinite), and
/// whether any was: L L^T is positive semi-definite, and equal to `m` to
/// rounding where nothing was dropped. A small positive pivot is kept: in
/// an ill-conditioned fit (a link's ten parameters at once) it can be real
/// information, and dropping those below 1e-14 moved a held-out error on
/// the Panda log by half.
fn semidefinite_cholesky(m: &DMatrix<f64>) -> (DMatrix<f64>, bool) {
    let n = m.nrows();
    let mut l = DMatrix::<f64>::zeros(n, n);
    let mut dropped = false;
    for k in 0..n {
        let pivot = m[(k, k)] - (0..k).map(|j| l[(k, j)] * l[(k, j)]).sum::<f64>();
        if pivot <= 0.0 {
            // A zero column (a candidate column these data never excite)
            // drops nothing.
            dropped |= m[(k, k)] != 0.0;
            continue;
        }
        let root = pivot.sqrt();
        l[(k, k)] = root;
        for i in k + 1..n {
            let inner: f64 = (0..k).map(|j| l[(i, j)] * l[(k, j)]).sum();
            l[(i, k)] = (m[(i, k)] - inner) / root;
        }
    }
    (l, dropped)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Columns X and a residual r in the span of X: the exact fit's sum of
    /// squares is zero, and the fold's subtraction makes the computed M
    /// indefinite at rounding level; the sum of squares stays >= 0.
    #[test]
    fn the_sum_of_squares_is_never_negative() {
        let x = DMatrix::from_fn(40, 3, |i, j| ((i * (j + 2)) as f64 * 0.37).sin());
        let r = &x * DVector::from_vec(vec![0.3, -1.1, 2.0]);
        let (a, b, rr) = (x.transpose() * &x, x.transpose() * &r, r.dot(&r));
        // An indefinite copy: the rr entry a hair below the fit's explained sum.
        let problem = SquareRoot::new(a.clone(), b.clone(), rr * (1.0 - 1e-9)).unwrap();
        let best = pseudo_solve(&a, &b);
        let expanded = rr * (1.0 - 1e-9) - 2.0 * best.dot(&b) + best.dot(&(&a * &best));
        assert!(expanded < 0.0, "{expanded}");
        assert!(problem.sse(&best) >= 0.0);
        assert!(problem.sse(&best) < 1e-8 * rr);
        // A definite problem keeps its numbers.
        let definite = SquareRoot::new(a.clone(), b.clone(), 2.0 * rr).unwrap();
        assert_eq!(definite.a, a);
        let c = DVector::from_vec(vec![1.0, 0.5, -0.2]);
        let direct = 2.0 * rr - 2.0 * c.dot(&b) + c.dot(&(&a * &c));
        assert!((definite.sse(&c) - direct).abs() < 1e-12 * direct);
    }
}
