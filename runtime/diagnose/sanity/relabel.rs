//! Are two joints' torque columns exchanged? The rigid body is fitted to
//! the measured torques by least squares (every link's ten inertial
//! parameters, free, and each joint's own friction and offset), once as
//! recorded and once with each pair of torque columns exchanged. Free
//! parameters absorb a payload, a heavier link or a wrong model, so what
//! is left unexplained is what no body with this kinematics produces; a
//! recorded order that leaves far more of it than an exchanged one is the
//! wrong order. A sign flip of either joint is tried too, so that a
//! flipped torque is not taken for an exchange.

use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use super::super::candidate::Candidate;
use super::super::kind::Kind;
use super::super::stacked::GENERIC_FEATURES;
use super::super::stacked::Stacked;
use super::{Check, Finding};

/// An exchange is named when it leaves at most this share of what the
/// recorded order leaves unexplained (on the worse of the two joints): a
/// fourfold cut. On correctly recorded data the best exchange leaves as
/// much or more: 1.0-150,000 times the recorded order's share over the 268
/// runs of the hidden-effect benchmark (1.0: a 2 N m/rad spring on joint
/// 3, which no rigid body explains in either order), 8-3300 on clean and
/// payload recordings of four arms, 85 on the real Panda log. A real
/// exchange left 0.0001-0.05 of it, and 0.12 on Panda joints 5 and 7, two
/// small torques that are mostly friction and noise (docs/diagnosis.md,
/// "The sanity gate").
pub const EXCHANGE_RATIO: f64 = 0.25;

/// Two joints' torque columns exchanged, against the recorded order.
#[derive(Debug, Clone, Serialize)]
pub struct Exchange {
    /// The two joints, 1-based.
    pub joints: [usize; 2],
    /// The larger share of the two joints' torque energy the rigid-body
    /// fit leaves unexplained, exchanged and as recorded.
    pub exchanged: f64,
    pub recorded: f64,
    /// `exchanged / recorded`.
    pub ratio: f64,
    /// Whether a sign flip of one of the two joints fits better still.
    #[serde(skip)]
    flip_fits_better: bool,
}

impl Exchange {
    /// Whether the two joints look exchanged.
    pub(super) fn swapped(&self) -> bool {
        self.ratio <= EXCHANGE_RATIO && !self.flip_fits_better
    }

    pub(super) fn finding(&self) -> Finding {
        let [j, k] = self.joints;
        Finding {
            check: Check::SwappedJoints,
            joints: vec![j, k],
            value: self.ratio,
            message: format!(
                "joints {j} and {k} look exchanged: a rigid-body fit of the torques leaves {:.2}% \
                 of their torque unexplained with tau{j} and tau{k} swapped, against {:.1}% as \
                 recorded: check the joint order (the CSV's columns, `--joints` for a bag)",
                100.0 * self.exchanged,
                100.0 * self.recorded
            ),
        }
    }
}

/// The least squares of the measured torques on the rigid body's columns:
/// the normal equations' pseudo-inverse, the cross moments of each joint's
/// regressor rows with each joint's torque, and each torque's energy.
struct Fit<'a> {
    data: &'a Stacked,
    inertial: Vec<&'a DVector<f64>>,
    own: Vec<usize>,
    inverse: DMatrix<f64>,
    /// `cross[i][k]`: sum over samples of joint i's row times joint k's torque.
    cross: Vec<Vec<DVector<f64>>>,
    energy: Vec<f64>,
}

