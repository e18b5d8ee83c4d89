//! How much held-out error a candidate removes, the measure forward
//! selection and the near-tie rules compare.

/// Largest relative drop of any joint's MSE from `before` to `after`, a
/// drop counting only when it reaches [`GAIN_FLOOR`] of the joint's
/// `reference` MSE: the residual at the step for the selection (a large
/// effect named first does not raise the bar for a small one beside it,
/// issue 25), the error before the diagnosis for the reversal stage.
pub(super) fn relative_gain(before: &[f64], after: &[f64], reference: &[f64]) -> Gain {
    before
        .iter()
        .zip(after)
        .zip(reference)
        .enumerate()
        .map(|(joint, ((b, a), r))| {
            // A drop below the floor is noise-level structure, however
            // large a share of what is left it is.
            let share = if *b > 0.0 && b - a >= GAIN_FLOOR * r {
                (b - a) / b
            } else {
                0.0
            };
            Gain { share, joint }
        })
        .fold(
            Gain {
                share: f64::NEG_INFINITY,
                joint: 0,
            },
            |best, g| {
                if g.share > best.share { g } else { best }
            },
        )
}

/// The least held-out MSE an effect must remove from a joint, as a share of
/// that joint's reference MSE (see [`relative_gain`]).
pub const GAIN_FLOOR: f64 = 1e-3;

/// A candidate's held-out gain: the largest share of a joint's current
/// held-out MSE it removes, and that joint.
#[derive(Debug, Clone, Copy)]
pub(super) struct Gain {
    pub(super) share: f64,
    pub(super) joint: usize,
}

impl Gain {
    /// No gain (the backward check asks only whether a fit is physical).
    pub(super) const NONE: Gain = Gain {
        share: 0.0,
        joint: 0,
    };

    /// "would cut joint 2's held-out MSE by 76%".
    pub(super) fn would_cut(&self) -> String {
        format!(
            "would cut joint {}'s held-out MSE by {:.0}%",
            self.joint + 1,
            100.0 * self.share
        )
    }
}
