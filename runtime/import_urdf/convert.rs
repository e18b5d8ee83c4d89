//! URDF links and joints into description links and joints: inertias into
//! the link frame and judged, limits and `<dynamics>` kept, each joint
//! written as its role in the import says (moving, locked, mimic, fixed).

use std::collections::HashSet;

use super::chain::Role;
use super::inertia::{self, Judgement};
use super::parse::{Inertial, Joint, JointData, Kind, Link, Mimic};
use super::{Attachment, ImportError, Messages, invalid, option_error};

/// Radius of the solid sphere that stands in for a point-mass attachment,
/// so the payload's inertia is that of a small body (2/5 m r^2).
const POINT_MASS_RADIUS: f64 = 1e-3;

/// A description link: a massless frame or a rigid body.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct LinkOut {
    pub name: String,
    pub body: Option<Body>,
    /// `nonphysical_inertia`: why the inertia is kept anyway.
    pub nonphysical: Option<String>,
    pub comment: Option<String>,
}

/// Mass (kg), COM in the link frame (m), inertia about the COM in link axes
/// (kg m^2; ixx iyy izz ixy ixz iyz).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Body {
    pub mass: f64,
    pub com: [f64; 3],
    pub inertia: [f64; 6],
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum KindOut {
    Revolute,
    Prismatic,
    Fixed,
}

/// Limits that are present: position (rad or m), velocity, effort.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct LimitsOut {
    pub lower: Option<f64>,
    pub upper: Option<f64>,
    pub velocity: Option<f64>,
    pub effort: Option<f64>,
}

/// A description joint.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct JointOut {
    pub name: String,
    pub kind: KindOut,
    pub parent: String,
    pub child: String,
    pub xyz: [f64; 3],
    pub rpy: [f64; 3],
    pub axis: [f64; 3],
    pub limits: Option<LimitsOut>,
    pub locked: Option<f64>,
    pub mimic: Option<Mimic>,
    /// viscous, coulomb.
    pub effects: Option<(f64, f64)>,
}

/// How a link is written: `fixed_base` links never move, so an inertia
/// they carry changes no torque.
pub(super) fn convert_link(
    link: &Link,
    fixed_base: bool,
    nonphysical_allowed: bool,
    messages: &mut Messages,
) -> Result<LinkOut, ImportError> {
    let mut out = LinkOut {
        name: link.name.clone(),
        body: None,
        nonphysical: None,
        comment: None,
    };
    let Some(inertial) = link.inertial.clone()? else {
        return Ok(out);
    };
    let element = format!("link '{}' <inertial> (line {})", link.name, inertial.line);
    let inertia = inertia::rotate(&inertial.inertia, &inertial.rpy);
    if inertial.mass == 0.0 {
        if inertia.iter().any(|&x| x != 0.0) && !fixed_base {
            messages.warnings.push(format!(
                "{element}: mass 0 with a non-zero inertia; imported as a massless frame"
            ));
        }
        return Ok(out);
    }
    match inertia::judge(&inertia) {
        Judgement::Physical => {}
        _ if fixed_base => {
            out.comment = Some(format!(
                "On the fixed base: the URDF's non-physical inertial (line {}) is left out; \
                 it changes no torque.",
                inertial.line
            ));
            return Ok(out);
        }
        Judgement::Triangle(p) => {
            let why = inertia::breach(&p);
            messages.warnings.push(format!(
                "{element}: {why}, which no rigid body has (the triangle inequality); \
                 imported as it is, with `nonphysical_inertia`"
            ));
            out.nonphysical = Some(format!("imported from URDF: {why}"));
        }
        Judgement::Negative(p) => {
            let moments = p.map_or_else(|| "no principal moments".into(), |p| inertia::moments(&p));
            if !nonphysical_allowed {
                return Err(invalid(
                    element,
                    format!(
                        "the inertia is not positive semi-definite ({moments}); fix the file, or \
                         keep it on purpose with --nonphysical-inertia {}",
                        link.name
                    ),
                ));
            }
            out.nonphysical = Some(format!(
                "imported from URDF with --nonphysical-inertia: {moments}"
            ));
        }
    }
    out.body = Some(body(&inertial, inertia));
    Ok(out)
}

