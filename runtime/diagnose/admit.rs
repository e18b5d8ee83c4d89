//! Whether a fitted candidate may be named: its parameters significant
//! ([`super::significance`]) and physical (a sign, size or reach a real effect can have;
//! otherwise a note says what the data show instead).

use super::candidate::{Candidate, Shape, width};
use super::fit::fit;
use super::gain::Gain;
use super::kind::Kind;
use super::moments::Moments;
use super::shape::plausible_moment;
use super::significance::significant;
use super::stacked::EXTENT_MARGIN;
use super::whole::{PHYSICAL_LOSS, com_distance, named_within};

/// A link's fitted mass beyond this factor of its modelled mass (either
/// way) is not taken as an inertial error of that link.
pub const MASS_FACTOR: f64 = 3.0;

/// Whether fitted `values` can be the candidate's physical effect; if not,
/// the note that says what the data show instead.
pub(super) fn physical(
    candidate: &Candidate,
    values: &[f64],
    gain: Gain,
    reach: f64,
) -> Result<(), String> {
    let at = match (&candidate.joint, &candidate.link) {
        (Some(j), _) => format!("joint {}", j + 1),
        (None, Some((k, name))) if candidate.kind == Kind::InertialError => {
            format!("link {} (`{name}`)", k + 1)
        }
        _ => "the last link".to_string(),
    };
    let cut = gain.would_cut();
    let value = values[0];
    let meaning = match candidate.kind {
        Kind::TorqueOffset | Kind::CoulombAsymmetry | Kind::TorqueRipple => return Ok(()),
        Kind::TorqueScale | Kind::TorqueDelay | Kind::GravityDirection => {
            return plausible_data_effect(candidate, values, &at, &cut);
        }
        Kind::InertialError if matches!(candidate.shape, Shape::Whole { .. }) => {
            return plausible_body(candidate, values, reach, &at, &cut);
        }
        Kind::InertialError if matches!(candidate.shape, Shape::Moment { .. }) => {
            let Shape::Moment { base_mass, .. } = candidate.shape else {
                unreachable!("matched above")
            };
            let distance = values.iter().map(|h| h * h).sum::<f64>().sqrt() / base_mass;
            return within(candidate, distance, reach).map_err(|bound| {
                format!(
                    "{at}: the data fit a first moment that puts the centre of mass {distance:.2} m \
                     from the link origin at the modelled mass {base_mass:.4} kg ({bound}): not a \
                     physical body; not named (it {cut})"
                )
            });
        }
        Kind::InertialError => {
            let distance = values[1..].iter().map(|c| c * c).sum::<f64>().sqrt();
            let modelled = match candidate.shape {
                Shape::Body { base_mass, .. } => base_mass,
                _ => 0.0,
            };
            if modelled > 0.0 && !(modelled / MASS_FACTOR..=modelled * MASS_FACTOR).contains(&value)
            {
                return Err(format!(
                    "{at}: the data fit a mass of {value:.4} kg for a link modelled at \
                     {modelled:.4} kg, beyond a factor of {MASS_FACTOR}: not a plausible \
                     correction of this link but the trace of another effect (an armature, a \
                     payload); not named (it {cut})"
                ));
            }
            let bound = within(candidate, distance, reach);
            if value > 0.0 && bound.is_ok() {
                return Ok(());
            }
            let bound = bound
                .err()
                .unwrap_or_else(|| "a mass must be positive".to_string());
            return Err(format!(
                "{at}: the data fit a mass of {value:.4} kg with its centre of mass {distance:.2} m \
                 from the link origin ({bound}): not a physical body; not named (it {cut})"
            ));
        }
        _ if value <= 0.0 => match candidate.kind {
            Kind::Armature => {
                "the model's inertia about this joint is too high (an inertial error, not a rotor)"
            }
            Kind::ViscousFriction => {
                "torque falls with speed: not viscous friction (check the velocity filter, or a Stribeck effect)"
            }
            Kind::CoulombFriction => {
                "the residual opposes friction's direction: check the torque sign convention"
            }
            Kind::JointSpring => {
                "torque that pushes the joint away from a rest angle is not a spring (a link \
                 modelled too light about this joint?)"
            }
            Kind::StribeckFriction => {
                "friction that grows with speed past rest: not a Stribeck breakaway (a \
                 Coulomb level set too high?)"
            }
            _ => "the last link is lighter than modelled (an inertial error, not a payload)",
        },
        Kind::Payload => {
            let com = &values[1..4];
            let distance = com.iter().map(|c| c * c).sum::<f64>().sqrt();
            if distance > reach {
                return Err(format!(
                    "{at}: the data fit a mass of only {value:.4} kg with its centre of mass at \
                     [{:.3}, {:.3}, {:.3}] m, {distance:.2} m away, beyond the arm's reach \
                     ({reach:.2} m): a first-moment change, i.e. an inertial error of the last \
                     link, not a payload; not named (it {cut})",
                    com[0], com[1], com[2]
                ));
            }
            let own = matches!(
                candidate.shape,
                Shape::Body {
                    own_inertia: true,
                    ..
                }
            );
            if own && !plausible_moment(values[4], value, reach) {
                return Err(format!(
                    "{at}: the data fit the payload a moment of inertia about its centre of mass \
                     of {:.3e} kg m^2, not that of a {value:.3} kg body within the arm's reach \
                     ({reach:.2} m); kept a point mass (it {cut})",
                    values[4]
                ));
            }
            return Ok(());
        }
        _ => return Ok(()),
    };
    let kind = candidate.kind.name();
    Err(format!(
        "{at}: the data fit {kind} = {value:.4}, a negative value (it {cut}): {meaning}; \
         not named"
    ))
}

