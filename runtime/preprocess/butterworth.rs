//! Zero-phase Butterworth low-pass (forward-backward, as MATLAB's and
//! SciPy's `filtfilt`): the standard state and torque filter of robot
//! identification. Forward and backward passes cancel each other's phase, so
//! the filter neither delays nor distorts the motion below its cut-off; the
//! magnitude is that of a Butterworth squared, -6 dB at the cut-off.

use super::filters::{PreprocessError, check_dt};

/// Order of each pass (two second-order sections).
pub const ORDER: usize = 4;

/// Second-order sections per pass.
const SECTIONS: usize = ORDER / 2;

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
    /// One sample of [`Biquad::run`] on every lane of `v`, with the
    /// section's state `z` of each lane.
    #[inline(always)]
    fn step_lanes(&self, v: &mut Lanes, [z1, z2]: &mut [Lanes; 2]) {
        let [b0, b1, b2] = self.b;
        let [a1, a2] = self.a;
        for l in 0..LANES {
            let y = b0 * v[l] + z1[l];
            z1[l] = b1 * v[l] - a1 * y + z2[l];
            z2[l] = b2 * v[l] - a2 * y;
            v[l] = y;
        }
    }

    /// The state [`Biquad::run`] starts from, for each lane's first input.
    #[inline(always)]
    fn start_lanes(&self, first: &Lanes) -> [Lanes; 2] {
        let [b0, _, b2] = self.b;
        let [_, a2] = self.a;
        [first.map(|x| (1.0 - b0) * x), first.map(|x| (b2 - a2) * x)]
    }
}

/// [`Biquad::run`] of each of `sections` in turn on every lane of `x`,
/// visited in the iterator's order (backwards for the second pass), in
/// one sweep: each sample passes every section before the next sample. A
/// section's output at a sample depends on its input up to that sample
/// only, so these are the operations of running the sections one after
/// the other over the whole series, in the same order per value (the
/// same bits), with the buffer read once, not once per section.
#[inline(always)]
fn run_cascade<'a>(sections: &[Biquad; SECTIONS], mut x: impl Iterator<Item = &'a mut Lanes>) {
    let Some(head) = x.next() else { return };
    // Each section starts in the steady state of its own first input: the
    // previous section's first output.
    let mut states = [[[0.0; LANES]; 2]; SECTIONS];
    for (section, state) in sections.iter().zip(&mut states) {
        *state = section.start_lanes(head);
        section.step_lanes(head, state);
    }
    for v in x {
        for (section, state) in sections.iter().zip(&mut states) {
            section.step_lanes(v, state);
        }
    }
}

/// A zero-phase Butterworth low-pass of order [`ORDER`] per pass.
#[derive(Debug, Clone)]
pub struct ZeroPhaseLowPass {
    sections: [Biquad; SECTIONS],
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
        let sections = std::array::from_fn(|k| {
            let angle = (2 * k + 1) as f64 * std::f64::consts::PI / (2 * ORDER) as f64;
            Biquad::low_pass(w0, 1.0 / (2.0 * angle.sin()))
        });
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
        let n = columns.first().map_or(0, |c| c.len() / width.max(1));
        let every: Vec<usize> = (0..n).collect();
        let shared: Vec<&[f64]> = columns.iter().map(|c| &c[..]).collect();
        let filtered = self.apply_interleaved_at(&shared, width, &every);
        for (column, filtered) in columns.iter_mut().zip(filtered) {
            column[..filtered.len()].copy_from_slice(&filtered);
        }
    }

    /// [`ZeroPhaseLowPass::apply_interleaved`] kept at the samples
    /// `samples` alone: per column, its rows there (`width` values per
    /// sample). Every sample passes the filter; only the kept ones are
    /// written out (a diagnosis keeps one sample in tens).
    pub fn apply_interleaved_at(
        &self,
        columns: &[&[f64]],
        width: usize,
        samples: &[usize],
    ) -> Vec<Vec<f64>> {
        let width = width.max(1);
        let n = columns.first().map_or(0, |c| c.len() / width);
        let mut kept: Vec<Vec<f64>> = columns
            .iter()
            .map(|c| match n < 2 {
                // Nothing to filter: the series as they are.
                true => samples
                    .iter()
                    .flat_map(|&s| &c[s * width..(s + 1) * width])
                    .copied()
                    .collect(),
                false => vec![0.0; samples.len() * width],
            })
            .collect();
        if n < 2 {
            return kept;
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
            for (k, &s) in samples.iter().enumerate() {
                let v = &buffer[pad + s];
                for (l, &(c, j)) in batch.iter().enumerate() {
                    kept[c][k * width + j] = v[l];
                }
            }
        }
        kept
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
        run_cascade(&self.sections, buffer.iter_mut());
        run_cascade(&self.sections, buffer.iter_mut().rev());
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

    #[test]
    fn kept_samples_are_those_of_the_whole_filtered_series() {
        let filter = ZeroPhaseLowPass::new(3.0, 1e-3).unwrap();
        let width = 2;
        let columns: Vec<Vec<f64>> = (0..9)
            .map(|c| {
                (0..3000)
                    .map(|k| ((k * (c + 1)) as f64 * 0.007).sin())
                    .collect()
            })
            .collect();
        let mut whole = columns.clone();
        let mut views: Vec<&mut [f64]> = whole.iter_mut().map(|c| c.as_mut_slice()).collect();
        filter.apply_interleaved(&mut views, width);
        let samples: Vec<usize> = (40..1460).step_by(30).chain([1499]).collect();
        let shared: Vec<&[f64]> = columns.iter().map(|c| c.as_slice()).collect();
        let kept = filter.apply_interleaved_at(&shared, width, &samples);
        for (column, kept) in whole.iter().zip(&kept) {
            let picked = samples
                .iter()
                .flat_map(|&s| &column[s * width..(s + 1) * width]);
            let bits = |x: &f64| x.to_bits();
            assert!(picked.map(bits).eq(kept.iter().map(bits)));
        }
        // Too short to filter: the samples as they are.
        let short = [&[1.0, 2.0][..]];
        assert_eq!(
            filter.apply_interleaved_at(&short, 2, &[0]),
            vec![vec![1.0, 2.0]]
        );
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
