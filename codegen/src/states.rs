//! Joint states for checks: program inputs of a state, and a small
//! deterministic generator (the cross-check and the tests need no RNG crate).

use crate::schema::{JointEffects, sign};

/// Program inputs of a state: per joint sin, cos, qd, qdd, sign(qd), q,
/// the Stribeck shape and the ripple's sine and cosine, whose shaping
/// numbers come from the joints' `effects` (sign(0) = 0, as the generated
/// code).
pub(crate) fn inputs(q: &[f64], qd: &[f64], qdd: &[f64], effects: &[JointEffects]) -> Vec<f64> {
    (0..q.len())
        .flat_map(|i| {
            let e = &effects[i];
            let (ripple_sin, ripple_cos) = (e.ripple_cycles * q[i]).sin_cos();
            [
                q[i].sin(),
                q[i].cos(),
                qd[i],
                qdd[i],
                sign(qd[i]),
                q[i],
                e.stribeck_shape(qd[i]),
                ripple_sin,
                ripple_cos,
            ]
        })
        .collect()
}

/// A deterministic pseudo-random number in [-1, 1) (64-bit LCG).
pub(crate) fn uniform(state: &mut u64) -> f64 {
    *state = state
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (*state >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}