fn body(inertial: &Inertial, inertia: [f64; 6]) -> Body {
    Body {
        mass: inertial.mass,
        com: inertial.xyz,
        inertia,
    }
}

/// A kept joint as its role says; `user_lock` when `--lock` holds it.
pub(super) fn convert_joint(
    joint: &Joint,
    role: &Role,
    user_lock: bool,
    messages: &mut Messages,
) -> Result<JointOut, ImportError> {
    let data = joint.data.clone()?;
    let kind = match (role, joint.kind) {
        (Role::Fixed, _) => KindOut::Fixed,
        (_, Kind::Prismatic) => KindOut::Prismatic,
        _ => KindOut::Revolute,
    };
    if kind != KindOut::Fixed && data.axis.iter().all(|&a| a == 0.0) {
        return Err(invalid(
            // The joint's line: the parsed data keeps none of its <axis>.
            format!("joint '{}' (line {})", joint.name, joint.line),
            "its <axis> is zero",
        ));
    }
    let moving = *role == Role::Moving;
    let limits = match kind {
        KindOut::Fixed => None,
        _ => limits(joint, &data, moving, messages),
    };
    if let (Role::Locked(value), Some(l)) = (role, &limits)
        && let (Some(lower), Some(upper)) = (l.lower, l.upper)
        && (*value < lower || *value > upper)
        && user_lock
    {
        messages.warnings.push(format!(
            "joint '{}' is locked at {value}, outside its limits [{lower}, {upper}]",
            joint.name
        ));
    }
    let has_dynamics = data.damping != 0.0 || data.friction != 0.0;
    // A mimic keeps its friction: it acts on the joint it follows when that
    // one moves (and is lumped away with it when it is held).
    let mimic = matches!(role, Role::Mimic(_));
    if has_dynamics && !moving && !mimic && kind != KindOut::Fixed {
        messages.idle_dynamics.push(joint.name.clone());
    }
    if has_dynamics && (moving || mimic) {
        messages.friction.push(joint.name.clone());
    }
    Ok(JointOut {
        name: joint.name.clone(),
        kind,
        parent: joint.parent.clone(),
        child: joint.child.clone(),
        xyz: data.xyz,
        rpy: data.rpy,
        axis: data.axis,
        limits,
        locked: match role {
            Role::Locked(value) => Some(*value),
            _ => None,
        },
        mimic: match role {
            Role::Mimic(m) => Some(m.clone()),
            _ => None,
        },
        effects: ((moving || mimic) && has_dynamics).then_some((data.damping, data.friction)),
    })
}

/// Position limits of revolute and prismatic joints (a continuous joint
/// has none), velocity and effort of every moving kind. Zero velocity or
/// effort, and lower = upper = 0, are URDF placeholders for "not given".
fn limits(
    joint: &Joint,
    data: &JointData,
    moving: bool,
    messages: &mut Messages,
) -> Option<LimitsOut> {
    let l = &data.limit;
    let positive = |v: Option<f64>| v.filter(|&v| v > 0.0);
    let mut out = LimitsOut {
        lower: None,
        upper: None,
        velocity: positive(l.velocity),
        effort: positive(l.effort),
    };
    if joint.kind != Kind::Continuous {
        match (l.lower, l.upper) {
            (Some(lower), Some(upper)) if lower != 0.0 || upper != 0.0 => {
                (out.lower, out.upper) = (Some(lower), Some(upper));
            }
            _ if moving => messages.warnings.push(format!(
                "joint '{}' ({}) has no <limit lower upper>; imported without position limits",
                joint.name,
                joint.kind.name()
            )),
            _ => {}
        }
    }
    (out != LimitsOut::default()).then_some(out)
}

