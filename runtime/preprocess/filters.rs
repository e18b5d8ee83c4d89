//! The filters of preprocessing: thesis section 2.4 downsampling, smoothing of the
//! noisy joint velocity, and acceleration by finite differences (Eq. 2.26).
//!
//! Every filter returns as many samples as it is given.
//!
//! ```
//! use sdnn_runtime::preprocess::{central_difference, moving_average, Centering};
//! let v = [0.0, 1.0, 2.0, 3.0, 4.0];
//! assert_eq!(moving_average(&v, 3, Centering::Centered).unwrap(), v);
//! assert_eq!(central_difference(&v, 0.5).unwrap(), vec![2.0; 5]);
//! ```

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::trajectory::{Trajectory, TrajectoryError};

/// Errors from preprocessing.
#[derive(Debug, Error)]
pub enum PreprocessError {
    /// The downsampling factor is zero.
    #[error("downsample factor must be at least 1, got {factor}")]
    InvalidFactor { factor: usize },
    /// A filter window is unusable.
    #[error("invalid filter window {window}: {reason}")]
    InvalidWindow { window: usize, reason: &'static str },
    /// A Savitzky-Golay polynomial order does not fit its window.
    #[error("Savitzky-Golay order {order} must be smaller than the window {window}")]
    InvalidOrder { order: usize, window: usize },
    /// A derivative above the polynomial order is identically zero.
    #[error("Savitzky-Golay derivative {deriv} must not exceed the polynomial order {order}")]
    InvalidDeriv { deriv: usize, order: usize },
    /// A low-pass cut-off outside (0, Nyquist).
    #[error(
        "low-pass cut-off {cutoff_hz} Hz must be positive and below the Nyquist frequency {nyquist_hz} Hz of the data"
    )]
    InvalidCutoff { cutoff_hz: f64, nyquist_hz: f64 },
    /// A cut-off too low for the recordings' length.
    #[error(
        "low-pass cut-off {cutoff_hz} Hz is too low for a {seconds:.2} s recording: it needs a \
         cut-off of at least {lowest_hz:.3} Hz (four periods in the shortest recording)"
    )]
    CutoffTooLow {
        cutoff_hz: f64,
        lowest_hz: f64,
        seconds: f64,
    },
    /// A decimated rate too low for the cut-off.
    #[error(
        "decimated rate {rate_hz} Hz must be at least twice the low-pass cut-off ({cutoff_hz} Hz)"
    )]
    InvalidRate { rate_hz: f64, cutoff_hz: f64 },
    /// The sampling interval is not a positive finite number.
    #[error("sampling interval must be a positive finite number of seconds, got {dt}")]
    InvalidStep { dt: f64 },
    /// The signal is shorter than the operation needs.
    #[error("{what} needs at least {needed} samples, the signal has {found}")]
    TooFewSamples {
        what: &'static str,
        needed: usize,
        found: usize,
    },
    /// The least-squares fit could not be solved.
    #[error("Savitzky-Golay fit failed: {0}")]
    Numerical(&'static str),
    /// Rebuilding the trajectory failed.
    #[error(transparent)]
    Trajectory(#[from] TrajectoryError),
}

/// Where a moving-average window sits relative to the output sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Centering {
    /// Window around the sample: no lag (for an odd window).
    Centered,
    /// Window ending at the sample: causal, lags by (window - 1) / 2 samples.
    Trailing,
}

impl Centering {
    /// `Centered` for the configuration's `centered: true`.
    pub(crate) fn of(centered: bool) -> Centering {
        if centered {
            Centering::Centered
        } else {
            Centering::Trailing
        }
    }
}

/// Keeps every `factor`-th sample, starting with the first.
///
/// Plain decimation rather than block averaging: each kept row stays a real,
/// simultaneous measurement of q, qd and tau (as in the thesis, which simply
/// reduces 1 kHz to 100 Hz), and the velocity smoothing that follows (a 0.4 s
/// moving average by default) is a far stronger low-pass than a 10-sample
/// block mean would be.
pub fn downsample(traj: &Trajectory, factor: usize) -> Result<Trajectory, PreprocessError> {
    if factor == 0 {
        return Err(PreprocessError::InvalidFactor { factor });
    }
    let keep: Vec<usize> = (0..traj.len()).step_by(factor).collect();
    let rows = |m: &DMatrix<f64>| m.select_rows(keep.iter());
    let t = keep.iter().map(|&i| traj.t()[i]).collect();
    let qdd = traj.qdd().map(rows);
    Ok(Trajectory::new(
        t,
        rows(traj.q()),
        rows(traj.qd()),
        qdd,
        rows(traj.tau()),
    )?)
}

