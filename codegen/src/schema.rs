//! The description's types, as the TOML spells them (serde): links, joints,
//! inertia, origin, limits and joint effects. Parsing and validation are in
//! `description.rs`.

use nalgebra::Matrix3;
use serde::Deserialize;

/// Relative tolerance for inertia symmetry and the triangle inequality.
pub(crate) const INERTIA_RTOL: f64 = 1e-9;

/// A rigid body. A link without `mass` is a massless frame.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Link {
    pub name: String,
    /// Mass in kg; absent for a massless frame.
    pub mass: Option<f64>,
    /// Centre of mass in the link frame, m.
    #[serde(default)]
    pub com: [f64; 3],
    /// Inertia about the centre of mass, in link-frame axes, kg m^2.
    #[serde(default)]
    pub inertia: Option<Inertia>,
    /// Opt-in to keep an inertia tensor that is not physically realisable
    /// (violates the triangle inequality). The value says why.
    #[serde(default)]
    pub nonphysical_inertia: Option<String>,
}

/// The six independent entries of a symmetric inertia tensor, or a full
/// 3x3 matrix (checked for symmetry).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Inertia {
    pub ixx: f64,
    pub iyy: f64,
    pub izz: f64,
    pub ixy: f64,
    pub ixz: f64,
    pub iyz: f64,
}

/// The joint kinds a description may use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JointKind {
    /// Turns about `axis`: q in rad, effects in N m.
    Revolute,
    /// Slides along `axis`: q in m, effects in N.
    Prismatic,
    Fixed,
}

impl JointKind {
    /// Revolute and prismatic joints have a position q.
    pub fn has_position(self) -> bool {
        self != JointKind::Fixed
    }
}

/// A joint whose position follows another's (URDF `<mimic>`):
/// q = multiplier * q_master + offset.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Mimic {
    /// The joint it follows.
    pub joint: String,
    #[serde(default = "one")]
    pub multiplier: f64,
    #[serde(default)]
    pub offset: f64,
}

fn one() -> f64 {
    1.0
}

/// A joint connecting `parent` to `child`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Joint {
    pub name: String,
    #[serde(rename = "type")]
    pub kind: JointKind,
    pub parent: String,
    pub child: String,
    /// Joint frame in the parent link frame.
    #[serde(default)]
    pub origin: Origin,
    /// Rotation axis (revolute) or direction of travel (prismatic) in the
    /// joint frame; normalized on load.
    #[serde(default = "default_axis")]
    pub axis: [f64; 3],
    #[serde(default)]
    pub limits: Option<Limits>,
    /// A joint held at this position (rad or m): lumped like a fixed joint.
    #[serde(default)]
    pub locked: Option<f64>,
    /// The joint follows another one's position instead of moving alone.
    #[serde(default)]
    pub mimic: Option<Mimic>,
    #[serde(default)]
    pub effects: JointEffects,
}

impl Joint {
    /// A joint that moves on its own: a degree of freedom of the chain.
    pub fn is_free(&self) -> bool {
        self.kind.has_position() && self.locked.is_none() && self.mimic.is_none()
    }
}

/// A frame offset: translation, then roll-pitch-yaw (fixed axes x, y, z).
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Origin {
    #[serde(default)]
    pub xyz: [f64; 3],
    #[serde(default)]
    pub rpy: [f64; 3],
}

/// Joint limits in the joint's units (rad or m; rad/s or m/s; N m or N);
/// informative for the generator, used by the virtual robot and trajectory
/// tools. A continuous joint has no position limits.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Limits {
    #[serde(default)]
    pub lower: Option<f64>,
    #[serde(default)]
    pub upper: Option<f64>,
    #[serde(default)]
    pub velocity: Option<f64>,
    #[serde(default)]
    pub effort: Option<f64>,
}

impl Limits {
    /// The position range, when the joint has one.
    pub fn position(&self) -> Option<(f64, f64)> {
        self.lower.zip(self.upper)
    }
}

