//! The helpers every generated file carries after its functions: `sign`,
//! `stribeck`, the fused multiply-add `AddMul` the emitted sums use, and
//! `sin_cos`.
//! They need only `core`, so a generated file compiles in a `#![no_std]`
//! crate with no dependency.

use proc_macro2::TokenStream;
use quote::quote;

/// The helper items, in file order.
pub fn items() -> TokenStream {
    let sin_cos = sin_cos();
    quote! {
        /// Coulomb friction direction: sign(x), with sign(0) = 0.
        #[inline]
        #[must_use]
        pub fn sign(x: f64) -> f64 {
            if x > 0.0 { 1.0 } else if x < 0.0 { -1.0 } else { 0.0 }
        }
        /// The Stribeck shape sign(v) exp(-(v/v_s)^2): the breakaway excess's
        /// share at speed v, 1 leaving rest, fading past v_s; 0 without a
        /// Stribeck velocity (v_s <= 0).
        #[inline]
        #[must_use]
        pub fn stribeck(v: f64, v_s: f64) -> f64 {
            if !(v_s > 0.0) {
                return 0.0;
            }
            let x = v / v_s;
            sign(v) * exp_neg(x * x)
        }
        /// exp(-y) for y >= 0 to about one ulp (`core` has no `exp`): y =
        /// k ln 2 + r with |r| <= ln 2 / 2 (ln 2 in two parts, k ln2_hi
        /// exact), exp(-r) by its Taylor polynomial to r^13 (the first
        /// omitted term is below 4e-18), times 2^-k; 0 past y = 708, where
        /// exp(-y) leaves the normal range.
        #[allow(clippy::excessive_precision)]
        fn exp_neg(y: f64) -> f64 {
            if !(y <= 708.0) {
                return if y.is_nan() { y } else { 0.0 };
            }
            // y >= 0, so truncation rounds to nearest.
            let k = (y * 1.4426950408889634 + 0.5) as u64;
            let kf = k as f64;
            let r = (kf * 6.93147180369123816490e-01 - y) + kf * 1.90821492927058770002e-10;
            let coefficients = [
                1.0,
                1.0,
                0.5,
                0.16666666666666666,
                0.041666666666666664,
                0.008333333333333333,
                0.001388888888888889,
                0.0001984126984126984,
                2.48015873015873e-5,
                2.7557319223985893e-6,
                2.755731922398589e-7,
                2.505210838544172e-8,
                2.08767569878681e-9,
                1.6059043836821613e-10,
            ];
            let polynomial = coefficients.iter().rev().fold(0.0f64, |acc, &c| c.add_mul(r, acc));
            polynomial * f64::from_bits((1023 - k) << 52)
        }
        /// `self + a * b` and `self - a * b` (see `fused`).
        trait AddMul {
            fn add_mul(self, a: f64, b: f64) -> f64;
            fn sub_mul(self, a: f64, b: f64) -> f64;
        }
        impl AddMul for f64 {
            #[inline(always)]
            fn add_mul(self, a: f64, b: f64) -> f64 {
                fused(a, b, self)
            }
            #[inline(always)]
            fn sub_mul(self, a: f64, b: f64) -> f64 {
                fused(-a, b, self)
            }
        }
        /// Two derivatives at once (`tau_derivatives`: a joint's angle and
        /// speed in two lanes). Each operation scales by one primal value,
        /// broadcast, so both lanes take one packed instruction: SSE2
        /// intrinsics on x86-64 (part of its baseline), where the compiler
        /// on its own paired only some of them; plain pairs elsewhere.
        #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
        mod lanes {
            use core::arch::x86_64::{
                __m128d, _mm_add_pd, _mm_cvtsd_f64, _mm_mul_pd, _mm_set1_pd, _mm_set_pd,
                _mm_sub_pd, _mm_unpackhi_pd, _mm_xor_pd,
            };
            #[derive(Clone, Copy)]
            pub(super) struct Lanes(__m128d);
            // SAFETY (every block below): SSE2 is enabled (the cfg above) and
            // the intrinsics only compute on registers.
            impl Lanes {
                #[inline(always)]
                pub(super) fn new(a: f64, b: f64) -> Lanes {
                    Lanes(unsafe { _mm_set_pd(b, a) })
                }
                #[inline(always)]
                pub(super) fn lanes(self) -> [f64; 2] {
                    unsafe { [_mm_cvtsd_f64(self.0), _mm_cvtsd_f64(_mm_unpackhi_pd(self.0, self.0))] }
                }
                #[inline(always)]
                pub(super) fn times(self, k: f64) -> Lanes {
                    Lanes(unsafe { _mm_mul_pd(self.0, _mm_set1_pd(k)) })
                }
                /// `self + k * d`, fused where the target has FMA (as `fused`).
                #[inline(always)]
                pub(super) fn add_mul(self, k: f64, d: Lanes) -> Lanes {
                    #[cfg(target_feature = "fma")]
                    {
                        Lanes(unsafe { core::arch::x86_64::_mm_fmadd_pd(_mm_set1_pd(k), d.0, self.0) })
                    }
                    #[cfg(not(target_feature = "fma"))]
                    {
                        Lanes(unsafe { _mm_add_pd(self.0, _mm_mul_pd(_mm_set1_pd(k), d.0)) })
                    }
                }
                /// `self - k * d`.
                #[inline(always)]
                pub(super) fn sub_mul(self, k: f64, d: Lanes) -> Lanes {
                    #[cfg(target_feature = "fma")]
                    {
                        Lanes(unsafe { core::arch::x86_64::_mm_fnmadd_pd(_mm_set1_pd(k), d.0, self.0) })
                    }
                    #[cfg(not(target_feature = "fma"))]
                    {
                        Lanes(unsafe { _mm_sub_pd(self.0, _mm_mul_pd(_mm_set1_pd(k), d.0)) })
                    }
                }
            }
            impl core::ops::Add for Lanes {
                type Output = Lanes;
                #[inline(always)]
                fn add(self, d: Lanes) -> Lanes {
                    Lanes(unsafe { _mm_add_pd(self.0, d.0) })
                }
            }
            impl core::ops::Sub for Lanes {
                type Output = Lanes;
                #[inline(always)]
                fn sub(self, d: Lanes) -> Lanes {
                    Lanes(unsafe { _mm_sub_pd(self.0, d.0) })
                }
            }
            impl core::ops::Neg for Lanes {
                type Output = Lanes;
                #[inline(always)]
                fn neg(self) -> Lanes {
                    Lanes(unsafe { _mm_xor_pd(self.0, _mm_set1_pd(-0.0)) })
                }
            }
        }
        /// `Lanes` as a plain pair, lane by lane through `AddMul`.
        #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
        mod lanes {
            use super::AddMul;
            #[derive(Clone, Copy)]
            pub(super) struct Lanes([f64; 2]);
            impl Lanes {
                #[inline(always)]
                pub(super) fn new(a: f64, b: f64) -> Lanes {
                    Lanes([a, b])
                }
                #[inline(always)]
                pub(super) fn lanes(self) -> [f64; 2] {
                    self.0
                }
                #[inline(always)]
                pub(super) fn times(self, k: f64) -> Lanes {
                    Lanes(self.0.map(|x| x * k))
                }
                #[inline(always)]
                pub(super) fn add_mul(self, k: f64, d: Lanes) -> Lanes {
                    Lanes([self.0[0].add_mul(k, d.0[0]), self.0[1].add_mul(k, d.0[1])])
                }
                #[inline(always)]
                pub(super) fn sub_mul(self, k: f64, d: Lanes) -> Lanes {
                    Lanes([self.0[0].sub_mul(k, d.0[0]), self.0[1].sub_mul(k, d.0[1])])
                }
            }
            impl core::ops::Add for Lanes {
                type Output = Lanes;
                #[inline(always)]
                fn add(self, d: Lanes) -> Lanes {
                    Lanes([self.0[0] + d.0[0], self.0[1] + d.0[1]])
                }
            }
            impl core::ops::Sub for Lanes {
                type Output = Lanes;
                #[inline(always)]
                fn sub(self, d: Lanes) -> Lanes {
                    Lanes([self.0[0] - d.0[0], self.0[1] - d.0[1]])
                }
            }
            impl core::ops::Neg for Lanes {
                type Output = Lanes;
                #[inline(always)]
                fn neg(self) -> Lanes {
                    Lanes(self.0.map(|x| -x))
                }
            }
        }
        use lanes::Lanes;
        /// x with L D L^T x = -b for two right-hand sides at once, one per
        /// lane (`forward_dynamics_derivatives`: a joint's angle and speed
        /// columns); the minus rides on the pivots' scaling. (`inline`, not
        /// `inline(always)`: forced into the caller seven times it measured
        /// slower than the scalar columns' solve.)
        #[inline]
        fn solve_factored_lanes_negated<const N: usize>(
            factor: &[[f64; N]; N],
            b: [Lanes; N],
        ) -> [Lanes; N] {
            let mut x = b;
            for i in 0..N {
                for k in 0..i {
                    x[i] = x[i].sub_mul(factor[i][k], x[k]);
                }
            }
            for i in 0..N {
                x[i] = x[i].times(-factor[i][i]);
            }
            for i in (0..N).rev() {
                for k in i + 1..N {
                    x[i] = x[i].sub_mul(factor[k][i], x[k]);
                }
            }
            x
        }
        /// `a * b + c`: one fused instruction and one rounding where the
        /// target has FMA (x86-64 built with `-C target-feature=+fma` or
        /// `-C target-cpu=native` on a CPU with FMA; every aarch64), chosen
        /// at compile time; a multiply and an add elsewhere. `core` only.
        #[inline(always)]
        fn fused(a: f64, b: f64, c: f64) -> f64 {
            #[cfg(all(target_arch = "x86_64", target_feature = "fma"))]
            {
                use core::arch::x86_64::{_mm_cvtsd_f64, _mm_fmadd_sd, _mm_set_sd};
                // SAFETY: compiled only for targets with FMA (and SSE2).
                unsafe { _mm_cvtsd_f64(_mm_fmadd_sd(_mm_set_sd(a), _mm_set_sd(b), _mm_set_sd(c))) }
            }
            #[cfg(all(target_arch = "aarch64", target_feature = "neon"))]
            {
                use core::arch::aarch64::{vdup_n_f64, vfma_f64, vget_lane_f64};
                // SAFETY: compiled only for targets with NEON.
                unsafe { vget_lane_f64::<0>(vfma_f64(vdup_n_f64(c), vdup_n_f64(a), vdup_n_f64(b))) }
            }
            #[cfg(not(any(
                all(target_arch = "x86_64", target_feature = "fma"),
                all(target_arch = "aarch64", target_feature = "neon")
            )))]
            {
                a * b + c
            }
        }
        #sin_cos
    }
}

