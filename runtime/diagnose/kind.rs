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
