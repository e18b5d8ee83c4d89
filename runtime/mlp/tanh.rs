//! A branch-free, vectorizable `tanh`, accurate to a few ulp.
//!
//! Training spends most of its time in the hidden layers' activations (128
//! `tanh` per sample for 64-64 layers); libm's scalar `tanh` (or one `exp`)
//! costs several nanoseconds each and cannot be vectorized. Here
//! tanh(x) = sign(x) e / (e + 2) with e = expm1(2|x|), and expm1 by
//! Cody-Waite reduction y = k ln2 + r (|r| <= ln2 / 2, k found with the
//! round-to-nearest magic constant), a degree-13 Taylor polynomial for
//! expm1(r), and 2^k built from the exponent bits: only multiplies, adds, a
//! division and bit operations, which the compiler turns into SIMD over a
//! slice. expm1 keeps small arguments accurate (no cancellation in 1 - ...),
//! so the error is a few ulp relative over the whole range (tested against
//! `f64::tanh`).

/// 1.5 * 2^52: adding it rounds a value below 2^51 to an integer, which then
/// sits in the low mantissa bits.
const ROUND: f64 = 6_755_399_441_055_744.0;
const LOG2_E: f64 = std::f64::consts::LOG2_E;
/// ln 2 split so that k * LN2_HI is exact for the k used here.
const LN2_HI: f64 = 6.931_471_803_691_238e-1;
const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;
/// Beyond this |x|, tanh(x) rounds to +-1 (and 2|x| stays clear of overflow).
const SATURATED: f64 = 20.0;

/// tanh(x). NaN propagates.
#[inline(always)]
pub fn tanh(x: f64) -> f64 {
    // A comparison, not `min`, so that NaN propagates.
    let y = 2.0
        * if x.abs() > SATURATED {
            SATURATED
        } else {
            x.abs()
        };
    let rounded = y * LOG2_E + ROUND;
    let k = rounded - ROUND;
    let r = (y - k * LN2_HI) - k * LN2_LO;
    // 2^k from the integer k held in the low mantissa bits of `rounded`.
    let scale = f64::from_bits((rounded.to_bits() << 52).wrapping_add(1023 << 52));
    let e = scale * expm1_reduced(r) + (scale - 1.0);
    (e / (e + 2.0)).copysign(x)
}

/// expm1(r) for |r| <= ln2 / 2: Taylor to degree 13 (truncation < 1e-17
/// relative), Horner.
#[inline(always)]
fn expm1_reduced(r: f64) -> f64 {
    const C: [f64; 12] = [
        1.0 / 2.0,
        1.0 / 6.0,
        1.0 / 24.0,
        1.0 / 120.0,
        1.0 / 720.0,
        1.0 / 5_040.0,
        1.0 / 40_320.0,
        1.0 / 362_880.0,
        1.0 / 3_628_800.0,
        1.0 / 39_916_800.0,
        1.0 / 479_001_600.0,
        1.0 / 6_227_020_800.0,
    ];
    let mut p = C[11];
    for c in C[..11].iter().rev() {
        p = p * r + c;
    }
    r + r * r * p
}

/// `out[i] = tanh(z[i])` over slices, vectorized by the compiler: with
/// AVX-512 or AVX2 when the CPU has them (checked once per call, the same
/// code compiled for those features), else with the build's baseline SIMD.
pub fn tanh_slice(out: &mut [f64], z: &[f64]) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f") {
            // SAFETY: the CPU supports the features the function enables.
            return unsafe { tanh_slice_avx512(out, z) };
        }
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: as above.
            return unsafe { tanh_slice_avx2(out, z) };
        }
    }
    tanh_slice_baseline(out, z);
}

#[inline(always)]
fn tanh_slice_baseline(out: &mut [f64], z: &[f64]) {
    for (a, &x) in out.iter_mut().zip(z) {
        *a = tanh(x);
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn tanh_slice_avx512(out: &mut [f64], z: &[f64]) {
    tanh_slice_baseline(out, z);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn tanh_slice_avx2(out: &mut [f64], z: &[f64]) {
    tanh_slice_baseline(out, z);
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn relative_error(x: f64) -> f64 {
        let (ours, reference) = (tanh(x), x.tanh());
        if reference == 0.0 {
            ours.abs()
        } else {
            ((ours - reference) / reference).abs()
        }
    }

    #[test]
    fn a_dense_sweep_matches_libm_to_a_few_ulp() {
        let mut worst: f64 = 0.0;
        for k in -200_000..=200_000 {
            let x = f64::from(k) * 1e-4; // -20 .. 20
            worst = worst.max(relative_error(x));
        }
        for e in -300..0 {
            worst = worst.max(relative_error(10f64.powi(e)));
            worst = worst.max(relative_error(-3.7 * 10f64.powi(e)));
        }
        assert!(worst < 1e-15, "worst relative error {worst:e}");
    }

    #[test]
    fn every_code_path_of_the_slice_gives_the_scalar_values() {
        let z: Vec<f64> = (0..1001).map(|k| f64::from(k - 500) * 0.037).collect();
        let scalar: Vec<f64> = z.iter().map(|&x| tanh(x)).collect();
        let mut out = vec![0.0; z.len()];
        tanh_slice(&mut out, &z);
        assert_eq!(out, scalar);
        tanh_slice_baseline(&mut out, &z);
        assert_eq!(out, scalar);
    }

    #[test]
    fn saturation_signs_zeros_and_nan() {
        assert_eq!(tanh(25.0), 1.0);
        assert_eq!(tanh(-1e300), -1.0);
        assert_eq!(tanh(f64::INFINITY), 1.0);
        assert_eq!(tanh(f64::NEG_INFINITY), -1.0);
        assert_eq!(tanh(0.0).to_bits(), 0.0f64.to_bits());
        assert_eq!(tanh(-0.0).to_bits(), (-0.0f64).to_bits());
        assert!(tanh(f64::NAN).is_nan());
    }

    proptest! {
        #[test]
        fn any_finite_value_matches_libm(x in -1e3f64..1e3) {
            prop_assert!(relative_error(x) < 1e-15, "x = {x}: {:e}", relative_error(x));
        }

        #[test]
        fn odd_and_bounded(x in proptest::num::f64::NORMAL) {
            prop_assert_eq!(tanh(-x), -tanh(x));
            prop_assert!(tanh(x).abs() <= 1.0);
        }
    }
}
