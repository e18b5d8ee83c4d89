//! Positions against the description's limits: a joint that leaves its
//! range by more than encoders and conservative limits explain is not
//! this joint, or not in these units.

use std::f64::consts::TAU;

use super::super::digits::sig;
use super::{Check, Finding};
use crate::dynamics::Dynamics;
use crate::trajectory::Trajectory;

/// Room past a limit, as a share of the joint's range: encoders read a
/// little past a limit (a description's limits are often the controller's
/// soft limits, inside the mechanical stops; an overshoot; a zero offset).
/// A tenth of the range is well beyond those and well short of what
/// degrees read as radians make of any motion of a few degrees or more
/// (57 times the value).
pub const LIMIT_MARGIN: f64 = 0.1;

/// One moving joint's limits as the description states them.
struct Joint {
    lower: f64,
    upper: f64,
    revolute: bool,
}

/// The model's moving joints with position limits (`None` for a joint
/// without), or nothing when the model has no description.
fn joints(model: &dyn Dynamics) -> Vec<Option<Joint>> {
    let Ok(description) = crate::dynamics::parsed_description(model) else {
        return Vec::new();
    };
    description
        .chain()
        .free_bodies()
        .map(|b| {
            let (lower, upper) = b.limits.and_then(|l| l.position())?;
            Some(Joint {
                lower,
                upper,
                revolute: b.kind != codegen::JointKind::Prismatic,
            })
        })
        .collect()
}

/// The findings of every joint that leaves its limits.
pub(super) fn findings(model: &dyn Dynamics, recordings: &[Trajectory]) -> Vec<Finding> {
    let joints = joints(model);
    let all_revolute = joints.iter().flatten().all(|j| j.revolute);
    joints
        .iter()
        .enumerate()
        .filter_map(|(j, limits)| {
            let range = observed(recordings, j)?;
            finding(limits.as_ref()?, range, j, all_revolute)
        })
        .collect()
}

/// A hint for torque findings when a revolute joint's positions go beyond
/// a turn: degrees read as radians on a joint the description gives no
/// limits (the position check cannot tell there).
pub(super) fn beyond_a_turn(model: &dyn Dynamics, recordings: &[Trajectory]) -> Option<String> {
    let levers = crate::dynamics::joint_levers(model);
    let largest = (0..model.dof())
        .filter(|&j| levers.get(j) == Some(&1.0))
        .filter_map(|j| observed(recordings, j))
        .map(|(low, high)| low.abs().max(high.abs()))
        .fold(0.0, f64::max);
    let all_revolute = levers.iter().all(|&l| l == 1.0);
    (largest > TAU).then(|| {
        format!(
            "; the angles reach {} rad, beyond a turn: if they are degrees, {}",
            sig(largest),
            if all_revolute {
                "pass `--angles deg`"
            } else {
                "convert them to radians"
            }
        )
    })
}

/// The smallest and largest position of joint `j` over the recordings.
fn observed(recordings: &[Trajectory], j: usize) -> Option<(f64, f64)> {
    let values = recordings
        .iter()
        .filter(|r| j < r.dof())
        .flat_map(|r| r.q().column(j).iter().copied().collect::<Vec<_>>());
    values.fold(None, |range, q| match range {
        None => Some((q, q)),
        Some((low, high)) => Some((low.min(q), high.max(q))),
    })
}

