//! Discrepancy diagnosis: where the model and measured data disagree, which
//! physical effect explains it, and how much it closes the gap on held-out
//! segments of the recordings.
//!
//! The raw recordings are preprocessed by a [`Pipeline`] (by default chosen
//! from the data), and the residual r = tau_measured - tau_model(filtered
//! states) and every candidate column pass the torque's filter before
//! decimation (parallel filtering, [`data`]); the recordings are cut into
//! contiguous cross-validation segments ([`segment_counts`]).
//! The residual is linear in the parameters of
//! every candidate effect: per joint viscous friction (column qd_j), Coulomb
//! friction (sign(qd_j), zero at rest), armature (qdd_j) and a torque offset
//! (1) and the other kinds of [`Kind`]; a payload on the last link and an
//! inertial error of any link (the generated regressor's inertial columns). Effects are
//! chosen by forward selection, each step keeping the candidate that lowers
//! the leave-one-segment-out MSE most (scored with the fitted columns, so a
//! sticking joint does not favour a wrong kind; reported MSEs use the applied
//! model's columns; among those within 10% of the best on its joint, the one
//! that cuts the most error over all joints), while it lowers it
//! by at least `min_gain` and its parameters are significant (|t| > 3, each
//! with the larger of its least-squares and its delete-one-segment
//! jackknife standard error; the reported 95% intervals add the bias the
//! data cannot rule out, see `supported.rs`). An effect the data support that
//! is not named is listed with its interval (`Diagnosis::supported`). What
//! no candidate explains is reported as [`Unexplained`].
//! A fit with a physically impossible sign (negative friction, armature or
//! payload mass) is never named as that effect: it is reported as a note
//! (e.g. a negative "armature" means the model's inertia about that joint is
//! too high) and selection goes on with the other candidates.
//! Parameters come from least squares with 95% confidence intervals.
//!
//! Inertial effects are fitted as physical bodies, not as free columns:
//! - `payload`: a point mass m at c (last link's frame) added to the last
//!   link. Its standard parameters are m * [1, c, |c|^2 E - c c^T] (the
//!   inertia about the link origin included, which is what a point mass at
//!   c adds), so the fit is nonlinear in c: Levenberg-Marquardt on the
//!   moment matrices of the link's ten inertial regressor columns, started
//!   from the linear fit of its mass and first-moment columns.
//! - `inertial_error`: the mass and centre of mass of a link differ from
//!   the model, its inertia about its centre of mass as
//!   modelled. Standard parameters [m', m'c', I_C + m'(|c'|^2 E - c'c'^T)]
//!   minus the model's; reported as the corrected mass and COM.
//!
//! A link's mass is identifiable from torques only through the acceleration
//! of the link's origin (its mass column in the regressor); its first
//! moment m*c and inertia have their own columns. When the origin lies on
//! the axes of every joint that moves the link (link 2 of the 3-DOF Kinova:
//! on both the joint-1 and joint-2 axes), that column vanishes and a fitted
//! mass would come only from the parallel-axis terms of the assumed inertia
//! about the COM. Rule (`select::mass_identifiable`): with the mass put in the
//! first moments' units by the arm's size, the mass is identifiable when the
//! information left about it once the link's first moments are projected
//! out is at least [`COLLINEAR`] times the largest eigenvalue of the link's
//! (mass, first moment) information. When it is not, the mass is fitted
//! through the link's second moments with its inertia about the COM held
//! (a note says so), unless that fit is unidentifiable, implausible or
//! rejected; then the candidate fits the
//! first moment h = m*c alone (the mass held as modelled, the inertia about
//! the COM as modelled) and reports `first_moment` (kg m, with 95% CIs),
//! `mass` and `com` as `null` and a note saying why; `--apply` then keeps
//! the mass and moves the COM to h / (modelled mass), the assumption the
//! note states, and never changes the mass.
//!
//! The last link: an added point mass (`payload`) and a heavier last link
//! with its COM moved (`inertial_error`) change the same ten columns and
//! differ only in the second moments, so both compete; where the data
//! barely tell them apart the named one lists the other as ambiguous. A
//! negative fitted payload mass is a note, never a payload.
//!
//! Identifiability: a candidate whose parameters the data cannot separate
//! (its information matrix, after the already-selected effects are
//! projected out and scaled to unit diagonal, has a relative eigenvalue
//! below [`COLLINEAR`]: collinear columns, or parameters that only enter
//! through a base-parameter combination, such as the first link's mass and
//! COM, which act only through its inertia about the first axis) is never
//! named; if it would have been selected, a note says so. A named payload's
//! or link's COM (or first-moment) component whose 95% confidence
//! half-width exceeds [`Settings::com_resolution`] of the arm's size is
//! reported with its wide interval and a note: the data barely determine it
//! (typically the component along the joint axes, which acts only through
//! couplings with the first joint), so the torques barely depend on it.