/// Whether a whole-body fit names a plausible body of its link: reaching
/// the nearest physical body with its centre of mass within the link's
/// extent gives up at most [`PHYSICAL_LOSS`] of the torque the fit
/// explains, its mass stays within [`MASS_FACTOR`] of the model's, and its
/// mass lies within the link's span on average. A fit whose nearest body
/// lies beyond the arm's size is refused.
fn plausible_body(
    candidate: &Candidate,
    values: &[f64],
    reach: f64,
    at: &str,
    cut: &str,
) -> Result<(), String> {
    let Shape::Whole { basis, gram } = &candidate.shape else {
        return Ok(());
    };
    let modelled = candidate.modelled[0];
    let named = named_within(&candidate.modelled, (basis, gram), values, candidate.extent);
    let (body, lost) = (named.body, named.lost);
    let free_lost = named.beyond.map_or(lost, |(_, free)| free);
    if free_lost > PHYSICAL_LOSS {
        return Err(format!(
            "{at}: the data fit a change of the link's ten inertial parameters that no physical \
             body makes (the nearest body gives up {:.0}% of the torque it explains): the trace \
             of another effect; not named (it {cut})",
            100.0 * free_lost
        ));
    }
    if let Some((distance, _)) = named.beyond {
        let bound = if distance > reach {
            Some(format!("the arm's size is {reach:.2} m"))
        } else if lost > PHYSICAL_LOSS {
            Some(format!(
                "beyond the link's extent, {:.2} m, and the nearest body within it gives up \
                 {:.0}% of the torque the fit explains",
                candidate.extent,
                100.0 * lost
            ))
        } else {
            None
        };
        if let Some(bound) = bound {
            return Err(format!(
                "{at}: the data fit a body whose centre of mass lies {distance:.2} m from the link \
                 origin ({bound}): not a physical correction; not named (it {cut})"
            ));
        }
    }
    let mass = body[0];
    if modelled > 0.0 && !(modelled / MASS_FACTOR..=modelled * MASS_FACTOR).contains(&mass) {
        return Err(format!(
            "{at}: the data fit a body of {mass:.4} kg for a link modelled at {modelled:.4} kg, \
             beyond a factor of {MASS_FACTOR}: not a plausible correction of this link but the \
             trace of another effect; not named (it {cut})"
        ));
    }
    let distance = com_distance(&body);
    // A body held within the extent reaches it to the penalty's 1e-9.
    within(candidate, distance * (1.0 - 1e-6), reach).map_err(|bound| {
        format!(
            "{at}: the data fit a body whose centre of mass lies {distance:.2} m from the link \
             origin ({bound}): not a physical correction; not named (it {cut})"
        )
    })?;
    spread_within(candidate, &body, reach).map_err(|(rms, bound)| {
        format!(
            "{at}: the data fit a body of {mass:.4} kg whose inertia puts its mass {rms:.2} m \
             from the link origin on average (root mean square), beyond the {bound:.2} m the \
             link's span allows: not a physical correction of this link but the trace of \
             another effect (an armature?); not named (it {cut})"
        )
    })
}