impl<'a> Fit<'a> {
    fn new(data: &'a Stacked, candidates: &'a [Candidate]) -> Fit<'a> {
        let inertial: Vec<&DVector<f64>> = candidates
            .iter()
            .filter(|c| c.kind == Kind::InertialError)
            .flat_map(|c| c.columns.iter())
            .collect();
        let own = ["qd", "sign(qd)", "1"]
            .iter()
            .filter_map(|f| GENERIC_FEATURES.iter().position(|g| g.1 == *f))
            .collect();
        let mut fit = Fit {
            data,
            inertial,
            own,
            inverse: DMatrix::zeros(0, 0),
            cross: Vec::new(),
            energy: vec![0.0; data.dof],
        };
        fit.accumulate();
        fit
    }

    fn width(&self) -> usize {
        self.inertial.len() + self.own.len() * self.data.dof
    }

    /// Regressor row `r` (a joint's equation at one sample) into `x`.
    fn row(&self, r: usize, x: &mut DVector<f64>) {
        x.fill(0.0);
        for (c, column) in self.inertial.iter().enumerate() {
            x[c] = column[r];
        }
        let at = self.inertial.len() + self.own.len() * (r % self.data.dof);
        for (c, &f) in self.own.iter().enumerate() {
            x[at + c] = self.data.generic[f][r];
        }
    }

    fn accumulate(&mut self) {
        let (n, p) = (self.data.dof, self.width());
        let mut a = DMatrix::zeros(p, p);
        let mut cross = vec![vec![DVector::zeros(p); n]; n];
        let mut x = DVector::zeros(p);
        for sample in 0..self.data.measured.len() / n {
            let torque = |k: usize| self.data.measured[sample * n + k];
            for (k, e) in self.energy.iter_mut().enumerate() {
                *e += torque(k).powi(2);
            }
            for (i, row) in cross.iter_mut().enumerate() {
                self.row(sample * n + i, &mut x);
                a.ger(1.0, &x, &x, 1.0);
                for (k, c) in row.iter_mut().enumerate() {
                    c.axpy(torque(k), &x, 1.0);
                }
            }
        }
        self.inverse = pseudo_inverse(&a);
        self.cross = cross;
    }

    /// The parameters fitted to the torques with joint i's equation given
    /// torque column `target[i]` times `sign[i]`.
    fn solve(&self, target: &[usize], sign: &[f64]) -> DVector<f64> {
        let b = (0..self.data.dof).fold(DVector::zeros(self.width()), |b, i| {
            b + &self.cross[i][target[i]] * sign[i]
        });
        &self.inverse * b
    }

    /// The share of torque column `k` (times `sign`) that joint i's
    /// equations leave unexplained at parameters `theta`.
    fn unexplained(&self, theta: &DVector<f64>, i: usize, k: usize, sign: f64) -> f64 {
        let n = self.data.dof;
        let mut x = DVector::zeros(self.width());
        let mut sse = 0.0;
        for sample in 0..self.data.measured.len() / n {
            self.row(sample * n + i, &mut x);
            sse += (sign * self.data.measured[sample * n + k] - x.dot(theta)).powi(2);
        }
        sse / self.energy[k].max(f64::MIN_POSITIVE)
    }
}

/// The pseudo-inverse of a symmetric positive semi-definite matrix, through
/// its unit-diagonal scaling (directions below 1e-12 of the largest
/// eigenvalue, unidentifiable parameter combinations, count as none).
fn pseudo_inverse(a: &DMatrix<f64>) -> DMatrix<f64> {
    let p = a.nrows();
    let d = DVector::from_fn(p, |i, _| {
        let v = a[(i, i)];
        if v > 0.0 { 1.0 / v.sqrt() } else { 1.0 }
    });
    let scaled = DMatrix::from_fn(p, p, |i, j| a[(i, j)] * d[i] * d[j]);
    let Some(eigen) = crate::kernels::symmetric_eigen(scaled) else {
        return DMatrix::zeros(p, p);
    };
    let largest = eigen.eigenvalues.max().max(f64::MIN_POSITIVE);
    let inverted = eigen
        .eigenvalues
        .map(|v| if v > 1e-12 * largest { 1.0 / v } else { 0.0 });
    let v = &eigen.eigenvectors;
    let inner = v * DMatrix::from_diagonal(&inverted) * v.transpose();
    DMatrix::from_fn(p, p, |i, j| inner[(i, j)] * d[i] * d[j])
}

/// Every pair of joints' exchange, against the recorded order.
pub(super) fn exchanges(data: &Stacked, candidates: &[Candidate]) -> Vec<Exchange> {
    let n = data.dof;
    if n < 2 {
        return Vec::new();
    }
    let fit = Fit::new(data, candidates);
    let order: Vec<usize> = (0..n).collect();
    let plus = vec![1.0; n];
    let recorded = fit.solve(&order, &plus);
    let flipped: Vec<DVector<f64>> = (0..n)
        .map(|j| {
            let mut sign = plus.clone();
            sign[j] = -1.0;
            fit.solve(&order, &sign)
        })
        .collect();
    // Each joint's share as recorded and with any one torque flipped, once
    // (every pair below uses them).
    let as_recorded: Vec<f64> = (0..n)
        .map(|i| fit.unexplained(&recorded, i, i, 1.0))
        .collect();
    let flipped_share: Vec<Vec<f64>> = (0..n)
        .map(|f| {
            let sign = |i: usize| if i == f { -1.0 } else { 1.0 };
            (0..n)
                .map(|i| fit.unexplained(&flipped[f], i, i, sign(i)))
                .collect()
        })
        .collect();
    let mut found = Vec::new();
    for j in 0..n {
        for k in j + 1..n {
            let mut target = order.clone();
            target.swap(j, k);
            let theta = fit.solve(&target, &plus);
            let exchanged = fit
                .unexplained(&theta, j, k, 1.0)
                .max(fit.unexplained(&theta, k, j, 1.0));
            let as_recorded = as_recorded[j].max(as_recorded[k]);
            let flip = |f: usize| flipped_share[f][j].max(flipped_share[f][k]);
            found.push(Exchange {
                joints: [j + 1, k + 1],
                exchanged,
                recorded: as_recorded,
                ratio: exchanged / as_recorded.max(f64::MIN_POSITIVE),
                flip_fits_better: flip(j).min(flip(k)) < exchanged,
            });
        }
    }
    found
}
