//! The band that resolves velocity reversals: a joint's breakaway lasts as
//! long as its speed stays below the Stribeck velocity (tens to a few
//! hundred ms), and the motion band's velocity (low-passed at about three
//! times the motion's bandwidth) passes it too slowly, smearing the
//! breakaway into the Coulomb step. The reversal stage
//! ([`super::reversals`]) builds its dry-friction columns from the raw
//! velocity through the same zero-phase Butterworth at [`BAND_PER_CUTOFF`]
//! times the motion's cut-off.

use nalgebra::DMatrix;

use super::candidate::{Candidate, Place, place};
use super::kind::Kind;
use crate::preprocess::{Filter, Pipeline, Preprocess, step};
use crate::trajectory::Trajectory;

/// The reversal band's cut-off over the motion stage's: a decade above it,
/// so a breakaway of a tenth of the motion's period is passed.
pub const BAND_PER_CUTOFF: f64 = 10.0;
/// Highest reversal cut-off as a share of the sample rate (the auto
/// preset's bound on any cut-off).
const MAX_CUTOFF_PER_RATE: f64 = 0.2;

/// Which stage a stack is built for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Stage {
    /// The motion band: every kind competes but Stribeck friction.
    Motion,
    /// The reversal band: Stribeck friction is a candidate on every joint.
    Reversals,
}

/// The reversal band's cut-off for a motion cut-off and a sample rate, Hz.
pub fn cutoff(motion_cutoff_hz: f64, sample_rate_hz: f64) -> f64 {
    (BAND_PER_CUTOFF * motion_cutoff_hz)
        .min(MAX_CUTOFF_PER_RATE * sample_rate_hz)
        .max(motion_cutoff_hz)
}

/// A velocity that resolves reversals and each joint's at-rest speed in it.
pub(super) struct Band {
    pub(super) qd: DMatrix<f64>,
    pub(super) rest: Vec<f64>,
}

impl Band {
    /// The states' own velocity.
    pub(super) fn of(traj: &Trajectory, rest: &[f64]) -> Band {
        Band {
            qd: traj.qd().clone(),
            rest: rest.to_vec(),
        }
    }
}

/// The pipeline of the reversal band: the auto preset's filter at the
/// reversal cut-off, decimated to ten times it; `None` for other presets
/// (their filters are not a cut-off to raise: Stribeck friction is then not
/// tried).
pub(super) fn pipeline(motion: &Pipeline) -> Option<Pipeline> {
    let mut choice = motion.choice.clone()?;
    choice.cutoff_hz = cutoff(choice.cutoff_hz, choice.sample_rate_hz);
    choice.decimated_rate_hz =
        (crate::preprocess::auto::RATE_PER_CUTOFF * choice.cutoff_hz).min(choice.sample_rate_hz);
    let settings = Preprocess::identification(&choice, choice.sample_rate_hz);
    Some(Pipeline {
        choice: Some(choice),
        settings,
        ..motion.clone()
    })
}

/// The raw velocity through the same zero-phase Butterworth at the
/// reversal cut-off `band_hz` (at the reversal band's own pipeline, the
/// states' velocity), and the at-rest speeds of its noise (as for the
/// Coulomb column at the motion band).
pub(super) fn velocity(
    raw: &Trajectory,
    settings: &Preprocess,
    moving: &[f64],
    band_hz: f64,
) -> anyhow::Result<Band> {
    let dt = step(raw);
    let band = Preprocess {
        filter: Filter::Butterworth { cutoff_hz: band_hz },
        ..settings.clone()
    };
    let qd = band.smooth_columns(raw.qd(), dt)?;
    let rest = rest_speeds(raw, &qd, band_hz, moving);
    Ok(Band { qd, rest })
}

/// What the reversal stage needs of the motion stage's choices: each
/// joint's ripple harmonic (not searched again), the links whose columns
/// are needed and whether the tilt's are (the stack builds only those).
pub(super) struct Needs {
    pub(super) ripple: Vec<Option<f64>>,
    /// The links of the named link effects (0-based, ascending).
    pub(super) links: Vec<usize>,
    pub(super) tilt: bool,
    /// The reversal band's cut-off, Hz.
    pub(super) band_hz: f64,
    /// The candidates the stage refits (those named) and tries (Stribeck
    /// friction on the joints tried): the only ones its stack builds.
    pub(super) places: Vec<Place>,
}

impl Needs {
    /// What `selected` of `candidates` (the motion stage's) needs, with
    /// Stribeck friction tried on `joints`.
    pub(super) fn of(
        (candidates, selected): (&[Candidate], &[usize]),
        dof: usize,
        joints: &[usize],
        band: &Pipeline,
    ) -> Needs {
        let named = || selected.iter().map(|&c| &candidates[c]);
        let stribeck = joints
            .iter()
            .map(|&j| (Kind::StribeckFriction, Some(j), None));
        Needs {
            ripple: (0..dof)
                .map(|j| {
                    named().find_map(|c| {
                        (c.kind == Kind::TorqueRipple && c.joint == Some(j))
                            .then(|| c.settings[0].1)
                    })
                })
                .collect(),
            links: (0..dof)
                .filter(|&k| named().any(|c| c.link.as_ref().is_some_and(|l| l.0 == k)))
                .collect(),
            tilt: named().any(|c| c.kind == Kind::GravityDirection),
            band_hz: band.choice.as_ref().map_or(0.0, |c| c.cutoff_hz),
            places: named().map(place).chain(stribeck).collect(),
        }
    }
}

/// Each joint's at-rest speed for the velocity `filtered` (low-passed at
/// `cutoff_hz`), as `data::rest_velocities` gives it for the states: three
/// noise deviations (raw minus filtered, scaled by the share of the band
/// the filter passes), at least `moving`.
pub(super) fn rest_speeds(
    raw: &Trajectory,
    filtered: &DMatrix<f64>,
    cutoff_hz: f64,
    moving: &[f64],
) -> Vec<f64> {
    let passed = (2.0 * cutoff_hz * step(raw)).min(1.0).sqrt();
    (0..raw.dof())
        .map(|j| {
            let difference = raw.qd().column(j) - filtered.column(j);
            let sigma = (difference.norm_squared() / raw.len().max(1) as f64).sqrt();
            (3.0 * sigma * passed).max(moving[j])
        })
        .collect()
}
