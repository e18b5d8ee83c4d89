//! A small deterministic generator of joint states for checks (the
//! cross-check and the tests need no RNG crate); the program inputs of a
//! state are `recursive::program_inputs`.

/// A deterministic pseudo-random number in [-1, 1) (64-bit LCG).
pub(crate) fn uniform(state: &mut u64) -> f64 {
    *state = state
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (*state >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}