/// sin and cos within about one ulp, several times faster than two libm
/// calls and with `core` only: Cody-Waite reduction by pi/2, then Taylor
/// polynomials on [-pi/4, pi/4] (the first omitted terms are below 1e-16
/// relative), evaluated by Estrin's scheme; the quadrant is applied with bit
/// operations, so a function's angles are computed together, in vector
/// lanes (four per instruction with AVX2). Up to |x| = 1e5 pi/2 is split in
/// 33 + 33 + 53 bits (k * part exact for |k| < 2^20); up to 1e10 rad (1.6e9
/// turns) a slower path splits it in 20-bit parts (exact for |k| < 2^33);
/// beyond, no joint angle is meant and the result is NaN.
fn sin_cos() -> TokenStream {
    quote! {
        /// sin(x) and cos(x) to about one ulp for |x| <= 1e10; NaN beyond.
        #[inline]
        #[must_use]
        pub fn sin_cos(x: f64) -> (f64, f64) {
            let ([s], [c]) = sin_cos_n([x]);
            (s, c)
        }
        /// `sin_cos` of each angle, lane by lane (the compiler vectorizes the
        /// loop); a slower reduction for all if any |x| exceeds 1e5.
        #[inline]
        #[must_use]
        #[allow(clippy::excessive_precision, clippy::approx_constant)]
        pub fn sin_cos_n<const N: usize>(x: [f64; N]) -> ([f64; N], [f64; N]) {
            if !x.iter().all(|x| x.abs() <= 1.0e5) {
                let wide = x.map(sin_cos_wide);
                return (wide.map(|p| p.0), wide.map(|p| p.1));
            }
            let mut sin = [0.0; N];
            let mut cos = [0.0; N];
            for i in 0..N {
                let x = x[i];
                // Round to nearest by the 1.5 * 2^52 shift: exact for |x| <= 1e5;
                // the low bits of `shifted` are the quadrant k mod 4.
                let shifted = 6755399441055744.0f64.add_mul(x, 0.6366197723675814);
                let k = shifted - 6755399441055744.0;
                let r = x
                    .sub_mul(k, 1.5707963267341256)
                    .sub_mul(k, 6.077100506303966e-11)
                    .sub_mul(k, 2.0222662487959506e-21);
                (sin[i], cos[i]) = quadrant_sin_cos(r, shifted.to_bits());
            }
            (sin, cos)
        }
        /// `sin_cos` for 1e5 < |x| <= 1e10 (pi/2 in 20-bit parts); NaN beyond.
        #[allow(clippy::excessive_precision, clippy::approx_constant)]
        fn sin_cos_wide(x: f64) -> (f64, f64) {
            if !(x.abs() <= 1.0e10) {
                return (f64::NAN, f64::NAN);
            }
            let shifted = 6755399441055744.0f64.add_mul(x, 0.6366197723675814);
            let k = shifted - 6755399441055744.0;
            let r = x
                .sub_mul(k, 1.5707969665527344)
                .add_mul(k, 6.39757672615815e-7)
                .add_mul(k, 1.651400370616951e-13)
                .sub_mul(k, 8.333742918520879e-20);
            quadrant_sin_cos(r, shifted.to_bits())
        }
        /// sin and cos of `r` in [-pi/4, pi/4] turned by quadrant `n` mod 4.
        #[inline(always)]
        #[allow(clippy::excessive_precision)]
        fn quadrant_sin_cos(r: f64, n: u64) -> (f64, f64) {
            // Estrin's scheme: short dependency chains.
            let z = r * r;
            let z2 = z * z;
            let z4 = z2 * z2;
            let sp = (-0.16666666666666666f64)
                .add_mul(z, 0.008333333333333333)
                .add_mul(z2, (-0.0001984126984126984f64).add_mul(z, 2.7557319223985893e-6))
                .add_mul(
                    z4,
                    (-2.505210838544172e-8f64)
                        .add_mul(z, 1.6059043836821613e-10)
                        .add_mul(z2, (-7.647163731819816e-13f64).add_mul(z, 2.8114572543455206e-15)),
                );
            let cp = (-0.5f64)
                .add_mul(z, 0.041666666666666664)
                .add_mul(z2, (-0.001388888888888889f64).add_mul(z, 2.48015873015873e-5))
                .add_mul(
                    z4,
                    (-2.755731922398589e-7f64)
                        .add_mul(z, 2.08767569878681e-9)
                        .add_mul(z2, (-1.1470745597729725e-11f64).add_mul(z, 4.779477332387385e-14)),
                );
            let s = r.add_mul(r * z, sp).to_bits();
            let c = 1.0f64.add_mul(z, cp).to_bits();
            // Odd quadrants swap sin and cos; sin changes sign in quadrants
            // 2 and 3, cos in 1 and 2.
            let swap = (n & 1).wrapping_neg();
            (
                f64::from_bits(((s & !swap) | (c & swap)) ^ ((n & 2) << 62)),
                f64::from_bits(((c & !swap) | (s & swap)) ^ ((n.wrapping_add(1) & 2) << 62)),
            )
        }
    }
}
