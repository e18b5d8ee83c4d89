//! Stribeck friction in the diagnosis: which joints try it, and how what
//! the reversal stage ([`super::reversals`]) finds joins the report.

use serde_json::json;

use super::candidate::{Candidate, Shape};
use super::diagnosis::Effect;
use super::kind::Kind;
use super::reversals::{self, Found, Motion};
use super::settings::Settings;
use crate::dynamics::Dynamics;
use crate::preprocess::Pipeline;
use crate::trajectory::Trajectory;

/// The joints on which Stribeck friction is tried: those with dry friction,
/// named at the motion stage or in the model (a breakaway excess is the
/// static end of dry friction: a joint without it has none to exceed, and
/// clean data never reach the reversal stage); every joint with
/// `settings.stribeck`.
fn joints(
    model: &dyn Dynamics,
    candidates: &[Candidate],
    selected: &[usize],
    settings: Settings,
) -> Vec<usize> {
    let modelled = super::modelled::joint_effects(model);
    let dry = |j: usize| {
        let named = selected.iter().any(|&c| {
            candidates[c].kind == Kind::CoulombFriction && candidates[c].joint == Some(j)
        });
        let in_model = modelled
            .get(j)
            .is_some_and(|e| e.coulomb > 0.0 || e.stribeck > 0.0)
            || candidates.iter().any(|c| {
                c.joint == Some(j)
                    && matches!(c.shape, Shape::Asymmetry { modelled_coulomb } if modelled_coulomb > 0.0)
            });
        named || in_model
    };
    (0..model.dof())
        .filter(|&j| settings.stribeck || dry(j))
        .collect()
}

/// Runs the reversal stage on the joints that try Stribeck friction.
pub(super) fn at_reversals(
    model: &dyn Dynamics,
    recordings: &[Trajectory],
    pipeline: &Pipeline,
    settings: Settings,
    motion: Motion,
) -> anyhow::Result<Found> {
    let tried = joints(model, motion.candidates, motion.selected, settings);
    reversals::stribeck((model, recordings), pipeline, settings, motion, &tried)
}

/// Adds the Stribeck friction found to the named effects and replaces the
/// values of the friction refitted beside it (the motion stage's Coulomb
/// level holds the breakaway's share), with a note for each.
pub(super) fn merge(found: Found, effects: &mut Vec<Effect>, notes: &mut Vec<String>) {
    notes.extend(found.notes);
    for (kind, joint, values) in found.refits {
        let Some(effect) = effects
            .iter_mut()
            .find(|e| e.kind == kind && e.joint == Some(joint + 1))
        else {
            continue;
        };
        let names: Vec<String> = effect.parameters.keys().cloned().collect();
        for (name, (value, half)) in names.iter().zip(values) {
            effect.parameters.insert(name.clone(), json!(value));
            effect
                .ci95
                .insert(name.clone(), json!([value - half, value + half]));
        }
        notes.push(format!(
            "{} on joint {}: refitted at the reversal band beside Stribeck friction (the \
             motion band's value held the breakaway's share)",
            kind.name(),
            joint + 1
        ));
    }
    for effect in found.effects {
        notes.push(format!(
            "stribeck_friction on joint {}: named at the reversal band (its held-out MSE \
             removed is of that band, on the samples where the joint moves); the generated model \
             applies it with sign(qd), also where the joint rests and friction is static",
            effect.joint.unwrap_or(0)
        ));
        effects.push(effect);
    }
}
