//! The reversal stage: Stribeck friction, judged where velocity reversals
//! are resolved ([`super::band`]).
//!
//! The motion stage low-passes at three times the motion's bandwidth (about
//! 3 Hz) and decimates to ten times that: enough for every kind whose
//! torque follows the motion, but a breakaway lasts as long as the joint's
//! speed stays below the Stribeck velocity, and the motion band's velocity
//! smears it into the Coulomb step (the fit of Coulomb friction alone on the
//! issue's case: 0.174 N m for a sliding level of 0.16). The effects the
//! motion stage named are refitted beside each joint's Stribeck candidate in
//! two passes over the same recordings, both on the rows where the joint
//! moves: the motion pipeline with the dry-friction columns built from the
//! velocity at the reversal band (the held-out gain), and the reversal
//! band's own pipeline, the same zero-phase Butterworth and parallel filter
//! at ten times the cut-off, decimated to ten times that, the model's
//! torque on the states [`super::band::states`] chooses (significance,
//! sign, the breakaway's floor and the reported values). The refitted
//! Coulomb and viscous values of the joint replace the motion stage's in
//! the report.

use super::admit::physical;
use super::band::{Needs, pipeline};
use super::candidate::{Candidate, Shape, label, width};
use super::data::stack;
use super::diagnosis::Effect;
use super::fit::fit;
use super::gain::{Gain, relative_gain};
use super::heldout::{Scoring, cv_mse};
use super::kind::Kind;
use super::moments::Moments;
use super::report::effect;
use super::rows::Rows;
use super::settings::Settings;
use super::significance::{searched_threshold, significant};
use super::stacked::Stacked;
use super::uncertainty::{fit_robust, widened};
use crate::dynamics::Dynamics;
use crate::parallel::map_in_order_on;
use crate::preprocess::Pipeline;
use crate::trajectory::Trajectory;
use nalgebra::DVector;

/// Longest recording, in (sample, joint) rows, whose two passes run side
/// by side: about 150 s at 1 kHz on a 7-joint arm, where one pass's
/// columns at the raw and the reversal band's rates reach a gigabyte.
const PARALLEL_MOST_ROWS: usize = 1 << 20;

/// A named effect refitted beside Stribeck friction: its kind, 0-based
/// joint, and each parameter's value with its 95% half-width.
pub(super) type Refit = (Kind, usize, Vec<(f64, f64)>);

/// What the reversal stage found: the Stribeck friction it names, the
/// refitted values of the friction already named on those joints, notes.
#[derive(Default)]
pub(super) struct Found {
    pub(super) effects: Vec<Effect>,
    pub(super) refits: Vec<Refit>,
    /// The friction named on the joints tried, fitted at the reversal band
    /// beside the other named effects, without Stribeck friction (half-widths
    /// zero): how far the filter's band moves the motion stage's values.
    pub(super) at_band: Vec<Refit>,
    pub(super) notes: Vec<String>,
}

/// What the motion stage has decided: its candidates and the named ones.
pub(super) struct Motion<'a> {
    pub(super) candidates: &'a [Candidate],
    pub(super) selected: &'a [usize],
    /// Each recording's kept rows at the motion band (see `data::stack`).
    pub(super) rows: &'a [Rows],
    /// Each joint's weight in the motion stage's fits (`Moments::noise_weighted`).
    pub(super) weights: &'a [f64],
}

/// One pass of the reversal stage: the motion stage's named effects and
/// the Stribeck candidates of the joints tried, on the rows where their
/// joint moves.
struct Pass {
    list: Vec<Candidate>,
    /// How many of `list` are the motion stage's effects (its first).
    base: usize,
    /// Per joint tried, its Stribeck candidate in `list`.
    tried: Vec<(usize, usize)>,
    /// Per Stribeck candidate in `list`, its columns at the neighbouring
    /// grid velocities, also in `list` (never tried or named).
    neighbours: Vec<(usize, Vec<usize>)>,
    m: Moments,
    dof: usize,
    initial: Vec<f64>,
}

