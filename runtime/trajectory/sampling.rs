//! Uniform sampling: checking a time column and resampling onto a
//! uniform grid by linear interpolation.

use super::*;

/// `traj` resampled to `opts.resample_hz`, or checked for uniform sampling
/// when no rate is given (any reader's last step).
pub fn uniform(
    path: &Path,
    traj: Trajectory,
    opts: &ReadOptions,
) -> Result<Trajectory, TrajectoryError> {
    match opts.resample_hz {
        Some(hz) => {
            let out = resample(&traj, hz)?;
            if out.len() < opts.min_samples {
                return Err(TrajectoryError::TooFewSamples {
                    path: path.to_owned(),
                    found: out.len(),
                    min: opts.min_samples,
                });
            }
            Ok(out)
        }
        None => check_uniform(path, traj.t()).map(|()| traj),
    }
}

/// Shortest time step accepted: a 1 MHz log.
pub const MIN_STEP: f64 = 1e-6;

pub(super) fn check_time(path: &Path, t: &[f64], lines: &[u64]) -> Result<(), TrajectoryError> {
    for (i, w) in t.windows(2).enumerate() {
        if w[1] > w[0] && w[1] - w[0] < MIN_STEP {
            return Err(TrajectoryError::Implausible {
                path: path.to_owned(),
                line: lines[i + 1],
                column: "t".into(),
                value: w[1],
                problem: format!(
                    "{:e} s after the previous sample; steps below {MIN_STEP:e} s (1 MHz) are \
                     not a joint log (time in another unit? the contract is seconds)",
                    w[1] - w[0]
                ),
            });
        }
        if w[1] <= w[0] {
            return Err(TrajectoryError::NonMonotonicTime {
                path: path.to_owned(),
                line: lines[i + 1],
                previous: w[0],
                current: w[1],
            });
        }
    }
    Ok(())
}

/// Fails when any step deviates from the median step by more than
/// [`JITTER_TOLERANCE`] (relative).
pub(super) fn check_uniform(path: &Path, t: &[f64]) -> Result<(), TrajectoryError> {
    let mut steps: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    if steps.is_empty() {
        return Ok(());
    }
    steps.sort_by(f64::total_cmp);
    let (min_step, max_step) = (steps[0], steps[steps.len() - 1]);
    let median_step = steps[steps.len() / 2];
    let deviation = (max_step - median_step).max(median_step - min_step) / median_step;
    if deviation > JITTER_TOLERANCE {
        return Err(TrajectoryError::NonUniformSampling {
            path: path.to_owned(),
            min_step,
            max_step,
            median_step,
        });
    }
    Ok(())
}

/// Resamples every channel onto the grid `t0 + k / hz` (k = 0, 1, ... while
/// not past the last sample) by linear interpolation between the two
/// neighbouring samples. Linear interpolation cannot overshoot, so it adds no
/// artefacts to noisy sensor data; it does slightly smooth content near the
/// new Nyquist rate.
pub fn resample(traj: &Trajectory, hz: f64) -> Result<Trajectory, TrajectoryError> {
    if !(hz.is_finite() && hz > 0.0) {
        return Err(TrajectoryError::InvalidResampleRate { hz });
    }
    let t = traj.t();
    let Some((&t0, &t_end)) = t.first().zip(t.last()) else {
        return Ok(traj.clone());
    };
    // The small slack keeps a grid point that lands on t_end despite rounding.
    let samples = ((t_end - t0) * hz * (1.0 + 1e-12)).floor() + 1.0;
    if samples > MAX_RESAMPLED as f64 {
        let span = t_end - t0;
        return Err(TrajectoryError::ResampleTooLarge { span, hz, samples });
    }
    let n = samples as usize;
    let grid: Vec<f64> = (0..n).map(|k| t0 + k as f64 / hz).collect();
    let weights = interpolation_weights(t, &grid);
    let interp = |m: &DMatrix<f64>| {
        DMatrix::from_fn(n, m.ncols(), |r, j| {
            let (i, w) = weights[r];
            let next = (i + 1).min(m.nrows() - 1);
            m[(i, j)] * (1.0 - w) + m[(next, j)] * w
        })
    };
    Trajectory::new(
        grid.clone(),
        interp(traj.q()),
        interp(traj.qd()),
        traj.qdd().map(interp),
        interp(traj.tau()),
    )
}

/// For each grid time, the left sample index and the weight of the right one.
pub(super) fn interpolation_weights(t: &[f64], grid: &[f64]) -> Vec<(usize, f64)> {
    let mut i = 0;
    grid.iter()
        .map(|&g| {
            while i + 2 < t.len() && t[i + 1] < g {
                i += 1;
            }
            if i + 1 >= t.len() {
                return (i, 0.0);
            }
            let w = ((g - t[i]) / (t[i + 1] - t[i])).clamp(0.0, 1.0);
            (i, w)
        })
        .collect()
}
