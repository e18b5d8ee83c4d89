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
use super::super::digits::{needed, sig, significant};
use super::super::kind::Kind;
use super::super::stacked::GENERIC_FEATURES;
use super::super::stacked::Stacked;
use super::scale::Estimate;
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

/// The largest share of the pair's torque energy a rigid-body fit of the
/// exchanged torque columns may leave unexplained for the exchange to be
/// named: an exchange that explains less than half of the torques is no
/// better order, however much worse the recorded one fits. Real torque
/// exchanges leave 0.003-0.15% (ten on a UR10e simulator). The unweighted
/// fit sacrifices small torques to large ones where no rigid body fits
/// the recordings (two recordings with different payloads pooled): a
/// UR10e's wrists were left 8314% of their torque energy as recorded and
/// 1479% with their torques exchanged, a ratio within [`EXCHANGE_RATIO`].
pub const MOST_UNEXPLAINED: f64 = 0.5;

/// What an exchange moves between two joints.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Exchanged {
    /// The torque columns alone (judged by a rigid-body fit).
    Torques,
    /// Positions, velocities and torques together (judged by the model's
    /// torque, see `reorder.rs`).
    Joints,
}

/// Two joints' columns exchanged, against the recorded order.
#[derive(Debug, Clone, Serialize)]
pub struct Exchange {
    pub columns: Exchanged,
    /// The two joints, 1-based.
    pub joints: [usize; 2],
    /// The larger share of the two joints' torque energy the fit leaves
    /// unexplained, exchanged and as recorded.
    pub exchanged: f64,
    pub recorded: f64,
    /// `exchanged / recorded`.
    pub ratio: f64,
    /// Whether a sign flip of one of the two joints fits better still.
    #[serde(skip)]
    flip_fits_better: bool,
    /// The model's torque gains that tell a whole-joint exchange where the
    /// shares alone do not: see [`GainsTell`].
    #[serde(skip)]
    pub(super) gains: Option<GainsTell>,
    /// How many recordings each tell the exchange alone where pooled they
    /// do not (the numbers are the least clear one's); 0 when told pooled.
    #[serde(skip)]
    pub(super) alone_in: usize,
}

/// A whole-joint exchange the gains of the model's torque tell: as
/// recorded some joint of the pair follows the model's torque with a gain
/// clearly below [`super::scale::LEAST_GAIN`] (the model predicts none of
/// it); exchanged, neither does, and one follows it with a gain clearly
/// above that and not clearly above [`super::scale::MOST_GAIN`] (the
/// other's model torque may be too small to tell: a wrist's; a payload
/// the model lacks takes a wrist's gain to 2.06 +- 0.09 on a UR10e). On
/// joints whose torque is mostly friction (explained in either
/// order, as each joint keeps its own velocity) the unexplained shares
/// differ by less than [`EXCHANGE_RATIO`] (a Kinova Gen3's joints 1 and 3
/// from one 1 kHz recording with pauses: 0.34), while the gains go from
/// 0.08 and 0.20 to about 1.
#[derive(Debug, Clone, Copy)]
pub struct GainsTell {
    /// The pair's gains as recorded and exchanged, in the pair's order
    /// (`None` where the model predicts no torque).
    pub(super) recorded: [Option<Estimate>; 2],
    pub(super) exchanged: [Option<Estimate>; 2],
}

impl Exchange {
    pub(super) fn new(
        columns: Exchanged,
        joints: [usize; 2],
        exchanged: f64,
        recorded: f64,
    ) -> Self {
        Exchange {
            columns,
            joints,
            exchanged,
            recorded,
            ratio: exchanged / recorded.max(f64::MIN_POSITIVE),
            flip_fits_better: false,
            gains: None,
            alone_in: 0,
        }
    }

    /// Whether the two joints look exchanged.
    pub(super) fn swapped(&self) -> bool {
        let told = self.gains.is_some() && self.ratio < 1.0;
        let explains = self.columns == Exchanged::Joints || self.exchanged <= MOST_UNEXPLAINED;
        (self.ratio <= EXCHANGE_RATIO || told) && explains && !self.flip_fits_better
    }

