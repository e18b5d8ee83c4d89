//! Velocities against the positions' change over time: the logged qd of a
//! moving joint is the rate of its logged q, up to noise and filtering. A
//! time column in milliseconds makes every logged velocity a thousand
//! times the positions' rate; velocities in deg/s beside angles in rad make
//! them 57 times it, and velocities in rad/s read as deg/s (`--angles deg`
//! beside a log whose angles alone are in degrees) a 57th of it. Either way
//! the fit would read every torque against motions that did not happen (a
//! Panda recording with t in ms: a tilt, a 3.8 kg link error and a ripple
//! named after 2 min of CPU and 5 GB; an ABB IRB 120 with qd a 57th of the
//! truth: viscous friction of 7-96 N m s/rad and a 42 kg m^2 armature).

use super::super::digits::sig;
use super::{Check, Finding};
use crate::preprocess::step;
use crate::trajectory::Trajectory;

/// The ratio of a joint's logged velocity RMS to its positions' rate RMS
/// beyond which (either way) the two disagree beyond any filter or noise:
/// a logged velocity filtered harder than the positions is smaller, the
/// positions' rate over [`SPAN`] barely carries their noise, so no honest
/// log comes near it; 57 (deg/s beside rad, or the reverse) and 1000 (ms)
/// clear it.
pub const RATE_RATIO: f64 = 10.0;

/// The positions' rate is their change over this time either side of a
/// sample, s: over a single sample the noise of encoder positions (1e-4
/// rad at 1 kHz: 0.07 rad/s) would pass for motion on a joint whose logged
/// velocity is small; over 10 ms it is 0.007 rad/s, and a motion below 5
/// Hz loses under 2% of its rate.
const SPAN: f64 = 0.01;

/// A joint is judged when its logged velocity RMS or its positions' rate
/// RMS is above this (rad/s or m/s): it moves, beyond the noise of a
/// velocity estimate on a joint held still (0.02 rad/s in the simulator).
const MOVING: f64 = 0.05;

/// One finding when most moving joints' logged velocities are more than
/// [`RATE_RATIO`] times their positions' rate, or less than its inverse.
pub(super) fn findings(recordings: &[Trajectory]) -> Vec<Finding> {
    let dof = recordings.first().map_or(0, Trajectory::dof);
    let ratios: Vec<(usize, f64)> = (0..dof)
        .filter_map(|j| ratio(recordings, j).map(|r| (j, r)))
        .collect();
    let beyond = |off: &dyn Fn(f64) -> bool| -> Vec<usize> {
        ratios
            .iter()
            .filter(|(_, r)| off(*r))
            .map(|(j, _)| j + 1)
            .collect()
    };
    let high = beyond(&|r| r > RATE_RATIO);
    let low = beyond(&|r| r < 1.0 / RATE_RATIO);
    let (joints, hint) = if 2 * high.len() > ratios.len() {
        (
            high,
            "check that the time column is in seconds (not milliseconds: divide it by 1000) \
             and that qd is in rad/s (not deg/s) and m/s",
        )
    } else if 2 * low.len() > ratios.len() {
        (
            low,
            "check that qd is in the unit of q per second (rad/s beside rad; with \
             `--angles deg` both are read as degrees, qd as deg/s, so a log with q in degrees \
             and qd in rad/s needs one of the two converted) and that the time column is in \
             seconds",
        )
    } else {
        return Vec::new();
    };
    let mut sorted: Vec<f64> = ratios.iter().map(|(_, r)| *r).collect();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    vec![Finding {
        check: Check::VelocityRate,
        joints,
        value: median,
        message: format!(
            "the logged velocities are {} times the rate at which the logged positions change \
             (median over the moving joints): {hint}",
            sig(median)
        ),
    }]
}

/// RMS of joint `j`'s logged velocity over RMS of its positions' change
/// over [`SPAN`] either side, over every recording; `None` where it barely
/// moves.
fn ratio(recordings: &[Trajectory], j: usize) -> Option<f64> {
    let (mut logged, mut rate, mut count) = (0.0, 0.0, 0usize);
    for r in recordings.iter().filter(|r| j < r.dof()) {
        let (t, q, qd) = (r.t(), r.q().column(j), r.qd().column(j));
        let reach = match step(r) {
            dt if dt > 0.0 => ((SPAN / dt).round() as usize).max(1),
            _ => 1,
        };
        for k in reach..t.len().saturating_sub(reach) {
            let dt = t[k + reach] - t[k - reach];
            if dt > 0.0 {
                let d = (q[k + reach] - q[k - reach]) / dt;
                rate += d * d;
                logged += qd[k] * qd[k];
                count += 1;
            }
        }
    }
    let floor = MOVING * MOVING * count as f64;
    let moving = (logged > floor || rate > floor) && rate > 0.0 && logged > 0.0;
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

    /// Joints held still, positions with 1e-4 rad of noise at 1 kHz (0.07
    /// rad/s differenced over one sample) and small logged velocities: not
    /// velocities a 57th of the positions' rate.
    #[test]
    fn noisy_positions_of_still_joints_pass() {
        let n = 4000;
        let mut noise = crate::diagnose::search::white_noise(7);
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
        let q = DMatrix::from_fn(n, 2, |_, _| 1e-4 * noise());
        let qd = DMatrix::from_fn(n, 2, |_, _| 1e-3 * noise());
        let recording = Trajectory::new(t, q, qd, None, DMatrix::zeros(n, 2)).unwrap();
        assert!(findings(&[recording]).is_empty());
    }

    #[test]
    fn milliseconds_and_degrees_per_second_are_caught() {
        let radians = 1.0 / 57.3;
        for (time, speed, expected) in [
            (1000.0, 1.0, 1000.0),
            (1.0, 57.3, 57.3),
            (1.0, radians, radians),
        ] {
            let found = findings(&[recording(time, speed)]);
            assert_eq!(found.len(), 1, "{found:?}");
            assert_eq!(found[0].joints, vec![1, 2]);
            assert!((found[0].value - expected).abs() < 0.01 * expected);
        }
    }
}
