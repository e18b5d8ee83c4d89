//! Preprocessing chosen from the data: the low-pass cut-off from the motion's
//! bandwidth, the decimation from the cut-off.
//!
//! The motion's bandwidth is read off the measured joint velocities: their
//! power spectrum (Welch: Hann windows of up to [`WELCH_SECONDS`], half
//! overlapping) is white measurement noise above a floor (the median of the
//! upper half of the band) plus the motion, which rises clearly above it at
//! low frequencies. The bandwidth is the frequency below which 99% of the
//! power above the floor lies, in the joint and recording where it is
//! highest. The cut-off is [`CUTOFF_PER_BANDWIDTH`] times that (the
//! zero-phase filter then passes the motion with a gain above 0.9998),
//! within [`MIN_CUTOFF_HZ`] and a fifth of the sample rate; the decimated rate
//! is [`RATE_PER_CUTOFF`] times the cut-off.

use rustfft::{FftPlanner, num_complex::Complex};
use serde::Serialize;

use crate::trajectory::Trajectory;

/// Longest Welch window, s (a frequency resolution of 1/8 Hz).
pub const WELCH_SECONDS: f64 = 8.0;
/// Cut-off over the motion's 99% bandwidth.
pub const CUTOFF_PER_BANDWIDTH: f64 = 3.0;
/// Lowest cut-off chosen, Hz.
pub const MIN_CUTOFF_HZ: f64 = 1.0;
/// Decimated sample rate over the cut-off.
pub const RATE_PER_CUTOFF: f64 = 10.0;
/// A spectral bin is motion when it exceeds the noise floor this many times.
const ABOVE_FLOOR: f64 = 6.0;

/// What the data say and what was chosen from them (printed in reports).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Choice {
    /// Sample rate of the recordings, Hz (the lowest when they differ).
    pub sample_rate_hz: f64,
    /// The highest sample rate of the recordings, Hz.
    pub fastest_rate_hz: f64,
    /// 99% bandwidth of the joint velocities, Hz; `None` when no joint's
    /// motion rises above the noise.
    pub motion_bandwidth_hz: Option<f64>,
    /// Zero-phase low-pass cut-off of states and torque, Hz.
    pub cutoff_hz: f64,
    /// Sample rate after decimation, Hz.
    pub decimated_rate_hz: f64,
}

/// Chooses the cut-off and the decimated rate for `recordings` (raw).
pub fn choose(recordings: &[Trajectory]) -> Choice {
    let sample_rate_hz = recordings
        .iter()
        .map(sample_rate)
        .fold(f64::INFINITY, f64::min);
    let motion_bandwidth_hz = recordings
        .iter()
        .flat_map(|traj| {
            let dt = 1.0 / sample_rate(traj);
            (0..traj.dof()).filter_map(move |j| {
                let v: Vec<f64> = traj.qd().column(j).iter().copied().collect();
                bandwidth(&v, dt)
            })
        })
        .reduce(f64::max);
    let ceiling = 0.2 * sample_rate_hz;
    let cutoff_hz = motion_bandwidth_hz
        .map_or(ceiling, |b| CUTOFF_PER_BANDWIDTH * b)
        .clamp(MIN_CUTOFF_HZ.min(ceiling), ceiling);
    Choice {
        sample_rate_hz,
        fastest_rate_hz: recordings.iter().map(sample_rate).fold(0.0, f64::max),
        motion_bandwidth_hz,
        cutoff_hz,
        decimated_rate_hz: (RATE_PER_CUTOFF * cutoff_hz).min(sample_rate_hz),
    }
}

/// Mean sample rate of a (uniformly sampled) recording, Hz.
pub fn sample_rate(traj: &Trajectory) -> f64 {
    let t = traj.t();
    match t {
        [first, .., last] => (t.len() - 1) as f64 / (last - first),
        _ => f64::INFINITY,
    }
}

