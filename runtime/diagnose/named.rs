//! The named effects as the report gives them: values with intervals, what
//! each is ambiguous with, what the unconstrained fit of a body says, and
//! the held-out MSE before and after, per joint.

use super::alternatives::{self, Alternative};
use super::candidate::{Candidate, label, width};
use super::diagnosis::Effect;
use super::dry;
use super::heldout::{Scoring, cv_mse, cv_mse_per_joint};
use super::moments::Moments;
use super::report::describe;
use super::settings::Settings;
use super::stacked::Stacked;
use super::supported::{self, Supported};
use super::unconstrained;

/// What the motion stage chose, over its stacked data.
pub(super) struct Named<'a> {
    pub(super) data: &'a Stacked,
    pub(super) moments: &'a Moments,
    pub(super) candidates: &'a [Candidate],
    pub(super) selected: &'a [usize],
}

/// The described effects and the held-out MSEs that go with them.
pub(super) struct Described {
    pub(super) effects: Vec<Effect>,
    pub(super) mse_before: Vec<f64>,
    pub(super) mse_after: Vec<f64>,
    pub(super) mse_after_fitted: Vec<f64>,
}

impl Named<'_> {
    /// Describes the named effects (in the order named), with the notes the
    /// description adds: ambiguities, dry-friction pairs the data barely
    /// tell apart, links whose mass acts only through second moments.
    pub(super) fn describe(
        &self,
        (alternatives, supported, second_moments): (Vec<Alternative>, &[Supported], &[usize]),
        settings: Settings,
        size: f64,
        notes: &mut Vec<String>,
    ) -> Described {
        let (m, candidates, selected) = (self.moments, self.candidates, self.selected);
        let alternatives: Vec<_> = alternatives
            .into_iter()
            .filter(|a| selected.contains(&a.named))
            .collect();
        notes.extend(
            alternatives
                .iter()
                .map(|a| alternatives::note(candidates, a)),
        );
        let dry_pairs = dry::offset_or_asymmetry(self.data, candidates, selected, notes);
        let dof = self.data.dof;
        let mse_before = cv_mse_per_joint(m, dof, candidates, &[]);
        let mse_after = cv_mse_per_joint(m, dof, candidates, selected);
        let mse_after_fitted = cv_mse(m, dof, candidates, selected, Scoring::Fitted);
        let mut effects = describe(
            m,
            candidates,
            selected,
            settings.com_resolution * size,
            &self.bias(supported),
            notes,
        );
        for (effect, &c) in effects.iter_mut().zip(selected) {
            let mut beside: Vec<usize> = Vec::new();
            let others = alternatives
                .iter()
                .filter(|a| a.named == c)
                .map(|a| a.runner_up);
            for r in others.chain(dry_pairs.iter().filter(|p| p.0 == c).map(|p| p.1)) {
                if !beside.contains(&r) {
                    beside.push(r);
                }
            }
            effect.ambiguous_with = beside.iter().map(|&r| label(&candidates[r])).collect();
            effect.unconstrained = unconstrained::unconstrained(
                m, candidates, selected, &mse_after, c, settings, notes,
            );
        }
        for &c in selected.iter().filter(|c| second_moments.contains(c)) {
            notes.push(format!(
                "{}: the link's origin does not accelerate in these motions (it lies on the axes \
                 of the joints that move it), so its mass acts only through its second moments: \
                 mass and COM are fitted with the link's inertia about its COM held as modelled; \
                 if that inertia is wrong too, so is the mass (the mass and COM estimates \
                 correlate strongly, see identifiability)",
                label(&candidates[c])
            ));
        }
        Described {
            effects,
            mse_before,
            mse_after,
            mse_after_fitted,
        }
    }

    /// The bias the reported intervals add (see `supported.rs`).
    fn bias(&self, supported: &[Supported]) -> nalgebra::DVector<f64> {
        let (candidates, selected) = (self.candidates, self.selected);
        let width = selected.iter().map(|&c| width(&candidates[c])).sum();
        let timing = supported::timing_shift(self.moments, candidates, selected);
        supported::bias(supported, timing, width)
    }
}
