//! Zero-phase Butterworth low-pass (forward-backward, as MATLAB's and
//! SciPy's `filtfilt`): the standard state and torque filter of robot
//! identification. Forward and backward passes cancel each other's phase, so
//! the filter neither delays nor distorts the motion below its cut-off; the
//! magnitude is that of a Butterworth squared, -6 dB at the cut-off.

use super::filters::{PreprocessError, check_dt};

/// Order of each pass (two second-order sections).
pub const ORDER: usize = 4;

/// One second-order section, normalized so that a0 = 1.
#[derive(Debug, Clone, Copy)]
struct Biquad {
    b: [f64; 3],
    a: [f64; 2],
}

impl Biquad {
    /// Low-pass section at normalized angular frequency `w0` with quality
    /// `q` (the bilinear transform prewarped at `w0`, so the cascade of the
    /// Butterworth `q`s is the digital Butterworth filter).
    fn low_pass(w0: f64, q: f64) -> Biquad {
        let (sin, cos) = w0.sin_cos();
        let alpha = sin / (2.0 * q);
        let a0 = 1.0 + alpha;
        let b0 = (1.0 - cos) / 2.0 / a0;
        Biquad {
            b: [b0, 2.0 * b0, b0],
            a: [-2.0 * cos / a0, (1.0 - alpha) / a0],
        }
    }

    /// Filters `x` in place (transposed direct form II), its state started
    /// in the steady state of a constant input equal to the first sample.
    fn run(&self, x: &mut [f64]) {
        let Some(&first) = x.first() else { return };
        let [b0, b1, b2] = self.b;
        let [a1, a2] = self.a;
        let (mut z1, mut z2) = ((1.0 - b0) * first, (b2 - a2) * first);
        for v in x.iter_mut() {
            let y = b0 * *v + z1;
            z1 = b1 * *v - a1 * y + z2;
            z2 = b2 * *v - a2 * y;
            *v = y;
        }
    }
}

/// Series filtered side by side by [`ZeroPhaseLowPass::apply_interleaved`]:
/// one series' recursion waits on its previous output every sample, so
/// interleaving independent series lets the processor overlap their
/// latencies and use its vector units. Each lane's arithmetic is the
/// single series' exactly (same operations in the same order), so the
/// results are bit-identical to [`ZeroPhaseLowPass::apply`].
const LANES: usize = 16;

type Lanes = [f64; LANES];

impl Biquad {
    /// [`Biquad::run`] on every lane of `x`, visited in the iterator's
    /// order (backwards for the second pass).
    #[inline(always)]
    fn run_lanes<'a>(&self, mut x: impl Iterator<Item = &'a mut Lanes>) {
        let Some(head) = x.next() else { return };
        let [b0, b1, b2] = self.b;
        let [a1, a2] = self.a;
        let mut z1 = head.map(|first| (1.0 - b0) * first);
        let mut z2 = head.map(|first| (b2 - a2) * first);
        for v in std::iter::once(head).chain(x) {
            for l in 0..LANES {
                let y = b0 * v[l] + z1[l];
                z1[l] = b1 * v[l] - a1 * y + z2[l];
                z2[l] = b2 * v[l] - a2 * y;
                v[l] = y;
            }
        }
    }
}

/// A zero-phase Butterworth low-pass of order [`ORDER`] per pass.
#[derive(Debug, Clone)]
pub struct ZeroPhaseLowPass {
    sections: Vec<Biquad>,
    /// Samples of odd reflection added at each end against start-up
    /// transients (about three periods of the cut-off).
    pad: usize,
}

impl ZeroPhaseLowPass {
    /// The filter for `cutoff_hz` at sampling interval `dt`; the cut-off
    /// must lie below the Nyquist frequency.
    pub fn new(cutoff_hz: f64, dt: f64) -> Result<Self, PreprocessError> {
        check_dt(dt)?;
        let nyquist = 0.5 / dt;
        if !(cutoff_hz.is_finite() && cutoff_hz > 0.0 && cutoff_hz < nyquist) {
            return Err(PreprocessError::InvalidCutoff {
                cutoff_hz,
                nyquist_hz: nyquist,
            });
        }
        let w0 = 2.0 * std::f64::consts::PI * cutoff_hz * dt;
        let sections = (0..ORDER / 2)
            .map(|k| {
                let angle = (2 * k + 1) as f64 * std::f64::consts::PI / (2 * ORDER) as f64;
                Biquad::low_pass(w0, 1.0 / (2.0 * angle.sin()))
            })
            .collect();
        let pad = (3.0 / (cutoff_hz * dt)).ceil() as usize;
        Ok(Self { sections, pad })
    }

