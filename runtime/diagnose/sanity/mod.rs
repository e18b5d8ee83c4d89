//! The sanity gate: before any effect is named, checks that the recordings
//! can be the model's robot as logged. A torque logged with the other sign,
//! angles logged in degrees or two joints' columns exchanged are not
//! missing physics, and the diagnosis would "explain" them with wrong
//! effects and a wall of notes. When a check fails nothing is named and
//! each finding says what to check ([`Refusal`]; `sdnn diagnose` exits 3).
//!
//! Four checks, each against a threshold a real missing effect does not
//! reach (docs/diagnosis.md, "The sanity gate"):
//! - [`positions`]: every joint stays within its description's limits
//!   (with a tenth of its range to spare), and [`rates`]: the logged
//!   velocities are the positions' rate, before anything is fitted;
//! - [`scale`]: the measured torque follows the model's with a positive
//!   gain (it enters with at least half of it, three standard errors
//!   clear, where the model predicts a sizeable torque, and at most twice
//!   it where that multiple explains the torque), and the joint's own
//!   friction resists the motion;
//! - [`relabel`]: no exchange of two joints' torque columns fits the rigid
//!   body (free inertial parameters) much better than the recorded order.

mod positions;
mod rates;
mod relabel;
mod reorder;
mod scale;

use serde::Serialize;

use super::candidate::Candidate;
use super::stacked::Stacked;
use crate::dynamics::Dynamics;
use crate::trajectory::Trajectory;
pub use relabel::{Exchange, Exchanged};
pub use scale::Estimate;

/// What the gate checks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Check {
    /// Positions beyond the description's limits (`value`: the farthest
    /// excursion past a limit, rad or m).
    BeyondLimits,
    /// Positions beyond the limits that fit them once read as degrees
    /// (`value`: the largest |q| as recorded).
    Degrees,
    /// The logged velocities are many times the positions' rate of
    /// change (`value`: their RMS ratio, median over the moving joints): a
    /// time column in milliseconds, velocities in deg/s.
    VelocityRate,
    /// The measured torque runs against the model's, or its friction
    /// pushes the motion (`value`: the fitted gain of the model's torque,
    /// near -1 unless the model's torque is too small to tell; null where
    /// the model predicts none).
    TorqueSign,
    /// The measured torque does not follow the model's (`value`: the
    /// fitted gain, below 0.5).
    TorqueUnexplained,
    /// The measured torque is the model's times a gain beyond 2 (`value`:
    /// the fitted gain): other units (mN m), a current or a torque before
    /// the gearbox.
    TorqueScale,
    /// Two joints' torques fit the rigid body far better exchanged
    /// (`value`: the unexplained share exchanged over as recorded).
    SwappedJoints,
}

/// One failed check.
#[derive(Debug, Clone, Serialize)]
pub struct Finding {
    pub check: Check,
    /// The joints concerned, 1-based.
    pub joints: Vec<usize>,
    /// The check's number (see [`Check`]).
    pub value: f64,
    /// What the check saw and what to check, as printed.
    pub message: String,
}

/// The recordings failed the gate: nothing is named (or evaluated).
#[derive(Debug, Clone, Serialize, thiserror::Error)]
pub struct Refusal {
    pub model: String,
    pub findings: Vec<Finding>,
    /// The command refused, for the wording (not in the JSON).
    #[serde(skip)]
    pub gated: Gated,
}

/// The command the gate stops: `sdnn diagnose`, or `sdnn evaluate`, which
/// runs the checks on recordings as logged (positions, velocity rate)
/// because its errors would blame the model for the data's units.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Gated {
    #[default]
    Diagnosis,
    Evaluation,
}

