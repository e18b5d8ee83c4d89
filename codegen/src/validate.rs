//! Validation of one link's and one joint's values (the physics: masses,
//! inertias, axes, limits, effects, locks and mimics); the topology is
//! checked in `description.rs`. Errors carry a key path, located later.

use nalgebra::SymmetricEigen;

use crate::error::{KeyPath, Located};
use crate::names::check_name;
use crate::schema::{Inertia, Joint, JointEffects, JointKind, Limits, Link};

pub(crate) fn validate_name(name: &str, at: KeyPath) -> Result<(), Located> {
    // An empty name cannot be referred to (a joint's parent, --lock, a
    // report's joint), and blank ones read as missing.
    if name.trim().is_empty() {
        return Err(Located::new(
            at,
            "the name is empty; give every link and joint a name",
        ));
    }
    check_name(name).map_err(|message| Located::new(at, message))
}

pub(crate) fn validate_link(link: &Link, at: KeyPath) -> Result<(), Located> {
    let Some(mass) = link.mass else {
        if link.inertia.is_some() || link.com != [0.0; 3] {
            return Err(Located::new(
                at.key("mass"),
                format!(
                    "link `{}` has `com` or `inertia` but no `mass`; give a mass > 0 or remove them for a massless frame",
                    link.name
                ),
            ));
        }
        return Ok(());
    };
    if !mass.is_finite() || mass <= 0.0 {
        return Err(Located::new(
            at.key("mass"),
            format!(
                "mass of link `{}` must be a finite number > 0 kg, found {mass}",
                link.name
            ),
        ));
    }
    if !link.com.iter().all(|c| c.is_finite()) {
        return Err(Located::new(
            at.key("com"),
            "com must be finite numbers (m)",
        ));
    }
    plausible(&[mass], PLAUSIBLE_MASS, at.key("mass"), "mass (kg)")?;
    plausible(
        &link.com,
        PLAUSIBLE_LENGTH,
        at.key("com"),
        "com component (m)",
    )?;
    let Some(inertia) = link.inertia else {
        return Err(Located::new(
            at.key("inertia"),
            format!(
                "link `{}` has a mass but no `inertia` about its centre of mass",
                link.name
            ),
        ));
    };
    validate_inertia(&inertia, link, at.key("inertia"))
}

fn validate_inertia(inertia: &Inertia, link: &Link, at: KeyPath) -> Result<(), Located> {
    if !inertia.values().iter().all(|v| v.is_finite()) {
        return Err(Located::new(
            at,
            "inertia entries must be finite numbers (kg m^2)",
        ));
    }
    let entries = inertia.values();
    plausible(
        &entries,
        PLAUSIBLE_INERTIA,
        at.clone(),
        "inertia entry (kg m^2)",
    )?;
    let eig = SymmetricEigen::new(inertia.matrix()).eigenvalues;
    let mut p = [eig[0], eig[1], eig[2]];
    p.sort_by(f64::total_cmp);
    if link.nonphysical_inertia.is_some() {
        return Ok(());
    }
    // A point mass (zero inertia) and a thin rod (one moment zero) are
    // physical; files round their numbers, so both checks allow for it.
    let rounding = INERTIA_ROUNDING * p[2] + INERTIA_FLOOR;
    if p[0] < -rounding {
        return Err(Located::new(
            at,
            format!(
                "inertia of link `{}` is not positive semi-definite: principal moments {:.6e}, {:.6e}, {:.6e} kg m^2, \
                 so no rigid body has it; fix the tensor, or keep it on purpose with `nonphysical_inertia = \"<why>\"`",
                link.name, p[0], p[1], p[2]
            ),
        ));
    }
    if p[0] + p[1] < p[2] - rounding {
        return Err(Located::new(
            at,
            format!(
                "inertia of link `{}` violates the triangle inequality: principal moments {:.6e} + {:.6e} < {:.6e} kg m^2, \
                 so no rigid body has it; fix the tensor, or keep it on purpose with `nonphysical_inertia = \"<why>\"`",
                link.name, p[0], p[1], p[2]
            ),
        ));
    }
    Ok(())
}

/// Rounding allowed in the inertia checks: relative to the largest principal
/// moment (files print five or six digits) plus an absolute floor, far below
/// any link of an arm (kg m^2).
pub const INERTIA_ROUNDING: f64 = 1e-5;
pub const INERTIA_FLOOR: f64 = 1e-12;

