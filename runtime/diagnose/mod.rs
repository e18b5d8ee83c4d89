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
mod applied_units;
pub mod apply;
mod band;
mod candidate;
mod choose;
mod com_hold;
mod companion;
pub mod data;
mod delay;
mod descent;
mod diagnosis;
use crate::digits;
mod dry;
mod extent;
mod fit;
mod gain;
mod held;
mod heldout;
mod identify;
mod kind;
mod modelled;
mod moments;
mod named;
mod nearest;
mod payload_body;
pub mod plots;
mod produce;
mod report;
mod reversals;
mod ripple;
mod rows;
mod sanity;
mod search;
mod select;
mod settings;
mod shape;
mod significance;
mod smooth;
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
use choose::{Chosen, choose};
pub use data::segment_counts;
use data::{reject_duplicates, stack};
pub use diagnosis::{Diagnosis, Effect, HeldoutLeft, Regimes, ResidualSamples};
pub use identify::{Confounded, Identifiability};
pub use kind::Kind;
use named::{Described, Named};
use report::{per_joint, regimes, residual_samples, residual_share};
pub use sanity::{
    Check, Exchange, Exchanged, Finding, Gated, Refusal, Sanity, positions as checks_as_logged,
    refuse,
};
pub use settings::{COLLINEAR, MIN_SECONDS, Settings, reach};
pub use stacked::Layout;
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
        sanity::refuse(model, &misplaced, Gated::Diagnosis)?;
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
        sanity::refuse(model, &sanity.findings, Gated::Diagnosis)?;
    }
    sanity.findings.splice(0..0, misplaced);
    let mut chosen = choose(&data, &mut candidates, settings, size);
    let named = &chosen.selected;
    if let Some(note) = delay::second_order(&data, &chosen.moments, &mut candidates, named) {
        chosen = choose(&data, &mut candidates, settings, size);
        chosen.notes.push(note);
    }
    let harmonics = ripple::researched(&data, &candidates, &chosen.selected);
    if !harmonics.is_empty() {
        let changed = ripple::set_harmonics(&data, &mut candidates, &harmonics);
        chosen = choose(&data, &mut candidates, settings, size);
        chosen.notes.extend(changed);
    }
    let Chosen {
        moments,
        selected,
        mut notes,
        supported,
        alternatives,
        second_moments,
    } = chosen;
    let motion = reversals::Motion {
        candidates: &candidates,
        selected: &selected,
        rows: &kept,
        weights: &moments.weights,
    };
    let named = Named {
        data: &data,
        moments: &moments,
        candidates: &candidates,
        selected: &selected,
    };
    // The reversal stage refits the named effects on its own pipeline; the
    // motion stage's effects are described meanwhile on the other core.
    let (stribeck, described) = std::thread::scope(|scope| {
        let reversal =
            scope.spawn(|| stribeck::at_reversals(model, recordings, pipeline, settings, motion));
        let described = named.describe(
            (alternatives, &supported, &second_moments),
            settings,
            size,
            &mut notes,
        );
        let found = reversal
            .join()
            .unwrap_or_else(|e| std::panic::resume_unwind(e));
        (found, described)
    });
    let Described {
        mut effects,
        mse_before,
        mse_after,
        mse_after_fitted,
    } = described;
    stribeck::merge(stribeck?, &mut effects, &mut notes);
    let resolution = settings.com_resolution * size;
    let mut listed = supported::listed(&candidates, &supported, resolution);
    applied_units::in_applied_units(&mut effects, &mut listed, &mut notes);
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
        supported: listed,
        identifiability: identify::identifiability(&moments, &candidates, &selected),
        notes,
        sanity,
        residuals,
    })
}
