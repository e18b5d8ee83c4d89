//! The trainer's two dense kernels beyond nalgebra: a strided matrix
//! product through matrixmultiply (a transpose costs nothing) and a
//! vectorizable sum.

use nalgebra::DMatrix;

/// Whether a factor of [`multiply`] enters transposed.
#[derive(Clone, Copy, PartialEq)]
pub(super) enum Transposed {
    Yes,
    No,
}

/// `c = op(a) op(b)` by matrixmultiply's blocked kernel, a transpose taken
/// by swapping strides (no copy); nalgebra's own `gemm_tr` is a loop of dot
/// products.
pub(super) fn multiply(
    c: &mut DMatrix<f64>,
    (a, ta): (&DMatrix<f64>, Transposed),
    (b, tb): (&DMatrix<f64>, Transposed),
) {
    // (rows, columns, row stride, column stride) of op(x), column-major x.
    let layout = |x: &DMatrix<f64>, t: Transposed| {
        let (r, k) = (x.nrows(), x.ncols());
        match t {
            Transposed::No => (r, k, 1, r as isize),
            Transposed::Yes => (k, r, r as isize, 1),
        }
    };
    let (m, k, rsa, csa) = layout(a, ta);
    let (kb, n, rsb, csb) = layout(b, tb);
    assert!(
        k == kb && c.nrows() == m && c.ncols() == n,
        "multiply: shapes do not match"
    );
    // SAFETY: the shapes are checked above, so every index the kernel forms
    // from (m, k, n) and these strides lies inside its (dense, column-major)
    // matrix; `c` is borrowed mutably and cannot alias `a` or `b`.
    unsafe {
        matrixmultiply::dgemm(
            m,
            k,
            n,
            1.0,
            a.as_ptr(),
            rsa,
            csa,
            b.as_ptr(),
            rsb,
            csb,
            0.0,
            c.as_mut_ptr(),
            1,
            m as isize,
        );
    }
}

/// Sum with four running totals (vectorizable, unlike a strict left fold).
pub(super) fn sum(x: &[f64]) -> f64 {
    let mut totals = [0.0; 4];
    let chunks = x.chunks_exact(4);
    let rest: f64 = chunks.remainder().iter().sum();
    for chunk in chunks {
        for (t, v) in totals.iter_mut().zip(chunk) {
            *t += v;
        }
    }
    (totals[0] + totals[2]) + (totals[1] + totals[3]) + rest
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strided_products_equal_nalgebras() {
        let a = DMatrix::from_fn(5, 3, |r, c| (r * 3 + c) as f64 * 0.3 - 1.0);
        let b = DMatrix::from_fn(5, 4, |r, c| ((r + 2 * c) as f64).sin());
        let mut c = DMatrix::zeros(3, 4);
        multiply(&mut c, (&a, Transposed::Yes), (&b, Transposed::No));
        assert!((c - a.transpose() * &b).amax() < 1e-12);
        let w = DMatrix::from_fn(4, 3, |r, c| (r as f64 - c as f64) * 0.7);
        let mut d = DMatrix::zeros(5, 3);
        multiply(
            &mut d,
            (&b, Transposed::No),
            (&w.transpose(), Transposed::Yes),
        );
        assert!((d - &b * &w).amax() < 1e-12);
    }

    #[test]
    fn the_sum_matches_a_fold_for_any_length() {
        for n in 0..13 {
            let x: Vec<f64> = (0..n).map(|k| f64::from(k) * 0.25).collect();
            assert!((sum(&x) - x.iter().sum::<f64>()).abs() < 1e-12);
        }
    }
}
