//! The generated functions written with the traced ones: forward dynamics,
//! `solve_mass` and the derivatives of forward dynamics, through the
//! traced `mass_factor` (M = L D L^T), `bias` and `tau_derivatives`, and
//! the triangular solves of `solve_factored` (support). The same text for
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
        /// Exact (d qdd / d q, d qdd / d qd) of `forward_dynamics` at
        /// (q, qd, tau): row i is qdd_i, column j is q_j or qd_j; d qdd / d tau
        /// is M^-1 (`solve_mass`). From tau(q, qd, qdd(q, qd, tau)) = tau:
        /// d qdd / d x = -M^-1 d tau / d x at the forward dynamics' qdd.
        #[inline]
        #[must_use]
        pub fn forward_dynamics_derivatives(
            q: &[f64; DOF],
            qd: &[f64; DOF],
            tau: &[f64; DOF],
        ) -> ([[f64; DOF]; DOF], [[f64; DOF]; DOF]) {
            let factor = mass_factor(q);
            let bias = bias(q, qd);
            let qdd = solve_factored(&factor, core::array::from_fn(|i| tau[i] - bias[i]));
            let (by_q, by_qd) = tau_derivatives(q, qd, &qdd);
            let solved = |by: [[f64; DOF]; DOF]| {
                let mut out = [[0.0; DOF]; DOF];
                for j in 0..DOF {
                    let column = solve_factored(&factor, core::array::from_fn(|i| -by[i][j]));
                    for i in 0..DOF {
                        out[i][j] = column[i];
                    }
                }
                out
            };
            (solved(by_q), solved(by_qd))
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
    }
}
