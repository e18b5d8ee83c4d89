//! Eigenvalues of the symmetric information matrices the search compares,
//! without eigenvectors: a Householder reduction to tridiagonal form, then
//! bisection on Sturm counts. The search needs thousands of spectra and no
//! vectors, which took most of a decomposition's time; bisection ends after
//! a bounded number of halvings whatever the input, so, as with
//! [`crate::kernels`], a bad matrix is a `None`, never a loop that does not end.

use nalgebra::DMatrix;
use nalgebra::linalg::SymmetricTridiagonal;

/// Most halvings of one bisection: an f64 interval is down to rounding
/// after about 1100 from the largest to the smallest magnitudes.
const HALVINGS: usize = 1100;

/// The diagonal and off-diagonal of the tridiagonal form of symmetric `m`
/// (its lower triangle is read), or `None` for an empty, non-square or
/// non-finite matrix.
fn tridiagonal(m: &DMatrix<f64>) -> Option<(Vec<f64>, Vec<f64>)> {
    if m.nrows() == 0 || !m.is_square() || m.iter().any(|x| !x.is_finite()) {
        return None;
    }
    if m.nrows() == 1 {
        return Some((vec![m[(0, 0)]], Vec::new()));
    }
    let (d, e) = SymmetricTridiagonal::new(m.clone()).unpack_tridiagonal();
    Some((d.as_slice().to_vec(), e.as_slice().to_vec()))
}

/// How many eigenvalues of the tridiagonal (d, e) lie below x (Sturm).
fn below(d: &[f64], e: &[f64], x: f64, tiny: f64) -> usize {
    let mut count = 0;
    let mut q = 1.0;
    for i in 0..d.len() {
        let coupling = if i > 0 { e[i - 1] * e[i - 1] / q } else { 0.0 };
        q = d[i] - x - coupling;
        // A zero pivot is moved off zero by the smallest amount that keeps
        // the next division finite (LAPACK's pivmin).
        if q.abs() < tiny {
            q = -tiny;
        }
        if q < 0.0 {
            count += 1;
        }
    }
    count
}

/// The k-th smallest eigenvalue (from 0) of the tridiagonal (d, e).
fn kth(d: &[f64], e: &[f64], k: usize) -> f64 {
    let n = d.len();
    let off = |i: usize| {
        (if i > 0 { e[i - 1].abs() } else { 0.0 }) + (if i + 1 < n { e[i].abs() } else { 0.0 })
    };
    // Gershgorin's discs hold every eigenvalue.
    let mut lo = (0..n).map(|i| d[i] - off(i)).fold(f64::INFINITY, f64::min);
    let mut hi = (0..n)
        .map(|i| d[i] + off(i))
        .fold(f64::NEG_INFINITY, f64::max);
    let scale = lo.abs().max(hi.abs()).max(f64::MIN_POSITIVE);
    let tiny = f64::MIN_POSITIVE * e.iter().map(|x| x * x).fold(1.0, f64::max);
    for _ in 0..HALVINGS {
        let mid = 0.5 * (lo + hi);
        if hi - lo <= 4.0 * f64::EPSILON * scale || mid <= lo || mid >= hi {
            break;
        }
        if below(d, e, mid, tiny) > k {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The smallest and the largest eigenvalue of symmetric `m`.
pub fn extremes(m: &DMatrix<f64>) -> Option<(f64, f64)> {
    let (d, e) = tridiagonal(m)?;
    Some((kth(&d, &e, 0), kth(&d, &e, d.len() - 1)))
}

/// Every eigenvalue of symmetric `m`, ascending.
pub fn eigenvalues(m: &DMatrix<f64>) -> Option<Vec<f64>> {
    let (d, e) = tridiagonal(m)?;
    Some((0..d.len()).map(|k| kth(&d, &e, k)).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn random_symmetric(n: usize, spread: f64) -> DMatrix<f64> {
        let a = DMatrix::from_fn(n, n, |r, c| ((r * 31 + c * 17) as f64 * 0.37).sin());
        let g = a.transpose() * &a;
        let d = DMatrix::from_fn(n, n, |r, c| {
            if r == c {
                spread.powf(r as f64 / n as f64)
            } else {
                0.0
            }
        });
        &d * g * &d
    }

    #[test]
    fn they_agree_with_the_full_decomposition() {
        for (n, spread) in [(1, 1.0), (2, 3.0), (7, 10.0), (40, 1e4), (76, 1e6)] {
            let m = random_symmetric(n, spread);
            let mut full: Vec<f64> = crate::kernels::symmetric_eigenvalues(m.clone())
                .unwrap()
                .iter()
                .copied()
                .collect();
            full.sort_by(f64::total_cmp);
            let ours = eigenvalues(&m).unwrap();
            let top = full[n - 1].abs();
            for (a, b) in ours.iter().zip(&full) {
                assert!((a - b).abs() <= 1e-11 * top, "n {n}: {a} against {b}");
            }
            let (lo, hi) = extremes(&m).unwrap();
            assert_eq!((lo, hi), (ours[0], ours[n - 1]));
        }
    }

    #[test]
    fn a_repeated_eigenvalue_and_a_zero_one_are_found() {
        let m = DMatrix::from_diagonal(&nalgebra::DVector::from_vec(vec![2.0, 0.0, 2.0, 5.0]));
        let e = eigenvalues(&m).unwrap();
        for (a, b) in e.iter().zip([0.0, 2.0, 2.0, 5.0]) {
            assert!((a - b).abs() < 1e-14, "{e:?}");
        }
    }

    #[test]
    fn bad_matrices_are_refused() {
        assert!(eigenvalues(&DMatrix::zeros(0, 0)).is_none());
        assert!(eigenvalues(&DMatrix::from_element(2, 2, f64::NAN)).is_none());
        assert!(extremes(&DMatrix::zeros(2, 3)).is_none());
    }
}