mod admit;
mod alternatives;
pub mod apply;
mod band;
mod candidate;
mod companion;
pub mod data;
mod descent;
mod diagnosis;
mod digits;
mod fit;
mod gain;
mod held;
mod heldout;
mod identify;
mod kind;
mod modelled;
mod moments;
pub mod plots;
mod report;
mod reversals;
mod rows;
mod sanity;
mod search;
mod select;
mod settings;
mod shape;
mod solve;
mod stacked;
mod stribeck;
mod supported;
mod text;
mod uncertainty;
mod unconstrained;
mod unexplained;
mod whole;

use crate::dynamics::Dynamics;
use crate::preprocess::Pipeline;
use crate::trajectory::Trajectory;
use candidate::{Candidate, Shape, label};
pub use data::segment_counts;
use data::{reject_duplicates, stack};
pub use diagnosis::{Diagnosis, Effect, Regimes, ResidualSamples};
use heldout::{Scoring, cv_mse, cv_mse_per_joint};
pub use identify::{Confounded, Identifiability};
pub use kind::Kind;
use moments::Moments;
use report::{describe, per_joint, regimes, residual_samples, residual_share};
pub use sanity::{Check, Exchange, Finding, Refusal, Sanity};
use select::{body_identifiable, mass_identifiable, select};
pub use settings::{COLLINEAR, MIN_SECONDS, Settings, reach};
pub use stacked::Layout;
use stacked::Stacked;
pub use unconstrained::Unconstrained;
pub use unexplained::{RegimeShare, Unexplained};

/// Each joint's kind as the description names it (revolute when the model's
/// description cannot be read).
fn joint_kinds(model: &dyn Dynamics) -> Vec<String> {
    let kinds: Option<Vec<String>> = crate::dynamics::parsed_description(model).ok().map(|d| {
        d.chain()
            .free_bodies()
            .map(|b| match b.kind {
                codegen::JointKind::Prismatic => "prismatic".to_string(),
                _ => "revolute".to_string(),
            })
            .collect()
    });
    kinds.unwrap_or_else(|| vec!["revolute".to_string(); model.dof()])
}

/// Drops, one at a time, a named effect that removes no held-out error
/// from its joints once applied (the generated model's columns, counted in
/// selection order): selection scores the fitted columns, and an effect at
/// the noise floor can pass it yet make the applied model no better.
fn drop_unhelpful(
    m: &Moments,
    candidates: &[Candidate],
    selected: &mut Vec<usize>,
    notes: &mut Vec<String>,
) {
    while let Some(position) = report::heldout_removals(m, candidates, selected)
        .iter()
        .enumerate()
        .position(|(k, &(removed, _))| {
            removed <= 0.0 && !helps_the_rest(m, candidates, selected, k)
        })
    {
        let dropped = selected.remove(position);
        notes.push(format!(
            "{}: significant in the fit, but once applied it removes no held-out error from its \
             joints; dropped",
            label(&candidates[dropped])
        ));
    }
}

/// Whether the effect at `position` of `selected` lowers its joints'
/// held-out MSE (applied columns) beside all the others. Counted in the
/// order named, an effect can seem to remove nothing because one named
/// after it does the work it needed: viscous friction named beside a
/// joint's Coulomb friction before a payload that dominates the joint's
/// residual (a Panda with friction on every joint and 0.8 kg at the
/// flange: joint 4's held-out MSE 0.0018 with it in the final model,
/// 0.0100 without it, and -0.009 of 15 "removed" where it was named).
fn helps_the_rest(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
    position: usize,
) -> bool {
    let (with, without) = heldout::with_and_without(m, candidates, selected, position);
    without > with
}