/// The 99% bandwidth of `x` above its white-noise floor, Hz.
fn bandwidth(x: &[f64], dt: f64) -> Option<f64> {
    let psd = welch(x, dt)?;
    let bins = psd.len();
    let df = 0.5 / dt / (bins - 1) as f64;
    let mut upper: Vec<f64> = psd[bins / 2..].to_vec();
    upper.sort_by(f64::total_cmp);
    let floor = upper[upper.len() / 2];
    let excess: Vec<f64> = psd
        .iter()
        .map(|&p| {
            if p > ABOVE_FLOOR * floor {
                p - floor
            } else {
                0.0
            }
        })
        .collect();
    let total: f64 = excess.iter().sum();
    if total <= 0.0 {
        return None;
    }
    let mut sum = 0.0;
    for (k, e) in excess.iter().enumerate() {
        sum += e;
        if sum >= 0.99 * total {
            return Some((k as f64 + 0.5) * df);
        }
    }
    None
}

/// One-sided Welch power spectrum (arbitrary scale), bins 0..=L/2; `None`
/// for fewer than 64 samples.
fn welch(x: &[f64], dt: f64) -> Option<Vec<f64>> {
    let longest = (WELCH_SECONDS / dt) as usize;
    let len = prev_power_of_two(x.len().min(longest.max(64)));
    if len < 64 {
        return None;
    }
    let mean = x.iter().sum::<f64>() / x.len() as f64;
    let window: Vec<f64> = (0..len)
        .map(|i| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / len as f64).cos())
        .collect();
    let fft = FftPlanner::new().plan_fft_forward(len);
    let mut psd = vec![0.0; len / 2 + 1];
    let mut buffer = vec![Complex::new(0.0, 0.0); len];
    let mut start = 0;
    while start + len <= x.len() {
        for (b, (v, w)) in buffer.iter_mut().zip(x[start..].iter().zip(&window)) {
            *b = Complex::new((v - mean) * w, 0.0);
        }
        fft.process(&mut buffer);
        for (p, b) in psd.iter_mut().zip(&buffer) {
            *p += b.norm_sqr();
        }
        start += len / 2;
    }
    Some(psd)
}

fn prev_power_of_two(n: usize) -> usize {
    if n == 0 {
        0
    } else {
        1 << (usize::BITS - 1 - n.leading_zeros())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;
    use rand::{Rng, SeedableRng};

    /// Velocity: sines at `frequencies` (Hz) plus uniform white noise of
    /// standard deviation `noise`, at `rate` Hz.
    fn recording(rate: f64, frequencies: &[f64], noise: f64, seconds: f64) -> Trajectory {
        let n = (rate * seconds) as usize;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let t: Vec<f64> = (0..n).map(|i| i as f64 / rate).collect();
        let qd = DMatrix::from_fn(n, 1, |i, _| {
            let s: f64 = frequencies
                .iter()
                .map(|f| (2.0 * std::f64::consts::PI * f * t[i]).sin())
                .sum();
            s + noise * 12f64.sqrt() * (rng.random::<f64>() - 0.5)
        });
        let zero = DMatrix::zeros(n, 1);
        Trajectory::new(t, zero.clone(), qd, None, zero).unwrap()
    }

    #[test]
    fn the_cutoff_follows_the_motion_not_the_sample_rate() {
        for rate in [100.0, 500.0, 1000.0] {
            let choice = choose(&[recording(rate, &[0.2, 0.7, 1.5], 0.02, 20.0)]);
            let b = choice.motion_bandwidth_hz.unwrap();
            // The 1.5 Hz line plus the Hann window's leakage (bins of 1/8 Hz, 0.2 Hz at 100 Hz).
            assert!((1.5..2.0).contains(&b), "{rate} Hz: bandwidth {b}");
            assert!((choice.cutoff_hz - CUTOFF_PER_BANDWIDTH * b).abs() < 1e-12);
            assert!(choice.decimated_rate_hz <= rate);
        }
    }

    #[test]
    fn noise_alone_gives_the_ceiling() {
        let choice = choose(&[recording(100.0, &[], 0.5, 10.0)]);
        assert_eq!(choice.motion_bandwidth_hz, None);
        assert_eq!(choice.cutoff_hz, 20.0);
    }
}