/// Per-joint effects added to the rigid-body torque (force, for a
/// prismatic joint; every unit's radian reads metre there):
/// `armature*qdd + viscous*qd + coulomb*sign(qd) + coulomb_asymmetry*|sign(qd)|
/// + stribeck*sign(qd)*exp(-(qd/stribeck_velocity)^2) + offset`, and the
/// torques of the position alone (part of the generated `gravity`): a joint
/// spring `spring*(q - spring_rest)` and a torque ripple
/// `ripple_sin*sin(ripple_cycles*q) + ripple_cos*cos(ripple_cycles*q)`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointEffects {
    /// Reflected rotor inertia, kg m^2.
    #[serde(default)]
    pub armature: f64,
    /// Viscous friction, N m s/rad.
    #[serde(default)]
    pub viscous: f64,
    /// Coulomb friction level, N m (sign(0) = 0).
    #[serde(default)]
    pub coulomb: f64,
    /// Constant torque offset, N m.
    #[serde(default)]
    pub offset: f64,
    /// Direction-dependent dry friction, N m, added while the joint moves
    /// either way: the Coulomb levels are coulomb + coulomb_asymmetry
    /// forwards and coulomb - coulomb_asymmetry backwards.
    #[serde(default)]
    pub coulomb_asymmetry: f64,
    /// Joint spring stiffness, N m/rad (a gravity-balancing spring, a cable).
    #[serde(default)]
    pub spring: f64,
    /// The spring's rest angle, rad.
    #[serde(default)]
    pub spring_rest: f64,
    /// Stribeck friction: how far the breakaway friction at rest exceeds
    /// the sliding (Coulomb) level, N m; it fades as the speed grows past
    /// `stribeck_velocity`.
    #[serde(default)]
    pub stribeck: f64,
    /// The Stribeck velocity, rad/s (> 0 when `stribeck` is not 0).
    #[serde(default)]
    pub stribeck_velocity: f64,
    /// Position-dependent torque ripple (cogging, gear or sensor
    /// harmonics), N m: the sine and cosine amplitudes of its harmonic.
    #[serde(default)]
    pub ripple_sin: f64,
    #[serde(default)]
    pub ripple_cos: f64,
    /// The ripple's periods per joint revolution (> 0 when a ripple
    /// amplitude is not 0).
    #[serde(default)]
    pub ripple_cycles: f64,
}

/// Names of the joint-effect parameters of joint i (the order of
/// `JointEffects::parameters`).
pub const EFFECT_NAMES: [&str; EFFECTS_PER_JOINT] = [
    "armature",
    "viscous",
    "coulomb",
    "offset",
    "coulomb_asymmetry",
    "spring",
    "stribeck",
    "ripple_sin",
    "ripple_cos",
];
/// Regressor columns per joint: its effects.
pub const EFFECTS_PER_JOINT: usize = 9;
/// Regressor columns per degree of freedom: ten inertial and the effects.
pub const PARAMETERS_PER_JOINT: usize = 10 + EFFECTS_PER_JOINT;
/// The generated constants of the effects, `JOINT{i}_` + these.
pub const EFFECT_CONSTANTS: [&str; EFFECTS_PER_JOINT] = [
    "ARMATURE",
    "VISCOUS",
    "COULOMB",
    "OFFSET",
    "COULOMB_ASYMMETRY",
    "SPRING",
    "STRIBECK",
    "RIPPLE_SIN",
    "RIPPLE_COS",
];

impl JointEffects {
    /// The effect parameters in regressor order (see `EFFECT_NAMES`); the
    /// spring's rest angle, the Stribeck velocity and the ripple's cycles
    /// are not (they shape the columns: q - spring_rest,
    /// sign(qd) exp(-(qd/stribeck_velocity)^2), sin and cos of
    /// ripple_cycles*q; see [`JointEffects::shapes`]).
    pub fn parameters(&self) -> [f64; EFFECTS_PER_JOINT] {
        [
            self.armature,
            self.viscous,
            self.coulomb,
            self.offset,
            self.coulomb_asymmetry,
            self.spring,
            self.stribeck,
            self.ripple_sin,
            self.ripple_cos,
        ]
    }

    /// The numbers that shape the regressor's columns: spring_rest,
    /// stribeck_velocity, ripple_cycles.
    pub fn shapes(&self) -> [f64; 3] {
        [self.spring_rest, self.stribeck_velocity, self.ripple_cycles]
    }