    pub(super) fn finding(&self) -> Finding {
        let [j, k] = self.joints;
        // Percentages with the digits it takes to print them apart.
        let shares = [self.exchanged, self.recorded].map(|x| 100.0 * x);
        let digits = needed(shares[0], shares[1]);
        let [exchanged, recorded] = shares.map(|x| significant(x, digits));
        let seen = match self.columns {
            Exchanged::Torques => format!(
                "a rigid-body fit of the torques leaves {exchanged}% of their torque unexplained \
                 with tau{j} and tau{k} swapped"
            ),
            Exchanged::Joints => format!(
                "the model's torque leaves {exchanged}% of their torque unexplained with their \
                 positions, velocities and torques swapped"
            ),
        };
        let gains = self.gains.map_or(String::new(), |g| {
            format!(
                ", and their torques follow the model's with gains {} swapped, {} as recorded",
                gain_pair(g.exchanged),
                gain_pair(g.recorded)
            )
        });
        let alone = match self.alone_in {
            0 => String::new(),
            count => format!(" in each of the {count} recordings alone (in the least clear one"),
        };
        let close = if self.alone_in > 0 { ")" } else { "" };
        Finding {
            check: Check::SwappedJoints,
            joints: vec![j, k],
            value: self.ratio,
            message: format!(
                "joints {j} and {k} look exchanged{alone}: {seen}, against {recorded}% as \
                 recorded{gains}{close}: check the joint order (the CSV's columns, `--joints` for \
                 a bag)"
            ),
        }
    }
}

/// Two gains as "a ± h and b ± h" (95%), "none" where the model predicts
/// no torque.
fn gain_pair(gains: [Option<Estimate>; 2]) -> String {
    let one = |g: Option<Estimate>| {
        g.map_or("none".to_string(), |g| {
            format!("{} ± {}", sig(g.value), sig(1.96 * g.se))
        })
    };
    format!("{} and {}", one(gains[0]), one(gains[1]))
}