    /// The filtered signal, as long as `x`.
    pub fn apply(&self, x: &[f64]) -> Vec<f64> {
        let n = x.len();
        if n < 2 {
            return x.to_vec();
        }
        let pad = self.pad.min(n - 1);
        // Odd reflection keeps value and slope continuous at the ends.
        let mut y = Vec::with_capacity(n + 2 * pad);
        y.extend((1..=pad).rev().map(|i| 2.0 * x[0] - x[i]));
        y.extend_from_slice(x);
        y.extend((1..=pad).map(|i| 2.0 * x[n - 1] - x[n - 1 - i]));
        for pass in 0..2 {
            for section in &self.sections {
                section.run(&mut y);
            }
            if pass == 0 {
                y.reverse();
            }
        }
        y.reverse();
        y[pad..pad + n].to_vec()
    }

    /// Filters in place every series of `columns`, each column holding
    /// `width` series interleaved sample by sample (series j at j,
    /// j + width, ...; all columns as long), each exactly as
    /// [`ZeroPhaseLowPass::apply`] filters it, [`LANES`] series at a time.
    pub fn apply_interleaved(&self, columns: &mut [&mut [f64]], width: usize) {
        let width = width.max(1);
        let Some(n) = columns.first().map(|c| c.len() / width) else {
            return;
        };
        if n < 2 {
            return;
        }
        let pad = self.pad.min(n - 1);
        let series: Vec<(usize, usize)> = (0..columns.len())
            .flat_map(|c| (0..width).map(move |j| (c, j)))
            .collect();
        let mut buffer = vec![[0.0; LANES]; n + 2 * pad];
        for batch in series.chunks(LANES) {
            // Sample by sample, so that each sample's lanes are written
            // together; unused lanes hold zeros.
            let x = |l: usize, s: usize| {
                batch
                    .get(l)
                    .map_or(0.0, |&(c, j)| columns[c][s * width + j])
            };
            for (s, v) in buffer[pad..pad + n].iter_mut().enumerate() {
                *v = std::array::from_fn(|l| x(l, s));
            }
            // Odd reflection, as in `apply`.
            for i in 1..=pad {
                buffer[pad - i] = std::array::from_fn(|l| 2.0 * x(l, 0) - x(l, i));
                buffer[pad + n - 1 + i] =
                    std::array::from_fn(|l| 2.0 * x(l, n - 1) - x(l, n - 1 - i));
            }
            self.run_both_passes(&mut buffer);
            for (s, v) in buffer[pad..pad + n].iter().enumerate() {
                for (l, &(c, j)) in batch.iter().enumerate() {
                    columns[c][s * width + j] = v[l];
                }
            }
        }
    }

    /// Both passes of every section over the lanes of `buffer`, with the
    /// processor's 256-bit vectors where it has them: the same IEEE
    /// operations in the same order either way (no fused multiply-add),
    /// so the same bits, at about twice the throughput.
    fn run_both_passes(&self, buffer: &mut [Lanes]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the processor has AVX2, checked just above.
            return unsafe { self.run_both_passes_avx2(buffer) };
        }
        self.run_both_passes_portable(buffer)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn run_both_passes_avx2(&self, buffer: &mut [Lanes]) {
        self.run_both_passes_portable(buffer)
    }

    #[inline(always)]
    fn run_both_passes_portable(&self, buffer: &mut [Lanes]) {
        for section in &self.sections {
            section.run_lanes(buffer.iter_mut());
        }
        for section in &self.sections {
            section.run_lanes(buffer.iter_mut().rev());
        }
    }