    /// sign(qd) exp(-(qd/stribeck_velocity)^2), 0 without a Stribeck
    /// velocity: the Stribeck column (std's `exp`; the generated code has
    /// its own).
    pub fn stribeck_shape(&self, qd: f64) -> f64 {
        if self.stribeck_velocity > 0.0 {
            let x = qd / self.stribeck_velocity;
            sign(qd) * (-x * x).exp()
        } else {
            0.0
        }
    }

    /// The torque of the position alone: spring and ripple.
    pub fn position_torque(&self, q: f64) -> f64 {
        let (s, c) = (self.ripple_cycles * q).sin_cos();
        self.spring * (q - self.spring_rest) + self.ripple_sin * s + self.ripple_cos * c
    }

    /// The velocity and acceleration effects, armature included.
    pub fn motion_torque(&self, qd: f64, qdd: f64) -> f64 {
        let sign = sign(qd);
        self.armature * qdd
            + self.viscous * qd
            + self.coulomb * sign
            + self.coulomb_asymmetry * sign * sign
            + self.stribeck * self.stribeck_shape(qd)
            + self.offset
    }
}

/// sign(x) with sign(0) = 0, as the generated code.
pub fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

pub(crate) fn default_axis() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

impl Inertia {
    /// The tensor as a symmetric matrix.
    pub fn matrix(&self) -> Matrix3<f64> {
        Matrix3::new(
            self.ixx, self.ixy, self.ixz, self.ixy, self.iyy, self.iyz, self.ixz, self.iyz,
            self.izz,
        )
    }

    /// The six entries of a symmetric matrix (its upper triangle).
    pub fn from_matrix(m: &Matrix3<f64>) -> Inertia {
        Inertia {
            ixx: m[(0, 0)],
            iyy: m[(1, 1)],
            izz: m[(2, 2)],
            ixy: m[(0, 1)],
            ixz: m[(0, 2)],
            iyz: m[(1, 2)],
        }
    }

    pub(crate) fn values(&self) -> [f64; 6] {
        [self.ixx, self.iyy, self.izz, self.ixy, self.ixz, self.iyz]
    }
}

impl<'de> Deserialize<'de> for Inertia {
    fn deserialize<D: serde::Deserializer<'de>>(de: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct Entries {
            ixx: f64,
            iyy: f64,
            izz: f64,
            #[serde(default)]
            ixy: f64,
            #[serde(default)]
            ixz: f64,
            #[serde(default)]
            iyz: f64,
        }
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Form {
            Entries(Entries),
            Matrix([[f64; 3]; 3]),
        }
        let form = Form::deserialize(de).map_err(|_| {
            serde::de::Error::custom(
                "expected `inertia = { ixx = .., iyy = .., izz = .., ixy = .., ixz = .., iyz = .. }` \
                 or a symmetric 3x3 matrix `[[..], [..], [..]]` of numbers",
            )
        })?;
        Ok(match form {
            Form::Entries(e) => Inertia {
                ixx: e.ixx,
                iyy: e.iyy,
                izz: e.izz,
                ixy: e.ixy,
                ixz: e.ixz,
                iyz: e.iyz,
            },
            Form::Matrix(m) => {
                let (sym, skew) = symmetric_parts(&m);
                if skew > INERTIA_RTOL * sym.max(f64::MIN_POSITIVE) {
                    return Err(serde::de::Error::custom(format!(
                        "inertia matrix is not symmetric (largest asymmetry {skew:e} kg m^2)"
                    )));
                }
                Inertia::from_matrix(&Matrix3::from_fn(|r, c| m[r][c]))
            }
        })
    }
}

/// Largest absolute entry and largest asymmetry |m_rc - m_cr| of a matrix.
fn symmetric_parts(m: &[[f64; 3]; 3]) -> (f64, f64) {
    let cells = (0..3).flat_map(|r| (0..3).map(move |c| (r, c)));
    cells.fold((0.0, 0.0), |(largest, skew): (f64, f64), (r, c)| {
        (
            largest.max(m[r][c].abs()),
            skew.max((m[r][c] - m[c][r]).abs()),
        )
    })
}