/// A torque offset and direction-dependent dry friction are the same torque
/// while the joint moves; only samples at rest tell them apart, and there
/// the friction is static or follows the plant's own law near zero speed,
/// which no column here knows. Where one is named on a joint with dry
/// friction and the other is not, the other is listed as ambiguous with it
/// (named candidate, other candidate) and a note says how many samples
/// could tell.
fn offset_or_asymmetry(
    data: &Stacked,
    candidates: &[Candidate],
    selected: &[usize],
    notes: &mut Vec<String>,
) -> Vec<(usize, usize)> {
    let find = |kind: Kind, j: usize| {
        candidates
            .iter()
            .position(|c| c.kind == kind && c.joint == Some(j))
    };
    let named = |kind: Kind, j: usize| {
        selected
            .iter()
            .any(|&c| candidates[c].kind == kind && candidates[c].joint == Some(j))
    };
    let mut pairs = Vec::new();
    for j in 0..data.dof {
        let (offset, asymmetry) = (
            named(Kind::TorqueOffset, j),
            named(Kind::CoulombAsymmetry, j),
        );
        let (Some(o), Some(a)) = (find(Kind::TorqueOffset, j), find(Kind::CoulombAsymmetry, j))
        else {
            continue;
        };
        let dry = &candidates[a];
        let modelled =
            matches!(dry.shape, Shape::Asymmetry { modelled_coulomb } if modelled_coulomb > 0.0);
        if offset == asymmetry || !(modelled || named(Kind::CoulombFriction, j)) {
            continue;
        }
        // The asymmetry's column is 1 while moving, 0 at rest (filtered).
        let rows = data.rows_of(j);
        let count = rows.clone().count().max(1) as f64;
        let resting = rows.filter(|&r| dry.columns[0][r] < 0.5).count() as f64 / count;
        pairs.push(if offset { (o, a) } else { (a, o) });
        let (this, other) = if offset {
            (
                "a torque offset",
                "direction-dependent dry friction (coulomb_asymmetry)",
            )
        } else {
            ("direction-dependent dry friction", "a torque offset")
        };
        notes.push(format!(
            "joint {}: {this} and {other} are the same torque while the joint moves; only the \
             {:.0}% of samples at rest tell them apart, so {other} fits these data {}: record \
             motions that rest to tell",
            j + 1,
            100.0 * resting,
            if resting < 0.2 {
                "almost as well"
            } else {
                "less well here, but how friction behaves near zero speed decides that"
            }
        ));
    }
    pairs
}

/// Fits the first moment alone (the mass held as modelled) for these body
/// candidates.
fn hold_mass(candidates: &mut [Candidate], which: &[usize]) {
    for &c in which {
        if let Shape::Body {
            offset,
            base_mass,
            base_moment,
        } = candidates[c].shape
        {
            candidates[c].shape = Shape::Moment {
                offset,
                base_mass,
                base_moment,
            };
            candidates[c].names = vec!["mx", "my", "mz"];
        }
    }
}

/// Diagnoses `model` on raw recordings, preprocessed by `pipeline`.
/// Most moving joints a diagnosed model may have.
pub const MAX_DOF: usize = 32;

