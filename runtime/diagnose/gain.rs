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

/// Whether some joint's held-out MSE is clearly worse `after` than
/// `before`: beyond `near` times it, by at least [`GAIN_FLOOR`] of the
/// joint's MSE before the diagnosis (`initial`). A smaller rise is
/// noise-level structure, as a smaller drop is in [`relative_gain`]: a
/// payload alone in place of a payload and a wrist link beside it left a
/// Kinova Gen3's last joint at 1.19 times an MSE 1e-4 of its first.
pub(super) fn clearly_worse(after: &[f64], before: &[f64], initial: &[f64], near: f64) -> bool {
    after
        .iter()
        .zip(before.iter().zip(initial))
        .any(|(a, (b, i))| *a > near * b && a - b >= GAIN_FLOOR * i)
}

/// The joint an effect leaves worse than the model before the diagnosis,
/// by more than [`WORSE_THAN_BEFORE`] times its held-out MSE then, where
/// the effect itself raised it (from `current`, the error at the step), and
/// that factor (the largest). A cut on one joint bought that way is a fit
/// trading one joint's structure for another's, not an effect of the arm:
/// on the independent suite's Panda with link 6 wholly wrong, link 7's
/// error halved joint 5's leftover and left joint 7 at 11 times its error
/// before.
pub(super) fn worse_than_before(
    after: &[f64],
    (current, initial): (&[f64], &[f64]),
) -> Option<(usize, f64)> {
    after
        .iter()
        .zip(current.iter().zip(initial))
        .enumerate()
        .filter(|(_, (a, (c, i)))| **i > 0.0 && **a > **c && **a > WORSE_THAN_BEFORE * **i)
        .map(|(j, (a, (_, i)))| (j, a / i))
        .max_by(|a, b| a.1.total_cmp(&b.1))
}

/// How much worse than before the diagnosis a joint's held-out MSE may be
/// left by an effect named elsewhere: twice, well beyond what refitting
/// the other effects moves a joint at its noise level.
pub const WORSE_THAN_BEFORE: f64 = 2.0;

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_joint_left_worse_than_before_the_diagnosis_is_named() {
        // The independent suite's Panda, link 6 wholly wrong, one
        // recording: link 7's error halves joint 5's leftover and spoils
        // joint 7 elevenfold.
        let initial = [0.109, 1.87, 0.102, 0.888, 8.58e-2, 2.96e-2, 4.94e-7];
        let after = [
            5.64e-3, 9.94e-3, 2.44e-3, 2.46e-3, 8.92e-6, 3.83e-5, 5.66e-6,
        ];
        let current = [
            5.65e-3, 9.94e-3, 2.45e-3, 2.46e-3, 1.90e-5, 3.82e-5, 4.94e-7,
        ];
        let (joint, factor) = worse_than_before(&after, (&current, &initial)).unwrap();
        assert_eq!(joint, 6);
        assert!((factor - 11.46).abs() < 0.01, "{factor}");
        // Worse than at the step but far below the error before (a real
        // UR10e's wrist, 3.9 times its leftover, 8% of its error before).
        let after = [5.64e-3, 9.94e-3, 2.44e-3, 0.071, 8.92e-6, 3.83e-5, 4.9e-7];
        assert_eq!(worse_than_before(&after, (&current, &initial)), None);
        // A joint already above the bar that this effect does not raise.
        let worse = [5.65e-3, 9.94e-3, 2.45e-3, 2.46e-3, 1.90e-5, 3.82e-5, 2e-6];
        let after = [5.64e-3, 9.94e-3, 2.44e-3, 2.46e-3, 8.92e-6, 3.83e-5, 1.9e-6];
        assert_eq!(worse_than_before(&after, (&worse, &initial)), None);
        // A joint with no error before is not judged.
        assert_eq!(worse_than_before(&[1.0], (&[0.5], &[0.0])), None);
    }

    #[test]
    fn a_rise_below_the_gain_floor_is_not_clearly_worse() {
        let initial = [0.5, 0.16];
        let before = [2e-3, 1e-4];
        // The last joint 19% worse, by 1.9e-5: 1.2e-4 of its error before.
        assert!(!clearly_worse(&[2e-3, 1.19e-4], &before, &initial, 1.1));
        // 19% worse by 1.9e-4, above the floor (1.6e-4).
        assert!(clearly_worse(&[2e-3, 2.9e-4], &before, &initial, 1.1));
        // Above the floor but within the factor.
        assert!(!clearly_worse(&[2.1e-3, 1e-4], &before, &initial, 1.1));
        // The first joint 1.2 times worse, by 4e-4: 8e-4 of 0.5, below.
        assert!(!clearly_worse(&[2.4e-3, 1e-4], &before, &initial, 1.1));
        assert!(clearly_worse(&[2.6e-3, 1e-4], &before, &initial, 1.1));
    }
}
