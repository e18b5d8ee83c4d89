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
use super::scale::{self, LEAST_GAIN, MOST_GAIN};
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

/// The sums with the joints read in `order` (joint i's signals and torque
/// are the recorded joint `order[i]`'s), and the model's torque at each
/// row of the stacked data (joint i's at the recorded joint `order[i]`'s
/// rows). `None` when the model cannot evaluate a sample.
fn sums(model: &dyn Dynamics, data: &Stacked, order: &[usize]) -> Option<(Sums, Vec<f64>)> {
    let n = data.dof;
    let feature = |formula: &str| GENERIC_FEATURES.iter().position(|f| f.1 == formula);
    let sign = &data.generic[feature("sign(qd)")?];
    let mut s = Sums {
        a: vec![Matrix4::zeros(); n],
        b: vec![Vector4::zeros(); n],
        yy: vec![0.0; n],
    };
    let samples = data.measured.len() / n.max(1);
    let mut torque = vec![0.0; data.measured.len()];
    let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    for sample in 0..samples {
        let row = |i: usize| sample * n + order[i];
        for i in 0..n {
            (q[i], qd[i], qdd[i]) = (data.angle[row(i)], data.qd[row(i)], data.qdd[row(i)]);
        }
        let tau = model.tau(&q, &qd, &qdd).ok()?;
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
    Some((s, torque))
}

/// The gain of the model's torque `torque` (per row) in recorded joint
/// `j`'s measured torque, as the torque checks fit it.
fn gain(data: &Stacked, torque: &[f64], j: usize) -> Option<scale::Estimate> {
    scale::gain_of(data, j, |r| torque[r]).model
}

/// Whether a pair's gains, as recorded and exchanged, tell their exchange:
/// see [`GainsTell`].
fn gains_tell(
    recorded: [Option<scale::Estimate>; 2],
    exchanged: [Option<scale::Estimate>; 2],
    min_t: f64,
) -> Option<GainsTell> {
    let low = |g: &Option<scale::Estimate>| g.is_some_and(|g| g.clearly_below(LEAST_GAIN, min_t));
    let follows = |g: &Option<scale::Estimate>| {
        g.is_some_and(|g| g.clearly_above(LEAST_GAIN, min_t) && g.value < MOST_GAIN)
    };
    let told =
        recorded.iter().any(low) && exchanged.iter().any(follows) && !exchanged.iter().any(low);
    told.then_some(GainsTell {
        recorded,
        exchanged,
    })
}

/// What the joint exchanges say: every pair's exchange against the
/// recorded order, and the exchanges found.
pub(super) struct Reorders {
    pub(super) each: Vec<Exchange>,
    /// Found one at a time, each judged against the order with the ones
    /// before it undone: two joints exchanged make a third joint's model
    /// torque wrong too, and exchanging that one with a fourth then looks
    /// better than the recorded order.
    pub(super) found: Vec<Exchange>,
}

/// Every pair of joints' exchange of all their columns, against the
/// recorded order (the share of the pair's torque energy unexplained, and
/// the gains, `min_t` standard errors clear), and the exchanges found.
pub(super) fn exchanges(model: &dyn Dynamics, data: &Stacked, min_t: f64) -> Reorders {
    let n = data.dof;
    let mut order: Vec<usize> = (0..n).collect();
    let mut reorders = Reorders {
        each: Vec::new(),
        found: Vec::new(),
    };
    loop {
        let Some((current, torque)) = sums(model, data, &order) else {
            return reorders;
        };
        let current_gains: Vec<_> = (0..n).map(|j| gain(data, &torque, j)).collect();
        let moved = |j: usize| reorders.found.iter().any(|e| e.joints.contains(&(j + 1)));
        let mut round = Vec::new();
        for j in (0..n).filter(|&j| !moved(j)) {
            for k in (j + 1..n).filter(|&k| !moved(k)) {
                let mut swapped = order.clone();
                swapped.swap(j, k);
                if let Some((exchanged, torque)) = sums(model, data, &swapped) {
                    let mut exchange = Exchange::new(
                        Exchanged::Joints,
                        [j + 1, k + 1],
                        exchanged.unexplained(&[j, k]),
                        current.unexplained(&[j, k]),
                    );
                    let pair = [order[j], order[k]];
                    let exchanged = pair.map(|p| gain(data, &torque, p));
                    exchange.gains = gains_tell(pair.map(|p| current_gains[p]), exchanged, min_t);
                    round.push(exchange);
                }
            }
        }
        let best = round
            .iter()
            .filter(|e| e.swapped())
            .min_by(|a, b| a.ratio.total_cmp(&b.ratio))
            .cloned();
        if reorders.found.is_empty() {
            reorders.each = round;
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
