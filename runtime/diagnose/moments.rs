//! Second moments of the candidate columns and the residual per
//! cross-validation group and joint: every fit below is a small solve on
//! them, independent of the number of samples.

use nalgebra::{DMatrix, DVector};

use super::candidate::{Candidate, columns_of};
use super::solve::pseudo_solve;
use super::stacked::Stacked;

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
    /// Each joint's weight in the fits (see [`Moments::weighted`]).
    pub(super) weights: Vec<f64>,
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
        let mut nonzero: Vec<(usize, f64)> = Vec::with_capacity(p);
        for (r, (&g, &y)) in data.group.iter().zip(data.residual.iter()).enumerate() {
            let j = r % data.dof;
            // Most columns are zero on a row (a joint's own columns on the
            // other joints' rows): only the nonzero products are added.
            // The sums start at +0 and never become -0, so a zero product
            // would change none of them: the same numbers as X^T X by
            // rank-one updates (x_b x_a + sum, and y x_b + sum, as
            // nalgebra's `ger` and `axpy` add them).
            nonzero.clear();
            nonzero.extend(
                (0..p)
                    .map(|k| (k, columns[k][r]))
                    .filter(|&(_, v)| v != 0.0),
            );
            let (xx, xr) = (xx[g][j].as_mut_slice(), xr[g][j].as_mut_slice());
            for &(b, vb) in &nonzero {
                let column = &mut xx[b * p..(b + 1) * p];
                for &(a, va) in &nonzero {
                    column[a] += vb * va;
                }
                xr[b] += y * vb;
            }
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
        let joints = xx.first().map_or(0, Vec::len);
        Moments::summed(xx, xr, rr, rows, applied, vec![1.0; joints])
    }

    /// The same moments with each joint's rows weighted by `weights`
    /// (weighted least squares): the fits below then weigh a joint's
    /// squared residual by its weight.
    pub(super) fn weighted(self, weights: Vec<f64>) -> Moments {
        Moments::summed(self.xx, self.xr, self.rr, self.rows, self.applied, weights)
    }

    /// The same moments weighted by each joint's noise: the inverse of the
    /// joint's residual variance once every candidate column is fitted at
    /// once, linearly (least squares: the first step of feasible weighted least
    /// squares, as Gautier's IDIM-WLS weighs an arm's joints), scaled to a
    /// mean of 1. An arm's joints differ in noise by orders of magnitude (an
    /// independent UR10e's shoulder 0.35 N m^2, its wrist 2e-5): fitted
    /// unweighted, an effect every joint sees (a body, a payload's own
    /// inertia) follows the noisiest joints, and its trace on the quiet
    /// wrist is left to the wrist's armatures. Every column, a body's and a
    /// tilt's too: a joint whose residual still holds an effect the columns
    /// know is not noisy (with the linear candidates alone, a 3 degree tilt
    /// left in the gravity-loaded joints' residual made the tilt not
    /// significant there, and a link error was named in its place).
    pub(super) fn noise_weighted(self, candidates: &[Candidate]) -> Moments {
        let every: Vec<usize> = (0..candidates.len()).collect();
        let columns = columns_of(candidates, &every);
        let (a, b) = self.normal_equations(&columns, |_| true);
        let theta = pseudo_solve(&a, &b);
        let weights = inverse_variances(&self, &sse_per_joint(&self, &columns, &theta));
        self.weighted(weights)
    }

    fn summed(
        xx: Vec<Vec<DMatrix<f64>>>,
        xr: Vec<Vec<DVector<f64>>>,
        rr: Vec<Vec<f64>>,
        rows: Vec<Vec<usize>>,
        applied: Vec<usize>,
        weights: Vec<f64>,
    ) -> Moments {
        let p = xx.first().and_then(|g| g.first()).map_or(0, DMatrix::nrows);
        let sum_m = |parts: &[DMatrix<f64>]| {
            parts
                .iter()
                .zip(&weights)
                .fold(DMatrix::zeros(p, p), |a, (x, w)| a + x * *w)
        };
        let sum_v = |parts: &[DVector<f64>]| {
            parts
                .iter()
                .zip(&weights)
                .fold(DVector::zeros(p), |a, (x, w)| a + x * *w)
        };
        let group_xx: Vec<DMatrix<f64>> = xx.iter().map(|g| sum_m(g)).collect();
        let group_xr: Vec<DVector<f64>> = xr.iter().map(|g| sum_v(g)).collect();
        let total_xx = group_xx.iter().fold(DMatrix::zeros(p, p), |a, x| a + x);
        let total_xr = group_xr.iter().fold(DVector::zeros(p), |a, x| a + x);
        Moments {
            total_xx,
            total_xr,
            group_xx,
            group_xr,
            xx,
            xr,
            rr,
            rows,
            applied,
            weights,
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

    /// Whether any of `columns` is nonzero on joint `j`'s rows: whether
    /// the effect of those columns acts on joint `j`.
    pub(super) fn acts_on(&self, columns: &[usize], j: usize) -> bool {
        let nonzero = |xx: &DMatrix<f64>| columns.iter().any(|&k| xx[(k, k)] != 0.0);
        self.xx.iter().any(|joints| nonzero(&joints[j]))
    }

    /// The residual's sum of squares over the groups `keep` accepts.
    pub(super) fn residual_sum(&self, keep: impl Fn(usize) -> bool) -> f64 {
        let kept = self.rr.iter().enumerate().filter(|(g, _)| keep(*g));
        let weighted = |joints: &Vec<f64>| -> f64 {
            joints.iter().zip(&self.weights).map(|(r, w)| r * w).sum()
        };
        kept.map(|(_, joints)| weighted(joints)).sum()
    }

    /// The scoring columns of fitted `columns` (see `Candidate::applied`).
    pub(super) fn applied(&self, columns: &[usize]) -> Vec<usize> {
        columns.iter().map(|&c| self.applied[c]).collect()
    }

    /// Residual sum of squares of group g, joint j after subtracting X theta.
    pub(super) fn sse(&self, g: usize, j: usize, columns: &[usize], theta: &DVector<f64>) -> f64 {
        let (xx, xr) = (&self.xx[g][j], &self.xr[g][j]);
        // Only the columns with a coefficient that are nonzero on this
        // joint's rows count (a column with no square has no product
        // either): most of a fit's columns are other joints' own, so this
        // is a few of them, read in place.
        let active: Vec<(usize, f64)> = columns
            .iter()
            .zip(theta.iter())
            .filter(|&(&k, &t)| t != 0.0 && xx[(k, k)] != 0.0)
            .map(|(&k, &t)| (k, t))
            .collect();
        let (mut linear, mut quadratic) = (0.0, 0.0);
        for &(k, t) in &active {
            linear += t * xr[k];
            let row: f64 = active.iter().map(|&(l, u)| xx[(l, k)] * u).sum();
            quadratic += t * row;
        }
        // Clamped: rounding can push a near-perfect fit's sum below zero.
        (self.rr[g][j] - 2.0 * linear + quadratic).max(0.0)
    }
}

/// Each joint's inverse residual variance (`sse` per joint over its rows),
/// scaled to a mean of 1. A joint the columns fit exactly is not given all
/// the weight: its variance is floored at 1e-12 of the largest.
fn inverse_variances(m: &Moments, sse: &[f64]) -> Vec<f64> {
    let rows = |j: usize| m.rows.iter().map(|g| g[j]).sum::<usize>().max(1) as f64;
    let variance: Vec<f64> = sse.iter().enumerate().map(|(j, s)| s / rows(j)).collect();
    let floor = variance
        .iter()
        .fold(f64::MIN_POSITIVE, |a, &v| a.max(v * 1e-12));
    let inverse: Vec<f64> = variance.iter().map(|v| 1.0 / v.max(floor)).collect();
    let mean = inverse.iter().sum::<f64>() / inverse.len().max(1) as f64;
    inverse.iter().map(|w| w / mean).collect()
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
    use crate::diagnose::candidate::linear;
    use crate::diagnose::fit::fit;
    use crate::diagnose::kind::Kind;

    /// Two joints see one effect (0.5 times a shared column); joint 1's
    /// noise is 1000 times joint 2's in amplitude. Weighted by each joint's
    /// noise, the fit follows the quiet joint. The weights come from the
    /// unweighted fit, whose error on the shared column (set by the noisy
    /// joint) is left in the quiet joint's residual: its weight is some
    /// thousands of times the other's, not the million of the noises alone,
    /// and that is enough.
    #[test]
    fn noise_weights_let_the_quiet_joint_determine_a_shared_effect() {
        let samples = 4000;
        let noise = |s: usize| ((s as f64 * 12.9898).sin() * 43758.5453).fract() - 0.5;
        let shared = DVector::from_fn(2 * samples, |r, _| ((r / 2) as f64 * 0.01).sin());
        let residual = DVector::from_fn(2 * samples, |r, _| {
            let amplitude = if r % 2 == 0 { 1.0 } else { 1e-3 };
            0.5 * shared[r] + amplitude * noise(r)
        });
        let data = Stacked::of_residual(residual, 2);
        let candidates = vec![linear(Kind::TorqueScale, shared)];
        let plain = Moments::new(&data, &candidates);
        let unweighted = fit(&plain, &candidates, &[0], |_| true).unwrap().theta[0];
        let weighted = plain.noise_weighted(&candidates);
        let ratio = weighted.weights[1] / weighted.weights[0];
        assert!(ratio > 1e3, "{ratio}");
        let theta = fit(&weighted, &candidates, &[0], |_| true).unwrap().theta[0];
        assert!((theta - 0.5).abs() < 1e-4, "{theta}");
        assert!(
            (unweighted - 0.5).abs() > 10.0 * (theta - 0.5).abs(),
            "{unweighted}"
        );
    }
}
