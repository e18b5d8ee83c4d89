//! Joint states for checks: program inputs of a state, and a small
//! deterministic generator (the cross-check and the tests need no RNG crate).

/// Program inputs of a state: per joint sin, cos, qd, qdd, sign(qd), q
/// (sign(0) = 0, as the generated code).
pub(crate) fn inputs(q: &[f64], qd: &[f64], qdd: &[f64]) -> Vec<f64> {
    let sign = |x: f64| if x == 0.0 { 0.0 } else { x.signum() };
    (0..q.len())
        .flat_map(|i| [q[i].sin(), q[i].cos(), qd[i], qdd[i], sign(qd[i]), q[i]])
        .collect()
}

/// A deterministic pseudo-random number in [-1, 1) (64-bit LCG).
pub(crate) fn uniform(state: &mut u64) -> f64 {
    *state = state
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (*state >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}