fn finding(
    limits: &Joint,
    (low, high): (f64, f64),
    j: usize,
    all_revolute: bool,
) -> Option<Finding> {
    let margin = LIMIT_MARGIN * (limits.upper - limits.lower);
    let inside = |a: f64, b: f64| a >= limits.lower - margin && b <= limits.upper + margin;
    if inside(low, high) {
        return None;
    }
    let beyond = (limits.lower - low).max(high - limits.upper);
    let unit = if limits.revolute { "rad" } else { "m" };
    let seen = format!(
        "joint {}: positions from {} to {} {unit} leave the description's limits [{}, {}] {unit}",
        j + 1,
        sig(low),
        sig(high),
        sig(limits.lower),
        sig(limits.upper)
    );
    let turns = (0.5 * (low + high) / TAU).round();
    let unwrapped = limits.revolute
        && turns != 0.0
        && low.abs().max(high.abs()) <= TAU
        && inside(low - turns * TAU, high - turns * TAU);
    let (radians_low, radians_high) = (low.to_radians(), high.to_radians());
    // Within one turn, angles kept in [0, 2 pi) (a logger's convention)
    // explain an excursion as well as degrees of a small motion do; beyond a
    // turn only degrees (or a multi-turn zero) do. Degrees read as radians
    // overshoot by 57 times the motion: an overshoot within the joint's
    // range is a motion in radians (a poorly tracked one) or a wrong zero,
    // not a few degrees of motion.
    let far = beyond > limits.upper - limits.lower;
    if limits.revolute && !unwrapped && far && inside(radians_low, radians_high) {
        let fix = if all_revolute {
            "pass `--angles deg`"
        } else {
            "convert them to radians (`--angles deg` converts every joint, and this model has \
             prismatic ones)"
        };
        return Some(Finding {
            check: Check::Degrees,
            joints: vec![j + 1],
            value: low.abs().max(high.abs()),
            message: format!(
                "{seen}; read as degrees they are {} to {} rad, inside them: the angles look \
                 like degrees: {fix}",
                sig(radians_low),
                sig(radians_high)
            ),
        });
    }
    let hint = if unwrapped {
        format!(
            "they fit them {turns:.0} turn(s) lower: unwrap the angles to the description's zero"
        )
    } else {
        "check the joint order (the CSV's q columns, `--joints` for a bag), the joint's zero \
         and its units"
            .to_string()
    };
    Some(Finding {
        check: Check::BeyondLimits,
        joints: vec![j + 1],
        value: beyond,
        message: format!(
            "{seen} by {} {unit} (more than a tenth of its range): {hint}",
            sig(beyond)
        ),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const REVOLUTE: Joint = Joint {
        lower: -2.69,
        upper: 2.69,
        revolute: true,
    };

    #[test]
    fn positions_within_the_limits_and_the_margin_pass() {
        assert!(finding(&REVOLUTE, (-2.69, 2.69), 0, true).is_none());
        assert!(finding(&REVOLUTE, (-3.2, 3.2), 0, true).is_none());
    }

    #[test]
    fn degrees_are_told_from_other_excursions() {
        let degrees = finding(&REVOLUTE, (-150.0, 120.0), 1, true).unwrap();
        assert_eq!(degrees.check, Check::Degrees);
        assert_eq!(degrees.joints, [2]);
        assert!(
            degrees.message.contains("--angles deg"),
            "{}",
            degrees.message
        );
        let wrapped = finding(&REVOLUTE, (4.0, 6.0), 0, true).unwrap();
        assert_eq!(wrapped.check, Check::BeyondLimits);
        assert!(
            wrapped.message.contains("1 turn(s) lower"),
            "{}",
            wrapped.message
        );
        // 0.39 to 4.17 rad against [-0.0175, 3.75]: a motion in radians
        // that overshoots, not 3.8 degrees of motion.
        let panda6 = Joint {
            lower: -0.0175,
            upper: 3.75,
            revolute: true,
        };
        let overshoot = finding(&panda6, (0.387, 4.17), 5, true).unwrap();
        assert_eq!(overshoot.check, Check::BeyondLimits);
        let prismatic = Joint {
            lower: 0.0,
            upper: 0.5,
            revolute: false,
        };
        let far = finding(&prismatic, (0.0, 20.0), 0, false).unwrap();
        assert_eq!(far.check, Check::BeyondLimits);
        assert!(far.message.contains("joint order"), "{}", far.message);
    }
}
