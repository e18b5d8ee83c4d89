//! The joint effects the model already has. A named effect of a kind the
//! model has on that joint is a correction of the model's value (the
//! residual holds what is missing): the report gives the model's value and
//! the total beside it, the total being what `--apply` writes.

use codegen::{EFFECT_NAMES, JointEffects};
use serde_json::{Map, Value, json};

use super::diagnosis::Effect;
use super::kind::Kind;
use crate::dynamics::Dynamics;

/// The model's effects of each moving joint (none when its description
/// cannot be read).
pub(super) fn joint_effects(model: &dyn Dynamics) -> Vec<JointEffects> {
    match crate::dynamics::parsed_description(model) {
        Ok(d) => d.chain().free_bodies().map(|b| b.effects).collect(),
        Err(_) => vec![JointEffects::default(); model.dof()],
    }
}

/// Per joint the periods per revolution of the model's torque ripple,
/// where it has one.
pub(super) fn ripple_cycles(effects: &[JointEffects]) -> Vec<Option<f64>> {
    effects
        .iter()
        .map(|e| {
            let has = (e.ripple_sin != 0.0 || e.ripple_cos != 0.0) && e.ripple_cycles > 0.0;
            has.then_some(e.ripple_cycles)
        })
        .collect()
}

/// The parameters of `kind` whose model value and total the report gives,
/// as (parameter, description key): the amounts, and a spring's rest angle
/// (two springs are one about their stiffness-weighted mean rest).
fn combined(kind: Kind) -> impl Iterator<Item = (&'static str, &'static str)> {
    kind.joint_parameters()
        .filter(move |p| !p.shape || kind == Kind::JointSpring)
        .filter_map(|p| Some((p.name, p.key?)))
}

/// The model's value of a description key of a joint (0 for no key).
fn value(e: &JointEffects, key: &str) -> f64 {
    let amounts = EFFECT_NAMES.into_iter().zip(e.parameters());
    // The order of `JointEffects::shapes`.
    let shapes = ["spring_rest", "stribeck_velocity", "ripple_cycles"];
    let shapes = shapes.into_iter().zip(e.shapes());
    amounts
        .chain(shapes)
        .find(|&(k, _)| k == key)
        .map_or(0.0, |(_, v)| v)
}

/// Fills `modelled` and `total` of every named joint effect the model
/// already has (some of its values not zero; a spring's rest alone is not
/// a spring).
/// On a joint with a named torque scale the correction is in the robot's
/// torque already (`applied_units`), as `--apply` writes it.
pub(super) fn add_totals(effects: &mut [Effect], modelled: &[JointEffects]) {
    for effect in effects {
        let pairs: Vec<_> = combined(effect.kind).collect();
        let Some(model) = effect.joint.and_then(|j| modelled.get(j - 1)) else {
            continue;
        };
        let present = pairs
            .iter()
            .any(|&(_, key)| key != "spring_rest" && value(model, key) != 0.0);
        if !present {
            continue;
        }
        let fitted = |name: &str| effect.parameters.get(name).and_then(Value::as_f64);
        let (mut was, mut total) = (Map::new(), Map::new());
        for &(name, key) in &pairs {
            let Some(correction) = fitted(name) else {
                continue;
            };
            let old = value(model, key);
            let new = match key {
                // Two springs are one of the summed stiffness about the
                // stiffness-weighted mean of the rest angles.
                "spring_rest" => {
                    let (k0, k) = (model.spring, fitted("stiffness").unwrap_or(0.0));
                    if k0 + k == 0.0 {
                        correction
                    } else {
                        (k0 * old + k * correction) / (k0 + k)
                    }
                }
                _ => old + correction,
            };
            was.insert(name.into(), json!(old));
            total.insert(name.into(), json!(new));
        }
        (effect.modelled, effect.total) = (was, total);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn named(kind: Kind, parameters: &[(&str, f64)]) -> Effect {
        let parameters = parameters
            .iter()
            .map(|&(k, v)| (k.to_string(), json!(v)))
            .collect();
        Effect::new(kind, (Some(1), None), parameters, Map::new())
    }

    #[test]
    fn corrections_add_to_what_the_model_has() {
        let model = JointEffects {
            ripple_sin: 0.1,
            ripple_cycles: 6.0,
            spring: 1.0,
            spring_rest: 0.2,
            ..JointEffects::default()
        };
        let mut effects = [
            named(
                Kind::TorqueRipple,
                &[("sin", 0.3), ("cos", 0.0), ("cycles", 6.0)],
            ),
            named(Kind::JointSpring, &[("stiffness", 3.0), ("rest", 0.6)]),
            named(Kind::ViscousFriction, &[("coefficient", 0.2)]),
        ];
        add_totals(&mut effects, &[model]);
        assert_eq!(effects[0].modelled["sin"], json!(0.1));
        assert!((effects[0].total["sin"].as_f64().unwrap() - 0.4).abs() < 1e-12);
        assert_eq!(effects[0].total["cos"], json!(0.0));
        assert_eq!(effects[1].total["stiffness"], json!(4.0));
        assert!((effects[1].total["rest"].as_f64().unwrap() - 0.5).abs() < 1e-12);
        // Viscous friction the model lacks: a plain missing effect.
        assert!(effects[2].modelled.is_empty() && effects[2].total.is_empty());
    }
}
