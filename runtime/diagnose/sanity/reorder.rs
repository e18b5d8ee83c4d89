//! Are two joints' columns exchanged together, positions, velocities and
//! torques (a log whose joint order is not the description's)? The model's
//! torque is evaluated on the samples as recorded and with each pair of
//! joints' positions, velocities and accelerations exchanged, and each
//! joint's torque (exchanged alike) is fitted by least squares to it times
//! a gain beside the joint's own friction and offset. A payload or a wrong
//! mass the model lacks leaves some torque unexplained in the recorded
//! order, but the gain, friction and offset absorb most of it; the model's
//! torque of another joint's motion explains little. Where the joints'
//! torques are mostly friction, which each joint's own velocity explains in
//! either order, the gains of the model's torque tell instead
//! ([`GainsTell`]). An exchange of the torque columns alone is
//! [`super::relabel`]'s.

use nalgebra::{Matrix4, Vector4};

use super::super::stacked::{GENERIC_FEATURES, Stacked};
use super::relabel::{Exchange, Exchanged, GainsTell};
use super::scale::{self, Estimate, Folds, LEAST_GAIN, MOST_GAIN};
use crate::dynamics::Dynamics;

/// Per joint, the normal equations of its torque on the columns model
/// torque, qd, sign(qd) and 1, and the torque's energy.
struct Sums {
    a: Vec<Matrix4<f64>>,
    b: Vec<Vector4<f64>>,
    yy: Vec<f64>,
}

impl Sums {
    /// The share of the torque energy of joints `joints` together that
    /// their fits leave unexplained: pooled, so that a joint whose torque
    /// is mostly noise (a UR10e's last wrist) does not hide its partner.
    fn unexplained(&self, joints: &[usize]) -> f64 {
        let (left, energy) = joints.iter().fold((0.0, 0.0), |(left, energy), &i| {
            let (a, b) = (&self.a[i], &self.b[i]);
            let theta = a
                .try_inverse()
                .map_or_else(Vector4::zeros, |inverse| inverse * b);
            (
                left + (self.yy[i] - theta.dot(b)).max(0.0),
                energy + self.yy[i],
            )
        });
        left / energy.max(f64::MIN_POSITIVE)
    }
}

impl Sums {
    fn zeros(n: usize) -> Sums {
        Sums {
            a: vec![Matrix4::zeros(); n],
            b: vec![Vector4::zeros(); n],
            yy: vec![0.0; n],
        }
    }

    /// The sums of several recordings together.
    fn pooled(each: &[Sums], n: usize) -> Sums {
        each.iter().fold(Sums::zeros(n), |mut total, s| {
            for i in 0..n {
                total.a[i] += s.a[i];
                total.b[i] += s.b[i];
                total.yy[i] += s.yy[i];
            }
            total
        })
    }
}

/// Per recording the sums with the joints read in `order` (joint i's
/// signals and torque are the recorded joint `order[i]`'s), and the
/// model's torque at each row of the stacked data (joint i's at the
/// recorded joint `order[i]`'s rows). `None` when the model cannot
/// evaluate a sample.
fn sums(model: &dyn Dynamics, data: &Stacked, order: &[usize]) -> Option<(Vec<Sums>, Vec<f64>)> {
    let n = data.dof;
    let feature = |formula: &str| GENERIC_FEATURES.iter().position(|f| f.1 == formula);
    let sign = &data.generic[feature("sign(qd)")?];
    let mut each: Vec<Sums> = data.recordings.iter().map(|_| Sums::zeros(n)).collect();
    let recording_of = |row: usize| data.recordings.iter().position(|r| r.rows.contains(&row));
    let samples = data.measured.len() / n.max(1);
    let mut torque = vec![0.0; data.measured.len()];
    let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    for sample in 0..samples {
        let row = |i: usize| sample * n + order[i];
        for i in 0..n {
            (q[i], qd[i], qdd[i]) = (data.angle[row(i)], data.qd[row(i)], data.qdd[row(i)]);
        }
        // The rigid body's torque, as the gains are judged (`super::rigid_body`).
        let tau = model.tau(&q, &qd, &qdd).ok()? - model.effects(&qd).ok()?;
        let s = &mut each[recording_of(sample * n)?];
        for i in 0..n {
            let r = row(i);
            let x = Vector4::new(tau[i], data.qd[r], sign[r], 1.0);
            let y = data.measured[r];
            s.a[i] += x * x.transpose();
            s.b[i] += x * y;
            s.yy[i] += y * y;
            torque[r] = tau[i];
        }
    }
    Some((each, torque))
}