impl Pass {
    /// The pass at `pipeline`; at the motion stage's own (`reuse`), only
    /// the dry-friction signals are built again.
    fn new(
        (model, recordings): (&dyn Dynamics, &[Trajectory]),
        (pipeline, reuse): (&Pipeline, bool),
        (settings, needs): (&Settings, &Needs),
        motion: &Motion,
        joints: &[usize],
    ) -> anyhow::Result<Pass> {
        let rows = reuse.then_some(motion.rows);
        let (mut data, all, ..) =
            stack(model, recordings, pipeline, settings, (Some(needs), rows))?;
        let mut list: Vec<Candidate> = motion
            .selected
            .iter()
            .filter_map(|&c| counterpart(&all, &motion.candidates[c]))
            .collect();
        let base = list.len();
        let stribeck: Vec<(usize, &Candidate)> = joints
            .iter()
            .filter_map(|&j| {
                all.iter()
                    .find(|c| c.kind == Kind::StribeckFriction && c.joint == Some(j))
                    .map(|c| (j, c))
            })
            .collect();
        let tried: Vec<(usize, usize)> = (0..stribeck.len())
            .map(|i| (stribeck[i].0, base + i))
            .collect();
        list.extend(stribeck.iter().map(|(_, c)| (*c).clone()));
        let mut neighbours = Vec::new();
        for i in 0..stribeck.len() {
            let columns = std::mem::take(&mut list[base + i].neighbours);
            let at = list.len();
            for column in columns {
                let neighbour = Candidate {
                    applied: Some(column.clone()),
                    columns: vec![column],
                    ..list[base + i].clone()
                };
                list.push(neighbour);
            }
            neighbours.push((base + i, (at..list.len()).collect()));
        }
        moving_rows_only(&mut data, &mut list);
        let m = Moments::new(&data, &list).weighted(motion.weights.to_vec());
        let initial = cv_mse(&m, data.dof, &list, &[], Scoring::Fitted);
        Ok(Pass {
            list,
            base,
            tried,
            neighbours,
            m,
            dof: data.dof,
            initial,
        })
    }

    /// The motion stage's effects.
    fn base(&self) -> Vec<usize> {
        (0..self.base).collect()
    }

    /// Joint `j`'s Stribeck candidate in `list`.
    fn stribeck(&self, j: usize) -> Option<usize> {
        self.tried.iter().find(|t| t.0 == j).map(|t| t.1)
    }

    fn mse(&self, named: &[usize]) -> Vec<f64> {
        cv_mse(&self.m, self.dof, &self.list, named, Scoring::Fitted)
    }
}

