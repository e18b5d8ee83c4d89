//! Velocities against the positions' change over time: the logged qd of a
//! moving joint is the rate of its logged q, up to noise and filtering. A
//! time column in milliseconds makes every logged velocity a thousand
//! times the positions' rate; velocities in deg/s beside angles in rad make
//! them 57 times it. Either way the fit would read every torque against
//! motions that did not happen (a Panda recording with t in ms: a tilt, a
//! 3.8 kg link error and a ripple named after 2 min of CPU and 5 GB).

use super::super::digits::sig;
use super::{Check, Finding};
use crate::trajectory::Trajectory;

/// The ratio of a joint's logged velocity RMS to its positions' rate RMS
/// above which the two disagree beyond any filter or noise: noise in the
/// positions raises their differenced rate, lowering the ratio, and a
/// logged velocity filtered harder than the positions is smaller, so no
/// honest log comes near it; 57 (deg/s beside rad) and 1000 (ms) clear it.
pub const RATE_RATIO: f64 = 10.0;

/// A joint is judged when its logged velocity RMS is above this (rad/s or
/// m/s): it moves by its own log, beyond the noise of a velocity estimate
/// on a joint held still (0.02 rad/s in the simulator), whose quantized
/// positions may barely change.
const MOVING: f64 = 0.05;

/// One finding when most moving joints' logged velocities are more than
/// [`RATE_RATIO`] times their positions' rate.
pub(super) fn findings(recordings: &[Trajectory]) -> Vec<Finding> {
    let dof = recordings.first().map_or(0, Trajectory::dof);
    let ratios: Vec<(usize, f64)> = (0..dof)
        .filter_map(|j| ratio(recordings, j).map(|r| (j, r)))
        .collect();
    let high: Vec<usize> = ratios
        .iter()
        .filter(|(_, r)| *r > RATE_RATIO)
        .map(|(j, _)| j + 1)
        .collect();
    if ratios.is_empty() || 2 * high.len() <= ratios.len() {
        return Vec::new();
    }
    let mut sorted: Vec<f64> = ratios.iter().map(|(_, r)| *r).collect();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    vec![Finding {
        check: Check::VelocityRate,
        joints: high,
        value: median,
        message: format!(
            "the logged velocities are {} times the rate at which the logged positions change \
             (median over the moving joints): check that the time column is in seconds (not \
             milliseconds: divide it by 1000) and that qd is in rad/s (not deg/s) and m/s",
            sig(median)
        ),
    }]
}

/// RMS of joint `j`'s logged velocity over RMS of its positions' central
/// difference in time, over every recording; `None` where it barely moves.
fn ratio(recordings: &[Trajectory], j: usize) -> Option<f64> {
    let (mut logged, mut rate) = (0.0, 0.0);
    for r in recordings.iter().filter(|r| j < r.dof()) {
        let (t, q, qd) = (r.t(), r.q().column(j), r.qd().column(j));
        for k in 1..t.len().saturating_sub(1) {
            let dt = t[k + 1] - t[k - 1];
            if dt > 0.0 {
                let d = (q[k + 1] - q[k - 1]) / dt;
                rate += d * d;
                logged += qd[k] * qd[k];
            }
        }
    }
    let count = recordings
        .iter()
        .map(|r| r.t().len().saturating_sub(2))
        .sum::<usize>();
    let moving = logged > MOVING * MOVING * count as f64 && rate > 0.0;
    (moving && rate.is_finite() && logged.is_finite()).then(|| (logged / rate).sqrt())
}

#[cfg(test)]
mod tests {
    use nalgebra::DMatrix;

    use super::*;

    /// Two joints moving as sin and cos of t, logged at 1 kHz; `time` and
    /// `speed` scale the time column and the velocities.
    fn recording(time: f64, speed: f64) -> Trajectory {
        let n = 2000;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
        let q = DMatrix::from_fn(n, 2, |k, j| (t[k] + j as f64).sin());
        let qd = DMatrix::from_fn(n, 2, |k, j| speed * (t[k] + j as f64).cos());
        let zeros = DMatrix::zeros(n, 2);
        let t = t.iter().map(|x| x * time).collect();
        Trajectory::new(t, q, qd, None, zeros).unwrap()
    }

    #[test]
    fn velocities_that_match_the_positions_pass() {
        assert!(findings(&[recording(1.0, 1.0)]).is_empty());
    }

    #[test]
    fn milliseconds_and_degrees_per_second_are_caught() {
        for (time, speed, expected) in [(1000.0, 1.0, 1000.0), (1.0, 57.3, 57.3)] {
            let found = findings(&[recording(time, speed)]);
            assert_eq!(found.len(), 1, "{found:?}");
            assert_eq!(found[0].joints, vec![1, 2]);
            assert!((found[0].value - expected).abs() < 0.01 * expected);
        }
    }
}