impl std::fmt::Display for Refusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (withheld, anyway) = match self.gated {
            Gated::Diagnosis => ("no effect is named", "diagnoses"),
            Gated::Evaluation => ("nothing is evaluated", "evaluates"),
        };
        write!(
            f,
            "the recordings fail the sanity checks against model `{}`, so {withheld} \
             (`--no-sanity-gate` {anyway} anyway):",
            self.model
        )?;
        for finding in &self.findings {
            write!(f, "\n  - {}", finding.message)?;
        }
        let signs = self
            .findings
            .iter()
            .filter(|x| x.check == Check::TorqueSign);
        if signs.count() >= 2 {
            // A sign convention is wrong one joint at a time; several at
            // once are likelier a mix-up of columns (q and qd exchanged
            // read as friction pushing the motion on three joints).
            write!(
                f,
                "\n  several joints at once: check first that the columns are what their names \
                 say (q, qd and tau not exchanged, joints in the model's order), then the signs"
            )?;
        }
        Ok(())
    }
}

/// What the torque checks measured on recordings that passed them (the
/// report's `sanity`).
#[derive(Debug, Clone, Default, Serialize)]
pub struct Sanity {
    /// Per joint the fitted gain of the model's rigid-body torque (its joint
    /// effects left out) in the measured torque (1 when the model's torque
    /// is as measured) with its standard error, or `None` where the model
    /// predicts no torque to compare.
    pub model_torque_gain: Vec<Option<Estimate>>,
    /// Per joint the mean power of the joint's own fitted friction, W
    /// (torque times angular velocity; force times velocity on a prismatic
    /// joint), with its standard error: positive where friction resists
    /// the motion; `None` where the joint does not move.
    pub friction_power: Vec<Option<Estimate>>,
    /// Per joint the share of the measured torque's energy that a rigid
    /// body with the model's kinematics (every link's inertial parameters
    /// free, each joint's friction and offset) leaves unexplained.
    pub rigid_body_unexplained: Vec<f64>,
    /// The exchange of two joints' torque columns that fits the rigid body
    /// best, with its unexplained share over the recorded order's
    /// (`None` for one joint).
    pub best_exchange: Option<Exchange>,
    /// The exchange of two joints' positions, velocities and torques
    /// together that the model's torque explains best, with its
    /// unexplained share over the recorded order's (`None` for one joint).
    pub best_joint_exchange: Option<Exchange>,
    /// The checks that failed, when the gate was skipped
    /// (`--no-sanity-gate`); empty otherwise.
    pub findings: Vec<Finding>,
}

/// The findings of the position and velocity checks (on the recordings as
/// logged, before preprocessing).
pub fn positions(model: &dyn Dynamics, recordings: &[Trajectory]) -> Vec<Finding> {
    let mut found = positions::findings(model, recordings);
    found.extend(rates::findings(recordings));
    found
}

/// The torque checks on the stacked data: whether the torques run against
/// the model's, do not follow it, or fit the rigid body far better with two
/// joints exchanged. `min_t`: the |t| a gain must clear; the recordings
/// as logged for a hint on degrees.
pub(super) fn torques(
    model: &dyn Dynamics,
    recordings: &[Trajectory],
    data: &Stacked,
    candidates: &[Candidate],
    min_t: f64,
) -> Sanity {
    let hint = positions::beyond_a_turn(model, recordings).unwrap_or_default();
    let rigid = rigid_body(data);
    let data = &rigid;
    let gains: Vec<scale::Gain> = (0..data.dof).map(|j| scale::gain(data, j)).collect();
    let (exchanges, recorded) = relabel::exchanges(data, candidates);
    let reorders = reorder::exchanges(model, data, min_t);
    // Joints exchanged whole make the torque exchanges, fitted on the
    // recorded positions, meaningless, and torques exchanged make the
    // model's torque of any order wrong: the kind of the exchange that
    // fits best decides which are reported.
    let torques = disjoint(exchanges.iter().filter(|e| e.swapped()).collect());
    let ratio = |found: &[&Exchange]| found.first().map_or(f64::INFINITY, |e| e.ratio);
    let each_alone = reorders.told_by_each();
    let whole: Vec<&Exchange> = reorders.found.iter().chain(&each_alone).collect();
    let reordered = ratio(&whole) < ratio(&torques);
    let swapped = if reordered { whole } else { torques };
    let mut findings: Vec<Finding> = swapped.iter().map(|e| e.finding()).collect();
    // A joint in an exchanged pair fails the gain check because of it; with
    // joints exchanged whole, every joint's model torque is wrong.
    let exchanged = |j: usize| reordered || swapped.iter().any(|e| e.joints.contains(&(j + 1)));
    // Other units scale every joint's torque alike.
    let told: Vec<usize> = (0..data.dof).filter(|&j| gains[j].told(min_t)).collect();
    let scaled = told.len() >= 2
        && told.iter().all(|&j| gains[j].above(min_t))
        && told.iter().any(|&j| gains[j].explains(data, j));
    findings.extend(
        gains
            .iter()
            .enumerate()
            .filter(|(j, _)| !exchanged(*j))
            .filter_map(|(j, gain)| {
                let rigid = (recorded.unexplained[j], recorded.friction[j]);
                gain.finding(data, j, min_t, scaled, rigid, &hint)
            }),
    );
    Sanity {
        model_torque_gain: gains.iter().map(|g| g.model).collect(),
        friction_power: gains.iter().map(|g| g.friction_power).collect(),
        rigid_body_unexplained: recorded.unexplained,
        best_exchange: best(exchanges),
        best_joint_exchange: best(reorders.each),
        findings,
    }
}