/// Stribeck friction on each of `joints`, judged beside the effects the
/// motion stage named, in joint order, on the rows where the joint moves
/// (at rest friction is static: no law of the speed predicts it, and the
/// fitted dry-friction columns are zero there). Two passes: at the motion
/// band and rate, with the dry-friction columns from the velocity at the
/// reversal band, the candidate must cut the joint's held-out MSE by
/// `min_gain` (there the noise of differentiated velocity times the
/// joint's inertia is filtered out: on a heavy shoulder it is 800 times
/// the breakaway's share at the reversal band); at the reversal band and a
/// ten times higher rate, where the breakaway is resolved, it must be
/// significant, physical and at least [`MIN_BREAKAWAY_SHARE`] of the
/// sliding level, and its values are reported from there.
pub(super) fn stribeck(
    (model, recordings): (&dyn Dynamics, &[Trajectory]),
    motion_pipeline: &Pipeline,
    settings: Settings,
    motion: Motion,
    joints: &[usize],
) -> anyhow::Result<Found> {
    let mut found = Found::default();
    let Some(band_pipeline) = pipeline(motion_pipeline).filter(|_| !joints.is_empty()) else {
        return Ok(found);
    };
    let needs = Needs::of(
        (motion.candidates, motion.selected),
        model.dof(),
        joints,
        (motion_pipeline, &band_pipeline),
    );
    let data = (model, recordings);
    let modelled = super::modelled::joint_effects(model);
    // The two passes are independent: one on each core, unless the
    // recordings are long enough that the memory of both at once matters
    // more than the wall time (each pass's filter still uses both cores).
    let rows = recordings.iter().map(|r| r.len() * r.dof()).max();
    let workers = match rows.unwrap_or(0) > PARALLEL_MOST_ROWS {
        true => 1,
        false => 2,
    };
    let [gains, band]: [anyhow::Result<Pass>; 2] = map_in_order_on(
        &[(motion_pipeline, true), (&band_pipeline, false)],
        |&pass| Pass::new(data, pass, (&settings, &needs), &motion, joints),
        workers,
    )
    .try_into()
    .unwrap_or_else(|_| unreachable!("two pipelines give two passes"));
    let (gains, band) = (gains?, band?);
    found.at_band = friction_at_band(&band);
    let (mut named_gains, mut named) = (gains.base(), band.base());
    let mut current = gains.mse(&named_gains);
    let mut band_current = band.mse(&named);
    let mut removed = Vec::new();
    for &j in joints {
        let (Some(g), Some(c)) = (gains.stribeck(j), band.stribeck(j)) else {
            continue;
        };
        let trial_gains = [named_gains.as_slice(), &[g]].concat();
        let mse = gains.mse(&trial_gains);
        let gain = relative_gain(&current[j..=j], &mse[j..=j], &gains.initial[j..=j]);
        let gain = Gain { joint: j, ..gain };
        if gain.share < settings.min_gain {
            continue;
        }
        let trial = [named.as_slice(), &[c]].concat();
        let Some(full) = fit(&band.m, &band.list, &trial, |_| true) else {
            continue;
        };
        let candidate = &band.list[c];
        let Some(values) = significant(&band.m, &band.list, &trial, &full, settings.min_t) else {
            found.notes.push(format!(
                "{}: {} with the reversals resolved, but at the reversal band its excess is not \
                 significant (|t| <= {:.1}); not named",
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
        let level = modelled[j].coulomb + named_coulomb(&band.list, &trial, &full.theta, j);
        if values[0] < MIN_BREAKAWAY_SHARE * level.abs() {
            found.notes.push(format!(
                "{}: {} with the reversals resolved, but its excess of {:.3} is {:.1}% of the \
                 joint's sliding level {level:.3}, under the {:.0}% a breakaway must exceed it by \
                 to be told from the level's own variation; not named",
                label(candidate),
                gain.would_cut(),
                values[0],
                100.0 * values[0] / level.abs(),
                100.0 * MIN_BREAKAWAY_SHARE
            ));
            continue;
        }
        if let Some(other) = unphysical_beside(&band.list, &trial, &full.theta, j, settings) {
            found.notes.push(format!(
                "{}: {} with the reversals resolved, but beside it {other} is no longer \
                 physical (a breakaway traded against the joint's friction, not found); not named",
                label(candidate),
                gain.would_cut()
            ));
            continue;
        }
        let band_mse = band.mse(&trial);
        removed.push((c, band_current[j] - band_mse[j], band.initial[j]));
        (named_gains, named) = (trial_gains, trial);
        (current, band_current) = (mse, band_mse);
    }
    if !removed.is_empty() {
        report(&band, &named, &removed, &mut found);
    }
    Ok(found)
}

/// The least Stribeck excess named, as a share of the joint's sliding
/// level (modelled plus named Coulomb friction). Static friction within a
/// tenth of the sliding level is within what the level itself varies with
/// load and temperature, and it is what a smooth friction law's rounding
/// at reversals leaves beside the model's sign(qd): on the independent
/// suite's plain Coulomb friction (tanh(qd / 0.01) at 200-500 Hz) the
/// reversal band fitted excesses of 1-5% of the level, mostly at the
/// grid's slowest fades, where true breakaways were 50-100% of it.
const MIN_BREAKAWAY_SHARE: f64 = 0.1;

/// The Coulomb level named on joint `j` among `trial`, in the fit `theta`.
fn named_coulomb(
    list: &[Candidate],
    trial: &[usize],
    theta: &nalgebra::DVector<f64>,
    j: usize,
) -> f64 {
    let mut offset = 0;
    let mut level = 0.0;
    for &c in trial {
        let candidate = &list[c];
        if candidate.joint == Some(j) && candidate.kind == Kind::CoulombFriction {
            level += theta[offset];
        }
        offset += width(candidate);
    }
    level
}

/// The first friction effect named on joint `j` (other than the last of
/// `trial`, the Stribeck candidate) whose value in the fit `theta` of
/// `trial` is not physical (a negative Coulomb level): a Stribeck shape
/// fading slowly trades against the sliding level and viscous friction.
fn unphysical_beside(
    list: &[Candidate],
    trial: &[usize],
    theta: &nalgebra::DVector<f64>,
    j: usize,
    settings: Settings,
) -> Option<String> {
    let mut offset = 0;
    for &c in &trial[..trial.len() - 1] {
        let candidate = &list[c];
        let w = width(candidate);
        let values: Vec<f64> = theta.rows(offset, w).iter().copied().collect();
        offset += w;
        if candidate.joint == Some(j)
            && REFITTED.contains(&candidate.kind)
            && physical(candidate, &values, Gain::NONE, settings.reach).is_err()
        {
            return Some(label(candidate));
        }
    }
    None
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
fn report(band: &Pass, named: &[usize], removed: &[(usize, f64, f64)], found: &mut Found) {
    let (m, list) = (&band.m, band.list.as_slice());
    let Some((fit, se)) = fit_robust(m, list, named) else {
        return;
    };
    let half = widened(&se, &grid_shift(band, named, &fit.theta));
    let joints: Vec<Option<usize>> = removed.iter().map(|&(c, ..)| list[c].joint).collect();
    let mut offset = 0;
    for &c in named {
        let candidate = &list[c];
        let w = width(candidate);
        let values: Vec<(f64, f64)> = (offset..offset + w)
            .map(|k| (fit.theta[k], half[k]))
            .collect();
        offset += w;
        let Some(j) = candidate
            .joint
            .filter(|_| joints.contains(&candidate.joint))
        else {
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

/// Per parameter of the fit `at` of `named`, what the Stribeck velocity grid's
/// resolution can cost it: half the largest move when a named Stribeck
/// candidate's column is replaced by a neighbouring grid velocity's (the
/// search picks a grid point, the law's own velocity lies between grid
/// points, and the excess trades with the velocity: a narrower fade needs
/// a larger excess for the same torque). A bias for [`widened`].
fn grid_shift(band: &Pass, named: &[usize], at: &DVector<f64>) -> DVector<f64> {
    let theta = |trial: &[usize]| fit(&band.m, &band.list, trial, |_| true).map(|f| f.theta);
    let mut shift = DVector::zeros(at.len());
    for (i, &c) in named.iter().enumerate() {
        let Some((_, others)) = band.neighbours.iter().find(|(s, _)| *s == c) else {
            continue;
        };
        for &other in others {
            let mut trial = named.to_vec();
            trial[i] = other;
            if let Some(moved) = theta(&trial) {
                shift = shift.zip_map(&(moved - at), |s: f64, d: f64| s.max(0.5 * d.abs()));
            }
        }
    }
    shift
}

/// The motion stage's friction on the joints tried, fitted at the reversal
/// band beside its other named effects (values, half-widths zero).
fn friction_at_band(band: &Pass) -> Vec<Refit> {
    let base = band.base();
    let Some(fitted) = fit(&band.m, &band.list, &base, |_| true) else {
        return Vec::new();
    };
    let mut at = 0;
    let mut refits = Vec::new();
    for &c in &base {
        let candidate = &band.list[c];
        let w = width(candidate);
        if let (true, Some(j)) = (REFITTED.contains(&candidate.kind), candidate.joint) {
            let values = (at..at + w).map(|k| (fitted.theta[k], 0.0)).collect();
            refits.push((candidate.kind, j, values));
        }
        at += w;
    }
    refits
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
    let whole = |c: &Candidate| matches!(c.shape, Shape::Whole { .. });
    // A link's ten columns are those of its mass-and-COM candidate; a
    // whole-body error combines them as the motion stage did.
    let mut found = all
        .iter()
        .find(|c| {
            c.kind == motion.kind && c.joint == motion.joint && link(c) == link(motion) && !whole(c)
        })?
        .clone();
    if let Shape::Whole { basis, .. } = &motion.shape {
        found.columns = super::whole::combine(&found.columns, basis);
    }
    if motion.kind != Kind::TorqueRipple {
        found.shape = motion.shape.clone();
        found.names = motion.names.clone();
    }
    Some(found)
}