/// Adds each `--attach` payload as a fixed child link of its link.
pub(super) fn attach_payloads(
    attachments: &[Attachment],
    taken: &mut HashSet<String>,
    links: &mut Vec<LinkOut>,
    joints: &mut Vec<JointOut>,
) -> Result<(), ImportError> {
    for a in attachments {
        if !links.iter().any(|l| l.name == a.link) {
            return Err(option_error(
                "--attach",
                format!("link '{}' is not in the imported chain", a.link),
            ));
        }
        if !moves(&a.link, joints) {
            return Err(option_error(
                "--attach",
                format!(
                    "link '{}' does not move (the base, or fixed or locked to it): a payload \
                     there changes no joint torque; attach it to a link the joints carry",
                    a.link
                ),
            ));
        }
        let body = payload_body(a)?;
        let name = unique_name(&format!("{}_payload", a.link), taken);
        let joint = unique_name(&format!("{name}_joint"), taken);
        let comment = match a.inertia {
            Some(_) => format!("Attached payload: --attach '{a}'"),
            None => format!(
                "Attached point mass: --attach '{a}'\n(inertia of a solid sphere of radius \
                 {POINT_MASS_RADIUS} m)"
            ),
        };
        links.push(LinkOut {
            name: name.clone(),
            body: Some(body),
            nonphysical: None,
            comment: Some(comment),
        });
        joints.push(JointOut {
            name: joint,
            kind: KindOut::Fixed,
            parent: a.link.clone(),
            child: name,
            xyz: [0.0; 3],
            rpy: [0.0; 3],
            axis: [0.0, 0.0, 1.0],
            limits: None,
            locked: None,
            mimic: None,
            effects: None,
        });
    }
    Ok(())
}

/// Whether a joint that moves lies between `link` and the base.
fn moves(link: &str, joints: &[JointOut]) -> bool {
    let mut current = link;
    // Each step goes one joint up; more steps than joints is a cycle.
    for _ in 0..=joints.len() {
        match joints.iter().find(|j| j.child == current) {
            Some(j) if j.kind != KindOut::Fixed && j.locked.is_none() => return true,
            Some(j) => current = &j.parent,
            None => return false,
        }
    }
    false
}

fn payload_body(a: &Attachment) -> Result<Body, ImportError> {
    let finite = a.mass.is_finite()
        && a.com.iter().all(|x| x.is_finite())
        && a.inertia.iter().flatten().all(|x| x.is_finite());
    if !finite || a.mass <= 0.0 {
        return Err(option_error(
            "--attach",
            format!("'{a}' needs a finite mass > 0 and finite com/inertia"),
        ));
    }
    // 2/5 m r^2, to 6 digits so the file does not show rounding noise.
    let sphere = 0.4 * a.mass * POINT_MASS_RADIUS * POINT_MASS_RADIUS;
    let sphere = format!("{sphere:.5e}").parse().unwrap_or(sphere);
    Ok(Body {
        mass: a.mass,
        com: a.com,
        inertia: a.inertia.unwrap_or([sphere, sphere, sphere, 0.0, 0.0, 0.0]),
    })
}

fn unique_name(wanted: &str, taken: &mut HashSet<String>) -> String {
    let name = std::iter::once(wanted.to_string())
        .chain((2..).map(|n| format!("{wanted}_{n}")))
        .find(|n| !taken.contains(n))
        .unwrap_or_default();
    taken.insert(name.clone());
    name
}

/// Refuses names a description would refuse (control characters, such as
/// a newline written `&#10;` in the URDF), naming the element to rename.
pub(super) fn check_names(
    name: &str,
    from_option: bool,
    links: &[LinkOut],
    joints: &[JointOut],
) -> Result<(), ImportError> {
    codegen::names::check_name(name).map_err(|m| {
        if from_option {
            invalid("--name", m)
        } else {
            invalid(
                "<robot name>",
                format!("{m}; pass --name to choose another"),
            )
        }
    })?;
    for link in links {
        codegen::names::check_name(&link.name)
            .map_err(|m| invalid(format!("<link name={:?}>", link.name), m))?;
    }
    for joint in joints {
        codegen::names::check_name(&joint.name)
            .map_err(|m| invalid(format!("<joint name={:?}>", joint.name), m))?;
    }
    Ok(())
}
