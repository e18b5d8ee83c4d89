//! The reversal stage: Stribeck friction judged at a band and rate that
//! resolve velocity reversals.
//!
//! The motion stage low-passes at three times the motion's bandwidth (about
//! 3 Hz) and decimates to ten times that: enough for every kind whose
//! torque follows the motion, but a joint's breakaway lasts as long as its
//! speed stays below the Stribeck velocity (tens to a few hundred ms), and
//! in the motion band that hump is smeared into the Coulomb step. Here the
//! same recordings pass the same zero-phase Butterworth and parallel filter
//! at [`BAND_PER_CUTOFF`] times the motion's cut-off (at most a fifth of the
//! sample rate) and are decimated to ten times that; the effects the motion
//! stage named are refitted there beside each candidate, and a joint's
//! Stribeck friction is named when it passes the selection's own tests at
//! this stage (held-out gain, significance for the searched velocity, a
//! positive excess). The motion stage then reports it with the others:
//! its fitted column comes from the velocity at this band, its applied
//! column from the states' velocity, as `sdnn evaluate` computes it.

use super::admit::{physical, searched_threshold, significant};
use super::candidate::{Candidate, label, width};
use super::data::stack;
use super::diagnosis::Effect;
use super::fit::fit;
use super::gain::{Gain, relative_gain};
use super::heldout::{Scoring, cv_mse};
use super::kind::Kind;
use super::moments::Moments;
use super::report::effect;
use super::settings::Settings;
use super::stacked::Stacked;
use super::uncertainty::fit_robust;
use crate::dynamics::Dynamics;
use crate::preprocess::{Pipeline, Preprocess};
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

/// The pipeline of the reversal stage: the auto preset's filter at the
/// reversal cut-off, decimated to ten times it; `None` for other presets
/// (their filters are not a cut-off to raise: Stribeck friction is then not
/// tried).
pub(super) fn pipeline(motion: &Pipeline) -> Option<Pipeline> {
    let mut choice = motion.choice.clone()?;
    choice.cutoff_hz = cutoff(choice.cutoff_hz, choice.sample_rate_hz);
    choice.decimated_rate_hz = (crate::preprocess::auto::RATE_PER_CUTOFF * choice.cutoff_hz)
        .min(choice.sample_rate_hz);
    let settings = Preprocess::identification(&choice, choice.sample_rate_hz);
    Some(Pipeline {
        choice: Some(choice),
        settings,
        ..motion.clone()
    })
}

/// What the reversal stage needs of the motion stage's choices: each
/// joint's ripple harmonic (not searched again), and whether a link's or
/// the tilt's columns are needed (the stack builds them only then).
pub(super) struct Needs {
    pub(super) ripple: Vec<Option<f64>>,
    pub(super) bodies: bool,
    pub(super) tilt: bool,
}

impl Needs {
    fn of(dof: usize, motion: &Motion) -> Needs {
        let named = || motion.selected.iter().map(|&c| &motion.candidates[c]);
        Needs {
            ripple: (0..dof)
                .map(|j| {
                    named().find_map(|c| {
                        (c.kind == Kind::TorqueRipple && c.joint == Some(j))
                            .then(|| c.settings[0].1)
                    })
                })
                .collect(),
            bodies: named().any(|c| c.link.is_some()),
            tilt: named().any(|c| c.kind == Kind::GravityDirection),
        }
    }
}

/// What the reversal stage found: the Stribeck friction it names, the
/// refitted values of the friction already named on those joints, notes.
#[derive(Default)]
pub(super) struct Found {
    pub(super) effects: Vec<Effect>,
    /// (kind, 0-based joint, each parameter's value and 95% half-width).
    pub(super) refits: Vec<(Kind, usize, Vec<(f64, f64)>)>,
    pub(super) notes: Vec<String>,
}

/// What the motion stage has decided: its candidates and the named ones.
pub(super) struct Motion<'a> {
    pub(super) candidates: &'a [Candidate],
    pub(super) selected: &'a [usize],
}