/// Simple moving average (thesis §2.4.2).
///
/// Near the ends the window shrinks instead of padding, so no invented values
/// enter the mean. A centred window shrinks symmetrically, keeping it unbiased
/// on linear trends (at the very first and last sample it is the raw value).
/// An even centred window cannot sit on a sample: it spans `window/2 - 1`
/// samples before and `window/2` after, a half-sample lead.
pub fn moving_average(
    x: &[f64],
    window: usize,
    centering: Centering,
) -> Result<Vec<f64>, PreprocessError> {
    check_window(x.len(), window, "moving average")?;
    let n = x.len();
    let (before, after) = match centering {
        Centering::Centered => ((window - 1) / 2, window / 2),
        Centering::Trailing => (window - 1, 0),
    };
    let out = (0..n)
        .map(|i| {
            let (mut l, mut r) = (before.min(i), after.min(n - 1 - i));
            if centering == Centering::Centered && (l < before || r < after) {
                (l, r) = (l.min(r), l.min(r));
            }
            x[i - l..=i + r].iter().sum::<f64>() / (l + r + 1) as f64
        })
        .collect();
    Ok(out)
}

fn check_window(n: usize, window: usize, what: &'static str) -> Result<(), PreprocessError> {
    if window == 0 {
        return Err(PreprocessError::InvalidWindow {
            window,
            reason: "must be at least 1",
        });
    }
    if n < window {
        return Err(PreprocessError::TooFewSamples {
            what,
            needed: window,
            found: n,
        });
    }
    Ok(())
}

pub(crate) fn check_dt(dt: f64) -> Result<(), PreprocessError> {
    if dt.is_finite() && dt > 0.0 {
        Ok(())
    } else {
        Err(PreprocessError::InvalidStep { dt })
    }
}

/// Derivative by finite differences, thesis Eq. 2.26: central
/// `(x[i+1] - x[i-1]) / 2dt` inside, first-order forward/backward
/// differences at the first/last sample.
pub fn central_difference(x: &[f64], dt: f64) -> Result<Vec<f64>, PreprocessError> {
    check_dt(dt)?;
    let n = x.len();
    if n < 2 {
        return Err(PreprocessError::TooFewSamples {
            what: "finite differences",
            needed: 2,
            found: n,
        });
    }
    let out = (0..n)
        .map(|i| match i {
            0 => (x[1] - x[0]) / dt,
            i if i == n - 1 => (x[i] - x[i - 1]) / dt,
            i => (x[i + 1] - x[i - 1]) / (2.0 * dt),
        })
        .collect();
    Ok(out)
}

/// Savitzky-Golay filter: least-squares polynomial of `order` over an odd
/// `window`, evaluated (or its `deriv`-th derivative) at each sample. Inside
/// the window is centred (zero phase); for the first/last `window/2` samples
/// the polynomial fitted to the first/last full window is evaluated at the
/// sample's own offset, so ends are neither padded nor shifted.
pub fn savitzky_golay(
    x: &[f64],
    window: usize,
    order: usize,
    deriv: usize,
    dt: f64,
) -> Result<Vec<f64>, PreprocessError> {
    check_dt(dt)?;
    if window.is_multiple_of(2) {
        return Err(PreprocessError::InvalidWindow {
            window,
            reason: "Savitzky-Golay needs an odd window",
        });
    }
    if order >= window {
        return Err(PreprocessError::InvalidOrder { order, window });
    }
    if deriv > order {
        return Err(PreprocessError::InvalidDeriv { deriv, order });
    }
    check_window(x.len(), window, "Savitzky-Golay filter")?;
    let half = window / 2;
    // Offsets are scaled to [-1, 1] for a well-conditioned fit.
    let scale = half.max(1) as f64;
    let fit = sg_fit_matrix(window, order, scale)?;
    let factor = (scale * dt).powi(-(deriv as i32));
    let centre = sg_weights(&fit, deriv, 0.0);
    let n = x.len();
    let out = (0..n)
        .map(|i| {
            let start = i.saturating_sub(half).min(n - window);
            let offset = i as f64 - (start + half) as f64;
            let dot = |w: &[f64]| w.iter().zip(&x[start..]).map(|(a, b)| a * b).sum::<f64>();
            let value = if offset == 0.0 {
                dot(&centre)
            } else {
                dot(&sg_weights(&fit, deriv, offset / scale))
            };
            value * factor
        })
        .collect();
    Ok(out)
}