pub(crate) fn validate_joint(joint: &Joint, at: KeyPath) -> Result<(), Located> {
    let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
    if !finite(&joint.origin.xyz) || !finite(&joint.origin.rpy) {
        return Err(Located::new(
            at.key("origin"),
            "origin xyz and rpy must be finite numbers",
        ));
    }
    if !finite(&joint.axis) {
        return Err(Located::new(at.key("axis"), "axis must be finite numbers"));
    }
    let origin = at.key("origin");
    plausible(
        &joint.origin.xyz,
        PLAUSIBLE_LENGTH,
        origin.key("xyz"),
        "origin component (m)",
    )?;
    plausible(
        &joint.origin.rpy,
        PLAUSIBLE_ANGLE,
        origin.key("rpy"),
        "rpy angle (rad)",
    )?;
    let (position_limit, unit) = match joint.kind {
        JointKind::Prismatic => (PLAUSIBLE_LENGTH, "position (m)"),
        _ => (PLAUSIBLE_ANGLE, "angle (rad)"),
    };
    if let Some(position) = joint.locked {
        plausible(
            &[position],
            position_limit,
            at.key("locked"),
            &format!("locked {unit}"),
        )?;
    }
    if joint.kind.has_position() && norm(&joint.axis) < 1e-12 {
        return Err(Located::new(
            at.key("axis"),
            format!(
                "axis of joint `{}` is zero; give a non-zero direction",
                joint.name
            ),
        ));
    }
    if joint.child == joint.parent {
        return Err(Located::new(
            at.key("child"),
            format!(
                "joint `{}` connects link `{}` to itself",
                joint.name, joint.child
            ),
        ));
    }
    let e = &joint.effects;
    let effects = e.parameters();
    if !finite(&effects) || !finite(&e.shapes()) {
        return Err(Located::new(
            at.key("effects"),
            "effects must be finite numbers",
        ));
    }
    plausible(
        &[e.spring_rest],
        PLAUSIBLE_ANGLE,
        at.key("effects").key("spring_rest"),
        "spring rest angle (rad)",
    )?;
    plausible(
        &effects,
        PLAUSIBLE_EFFECT,
        at.key("effects"),
        "effect coefficient",
    )?;
    shaping_numbers(e, &joint.name, &at.key("effects"))?;
    for (key, value) in [
        ("armature", e.armature),
        ("viscous", e.viscous),
        ("coulomb", e.coulomb),
        ("spring", e.spring),
        ("stribeck", e.stribeck),
    ] {
        if value < 0.0 {
            return Err(Located::new(
                at.key("effects").key(key),
                format!(
                    "{key} of joint `{}` must be >= 0, found {value}",
                    joint.name
                ),
            ));
        }
    }
    if e.coulomb_asymmetry.abs() > e.coulomb {
        return Err(Located::new(
            at.key("effects").key("coulomb_asymmetry"),
            format!(
                "coulomb_asymmetry of joint `{}` is {}, beyond coulomb ({}): one direction's \
                 friction level (coulomb - |coulomb_asymmetry|) would be negative",
                joint.name, e.coulomb_asymmetry, e.coulomb
            ),
        ));
    }
    validate_hold(joint, &at)?;
    if joint.mimic.is_some() && (e.stribeck != 0.0 || e.ripple_sin != 0.0 || e.ripple_cos != 0.0) {
        return Err(Located::new(
            at.key("effects"),
            format!(
                "joint `{}` is a mimic: it may have armature, friction, an offset and a spring \
                 (they act on the joint it follows), but not Stribeck friction or a ripple",
                joint.name
            ),
        ));
    }
    if !joint.is_free() && joint.mimic.is_none() && *e != JointEffects::default() {
        return Err(Located::new(
            at.key("effects"),
            format!(
                "joint `{}` does not move alone (fixed, locked or a mimic), so it cannot have effects",
                joint.name
            ),
        ));
    }
    if let Some(l) = joint.limits {
        validate_limits(&l, &at.key("limits"))?;
    }
    Ok(())
}

/// `locked` and `mimic`: only on joints with a position, not both, finite.
fn validate_hold(joint: &Joint, at: &KeyPath) -> Result<(), Located> {
    if joint.locked.is_some() && !joint.kind.has_position() {
        return Err(Located::new(
            at.key("locked"),
            "only a revolute or prismatic joint can be locked",
        ));
    }
    let Some(mimic) = &joint.mimic else {
        return Ok(());
    };
    let at = at.key("mimic");
    if !joint.kind.has_position() {
        return Err(Located::new(
            at,
            "only a revolute or prismatic joint can follow another",
        ));
    }
    if joint.locked.is_some() {
        return Err(Located::new(
            at,
            format!(
                "joint `{}` is locked and a mimic: remove one (a mimic is held when its master is locked)",
                joint.name
            ),
        ));
    }
    if !mimic.multiplier.is_finite() || !mimic.offset.is_finite() {
        return Err(Located::new(
            at,
            "mimic multiplier and offset must be finite numbers",
        ));
    }
    if mimic.multiplier == 0.0 {
        return Err(Located::new(
            at.key("multiplier"),
            format!(
                "mimic multiplier of joint `{}` is 0: the joint never moves; lock it at the \
                 offset instead (`locked = {}`)",
                joint.name, mimic.offset
            ),
        ));
    }
    plausible(
        &[mimic.multiplier, mimic.offset],
        PLAUSIBLE_EFFECT,
        at,
        "mimic multiplier or offset",
    )
}