/// The gain of the model's torque `torque` (per row) in recorded joint
/// `j`'s measured torque on the rows of `folds`, as the torque checks fit
/// it.
fn gain(data: &Stacked, torque: &[f64], j: usize, folds: Folds) -> Option<Estimate> {
    scale::gain_of(data, j, folds, |r| torque[r]).model
}

/// Whether a pair's gains, as recorded and exchanged, tell their exchange:
/// see [`GainsTell`].
fn gains_tell(
    recorded: [Option<Estimate>; 2],
    exchanged: [Option<Estimate>; 2],
    min_t: f64,
) -> Option<GainsTell> {
    let low = |g: &Option<Estimate>| g.is_some_and(|g| g.clearly_below(LEAST_GAIN, min_t));
    let follows = |g: &Option<Estimate>| {
        g.is_some_and(|g| g.clearly_above(LEAST_GAIN, min_t) && !g.clearly_above(MOST_GAIN, min_t))
    };
    let told =
        recorded.iter().any(low) && exchanged.iter().any(follows) && !exchanged.iter().any(low);
    told.then_some(GainsTell {
        recorded,
        exchanged,
    })
}

/// The fewest segments a recording needs to be judged alone: the gains'
/// standard errors take the delete-one-segment jackknife from three
/// (`scale::gain_of`), and least squares alone is too sure of itself on
/// correlated residuals.
const SEGMENTS_ALONE: usize = 3;

/// What the joint exchanges say: every pair's exchange against the
/// recorded order, and the exchanges found.
pub(super) struct Reorders {
    pub(super) each: Vec<Exchange>,
    /// Found one at a time, each judged against the order with the ones
    /// before it undone: two joints exchanged make a third joint's model
    /// torque wrong too, and exchanging that one with a fourth then looks
    /// better than the recorded order.
    pub(super) found: Vec<Exchange>,
    /// Per recording that can be judged alone (at least
    /// [`SEGMENTS_ALONE`] segments), every pair's exchange on its rows.
    pub(super) alone: Vec<Vec<Exchange>>,
}

impl Reorders {
    /// The exchange every recording tells alone, when there are two or
    /// more and the pooled recordings tell none: a swapped wrist's model
    /// torque differs from recording to recording, so pooled its gain
    /// loses the certainty each recording's has (a UR10e's joints 5 and 6
    /// from three recordings: 0.19 +- 0.11 pooled, -0.01 +- 0.02 in each).
    /// The least clear recording's numbers are reported.
    pub(super) fn told_by_each(&self) -> Option<Exchange> {
        if !self.found.is_empty() || self.alone.len() < 2 {
            return None;
        }
        let firsts: Vec<&Exchange> = self.alone.iter().map(|e| first(e)).collect::<Option<_>>()?;
        let joints = firsts[0].joints;
        if firsts.iter().any(|e| e.joints != joints) {
            return None;
        }
        let least = firsts.iter().max_by(|a, b| a.ratio.total_cmp(&b.ratio))?;
        let mut told = (*least).clone();
        told.alone_in = self.alone.len();
        Some(told)
    }
}

/// The exchange that looks best of those that look swapped.
fn first(round: &[Exchange]) -> Option<&Exchange> {
    round
        .iter()
        .filter(|e| e.swapped())
        .min_by(|a, b| a.ratio.total_cmp(&b.ratio))
}