/// Pseudo-inverse of the Vandermonde matrix: maps window samples to
/// polynomial coefficients, `(order + 1) x window`.
fn sg_fit_matrix(window: usize, order: usize, scale: f64) -> Result<DMatrix<f64>, PreprocessError> {
    let half = (window / 2) as f64;
    let vander = DMatrix::from_fn(window, order + 1, |k, p| {
        ((k as f64 - half) / scale).powi(p as i32)
    });
    crate::kernels::svd(vander)
        .ok_or(PreprocessError::Numerical(
            "the Savitzky-Golay fit matrix has no SVD (non-finite or not converging)",
        ))?
        .pseudo_inverse(1e-12)
        .map_err(PreprocessError::Numerical)
}

/// Weights giving the `deriv`-th derivative of the fitted polynomial at `u`.
fn sg_weights(fit: &DMatrix<f64>, deriv: usize, u: f64) -> Vec<f64> {
    let coeff: Vec<f64> = (0..fit.nrows())
        .map(|p| {
            if p < deriv {
                return 0.0;
            }
            let falling: f64 = ((p - deriv + 1)..=p).map(|k| k as f64).product();
            falling * u.powi((p - deriv) as i32)
        })
        .collect();
    (0..fit.ncols())
        .map(|j| coeff.iter().enumerate().map(|(p, c)| c * fit[(p, j)]).sum())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::preprocess::{Filter, Preprocess};
    use proptest::prelude::*;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol * (1.0 + a.abs().max(b.abs()))
    }

    /// A 1 kHz, 2 s, 2-joint trajectory with qd = d/dt q.
    fn sine_trajectory(noise: f64) -> Trajectory {
        let n = 2000;
        let t: Vec<f64> = (0..n).map(|i| i as f64 * 1e-3).collect();
        // Deterministic pseudo-noise, no RNG needed.
        let jitter = |i: usize| noise * ((i as f64 * 12.9898).sin() * 43758.5453).fract();
        let q = DMatrix::from_fn(n, 2, |i, j| (t[i] * (j + 1) as f64).sin());
        let qd = DMatrix::from_fn(n, 2, |i, j| {
            (j + 1) as f64 * (t[i] * (j + 1) as f64).cos() + jitter(i)
        });
        let tau = DMatrix::from_element(n, 2, 1.0);
        Trajectory::new(t, q, qd, None, tau).unwrap()
    }

    #[test]
    fn downsample_keeps_every_kth() {
        let traj = sine_trajectory(0.0);
        let out = downsample(&traj, 10).unwrap();
        assert_eq!(out.len(), 200);
        assert_eq!(out.t()[3], traj.t()[30]);
        assert_eq!(out.q()[(5, 1)], traj.q()[(50, 1)]);
        assert!(matches!(
            downsample(&traj, 0),
            Err(PreprocessError::InvalidFactor { .. })
        ));
    }

    #[test]
    fn default_pipeline_matches_thesis() {
        let cfg = Preprocess::default();
        assert_eq!(cfg.downsample, 10);
        let out = cfg.apply(&sine_trajectory(0.05)).unwrap();
        assert_eq!(out.len(), 200);
        // Away from the ends the SMA-smoothed acceleration follows -j^2 sin(j t)
        // up to the amplitude loss of a 0.4 s window.
        let qdd = out.qdd().unwrap();
        for i in 40..160 {
            let exact = -(out.t()[i]).sin();
            assert!(
                (qdd[(i, 0)] - exact).abs() < 0.1,
                "{i}: {} vs {exact}",
                qdd[(i, 0)]
            );
        }
    }

    #[test]
    fn savitzky_golay_pipeline_is_accurate() {
        let cfg = Preprocess {
            downsample: 10,
            filter: Filter::SavitzkyGolay {
                window: 21,
                order: 3,
            },
            filter_torque: false,
        };
        let out = cfg.apply(&sine_trajectory(0.0)).unwrap();
        let qdd = out.qdd().unwrap();
        for i in 0..out.len() {
            let exact = -4.0 * (2.0 * out.t()[i]).sin();
            // The end fits extrapolate within their window, so they are looser.
            let tol = if (10..out.len() - 10).contains(&i) {
                1e-4
            } else {
                1e-2
            };
            assert!(
                (qdd[(i, 1)] - exact).abs() < tol,
                "{i}: {} vs {exact}",
                qdd[(i, 1)]
            );
        }
    }

    /// `filter_torque` smooths the torque like the acceleration; off, the
    /// torque is kept as measured.
    #[test]
    fn torque_filter_removes_noise_only_when_asked() {
        let base = sine_trajectory(0.0);
        let jitter = |i: usize| 0.05 * ((i as f64 * 78.233).sin() * 43758.5453).fract();
        let tau = DMatrix::from_fn(base.len(), 2, |i, _| (0.5 * base.t()[i]).sin() + jitter(i));
        let noisy = Trajectory::new(
            base.t().to_vec(),
            base.q().clone(),
            base.qd().clone(),
            None,
            tau,
        )
        .unwrap();
        let sg = Filter::SavitzkyGolay {
            window: 21,
            order: 3,
        };
        for filter in [Preprocess::default().filter, sg] {
            let raw = Preprocess {
                filter: filter.clone(),
                ..Preprocess::default()
            };
            let kept = raw.apply(&noisy).unwrap();
            assert_eq!(kept.tau(), &downsample(&noisy, 10).unwrap().tau().clone());
            let smooth = Preprocess {
                filter_torque: true,
                ..raw
            }
            .apply(&noisy)
            .unwrap();
            // Away from the ends the pseudo-noise averages out and the slow
            // sine passes.
            let rms = |traj: &Trajectory| {
                let sum: f64 = (40..160)
                    .map(|i| (traj.tau()[(i, 0)] - (0.5 * traj.t()[i]).sin()).powi(2))
                    .sum();
                (sum / 120.0).sqrt()
            };
            assert!(
                rms(&smooth) < 0.4 * rms(&kept),
                "{filter:?}: {} vs {}",
                rms(&smooth),
                rms(&kept)
            );
        }
    }

    /// A joint that moves for 1 s and then stands still, logged as exactly
    /// zero: the Butterworth's tail of the move is not motion, so the
    /// filtered velocity is zero wherever the log says zero, and the move
    /// itself keeps its filtered velocity.
    #[test]
    fn a_joint_logged_still_has_zero_filtered_velocity() {
        let n = 4000;
        let t: Vec<f64> = (0..n).map(|i| i as f64 * 1e-3).collect();
        let pi = std::f64::consts::PI;
        let moving = |t: f64| t < 1.0;
        let q = DMatrix::from_fn(n, 1, |i, _| 0.5 * (1.0 - (pi * t[i].min(1.0)).cos()));
        let qd = DMatrix::from_fn(n, 1, |i, _| {
            if moving(t[i]) {
                0.5 * pi * (pi * t[i]).sin()
            } else {
                0.0
            }
        });
        let tau = DMatrix::from_element(n, 1, 0.0);
        let traj = Trajectory::new(t.clone(), q, qd.clone(), None, tau).unwrap();
        let butterworth = Preprocess {
            filter: Filter::Butterworth { cutoff_hz: 5.0 },
            downsample: 1,
            ..Preprocess::default()
        };
        let filtered = butterworth.filter_at_full_rate(&traj).unwrap();
        let tail = butterworth.smooth_columns(&qd, 1e-3).unwrap();
        let still: Vec<usize> = (0..n).filter(|&i| !moving(t[i])).collect();
        assert!(
            still.iter().any(|&i| tail[(i, 0)] != 0.0),
            "no tail to remove"
        );
        assert!(still.iter().all(|&i| filtered.qd()[(i, 0)] == 0.0));
        assert_eq!(filtered.qd()[(500, 0)], tail[(500, 0)]);
    }

    #[test]
    fn too_short_for_window_is_an_error() {
        let cfg = Preprocess {
            downsample: 100,
            ..Preprocess::default()
        };
        let err = cfg.apply(&sine_trajectory(0.0)).unwrap_err().to_string();
        assert!(
            err.contains("at least 40") && err.contains("has 20"),
            "{err}"
        );
    }

    #[test]
    fn config_serde_round_trip_and_defaults() {
        let json = serde_json::to_string(&Preprocess::default()).unwrap();
        assert_eq!(
            serde_json::from_str::<Preprocess>(&json).unwrap(),
            Preprocess::default()
        );
        let sg: Preprocess =
            serde_json::from_str(r#"{"filter":{"kind":"savitzky_golay","window":9,"order":2}}"#)
                .unwrap();
        assert_eq!(sg.downsample, 10);
        assert!(serde_json::from_str::<Preprocess>(r#"{"downsampel":3}"#).is_err());
    }

    #[test]
    fn bad_arguments_are_errors() {
        let x = [1.0; 10];
        assert!(moving_average(&x, 0, Centering::Centered).is_err());
        assert!(moving_average(&x, 11, Centering::Trailing).is_err());
        assert!(central_difference(&x[..1], 1.0).is_err());
        assert!(central_difference(&x, 0.0).is_err());
        assert!(savitzky_golay(&x, 4, 2, 0, 1.0).is_err());
        assert!(savitzky_golay(&x, 5, 5, 0, 1.0).is_err());
        assert!(savitzky_golay(&x, 5, 2, 3, 1.0).is_err());
    }

    #[test]
    fn trailing_average_is_causal() {
        let x = [0.0, 0.0, 3.0, 3.0, 3.0];
        let y = moving_average(&x, 3, Centering::Trailing).unwrap();
        assert_eq!(y, vec![0.0, 0.0, 1.0, 2.0, 3.0]);
    }

    proptest! {
        #[test]
        fn central_difference_exact_on_quadratics(
            a in -10.0f64..10.0, b in -10.0f64..10.0, c in -10.0f64..10.0,
            n in 3usize..50, dt in 1e-3f64..1.0,
        ) {
            let x: Vec<f64> = (0..n).map(|i| { let t = i as f64 * dt; a * t * t + b * t + c }).collect();
            let d = central_difference(&x, dt).unwrap();
            prop_assert_eq!(d.len(), n);
            for (i, di) in d.iter().enumerate().take(n - 1).skip(1) {
                let exact = 2.0 * a * i as f64 * dt + b;
                prop_assert!(close(*di, exact, 1e-8), "{} vs {}", di, exact);
            }
        }

        #[test]
        fn savitzky_golay_exact_on_polynomials(
            coeffs in prop::collection::vec(-3.0f64..3.0, 4),
            half in 1usize..8, order in 1usize..4, extra in 0usize..20, dt in 0.01f64..0.5,
        ) {
            let window = 2 * half + 1;
            prop_assume!(order < window);
            let n = window + extra;
            let degree = order.min(3);
            let poly = |t: f64| (0..=degree).map(|p| coeffs[p] * t.powi(p as i32)).sum::<f64>();
            let dpoly = |t: f64| (1..=degree).map(|p| p as f64 * coeffs[p] * t.powi(p as i32 - 1)).sum::<f64>();
            let x: Vec<f64> = (0..n).map(|i| poly(i as f64 * dt)).collect();
            let y = savitzky_golay(&x, window, order, 0, dt).unwrap();
            let dy = savitzky_golay(&x, window, order, 1, dt).unwrap();
            prop_assert_eq!((y.len(), dy.len()), (n, n));
            let tmax = n as f64 * dt;
            let mag = 1.0 + (0..=degree).map(|p| coeffs[p].abs() * tmax.powi(p as i32)).sum::<f64>();
            for i in 0..n {
                let t = i as f64 * dt;
                prop_assert!((y[i] - poly(t)).abs() < 1e-8 * mag, "value at {}", i);
                prop_assert!((dy[i] - dpoly(t)).abs() < 1e-7 * mag / dt, "slope at {}", i);
            }
        }

        #[test]
        fn moving_average_of_constant_is_constant(
            c in -1e6f64..1e6, n in 1usize..100, window in 1usize..50, centered in any::<bool>(),
        ) {
            prop_assume!(window <= n);
            let mode = if centered { Centering::Centered } else { Centering::Trailing };
            let y = moving_average(&vec![c; n], window, mode).unwrap();
            prop_assert_eq!(y.len(), n);
            for v in y {
                prop_assert!(close(v, c, 1e-12));
            }
        }

        #[test]
        fn centred_odd_average_keeps_lines(a in -5.0f64..5.0, b in -5.0f64..5.0, n in 5usize..60, half in 0usize..5) {
            let window = 2 * half + 1;
            prop_assume!(window <= n);
            let x: Vec<f64> = (0..n).map(|i| a * i as f64 + b).collect();
            let y = moving_average(&x, window, Centering::Centered).unwrap();
            for (yi, xi) in y.iter().zip(&x) {
                prop_assert!(close(*yi, *xi, 1e-10));
            }
        }
    }
}