    /// Power gain of the zero-phase filter at `f_hz` (|H|^4 of one pass).
    pub fn power_gain(cutoff_hz: f64, f_hz: f64) -> f64 {
        let r = (f_hz / cutoff_hz).powi(2 * ORDER as i32);
        1.0 / ((1.0 + r) * (1.0 + r))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn sine(f: f64, dt: f64, n: usize) -> Vec<f64> {
        (0..n)
            .map(|i| (2.0 * std::f64::consts::PI * f * i as f64 * dt).sin())
            .collect()
    }

    fn rms(x: &[f64]) -> f64 {
        (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
    }

    #[test]
    fn passes_the_band_without_phase_and_stops_above() {
        let dt = 1e-3;
        let filter = ZeroPhaseLowPass::new(5.0, dt).unwrap();
        let slow = sine(1.0, dt, 20_000);
        let out = filter.apply(&slow);
        // No lag: the output matches the input sample by sample.
        let error = out.iter().zip(&slow).map(|(a, b)| (a - b).abs());
        assert!(error.fold(0.0, f64::max) < 2e-3);
        // -6 dB (amplitude 1/2) at the cut-off; two octaves above, -96 dB.
        let at_cutoff = filter.apply(&sine(5.0, dt, 20_000));
        let ratio = rms(&at_cutoff[5000..15_000]) / rms(&sine(5.0, dt, 20_000)[5000..15_000]);
        assert!((ratio - 0.5).abs() < 0.01, "{ratio}");
        let fast = filter.apply(&sine(20.0, dt, 20_000));
        assert!(rms(&fast[5000..15_000]) < 1e-4);
    }

    #[test]
    fn constants_and_lines_pass_unchanged() {
        let filter = ZeroPhaseLowPass::new(2.0, 0.01).unwrap();
        let line: Vec<f64> = (0..500).map(|i| 0.3 + 0.01 * i as f64).collect();
        // No lag: a causal filter would trail by slope x delay (1e-2 per
        // sample); the odd reflection keeps start-up transients below 1e-4.
        for (i, (a, b)) in filter.apply(&line).iter().zip(&line).enumerate() {
            let tolerance = if (50..450).contains(&i) { 1e-5 } else { 1e-4 };
            assert!((a - b).abs() < tolerance, "{i}: {a} vs {b}");
        }
    }

    #[test]
    fn a_cutoff_at_or_above_nyquist_is_an_error() {
        assert!(ZeroPhaseLowPass::new(50.0, 0.01).is_err());
        assert!(ZeroPhaseLowPass::new(0.0, 0.01).is_err());
        assert!(ZeroPhaseLowPass::new(f64::NAN, 0.01).is_err());
    }

    #[test]
    fn interleaved_series_are_filtered_bit_for_bit_as_alone() {
        let filter = ZeroPhaseLowPass::new(3.0, 1e-3).unwrap();
        let width = 3;
        let series = |c: usize, j: usize| -> Vec<f64> {
            (0..2500)
                .map(|s| ((s * (c + 2) + 7 * j) as f64 * 0.013).sin() + 0.1 * (c + j) as f64)
                .collect()
        };
        // 11 columns of 3 series: 33 lanes, the last batch partly empty.
        let mut columns: Vec<Vec<f64>> = (0..11)
            .map(|c| {
                (0..2500 * width)
                    .map(|k| series(c, k % width)[k / width])
                    .collect()
            })
            .collect();
        let mut views: Vec<&mut [f64]> = columns.iter_mut().map(|c| c.as_mut_slice()).collect();
        filter.apply_interleaved(&mut views, width);
        for (c, column) in columns.iter().enumerate() {
            for j in 0..width {
                let alone = filter.apply(&series(c, j));
                let together: Vec<f64> = column.iter().skip(j).step_by(width).copied().collect();
                assert!(
                    alone
                        .iter()
                        .zip(&together)
                        .all(|(a, b)| a.to_bits() == b.to_bits())
                );
            }
        }
    }

    proptest! {
        #[test]
        fn output_is_as_long_and_finite(x in prop::collection::vec(-1e3f64..1e3, 0..300), fc in 0.5f64..40.0) {
            let filter = ZeroPhaseLowPass::new(fc, 0.01).unwrap();
            let y = filter.apply(&x);
            prop_assert_eq!(y.len(), x.len());
            prop_assert!(y.iter().all(|v| v.is_finite()));
        }
    }
}