/// `data` with the model's torque cut to its rigid body (inertia,
/// armature, gravity): the model's joint friction and offset are added back
/// to the residual. The torque checks fit each joint's own friction freely
/// (zero at rest), and a description's friction is what the diagnosis
/// corrects: an imported URDF's placeholder Coulomb of 1 N m on a wrist
/// whose torque is mostly 0.06-0.9 N m of friction made the model's torque
/// mostly a sign that is there at rest where the measured torque's is not
/// (an xArm6: gain 0.09), and the gate refused correct recordings.
fn rigid_body(data: &Stacked) -> Stacked {
    Stacked {
        residual: &data.residual + &data.effects,
        ..data.clone()
    }
}

/// The exchange with the lowest ratio.
fn best(exchanges: Vec<Exchange>) -> Option<Exchange> {
    exchanges
        .into_iter()
        .min_by(|a, b| a.ratio.total_cmp(&b.ratio))
}

/// The exchanges that share no joint, best first: with joints 2 and 4
/// exchanged, exchanging 1 and 4 too can fit joint 4's equations better
/// than the recorded order, but far worse than exchanging 2 and 4.
fn disjoint(mut exchanges: Vec<&Exchange>) -> Vec<&Exchange> {
    exchanges.sort_by(|a, b| a.ratio.total_cmp(&b.ratio));
    let mut kept: Vec<&Exchange> = Vec::new();
    for e in exchanges {
        if !kept
            .iter()
            .any(|k| k.joints.iter().any(|j| e.joints.contains(j)))
        {
            kept.push(e);
        }
    }
    kept
}

/// Refuses the recordings for `gated` when a check failed.
pub fn refuse(model: &dyn Dynamics, findings: &[Finding], gated: Gated) -> Result<(), Refusal> {
    if findings.is_empty() {
        return Ok(());
    }
    Err(Refusal {
        model: model.name().to_string(),
        findings: findings.to_vec(),
        gated,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn refusal(checks: &[Check]) -> String {
        let findings = checks
            .iter()
            .enumerate()
            .map(|(j, &check)| Finding {
                check,
                joints: vec![j + 1],
                value: -1.0,
                message: format!("joint {}: a finding", j + 1),
            })
            .collect();
        Refusal {
            model: "arm".to_string(),
            findings,
            gated: Gated::Diagnosis,
        }
        .to_string()
    }

    /// Two joints' signs at once point at the columns first; one does not.
    #[test]
    fn several_sign_findings_point_at_the_columns_first() {
        let hint = "check first that the columns are what their names say";
        assert!(refusal(&[Check::TorqueSign, Check::TorqueSign]).contains(hint));
        assert!(!refusal(&[Check::TorqueSign]).contains(hint));
        assert!(!refusal(&[Check::TorqueSign, Check::Degrees]).contains(hint));
    }
}
