//! Positions against the description's limits: a joint that leaves its
//! range by more than encoders and conservative limits explain is not
//! this joint, or not in these units. How an excursion reads (degrees, a
//! turn off, another joint) is [`crate::limits`]'s, shared with the
//! warnings of `tau`, `qdd` and `pose`; here it becomes a finding.

use std::f64::consts::TAU;

use nalgebra::DMatrix;

use super::super::digits::sig;
use super::{Check, Finding};
use crate::dynamics::Dynamics;
use crate::limits::{self, Range, Reading};
use crate::trajectory::{AngleUnit, Trajectory};

/// The findings of every joint that leaves its limits. The recordings are
/// judged as radians: the gate does not know whether `--angles deg`
/// converted them, and degrees of degrees (57^2 times a motion) are not
/// worth a guess.
pub(super) fn findings(model: &dyn Dynamics, recordings: &[Trajectory]) -> Vec<Finding> {
    limits::excursions(model, &observed(recordings), AngleUnit::Radians)
        .into_iter()
        .map(|e| Finding {
            check: match e.reading {
                Reading::BeyondLimits | Reading::Turned => Check::BeyondLimits,
                Reading::Degrees => Check::Degrees,
            },
            joints: vec![e.joint],
            value: e.value,
            message: e.message,
        })
        .collect()
}

/// A hint for torque findings when a revolute joint's positions go beyond
/// a turn: degrees read as radians on a joint the description gives no
/// limits (the position check cannot tell there).
pub(super) fn beyond_a_turn(model: &dyn Dynamics, recordings: &[Trajectory]) -> Option<String> {
    let levers = crate::dynamics::joint_levers(model);
    let ranges = observed(recordings);
    let largest = (0..model.dof())
        .filter(|&j| levers.get(j) == Some(&1.0))
        .filter_map(|j| ranges.get(j).copied().flatten())
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

/// Per joint, the smallest and largest position over the recordings.
fn observed(recordings: &[Trajectory]) -> Vec<Option<Range>> {
    let positions: Vec<&DMatrix<f64>> = recordings.iter().map(Trajectory::q).collect();
    limits::ranges(&positions)
}