pub fn diagnose(
    model: &dyn Dynamics,
    recordings: &[Trajectory],
    pipeline: &Pipeline,
    settings: Settings,
) -> anyhow::Result<Diagnosis> {
    reject_duplicates(recordings)?;
    if let Ok(d) = crate::dynamics::parsed_description(model)
        && let Some(b) = d.chain().bodies.iter().find(|b| b.coupling.is_some())
    {
        anyhow::bail!(
            "model `{}`: joint `{}` follows another on the chain (a mimic); the diagnosis \
             fits one set of parameters per moving joint and does not handle coupled joints \
             yet: lock the gripper's joint for the diagnosis",
            model.name(),
            b.joint
        );
    }
    if model.dof() > MAX_DOF {
        anyhow::bail!(
            "model `{}` has {} moving joints; the diagnosis handles up to {MAX_DOF} (its \
             candidates grow with the square of the joints): lock the joints the recordings do \
             not move (`locked = ANGLE` in the description)",
            model.name(),
            model.dof()
        );
    }
    let size = Some(reach(model))
        .filter(|r| r.is_finite() && *r > 0.0)
        .unwrap_or(1.0);
    let misplaced = sanity::positions(model, recordings);
    if settings.sanity_gate {
        sanity::refuse(model, &misplaced)?;
    }
    let (data, mut candidates, layout, kept) =
        stack(model, recordings, pipeline, &settings, (None, None))?;
    let seconds = layout.segments as f64 * layout.segment_seconds;
    if layout.segments < 2 || seconds < MIN_SECONDS {
        anyhow::bail!(
            "the recordings hold {seconds:.2} s of data after preprocessing ({} segment(s)): the \
             diagnosis needs at least {MIN_SECONDS} s to cross-validate (two segments of 2 s)",
            layout.segments
        );
    }
    let mut sanity = sanity::torques(model, recordings, &data, &candidates, settings.min_t);
    if settings.sanity_gate {
        sanity::refuse(model, &sanity.findings)?;
    }
    sanity.findings.splice(0..0, misplaced);
    let moments = Moments::new(&data, &candidates);
    // A link whose origin does not accelerate has no mass column of its
    // own: its mass acts only through its second moments, which identify it
    // if the inertia about the COM is as modelled (noted); where they do not,
    // or where the body it fits is rejected, only the first moment is fitted.
    let (mut second_moments, massless): (Vec<usize>, Vec<usize>) = (0..candidates.len())
        .filter(|&c| !mass_identifiable(&moments, &candidates, c, size))
        .partition(|&c| body_identifiable(&moments, &candidates, c));
    hold_mass(&mut candidates, &massless);
    let mut selection = select(&moments, data.dof, &candidates, settings);
    let retry: Vec<usize> = second_moments
        .iter()
        .copied()
        .filter(|c| selection.rejected.contains(c))
        .collect();
    if !retry.is_empty() {
        hold_mass(&mut candidates, &retry);
        second_moments.retain(|c| !retry.contains(c));
        selection = select(&moments, data.dof, &candidates, settings);
    }
    let (mut selected, mut notes) = (selection.selected, selection.notes);
    // Pruning and the body swaps may have changed the selection since its
    // last step.
    companion::complete_friction(
        &moments,
        data.dof,
        &candidates,
        &mut selected,
        &mut notes,
        settings,
    );
    select::prune(&moments, &candidates, &mut selected, &mut notes, settings);
    drop_unhelpful(&moments, &candidates, &mut selected, &mut notes);
    let bias = |selected: &[usize], supported: &[supported::Supported]| {
        let width = selected
            .iter()
            .map(|&c| candidate::width(&candidates[c]))
            .sum();
        let timing = supported::timing_shift(&moments, &candidates, selected);
        supported::bias(supported, timing, width)
    };
    // The last selection judged is the final one: its supported effects
    // are the report's.
    let mut supported = Vec::new();
    held::drop_unheld(&moments, &candidates, &mut selected, &mut notes, |s| {
        supported = supported::supported(&moments, data.dof, &candidates, s, settings);
        let timing = supported::timing_shift(&moments, &candidates, s);
        held::bias_elsewhere(&candidates, s, &supported, timing)
    });
    let motion = reversals::Motion {
        candidates: &candidates,
        selected: &selected,
        rows: &kept,
    };
    let stribeck = stribeck::at_reversals(model, recordings, pipeline, settings, motion)?;
    let alternatives: Vec<_> = selection
        .alternatives
        .into_iter()
        .filter(|a| selected.contains(&a.named))
        .collect();
    notes.extend(
        alternatives
            .iter()
            .map(|a| alternatives::note(&candidates, a)),
    );
    let dry_pairs = offset_or_asymmetry(&data, &candidates, &selected, &mut notes);
    let mse_before = cv_mse_per_joint(&moments, data.dof, &candidates, &[]);
    let mse_after = cv_mse_per_joint(&moments, data.dof, &candidates, &selected);
    let mse_after_fitted = cv_mse(&moments, data.dof, &candidates, &selected, Scoring::Fitted);
    let mut effects = describe(
        &moments,
        &candidates,
        &selected,
        settings.com_resolution * size,
        &bias(&selected, &supported),
        &mut notes,
    );
    for (effect, &c) in effects.iter_mut().zip(&selected) {
        let mut beside: Vec<usize> = Vec::new();
        let others = alternatives
            .iter()
            .filter(|a| a.named == c)
            .map(|a| a.runner_up);
        for r in others.chain(dry_pairs.iter().filter(|p| p.0 == c).map(|p| p.1)) {
            if !beside.contains(&r) {
                beside.push(r);
            }
        }
        effect.ambiguous_with = beside.iter().map(|&r| label(&candidates[r])).collect();
        effect.unconstrained = unconstrained::unconstrained(
            &moments,
            &candidates,
            &selected,
            &mse_after,
            c,
            settings,
            &mut notes,
        );
    }
    for &c in selected.iter().filter(|c| second_moments.contains(c)) {
        notes.push(format!(
            "{}: the link's origin does not accelerate in these motions (it lies on the axes of \
             the joints that move it), so its mass acts only through its second moments: mass \
             and COM are fitted with the link's inertia about its COM held as modelled; if that \
             inertia is wrong too, so is the mass (the mass and COM estimates correlate strongly, \
             see identifiability)",
            label(&candidates[c])
        ));
    }
    stribeck::merge(stribeck, &mut effects, &mut notes);
    modelled::add_totals(&mut effects, &modelled::joint_effects(model));
    let residuals = residual_samples(&data, &moments, &candidates, &selected);
    let joint_kinds = joint_kinds(model);
    Ok(Diagnosis {
        model: model.name().to_string(),
        preprocessing: pipeline.clone(),
        layout,
        samples: data.residual.len() / data.dof,
        unexplained: unexplained::unexplained(
            &data,
            &residuals.after,
            pipeline
                .choice
                .as_ref()
                .and_then(|c| Some((c.motion_bandwidth_hz?, c.decimated_rate_hz))),
            &joint_kinds,
        ),
        joint_kinds,
        residual_rms: per_joint(&data, |r, _| r * r)
            .iter()
            .map(|v| v.sqrt())
            .collect(),
        residual_share: residual_share(&data),
        regimes: regimes(&data, &candidates),
        mse_before,
        mse_after,
        mse_after_fitted,
        effects,
        supported: supported::listed(&candidates, &supported, settings.com_resolution * size),
        identifiability: identify::identifiability(&moments, &candidates, &selected),
        notes,
        sanity,
        residuals,
    })
}