/// How far beyond a link's span (the larger of its extent and its
/// description's root-mean-square radius) a fitted body's mass may lie on
/// average: the housing around the farthest joint, and the fit's error in
/// the directions the data barely see (a Panda wrist link scaled by 1.18
/// fits 0.19 m against the description's 0.18 m).
pub const SPREAD_FACTOR: f64 = 1.5;

/// Whether a body's mass lies within the link's span on average: the root
/// mean square of its distance from the link origin, sqrt of its second
/// moment there (half its inertia's trace: the integral of |x|^2 dm) per
/// kilogram, at most [`SPREAD_FACTOR`] times the larger of the link's
/// extent (within the arm's size) and the description's own root mean
/// square. A 3.8 kg, 0.57 m forearm with 8.5 kg m^2 about its COM (1.6 m)
/// is refused.
fn spread_within(candidate: &Candidate, body: &[f64; 10], reach: f64) -> Result<(), (f64, f64)> {
    let second_moment = |p: &[f64; 10]| (p[4] + p[6] + p[9]) / 2.0;
    let (mass, modelled) = (body[0], &candidate.modelled);
    let span = candidate.extent.min(reach);
    let described = if modelled[0] > 0.0 {
        second_moment(modelled) / modelled[0]
    } else {
        0.0
    };
    let allowed = SPREAD_FACTOR.powi(2) * span.powi(2).max(described);
    let mean_square = second_moment(body) / mass;
    if mean_square <= allowed {
        Ok(())
    } else {
        Err((mean_square.sqrt(), allowed.sqrt()))
    }
}

/// Whether a link's fitted centre of mass, `distance` from its origin, lies
/// within the link's extent (its child joints and modelled COM, plus a
/// margin) and the arm's size `reach`; if not, which bound it leaves.
fn within(candidate: &Candidate, distance: f64, reach: f64) -> Result<(), String> {
    if distance > reach {
        return Err(format!("the arm's size is {reach:.2} m"));
    }
    if distance > candidate.extent {
        return Err(format!(
            "beyond the link's extent, {:.2} m: its farthest child joint or modelled COM plus \
             {EXTENT_MARGIN} m",
            candidate.extent
        ));
    }
    Ok(())
}

/// Whether the last candidate of `trial`, fitted with the others, is
/// significant and physical: what naming it, or putting it in a named
/// effect's place, requires.
pub(super) fn admits(
    m: &Moments,
    candidates: &[Candidate],
    trial: &[usize],
    settings: super::settings::Settings,
) -> bool {
    let Some(&last) = trial.last() else {
        return false;
    };
    fit(m, candidates, trial, |_| true)
        .and_then(|full| significant(m, candidates, trial, &full, settings.min_t))
        .is_some_and(|v| physical(&candidates[last], &v, Gain::NONE, settings.reach).is_ok())
}

/// Whether the direction-dependent dry friction fitted with `trial` keeps
/// both directions' levels non-negative: |asymmetry| within the joint's
/// Coulomb level, modelled plus named. Beyond it friction would push the
/// motion one way, which no friction does (and a description refuses).
pub(super) fn levels_hold(
    candidates: &[Candidate],
    trial: &[usize],
    theta: &[f64],
) -> Result<(), String> {
    let mut at = 0;
    let mut coulomb = Vec::new();
    let mut asymmetries = Vec::new();
    for &c in trial {
        let candidate = &candidates[c];
        match (candidate.kind, &candidate.shape, candidate.joint) {
            (Kind::CoulombFriction, _, Some(j)) => coulomb.push((j, theta[at])),
            (Kind::CoulombAsymmetry, Shape::Asymmetry { modelled_coulomb }, Some(j)) => {
                asymmetries.push((j, theta[at], *modelled_coulomb))
            }
            _ => {}
        }
        at += width(candidate);
    }
    for (j, asymmetry, modelled) in asymmetries {
        let named: f64 = coulomb
            .iter()
            .filter(|(k, _)| *k == j)
            .map(|(_, v)| v)
            .sum();
        let level = modelled + named;
        if asymmetry.abs() > level {
            return Err(format!(
                "joint {}: the data fit direction-dependent dry friction of {asymmetry:.4} N m \
                 beside a Coulomb level of {level:.4} N m: one direction's friction would push \
                 the motion; not named (a torque offset, or friction the model lacks, shows \
                 this way)",
                j + 1
            ));
        }
    }
    Ok(())
}

