//! The kinds of effect the diagnosis knows, as the report names them.

use serde::Serialize;

/// The kinds of effect the diagnosis can name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    ViscousFriction,
    CoulombFriction,
    Armature,
    TorqueOffset,
    Payload,
    /// A link's mass and centre of mass differ from the model (`link`,
    /// corrected `mass` kg and `com` [x, y, z] m in the link frame, and the
    /// model's `nominal_mass`, `nominal_com`).
    InertialError,
    /// The logged torque of a joint is a scaled copy of the applied one (a
    /// torque-constant or gear-ratio error of the sensor): `scale`; a
    /// property of the data, corrected with `--torque-scale J=S`.
    TorqueScale,
    /// The torque is logged `delay` s after the state it belongs to (all
    /// joints); a property of the data, corrected with `--torque-delay S`.
    TorqueDelay,
    /// The base is tilted: gravity in the base frame is `gravity` (m/s^2),
    /// `tilt_deg` away from the model's.
    GravityDirection,
    /// A joint spring (a gravity-balancing spring, a cable): `stiffness`
    /// N m/rad about the `rest` angle, rad.
    JointSpring,
    /// Direction-dependent dry friction: `asymmetry` N m added while the
    /// joint moves either way (levels coulomb +- asymmetry).
    CoulombAsymmetry,
    /// Stribeck friction: breakaway friction `excess` N m above the sliding
    /// level, fading past the Stribeck `velocity` (rad/s, chosen on a grid).
    StribeckFriction,
    /// Torque ripple of the position (cogging, gear or sensor harmonics):
    /// `sin` and `cos` amplitudes (N m) of the harmonic with `cycles`
    /// periods per joint revolution (chosen from the data).
    TorqueRipple,
}

impl Kind {
    /// The kind as JSON names it (`viscous_friction`, ...).
    pub fn name(self) -> String {
        serde_json::to_value(self)
            .ok()
            .and_then(|v| v.as_str().map(str::to_string))
            .unwrap_or_default()
    }
}

/// A parameter of a joint effect, as the report, the description and a
/// torque scale meet it: the one table `--apply`, the model's totals and
/// the scaled joints' units read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct JointParameter {
    /// Its name in the report.
    pub name: &'static str,
    /// The description's key of the joint: an amount adds to the key's
    /// value; a shape sets it. None for a number the report derives.
    pub key: Option<&'static str>,
    /// A shape of the effect's columns (a rest angle, a Stribeck velocity,
    /// a ripple's cycles), not an amount.
    pub shape: bool,
    /// A torque, or a torque per unit of the joint's motion: a torque
    /// scale multiplies it.
    pub torque: bool,
}

const fn amount(name: &'static str, key: &'static str) -> JointParameter {
    JointParameter {
        name,
        key: Some(key),
        shape: false,
        torque: true,
    }
}

const fn shape(name: &'static str, key: &'static str) -> JointParameter {
    JointParameter {
        name,
        key: Some(key),
        shape: true,
        torque: false,
    }
}

/// The joint effects' parameters, in the report's order per kind.
static JOINT_PARAMETERS: [(Kind, JointParameter); 13] = [
    (Kind::ViscousFriction, amount("coefficient", "viscous")),
    (Kind::CoulombFriction, amount("level", "coulomb")),
    (Kind::Armature, amount("inertia", "armature")),
    (Kind::TorqueOffset, amount("offset", "offset")),
    (
        Kind::CoulombAsymmetry,
        amount("asymmetry", "coulomb_asymmetry"),
    ),
    (Kind::StribeckFriction, amount("excess", "stribeck")),
    (
        Kind::StribeckFriction,
        shape("velocity", "stribeck_velocity"),
    ),
    (Kind::TorqueRipple, amount("sin", "ripple_sin")),
    (Kind::TorqueRipple, amount("cos", "ripple_cos")),
    (Kind::TorqueRipple, shape("cycles", "ripple_cycles")),
    (Kind::JointSpring, amount("stiffness", "spring")),
    (Kind::JointSpring, shape("rest", "spring_rest")),
    // The spring is fitted as stiffness * q + constant (the rest angle is
    // -constant / stiffness); the description has no key for it.
    (
        Kind::JointSpring,
        JointParameter {
            name: "constant",
            key: None,
            shape: false,
            torque: true,
        },
    ),
];

impl Kind {
    /// The parameters of a joint effect (none for the other kinds).
    pub(super) fn joint_parameters(self) -> impl Iterator<Item = &'static JointParameter> {
        let own = move |(kind, p): &'static (Kind, JointParameter)| (*kind == self).then_some(p);
        JOINT_PARAMETERS.iter().filter_map(own)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every amount adds to one of the description's effect values, and a
    /// joint effect has at most one shape (`--apply` sets one).
    #[test]
    fn joint_parameters_meet_the_description() {
        for (kind, p) in &JOINT_PARAMETERS {
            if let (Some(key), false) = (p.key, p.shape) {
                assert!(codegen::EFFECT_NAMES.contains(&key), "{kind:?} {key}");
            }
            assert!(!(p.shape && p.torque), "{kind:?} {}", p.name);
            assert!(kind.joint_parameters().filter(|p| p.shape).count() <= 1);
        }
        assert_eq!(Kind::Payload.joint_parameters().count(), 0);
    }
}