/// Every pair of joints' exchange of all their columns, against the
/// recorded order (the share of the pair's torque energy unexplained, and
/// the gains, `min_t` standard errors clear), and the exchanges found.
pub(super) fn exchanges(model: &dyn Dynamics, data: &Stacked, min_t: f64) -> Reorders {
    let n = data.dof;
    let judged: Vec<usize> = (0..data.recordings.len())
        .filter(|&r| data.recordings[r].alone >= SEGMENTS_ALONE)
        .collect();
    let mut order: Vec<usize> = (0..n).collect();
    let mut reorders = Reorders {
        each: Vec::new(),
        found: Vec::new(),
        alone: Vec::new(),
    };
    loop {
        let Some((current, torque)) = sums(model, data, &order) else {
            return reorders;
        };
        let gains = |folds: Folds| -> Vec<Option<Estimate>> {
            (0..n).map(|j| gain(data, &torque, j, folds)).collect()
        };
        let pooled = Sums::pooled(&current, n);
        let current_gains = gains(Folds::Groups);
        let first_round = reorders.found.is_empty();
        let alone_gains: Vec<Vec<Option<Estimate>>> = match first_round {
            true => judged
                .iter()
                .map(|&r| gains(Folds::Alone(&data.recordings[r])))
                .collect(),
            false => Vec::new(),
        };
        let moved = |j: usize| reorders.found.iter().any(|e| e.joints.contains(&(j + 1)));
        let mut round = Vec::new();
        let mut alone = vec![Vec::new(); alone_gains.len()];
        for j in (0..n).filter(|&j| !moved(j)) {
            for k in (j + 1..n).filter(|&k| !moved(k)) {
                let mut swapped = order.clone();
                swapped.swap(j, k);
                let Some((exchanged, torque)) = sums(model, data, &swapped) else {
                    continue;
                };
                let pair = [order[j], order[k]];
                let judge = |exchanged: &Sums, current: &Sums, folds: Folds, gains: &[_]| {
                    let mut exchange = Exchange::new(
                        Exchanged::Joints,
                        [j + 1, k + 1],
                        exchanged.unexplained(&[j, k]),
                        current.unexplained(&[j, k]),
                    );
                    let exchanged = pair.map(|p| gain(data, &torque, p, folds));
                    exchange.gains = gains_tell(pair.map(|p| gains[p]), exchanged, min_t);
                    exchange
                };
                let everywhere = Sums::pooled(&exchanged, n);
                round.push(judge(&everywhere, &pooled, Folds::Groups, &current_gains));
                for (a, &r) in judged.iter().enumerate().take(alone.len()) {
                    let folds = Folds::Alone(&data.recordings[r]);
                    alone[a].push(judge(&exchanged[r], &current[r], folds, &alone_gains[a]));
                }
            }
        }
        let best = first(&round).cloned();
        if first_round {
            reorders.each = round;
            reorders.alone = alone;
        }
        let Some(best) = best else {
            return reorders;
        };
        order.swap(best.joints[0] - 1, best.joints[1] - 1);
        reorders.found.push(best);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An exchange of joints `joints` leaving `ratio` of the recorded
    /// order's unexplained share.
    fn exchange(joints: [usize; 2], ratio: f64) -> Exchange {
        Exchange::new(Exchanged::Joints, joints, 0.01 * ratio, 0.01)
    }

    fn reorders(found: Vec<Exchange>, alone: Vec<Vec<Exchange>>) -> Reorders {
        Reorders {
            each: Vec::new(),
            found,
            alone,
        }
    }

    /// The same exchange told by every recording alone is named, with the
    /// least clear recording's numbers; one recording, a disagreeing or a
    /// silent recording, or an exchange the pooled recordings tell, is not.
    #[test]
    fn an_exchange_is_told_alone_only_by_every_recording() {
        let told = |ratio| vec![exchange([5, 6], ratio), exchange([4, 6], 3.0)];
        let every = reorders(Vec::new(), vec![told(0.1), told(0.2), told(0.05)]);
        let named = every.told_by_each().expect("told by each");
        assert_eq!((named.joints, named.alone_in), ([5, 6], 3));
        assert!((named.ratio - 0.2).abs() < 1e-12, "{}", named.ratio);
        assert!(
            named
                .finding()
                .message
                .contains("in each of the 3 recordings alone")
        );
        let one = reorders(Vec::new(), vec![told(0.1)]);
        assert!(one.told_by_each().is_none());
        let other = vec![exchange([4, 6], 0.1), exchange([5, 6], 0.5)];
        let disagreeing = reorders(Vec::new(), vec![told(0.1), other]);
        assert!(disagreeing.told_by_each().is_none());
        let silent = reorders(Vec::new(), vec![told(0.1), vec![exchange([5, 6], 0.9)]]);
        assert!(silent.told_by_each().is_none());
        let pooled = reorders(vec![exchange([5, 6], 0.1)], vec![told(0.1), told(0.1)]);
        assert!(pooled.told_by_each().is_none());
    }

    #[test]
    fn a_torque_that_is_the_model_times_a_gain_plus_friction_is_explained() {
        let mut s = Sums {
            a: vec![Matrix4::zeros()],
            b: vec![Vector4::zeros()],
            yy: vec![0.0],
        };
        for t in 0..200 {
            let t = t as f64 * 0.05;
            let (model, qd) = (t.sin() * 3.0, (0.7 * t).cos());
            let x = Vector4::new(model, qd, qd.signum(), 1.0);
            let y = 1.2 * model + 0.3 * qd + 0.1 * qd.signum() - 0.05;
            s.a[0] += x * x.transpose();
            s.b[0] += x * y;
            s.yy[0] += y * y;
        }
        assert!(s.unexplained(&[0]) < 1e-12, "{}", s.unexplained(&[0]));
    }
}
