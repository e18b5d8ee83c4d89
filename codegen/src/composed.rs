//! The generated functions written with the traced ones: forward dynamics
//! and `solve_mass`, through the traced `mass_factor` (M = L D L^T) and
//! `bias`, and the triangular solves of `solve_factored` (support). (The
//! derivatives of forward dynamics are emitted by `emit_lanes.rs`.) The same text for
//! every model; the sizes come from its `DOF`.

use proc_macro2::TokenStream;
use quote::quote;

/// The composed functions, in file order.
pub fn items() -> TokenStream {
    quote! {
        /// Joint accelerations qdd = M(q)^-1 (tau - bias(q, qd)): forward
        /// dynamics with armature and every effect exactly as in `tau`, so
        /// `tau(q, qd, &forward_dynamics(q, qd, tau)) == tau` to rounding.
        #[inline]
        #[must_use]
        pub fn forward_dynamics(q: &[f64; DOF], qd: &[f64; DOF], tau: &[f64; DOF]) -> [f64; DOF] {
            let bias = bias(q, qd);
            let rhs = core::array::from_fn(|i| tau[i] - bias[i]);
            solve_factored(&mass_factor(q), rhs)
        }
        /// M(q)^-1 b, armature included.
        #[inline]
        #[must_use]
        pub fn solve_mass(q: &[f64; DOF], b: &[f64; DOF]) -> [f64; DOF] {
            solve_factored(&mass_factor(q), *b)
        }
    }
}

/// The support items the composed functions and the kinematics need.
pub fn support() -> TokenStream {
    quote! {
        /// A frame in the base frame: `rotation` takes the frame's
        /// coordinates to the base's (its columns are the frame's axes),
        /// `position` is its origin, m.
        #[derive(Debug, Clone, Copy, PartialEq)]
        pub struct Pose {
            pub rotation: [[f64; 3]; 3],
            pub position: [f64; 3],
        }
        /// x with L D L^T x = b, for `factor` as `mass_factor` returns it.
        #[inline]
        #[must_use]
        pub fn solve_factored<const N: usize>(factor: &[[f64; N]; N], b: [f64; N]) -> [f64; N] {
            let mut x = b;
            for i in 0..N {
                for k in 0..i {
                    x[i] = x[i].sub_mul(factor[i][k], x[k]);
                }
            }
            for i in 0..N {
                x[i] *= factor[i][i];
            }
            for i in (0..N).rev() {
                for k in i + 1..N {
                    x[i] = x[i].sub_mul(factor[k][i], x[k]);
                }
            }
            x
        }
        /// X with L D L^T X = B, every column of B a right-hand side (row by
        /// row, so the columns go through together).
        #[inline]
        #[must_use]
        pub fn solve_factored_columns<const N: usize, const M: usize>(
            factor: &[[f64; N]; N],
            b: [[f64; M]; N],
        ) -> [[f64; M]; N] {
            let mut x = b;
            for i in 0..N {
                for k in 0..i {
                    let (l, above) = (factor[i][k], x[k]);
                    for (xi, xk) in x[i].iter_mut().zip(above) {
                        *xi = xi.sub_mul(l, xk);
                    }
                }
            }
            for i in 0..N {
                let scale = factor[i][i];
                x[i] = x[i].map(|v| v * scale);
            }
            for i in (0..N).rev() {
                for k in i + 1..N {
                    let (l, below) = (factor[k][i], x[k]);
                    for (xi, xk) in x[i].iter_mut().zip(below) {
                        *xi = xi.sub_mul(l, xk);
                    }
                }
            }
            x
        }
    }
}