/// The least squares of the measured torques on the rigid body's columns:
/// the normal equations' pseudo-inverse, the cross moments of each joint's
/// regressor rows with each joint's torque, and each torque's energy.
struct Fit<'a> {
    data: &'a Stacked,
    inertial: Vec<&'a DVector<f64>>,
    own: Vec<usize>,
    inverse: DMatrix<f64>,
    /// `cross[i]` column k: sum over samples of joint i's row times joint
    /// k's torque.
    cross: Vec<DMatrix<f64>>,
    /// The measured torques, samples x joints.
    torques: DMatrix<f64>,
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
        let n = data.dof;
        let torques = DMatrix::from_fn(data.measured.len() / n, n, |s, k| data.measured[s * n + k]);
        let energy = torques.column_iter().map(|t| t.norm_squared()).collect();
        let mut fit = Fit {
            data,
            inertial,
            own,
            inverse: DMatrix::zeros(0, 0),
            cross: Vec::new(),
            torques,
            energy,
        };
        fit.accumulate();
        fit
    }

    fn width(&self) -> usize {
        self.inertial.len() + self.own.len() * self.data.dof
    }

    /// Joint i's regressor rows (samples x width): the inertial columns at
    /// its rows and its own features in its block, the other joints' zero.
    fn rows(&self, i: usize) -> DMatrix<f64> {
        let n = self.data.dof;
        let mut x = DMatrix::zeros(self.torques.nrows(), self.width());
        let at = self.inertial.len() + self.own.len() * i;
        let own = self.own.iter().map(|&f| &self.data.generic[f]);
        let columns = self.inertial.iter().copied().enumerate();
        for (c, column) in columns.chain(own.enumerate().map(|(c, f)| (at + c, f))) {
            for (s, v) in x.column_mut(c).iter_mut().enumerate() {
                *v = column[s * n + i];
            }
        }
        x
    }

    fn accumulate(&mut self) {
        let p = self.width();
        let mut a = DMatrix::zeros(p, p);
        self.cross = (0..self.data.dof)
            .map(|i| {
                let x = self.rows(i);
                a += x.tr_mul(&x);
                x.tr_mul(&self.torques)
            })
            .collect();
        self.inverse = pseudo_inverse(&a);
    }

    /// The parameters fitted to the torques with joint i's equation given
    /// torque column `target[i]` times `sign[i]`.
    fn solve(&self, target: &[usize], sign: &[f64]) -> DVector<f64> {
        let b = (0..self.data.dof).fold(DVector::zeros(self.width()), |b, i| {
            b + self.cross[i].column(target[i]) * sign[i]
        });
        &self.inverse * b
    }

    /// For each (parameters, torque column k, sign) of `asked`, the share of
    /// torque column k (times the sign) that joint i's equations leave
    /// unexplained at those parameters.
    fn unexplained(
        &self,
        thetas: &[DVector<f64>],
        i: usize,
        asked: &[(usize, usize, f64)],
    ) -> Vec<f64> {
        let predicted = self.rows(i) * DMatrix::from_columns(thetas);
        asked
            .iter()
            .map(|&(t, k, sign)| {
                let torque = self.torques.column(k);
                let left = predicted
                    .column(t)
                    .zip_fold(&torque, 0.0, |sse, p, m| sse + (sign * m - p).powi(2));
                left / self.energy[k].max(f64::MIN_POSITIVE)
            })
            .collect()
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

/// What the rigid-body fit (free parameters, each joint's own friction and
/// offset) says of each joint's torque as recorded.
pub(super) struct Recorded {
    /// The share of the joint's torque energy left unexplained.
    pub(super) unexplained: Vec<f64>,
    /// The joint's viscous and Coulomb coefficients fitted beside the free
    /// rigid body: a payload or a heavier link the model lacks does not
    /// leak into them.
    pub(super) friction: Vec<[f64; 2]>,
}

/// Every pair of joints' exchange, against the recorded order, and what
/// the fit says of the recorded order.
pub(super) fn exchanges(data: &Stacked, candidates: &[Candidate]) -> (Vec<Exchange>, Recorded) {
    let n = data.dof;
    let fit = Fit::new(data, candidates);
    let order: Vec<usize> = (0..n).collect();
    let plus = vec![1.0; n];
    let flip = |f: usize| -> Vec<f64> { (0..n).map(|i| if i == f { -1.0 } else { 1.0 }).collect() };
    let pairs: Vec<(usize, usize)> = (0..n)
        .flat_map(|j| (j + 1..n).map(move |k| (j, k)))
        .collect();
    // The parameters: as recorded, with torque f flipped (1 + f), with the
    // pair's columns exchanged (1 + n + pair).
    let mut thetas = vec![fit.solve(&order, &plus)];
    thetas.extend((0..n).map(|f| fit.solve(&order, &flip(f))));
    thetas.extend(pairs.iter().map(|&(j, k)| {
        let mut target = order.clone();
        target.swap(j, k);
        fit.solve(&target, &plus)
    }));
    // Per joint i: its share as recorded, with each torque flipped, and in
    // each exchange that moves it (its equation given the other's torque).
    let shares: Vec<Vec<f64>> = (0..n)
        .map(|i| {
            let mut asked = vec![(0, i, 1.0)];
            asked.extend((0..n).map(|f| (1 + f, i, if i == f { -1.0 } else { 1.0 })));
            asked.extend(pairs.iter().enumerate().filter_map(|(p, &(j, k))| match i {
                _ if i == j => Some((1 + n + p, k, 1.0)),
                _ if i == k => Some((1 + n + p, j, 1.0)),
                _ => None,
            }));
            fit.unexplained(&thetas, i, &asked)
        })
        .collect();
    let as_recorded = |i: usize| shares[i][0];
    let own = |i: usize, f: usize| thetas[0][fit.inertial.len() + fit.own.len() * i + f];
    let recorded = Recorded {
        unexplained: (0..n).map(as_recorded).collect(),
        friction: (0..n).map(|i| [own(i, 0), own(i, 1)]).collect(),
    };
    let flipped = |f: usize, i: usize| shares[i][1 + f];
    // Joint i's exchanges follow in pair order after its n + 1 shares.
    let exchanged = |p: usize, i: usize| {
        let before = pairs[..p]
            .iter()
            .filter(|&&(j, k)| j == i || k == i)
            .count();
        shares[i][1 + n + before]
    };
    let exchanges = pairs
        .iter()
        .enumerate()
        .map(|(p, &(j, k))| {
            let exchanged = exchanged(p, j).max(exchanged(p, k));
            let recorded = as_recorded(j).max(as_recorded(k));
            let flip = |f: usize| flipped(f, j).max(flipped(f, k));
            Exchange {
                flip_fits_better: flip(j).min(flip(k)) < exchanged,
                ..Exchange::new(Exchanged::Torques, [j + 1, k + 1], exchanged, recorded)
            }
        })
        .collect();
    (exchanges, recorded)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A torque exchange is named only where the exchanged order explains
    /// most of the torques, however much worse the recorded order fits; a
    /// whole-joint exchange is judged by its ratio (and gains) alone.
    #[test]
    fn an_exchange_that_explains_nothing_is_not_named() {
        let torques = |exchanged, recorded| {
            Exchange::new(Exchanged::Torques, [5, 6], exchanged, recorded).swapped()
        };
        assert!(torques(0.001, 0.77));
        assert!(!torques(14.8, 83.1), "a ratio of 0.18 explaining nothing");
        assert!(!torques(0.3, 0.9), "a ratio of 1/3");
        assert!(Exchange::new(Exchanged::Joints, [5, 6], 0.9, 4.0).swapped());
    }
}
