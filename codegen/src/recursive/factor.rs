//! M = L D L^T, traced: the factor forward dynamics and `solve_mass` use.
//! A symmetric positive definite M needs no pivoting; each pivot's
//! reciprocal is taken once and multiplies its column.

use crate::program::{Dag, NodeId};

/// The LDL^T factor of the symmetric n x n `m` (row-major) as one n x n
/// matrix: L strictly below the diagonal (its unit diagonal implied), 1/D
/// on the diagonal, zeros above.
pub fn ldlt(dag: &mut Dag, m: &[NodeId], n: usize) -> Vec<NodeId> {
    let zero = dag.constant(0.0);
    let mut factor = vec![zero; n * n];
    let mut pivots = vec![zero; n];
    for j in 0..n {
        // L_jk D_k, shared by the pivot and every entry below it.
        let scaled: Vec<NodeId> = (0..j)
            .map(|k| dag.product2(factor[j * n + k], pivots[k]))
            .collect();
        let mut pivot = m[j * n + j];
        for (k, &s) in scaled.iter().enumerate() {
            pivot = subtract_product(dag, pivot, factor[j * n + k], s);
        }
        pivots[j] = pivot;
        let inverse = dag.reciprocal(pivot);
        factor[j * n + j] = inverse;
        for i in j + 1..n {
            let mut entry = m[i * n + j];
            for (k, &s) in scaled.iter().enumerate() {
                entry = subtract_product(dag, entry, factor[i * n + k], s);
            }
            factor[i * n + j] = dag.product2(entry, inverse);
        }
    }
    factor
}

/// a - b c.
fn subtract_product(dag: &mut Dag, a: NodeId, b: NodeId, c: NodeId) -> NodeId {
    let product = dag.product2(b, c);
    let minus = dag.negate(product);
    dag.sum2(a, minus)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_factor_rebuilds_the_matrix() {
        let values = [4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0];
        let mut dag = Dag::default();
        let m: Vec<NodeId> = (0..9).map(|k| dag.input(k)).collect();
        let factor = ldlt(&mut dag, &m, 3);
        let f = dag.evaluate(&factor, &values);
        let l = |i: usize, k: usize| match i.cmp(&k) {
            std::cmp::Ordering::Greater => f[i * 3 + k],
            std::cmp::Ordering::Equal => 1.0,
            std::cmp::Ordering::Less => 0.0,
        };
        for i in 0..3 {
            for j in 0..3 {
                let rebuilt: f64 = (0..3).map(|k| l(i, k) * l(j, k) / f[k * 4]).sum();
                assert!((rebuilt - values[i * 3 + j]).abs() < 1e-14, "{i} {j}");
            }
            for j in i + 1..3 {
                assert_eq!(f[i * 3 + j], 0.0);
            }
        }
    }
}