/// Stribeck friction on each of `joints`, judged at the reversal stage
/// beside the effects the motion stage named, in joint order, on the rows
/// where the joint moves (at rest friction is static: no law of the speed
/// predicts it, and the fitted dry-friction columns are zero there, so
/// those rows would only dilute the gain with what no candidate explains).
pub(super) fn stribeck(
    model: &dyn Dynamics,
    recordings: &[Trajectory],
    motion_pipeline: &Pipeline,
    settings: Settings,
    motion: Motion,
    joints: &[usize],
) -> anyhow::Result<Found> {
    let mut found = Found::default();
    let Some(band) = pipeline(motion_pipeline).filter(|_| !joints.is_empty()) else {
        return Ok(found);
    };
    let needs = Needs::of(model.dof(), &motion);
    let (mut data, all, _) = stack(model, recordings, &band, &settings, Some(&needs))?;
    let mut list: Vec<Candidate> = motion
        .selected
        .iter()
        .filter_map(|&c| counterpart(&all, &motion.candidates[c]))
        .collect();
    let mut named: Vec<usize> = (0..list.len()).collect();
    let mut tried = Vec::new();
    for &j in joints {
        if let Some(c) = all
            .iter()
            .find(|c| c.kind == Kind::StribeckFriction && c.joint == Some(j))
        {
            tried.push((j, list.len()));
            list.push(c.clone());
        }
    }
    moving_rows_only(&mut data, &mut list);
    let m = Moments::new(&data, &list);
    let dof = data.dof;
    let initial = cv_mse(&m, dof, &list, &[], Scoring::Fitted);
    let mut current = cv_mse(&m, dof, &list, &named, Scoring::Fitted);
    let mut removed = Vec::new();
    for (j, c) in tried {
        let mut trial = named.clone();
        trial.push(c);
        let mse = cv_mse(&m, dof, &list, &trial, Scoring::Fitted);
        let gain = relative_gain(&current[j..=j], &mse[j..=j], &initial[j..=j]);
        let gain = Gain { joint: j, ..gain };
        if std::env::var("SDNN_DEBUG").is_ok() {
            let full = fit(&m, &list, &trial, |_| true);
            eprintln!(
                "reversals j{j}: cur {:?} trial {:?} initial {:?} gain {:.3} theta {:?} v {:?}",
                current, mse, initial, gain.share, full.map(|f| f.theta.as_slice().to_vec()), list[c].settings
            );
        }
        if gain.share < settings.min_gain {
            continue;
        }
        let Some(full) = fit(&m, &list, &trial, |_| true) else {
            continue;
        };
        let candidate = &list[c];
        let Some(values) = significant(&m, &list, &trial, &full, settings.min_t) else {
            found.notes.push(format!(
                "{}: {} at the reversal band, but its excess is not significant (|t| <= {:.1}); \
                 not named",
                label(candidate),
                gain.would_cut(),
                searched_threshold(settings.min_t, candidate.searched)
            ));
            continue;
        };
        if let Err(note) = physical(candidate, &values, gain, settings.reach) {
            found.notes.push(note);
            continue;
        }
        removed.push((c, current[j] - mse[j], initial[j]));
        named = trial;
        current = mse;
    }
    if !removed.is_empty() {
        report(&m, &list, &named, &removed, &mut found);
    }
    Ok(found)
}

/// Zeroes the residual and every column on the rows where their joint is
/// at rest (slower than its at-rest speed), which drops them from every
/// fit and held-out error.
fn moving_rows_only(data: &mut Stacked, list: &mut [Candidate]) {
    let dof = data.dof;
    let resting: Vec<usize> = (0..data.residual.len())
        .filter(|&r| data.qd[r].abs() <= data.rest[r % dof])
        .collect();
    let columns = list
        .iter_mut()
        .flat_map(|c| c.columns.iter_mut().chain(c.applied.iter_mut()));
    for column in std::iter::once(&mut data.residual).chain(columns) {
        for &r in &resting {
            column[r] = 0.0;
        }
    }
}

/// The named Stribeck friction as effects (value and 95% interval of the
/// joint fit at this band; held-out MSE removed on its joint's moving rows,
/// and its share of what that joint had before any effect), and the
/// refitted values of the dry and viscous friction named on those joints.
fn report(
    m: &Moments,
    list: &[Candidate],
    named: &[usize],
    removed: &[(usize, f64, f64)],
    found: &mut Found,
) {
    let Some((fit, se)) = fit_robust(m, list, named) else {
        return;
    };
    let joints: Vec<Option<usize>> = removed.iter().map(|&(c, ..)| list[c].joint).collect();
    let mut offset = 0;
    for &c in named {
        let candidate = &list[c];
        let w = width(candidate);
        let values: Vec<(f64, f64)> = (offset..offset + w)
            .map(|k| (fit.theta[k], 1.96 * se[k]))
            .collect();
        offset += w;
        let Some(j) = candidate.joint.filter(|_| joints.contains(&candidate.joint)) else {
            continue;
        };
        match removed.iter().find(|r| r.0 == c) {
            Some(&(_, cut, before)) => {
                let mut effect = effect(candidate, &values, f64::INFINITY, &mut found.notes);
                effect.heldout_mse_removed = cut;
                effect.heldout_share = (cut / before.max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
                found.effects.push(effect);
            }
            None if REFITTED.contains(&candidate.kind) => {
                found.refits.push((candidate.kind, j, values));
            }
            None => {}
        }
    }
}

/// Kinds whose values the reversal stage refits on a joint where it names
/// Stribeck friction: the friction laws of the speed that share its rows.
const REFITTED: [Kind; 3] = [
    Kind::ViscousFriction,
    Kind::CoulombFriction,
    Kind::CoulombAsymmetry,
];

/// The reversal stage's candidate for a motion-stage one: the same kind at
/// the same joint or link, fitted with the same shape (a body whose mass
/// the motion stage held, a modelled Coulomb level); a ripple keeps the
/// harmonic its own search chose.
fn counterpart(all: &[Candidate], motion: &Candidate) -> Option<Candidate> {
    let link = |c: &Candidate| c.link.as_ref().map(|(k, _)| *k);
    let mut found = all
        .iter()
        .find(|c| c.kind == motion.kind && c.joint == motion.joint && link(c) == link(motion))?
        .clone();
    if motion.kind != Kind::TorqueRipple {
        found.shape = motion.shape.clone();
        found.names = motion.names.clone();
    }
    Some(found)
}
