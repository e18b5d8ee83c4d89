//! The effects of a joint with a named torque scale, in the robot's torque.
//!
//! On a joint whose logged torque is s times the robot's, the fit meets
//! the effects in the logged torque: a friction level of 0.4 N m is fitted
//! as 0.4 s. `evaluate --torque-scale J=S` divides the logged torque by s
//! and `--apply` writes the robot's values, so the report gives those too:
//! every torque parameter of the joint's effects (and its interval)
//! divided by s. Angles, velocities and periods stay as fitted; held-out
//! MSEs stay those of the logged torque.

use serde_json::Value;

use super::diagnosis::Effect;
use super::kind::Kind;
use crate::corrections::Corrections;

/// Divides the torque parameters of the named and the supported effects
/// on each joint with a named torque scale by that scale; a note per such
/// joint says so.
pub(super) fn in_applied_units(
    named: &mut [Effect],
    supported: &mut [Effect],
    notes: &mut Vec<String>,
) {
    let scales = Corrections::named(named).scales;
    for &(joint, scale) in &scales {
        let mut changed = false;
        let on_joint = |e: &&mut Effect| e.joint == Some(joint);
        for effect in named
            .iter_mut()
            .chain(supported.iter_mut())
            .filter(on_joint)
        {
            let torques = effect.kind.joint_parameters().filter(|p| p.torque);
            for name in torques.map(|p| p.name) {
                changed |= divide(effect.parameters.get_mut(name), scale);
                if let Some(Value::Array(interval)) = effect.ci95.get_mut(name) {
                    interval.iter_mut().for_each(|v| {
                        divide(Some(v), scale);
                    });
                }
            }
        }
        if changed {
            // Named after the scale, so the report ranks it with the scale.
            notes.push(format!(
                "{} on joint {joint}: the joint's other effects are given in the robot's torque, \
                 the logged torque divided by the scale {scale:.4} (what `--apply` writes and \
                 `evaluate --torque-scale {joint}={scale:.4}` compares); its held-out MSEs are of \
                 the logged torque, after the named effects about {:.3} times what that \
                 `evaluate` shows",
                Kind::TorqueScale.name(),
                scale * scale
            ));
        }
    }
}

/// `value` / `scale` where `value` is a number; whether it was.
fn divide(value: Option<&mut Value>, scale: f64) -> bool {
    match value.and_then(|v| Some((v.as_f64()?, v))) {
        Some((x, v)) => {
            *v = serde_json::json!(x / scale);
            true
        }
        None => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn effect(kind: Kind, joint: usize, parameters: Value, ci95: Value) -> Effect {
        let map = |v: Value| match v {
            Value::Object(m) => m,
            _ => unreachable!("an object"),
        };
        Effect::new(kind, (Some(joint), None), map(parameters), map(ci95))
    }

    #[test]
    fn a_scaled_joints_torques_are_divided_and_its_angles_kept() {
        let scale = effect(Kind::TorqueScale, 2, json!({"scale": 1.25}), json!({}));
        let mut effects = vec![
            effect(
                Kind::CoulombFriction,
                2,
                json!({"level": 0.5}),
                json!({"level": [0.25, 0.75]}),
            ),
            effect(
                Kind::JointSpring,
                2,
                json!({"stiffness": 2.5, "constant": -0.75, "rest": 0.3}),
                json!({"stiffness": [2.0, 3.0], "rest": [0.2, 0.4]}),
            ),
        ];
        effects.insert(0, scale);
        let mut supported = vec![
            effect(Kind::Armature, 2, json!({"inertia": 0.5}), json!({})),
            effect(Kind::CoulombFriction, 1, json!({"level": 0.5}), json!({})),
        ];
        let mut notes = Vec::new();
        in_applied_units(&mut effects, &mut supported, &mut notes);
        assert_eq!(effects[0].parameters["scale"], json!(1.25));
        assert_eq!(effects[1].parameters["level"], json!(0.4));
        assert_eq!(effects[1].ci95["level"], json!([0.2, 0.6]));
        assert_eq!(effects[2].parameters["stiffness"], json!(2.0));
        assert_eq!(effects[2].parameters["constant"], json!(-0.6));
        assert_eq!(effects[2].parameters["rest"], json!(0.3));
        assert_eq!(effects[2].ci95["stiffness"], json!([1.6, 2.4]));
        assert_eq!(effects[2].ci95["rest"], json!([0.2, 0.4]));
        assert_eq!(supported[0].parameters["inertia"], json!(0.4));
        // Another joint's effects are not touched.
        assert_eq!(supported[1].parameters["level"], json!(0.5));
        assert_eq!(notes.len(), 1);
        assert!(
            notes[0].starts_with("torque_scale on joint 2:"),
            "{}",
            notes[0]
        );
    }

    #[test]
    fn without_a_scale_nothing_changes() {
        let mut effects = vec![effect(
            Kind::ViscousFriction,
            1,
            json!({"coefficient": 0.5}),
            json!({"coefficient": [0.4, 0.6]}),
        )];
        let before = effects.clone();
        let mut notes = Vec::new();
        in_applied_units(&mut effects, &mut [], &mut notes);
        assert_eq!(effects[0].parameters, before[0].parameters);
        assert!(notes.is_empty());
    }
}