/// Largest torque-scale error (either way), delay (s) and base tilt (rad)
/// taken as that effect: beyond them the fit is the trace of something else
/// (and a delay beyond it is outside the first-order model of its column).
const PLAUSIBLE_SCALE_ERROR: f64 = 0.5;
const PLAUSIBLE_DELAY: f64 = 0.1;
const PLAUSIBLE_TILT: f64 = 0.5;

fn plausible_data_effect(
    candidate: &Candidate,
    values: &[f64],
    at: &str,
    cut: &str,
) -> Result<(), String> {
    let (size, limit, what) = match candidate.kind {
        Kind::TorqueScale => (
            values[0].abs(),
            PLAUSIBLE_SCALE_ERROR,
            "a torque scale error",
        ),
        Kind::TorqueDelay => {
            let Shape::Delay { sample_period } = candidate.shape else {
                return Ok(());
            };
            // A torque read early by up to a sample is the logging
            // convention; a late one is a delay, however short.
            if (-sample_period..=0.0).contains(&values[0]) {
                return Err(format!(
                    "all joints: the data fit a torque delay of {:.2} ms, early by at most one \
                     sample period ({:.2} ms): the logging convention (a torque held over the \
                     sample interval reads half a sample early), not a delay; not named (it {cut})",
                    1e3 * values[0],
                    1e3 * sample_period
                ));
            }
            (values[0].abs(), PLAUSIBLE_DELAY, "a delay (s)")
        }
        _ => {
            let Shape::Tilt { gravity, .. } = &candidate.shape else {
                return Ok(());
            };
            let across = values[0].hypot(values[1]);
            (
                across.atan2(gravity.norm()),
                PLAUSIBLE_TILT,
                "a base tilt (rad)",
            )
        }
    };
    if size <= limit {
        return Ok(());
    }
    let place = if candidate.joint.is_some() {
        at
    } else {
        "all joints"
    };
    Err(format!(
        "{place}: the data fit {what} of {size:.3}, beyond the plausible {limit}: the trace of \
         another effect; not named (it {cut})"
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::candidate::Shape;
    use nalgebra::{DVector, Vector3};

    fn candidate(kind: Kind, joint: Option<usize>) -> Candidate {
        Candidate {
            kind,
            joint,
            link: None,
            modelled: [0.0; 10],
            extent: f64::INFINITY,
            names: vec![],
            columns: vec![],
            applied: None,
            shape: Shape::Linear,
            settings: Vec::new(),
            searched: 1,
            neighbours: Vec::new(),
        }
    }

    fn gain(share: f64) -> Gain {
        Gain { share, joint: 0 }
    }

    /// The Panda log's first 15 s fitted an asymmetry of -0.250 N m on
    /// joint 2 beside a named Coulomb level of 0.227: one direction's
    /// friction would be negative (and `--apply` failed on it). Within
    /// the named plus modelled level it holds.
    #[test]
    fn an_asymmetry_beyond_the_coulomb_level_is_refused() {
        let one_column = |kind, shape| Candidate {
            columns: vec![DVector::zeros(1)],
            shape,
            ..candidate(kind, Some(1))
        };
        let coulomb = one_column(Kind::CoulombFriction, Shape::Linear);
        let asymmetry = |modelled_coulomb| {
            one_column(
                Kind::CoulombAsymmetry,
                Shape::Asymmetry { modelled_coulomb },
            )
        };
        let named = [coulomb, asymmetry(0.0)];
        let beyond = levels_hold(&named, &[0, 1], &[0.227, -0.250]).unwrap_err();
        assert!(beyond.contains("joint 2"), "{beyond}");
        assert!(levels_hold(&named, &[0, 1], &[0.227, -0.200]).is_ok());
        let modelled = [asymmetry(0.1)];
        assert!(levels_hold(&modelled, &[0], &[0.09]).is_ok());
        assert!(levels_hold(&modelled, &[0], &[0.11]).is_err());
    }

    /// The forearm: a first moment that puts the COM 0.64 m out on
    /// a link whose child joint is 0.57 m away is refused; 0.40 m is not.
    #[test]
    fn a_com_beyond_the_link_is_not_this_link() {
        let forearm = Candidate {
            kind: Kind::InertialError,
            link: Some((2, "forearm".into())),
            extent: 0.57 + EXTENT_MARGIN,
            shape: Shape::Moment {
                offset: [0.0; 10],
                base_mass: 3.87,
                base_moment: Vector3::new(0.0, 0.0, 3.87 * 0.3),
            },
            ..candidate(Kind::InertialError, None)
        };
        let note = physical(&forearm, &[0.0, 0.0, 3.87 * 0.64], gain(0.2), 2.0).unwrap_err();
        assert!(note.contains("beyond the link's extent, 0.62 m"), "{note}");
        assert!(physical(&forearm, &[0.0, 0.0, 3.87 * 0.40], gain(0.2), 2.0).is_ok());
    }

    /// The UR10e's forearm (3.87 kg, its child joint 0.57 m out): a body
    /// of 3.8 kg with 8.5 kg m^2 about a COM 0.44 m out spreads its mass
    /// 1.6 m from the origin on average and is refused (the span allows
    /// 1.5 x 0.62 m); the description's own body is not. A description
    /// that already spreads wider than the link bounds itself.
    #[test]
    fn a_body_spread_beyond_the_link_is_not_this_link() {
        let body = |mass: f64, com_z: f64, about_com: f64| {
            let mut p = [0.0; 10];
            p[0] = mass;
            p[3] = mass * com_z;
            // ixx, iyy about the origin (the COM on z), izz a tenth.
            p[4] = about_com + mass * com_z * com_z;
            p[6] = p[4];
            p[9] = about_com / 10.0;
            p
        };
        let forearm = Candidate {
            kind: Kind::InertialError,
            link: Some((2, "forearm".into())),
            modelled: body(3.87, 0.2855, 0.11),
            extent: 0.57 + EXTENT_MARGIN,
            ..candidate(Kind::InertialError, None)
        };
        let (rms, span) = spread_within(&forearm, &body(3.8, 0.444, 8.5), 2.0).unwrap_err();
        assert!(rms > 1.5 && (span - 0.93).abs() < 1e-12, "{rms} {span}");
        assert!(spread_within(&forearm, &forearm.modelled, 2.0).is_ok());
        assert!(spread_within(&forearm, &body(3.87, 0.2855, 2.0), 2.0).is_ok());
        assert!(spread_within(&forearm, &body(3.87, 0.2855, 4.0), 2.0).is_err());
        let wide = Candidate {
            modelled: body(3.87, 0.2855, 3.0),
            ..forearm
        };
        assert!(spread_within(&wide, &body(3.87, 0.2855, 6.0), 2.0).is_ok());
        assert!(spread_within(&wide, &body(3.87, 0.2855, 8.0), 2.0).is_err());
    }

    #[test]
    fn impossible_signs_become_notes() {
        let armature = candidate(Kind::Armature, Some(3));
        let note = physical(&armature, &[-0.1], gain(0.15), 1.0).unwrap_err();
        assert!(
            note.starts_with("joint 4:") && note.contains("inertia"),
            "{note}"
        );
        assert!(physical(&armature, &[0.1], gain(0.15), 1.0).is_ok());
        let offset = candidate(Kind::TorqueOffset, Some(0));
        assert!(physical(&offset, &[-0.3], gain(0.5), 1.0).is_ok());
    }

    #[test]
    fn a_payload_beyond_the_arm_is_a_note() {
        let payload = candidate(Kind::Payload, None);
        // 0.5 kg at 0.1 m: a payload.
        assert!(physical(&payload, &[0.5, 0.0, 0.0, 0.05], gain(0.3), 1.0).is_ok());
        // 7 g at 1.7 m (a first moment of 0.012 kg m): beyond the arm.
        let note = physical(&payload, &[0.007, 0.0, 0.0, 1.7], gain(0.3), 1.0).unwrap_err();
        assert!(note.contains("first-moment"), "{note}");
    }
}