/// Both position limits or neither, finite, lower <= upper; speeds and
/// efforts finite and >= 0.
fn validate_limits(l: &Limits, at: &KeyPath) -> Result<(), Located> {
    match (l.lower, l.upper) {
        (Some(lower), Some(upper))
            if !(lower.is_finite() && upper.is_finite() && lower <= upper) =>
        {
            return Err(Located::new(
                at.clone(),
                format!("limits need finite lower <= upper, found {lower} > {upper}"),
            ));
        }
        (Some(_), None) | (None, Some(_)) => {
            return Err(Located::new(
                at.clone(),
                "give both `lower` and `upper`, or neither (a continuous joint)",
            ));
        }
        _ => {}
    }
    for (key, value) in [("velocity", l.velocity), ("effort", l.effort)] {
        if let Some(v) = value
            && !(v.is_finite() && v >= 0.0)
        {
            return Err(Located::new(
                at.key(key),
                format!("{key} limit must be a finite number >= 0, found {v}"),
            ));
        }
    }
    Ok(())
}

/// Euclidean length without overflow (components are scaled by the
/// largest first: an axis of [1e200, 0, 0] has length 1e200, not inf).
pub(crate) fn norm(v: &[f64; 3]) -> f64 {
    let largest = v.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
    if largest == 0.0 || !largest.is_finite() {
        return largest;
    }
    let s = v.map(|x| x / largest);
    largest * (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt()
}

/// Largest magnitudes accepted, far outside any arm: a value past them is
/// a typo or a unit slip, and squared in the dynamics it would overflow.
pub const PLAUSIBLE_MASS: f64 = 1e5; // kg
pub const PLAUSIBLE_LENGTH: f64 = 1e2; // m (origins, centres of mass)
pub const PLAUSIBLE_INERTIA: f64 = 1e5; // kg m^2
pub const PLAUSIBLE_ANGLE: f64 = 1e2; // rad (rpy, locked angles)
pub const PLAUSIBLE_EFFECT: f64 = 1e6; // armature, friction, offset, spring
pub const PLAUSIBLE_GRAVITY: f64 = 1e3; // m/s^2

/// A located error when a value exceeds `limit`.
pub(crate) fn plausible(
    values: &[f64],
    limit: f64,
    at: KeyPath,
    what: &str,
) -> Result<(), Located> {
    match values.iter().find(|v| v.abs() > limit) {
        Some(v) => Err(Located::new(
            at,
            format!("{what} {v:e} is beyond any arm (at most {limit:e}); a typo or a unit slip?"),
        )),
        None => Ok(()),
    }
}

/// Fastest Stribeck velocity, rad/s, and most ripple periods per revolution.
pub const PLAUSIBLE_STRIBECK_VELOCITY: f64 = 1e2;
pub const PLAUSIBLE_RIPPLE_CYCLES: f64 = 1e4;

/// The Stribeck velocity and the ripple's cycles: within range, and
/// positive where their effect is present (a zero would divide or vanish).
fn shaping_numbers(e: &JointEffects, joint: &str, at: &KeyPath) -> Result<(), Located> {
    let checks = [
        (
            "stribeck_velocity",
            e.stribeck_velocity,
            PLAUSIBLE_STRIBECK_VELOCITY,
            e.stribeck != 0.0,
            "rad/s, the speed past which the breakaway excess `stribeck` fades",
        ),
        (
            "ripple_cycles",
            e.ripple_cycles,
            PLAUSIBLE_RIPPLE_CYCLES,
            e.ripple_sin != 0.0 || e.ripple_cos != 0.0,
            "periods of the ripple per joint revolution",
        ),
    ];
    for (key, value, limit, needed, meaning) in checks {
        plausible(&[value], limit, at.key(key), key)?;
        if value < 0.0 || (needed && value == 0.0) {
            let requirement = if needed { "> 0" } else { ">= 0" };
            return Err(Located::new(
                at.key(key),
                format!(
                    "{key} of joint `{joint}` must be {requirement} ({meaning}), found {value}"
                ),
            ));
        }
    }
    Ok(())
}
