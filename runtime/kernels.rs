//! Bounded numerical kernels. nalgebra's iterative decompositions (SVD,
//! symmetric eigenvalues) loop until they converge by default; on finite
//! input they converge in a few dozen sweeps, on non-finite input they may
//! never. Every iterative decomposition in the runtime goes through here:
//! non-finite input is refused and the iterations are capped, so a bad
//! matrix is a `None` the caller handles, never a hang.

use nalgebra::{DMatrix, DVector, SVD, SymmetricEigen};

/// Iteration cap of the decompositions: far above what a finite matrix of
/// the sizes used here needs (tens), far below a noticeable wait.
pub const MAX_ITERATIONS: usize = 100_000;

fn finite(m: &DMatrix<f64>) -> bool {
    m.iter().all(|x| x.is_finite())
}

/// The SVD of `m` (U and V computed), or `None` when `m` holds a non-finite
/// entry or the iterations do not converge.
pub fn svd(m: DMatrix<f64>) -> Option<SVD<f64, nalgebra::Dyn, nalgebra::Dyn>> {
    if !finite(&m) {
        return None;
    }
    SVD::try_new(m, true, true, f64::EPSILON, MAX_ITERATIONS)
}

/// The eigenvalues of the symmetric matrix `m` (its lower triangle is
/// read), or `None` when `m` holds a non-finite entry or the iterations do
/// not converge.
pub fn symmetric_eigenvalues(m: DMatrix<f64>) -> Option<DVector<f64>> {
    symmetric_eigen(m).map(|e| e.eigenvalues)
}

/// The eigen-decomposition of the symmetric matrix `m` (its lower triangle
/// is read), with the same guarantees.
pub fn symmetric_eigen(m: DMatrix<f64>) -> Option<SymmetricEigen<f64, nalgebra::Dyn>> {
    if !finite(&m) || !m.is_square() {
        return None;
    }
    SymmetricEigen::try_new(m, f64::EPSILON, MAX_ITERATIONS)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn non_finite_matrices_are_refused_not_iterated() {
        let m = DMatrix::from_row_slice(2, 2, &[1.0, f64::NAN, 0.0, 1.0]);
        assert!(svd(m.clone()).is_none());
        assert!(symmetric_eigenvalues(m).is_none());
        let inf = DMatrix::from_element(3, 3, f64::INFINITY);
        assert!(svd(inf.clone()).is_none());
        assert!(symmetric_eigenvalues(inf).is_none());
    }

    #[test]
    fn finite_matrices_decompose_as_nalgebra_does() {
        let m = DMatrix::from_row_slice(3, 3, &[4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0]);
        let ours = symmetric_eigenvalues(m.clone()).unwrap();
        let reference = m.clone().symmetric_eigenvalues();
        for (a, b) in ours.iter().zip(reference.iter()) {
            assert!((a - b).abs() < 1e-12);
        }
        let s = svd(m.clone()).unwrap();
        let back = s.recompose().unwrap();
        assert!((back - m).norm() < 1e-12);
    }

    #[test]
    fn extreme_but_finite_scales_still_converge() {
        let m = DMatrix::from_fn(6, 6, |i, j| {
            if i == j {
                10f64.powi(3 * i as i32 - 9)
            } else {
                1e-12
            }
        });
        assert!(svd(m.clone()).is_some());
        assert!(symmetric_eigenvalues(m).is_some());
    }
}
