//! The stacked residual and the candidate columns built from trajectories.

use nalgebra::{DVector, Vector3};

use super::band::{self, Band, Needs, Stage};
use super::candidate::{Candidate, Columns, Shape, candidates};
use super::produce::{Inputs, Keep, RAW_BUDGET_BYTES, produce};
use super::rows::{MOVING, Rows, Tilted};
use super::settings::Settings;
use super::stacked::{EXTENT_MARGIN, Layout, Link, Span, Stacked};
use crate::dynamics::Dynamics;
use crate::oracle::Model;
use crate::preprocess::{Filter, Pipeline, Preprocess, central_difference, step};
use crate::trajectory::Trajectory;

/// Shortest cross-validation segment, s.
const MIN_SEGMENT_SECONDS: f64 = 1.0;

/// The same recording passed twice would leak into its own held-out fold.
pub(super) fn reject_duplicates(trajectories: &[Trajectory]) -> anyhow::Result<()> {
    for (a, first) in trajectories.iter().enumerate() {
        for (b, second) in trajectories.iter().enumerate().skip(a + 1) {
            if first.t() == second.t() && first.q() == second.q() {
                anyhow::bail!(
                    "trajectories {} and {} hold the same samples: pass each recording once \
                     (use --segments to cross-validate within one recording)",
                    a + 1,
                    b + 1
                );
            }
        }
    }
    Ok(())
}

/// The model's moving links. A link's extent is the farthest of its child
/// joints' origins and its modelled COM, plus [`EXTENT_MARGIN`]: a fitted
/// COM beyond it is not this link's (a 0.57 m forearm's COM at 0.64 m); the
/// last link, which may carry a tool, has none.
pub(super) fn links(model: &dyn Dynamics) -> Vec<Link> {
    let chain = crate::dynamics::parsed_description(model).map(|d| d.chain().clone());
    let names: Vec<String> = chain
        .as_ref()
        .map(|c| c.bodies.iter().map(|b| b.link.clone()).collect())
        .unwrap_or_default();
    let farthest_child = |k: usize| -> f64 {
        let Ok(chain) = &chain else {
            return f64::INFINITY;
        };
        chain
            .bodies
            .iter()
            .filter(|b| b.parent == Some(k))
            .map(|b| b.translation.norm())
            .reduce(f64::max)
            .unwrap_or(f64::INFINITY)
    };
    (0..model.dof())
        .map(|k| {
            let mut parameters = [0.0; 10];
            if let Some(p) = model.parameters().get(10 * k..10 * k + 10) {
                parameters.copy_from_slice(p);
            }
            let com = if parameters[0] > 0.0 {
                (parameters[1].powi(2) + parameters[2].powi(2) + parameters[3].powi(2)).sqrt()
                    / parameters[0]
            } else {
                0.0
            };
            Link {
                name: names
                    .get(k)
                    .cloned()
                    .unwrap_or_else(|| format!("link {}", k + 1)),
                parameters,
                extent: farthest_child(k).max(com) + EXTENT_MARGIN,
            }
        })
        .collect()
}

/// Preprocesses every raw recording with `pipeline` at its own rate, builds
/// the residual (filtered torque minus the model on filtered states, what
/// `sdnn evaluate` compares) and the candidate columns, filters every
/// fitted column with the torque's filter (parallel filtering), trims filter
/// transients, decimates and cuts the recordings into cross-validation
/// segments (`segments` per recording, or chosen by [`segment_counts`]).
/// Stribeck friction is a candidate at the reversal stage only (a less
/// decimated pipeline, see [`super::reversals`]; `reversal` says what it
/// needs of the motion stage's choices: the ripple's harmonic is given, and
/// a link's or the tilt's columns are built only for a named one).
/// Also returns each recording's kept rows: given back as `motion` to the
/// reversal stage's pass at the same pipeline, only its dry-friction
/// signals are built again (every other one is the same numbers).
pub(super) fn stack(
    model: &dyn Dynamics,
    recordings: &[Trajectory],
    pipeline: &Pipeline,
    settings: &Settings,
    (reversal, motion): (Option<&Needs>, Option<&[Rows]>),
) -> anyhow::Result<(Stacked, Vec<Candidate>, Layout, Vec<Rows>)> {
    let n = model.dof();
    let stage = match reversal {
        Some(_) => Stage::Reversals,
        None => Stage::Motion,
    };
    let built: Vec<usize> = match reversal {
        Some(r) => r.links.clone(),
        None => (0..n).collect(),
    };
    let tilted = tilted_models(model).filter(|_| reversal.is_none_or(|r| r.tilt));
    let levers = crate::dynamics::joint_levers(model);
    let moving: Vec<f64> = levers.iter().map(|lever| MOVING * lever).collect();
    let mut kept = Vec::new();
    // Columns are built a batch at a time in raw-rate memory reused for
    // the next batch and recording (`produce`): the full-rate columns are
    // most of what the diagnosis would allocate, and freshly allocated
    // memory is paid again in page faults.
    let mut raw = Vec::new();
    let template = Rows::with_columns(n, (stage, &built));
    let (mut durations, mut sample_counts) = (Vec::new(), Vec::new());
    let mut at_rest = vec![0.0_f64; n];
    let mut trimmed = 0;
    for (g, raw_recording) in recordings.iter().enumerate() {
        if raw_recording.dof() != n {
            anyhow::bail!(
                "recording {} has {} joints, model `{}` has {n}",
                g + 1,
                raw_recording.dof(),
                model.name()
            );
        }
        let settings = pipeline.for_recording(raw_recording);
        let reused = motion
            .and_then(|m| m.get(g))
            .filter(|_| matches!(settings.filter, Filter::Butterworth { .. }));
        let Recorded {
            rows,
            rest,
            samples,
            dt,
            non_finite,
        } = recording_rows(
            (model, models(&tilted)),
            (raw_recording, &settings),
            (stage, reversal, reused.is_some()),
            (&levers, &moving),
            (&template, &mut raw),
        )?;
        widen(&mut at_rest, &rest);
        if let Some(at) = non_finite {
            let (sample, joint) = (at / n, at % n + 1);
            anyhow::bail!(
                "recording {}: the model's torque or regressor is not finite at sample {sample}, \
                 joint {joint} (after preprocessing): the recording holds values no arm reaches \
                 (check its velocities and positions there)",
                g + 1
            );
        }
        trimmed = samples.first().copied().unwrap_or(0);
        durations.push(samples.len() as f64 * dt * settings.downsample.max(1) as f64);
        sample_counts.push(samples.len());
        let this = match reused {
            Some(motion) => motion.with_dry(rows, (&built, tilted.is_some())),
            None => rows,
        };
        kept.push(this);
    }
    // The raw-rate memory is not needed again: freed before the candidates'
    // columns are built.
    drop(raw);
    // Only the motion stage's rows are asked for again (by the reversal
    // stage's pass at the same pipeline).
    let all = template.concat(&mut kept, stage == Stage::Reversals);
    if stage == Stage::Reversals {
        kept.clear();
    }
    let counts = match settings.segments {
        Some(k) => vec![k; durations.len()],
        None => segment_counts(&durations),
    };
    let mut group = Vec::with_capacity(all.len());
    let mut spans = Vec::with_capacity(counts.len());
    for ((&samples, &count), &seconds) in sample_counts.iter().zip(&counts).zip(&durations) {
        // A segment of under a second validates nothing and multiplies the
        // folds: a requested count is cut to whole seconds (the report
        // states the segments used).
        let whole_seconds = (seconds / MIN_SEGMENT_SECONDS).floor().max(1.0) as usize;
        let cut = |count: usize| count.clamp(1, samples.max(1).min(whole_seconds));
        let (count, first) = (cut(count), group.last().map_or(0, |g| g + 1));
        let start = group.len();
        for s in 0..samples {
            group.extend(std::iter::repeat_n(first + s * count / samples, n));
        }
        spans.push(Span {
            rows: start..group.len(),
            alone: cut(settings.segments.unwrap_or(segment_counts(&[seconds])[0])),
        });
    }
    let groups = group.last().map_or(0, |g| g + 1);
    let total: f64 = durations.iter().sum();
    let layout = Layout {
        segments: groups,
        segment_seconds: total / groups.max(1) as f64,
        trimmed_samples: trimmed,
    };
    let vector = DVector::from_vec;
    let data = Stacked {
        residual: vector(all.residual),
        measured: vector(all.measured),
        angle: vector(all.own[4].clone()),
        qd: vector(all.qd),
        qdd: vector(all.qdd),
        gravity: vector(all.gravity),
        effects: vector(all.effects),
        measured_curvature: vector(all.measured_curvature),
        generic: all.generic.into_iter().map(DVector::from_vec).collect(),
        group,
        recordings: spans,
        dof: n,
        levers,
        rest: at_rest.clone(),
        friction: effect_levels(model, 1)
            .into_iter()
            .zip(effect_levels(model, 2))
            .map(|(viscous, coulomb)| [viscous, coulomb])
            .collect(),
    };
    let columns = Columns {
        own: all.own.map(DVector::from_vec),
        coulomb_applied: DVector::from_vec(all.coulomb_applied),
        inertial: all.inertial.into_iter().map(DVector::from_vec).collect(),
        tilt: tilted.map(|(shape, _)| (shape, all.tilt.map(DVector::from_vec))),
        measured_rate: DVector::from_vec(all.measured_rate),
        coulomb_levels: effect_levels(model, 2),
        sample_period: recordings.iter().map(step).fold(0.0, f64::max),
        stribeck: all.stribeck.into_iter().map(DVector::from_vec).collect(),
        rest: at_rest,
        modelled_ripple: super::modelled::ripple_cycles(&super::modelled::joint_effects(model)),
        ripple_given: reversal.map(|r| r.ripple.clone()),
        only: reversal.map(|r| r.places.clone()),
    };
    let candidates = candidates(&data, columns, &links(model));
    Ok((data, candidates, layout, kept))
}

/// One recording's rows at the samples its pipeline keeps (filtered in
/// parallel with the torque and decimated, see [`produce`]), each joint's
/// at-rest speed, the kept samples and the period they are numbered at, and
/// the first row where a checked signal is not finite. With `dry_only` (the
/// reversal stage's pass at the motion stage's own Butterworth pipeline)
/// only the dry-friction signals are built.
fn recording_rows(
    (model, tilted): (&dyn Dynamics, Option<&Tilted>),
    (raw, settings): (&Trajectory, &Preprocess),
    (stage, reversal, dry_only): (Stage, Option<&Needs>, bool),
    (levers, moving): (&[f64], &[f64]),
    (template, memory): (&Rows, &mut Vec<Vec<f64>>),
) -> anyhow::Result<Recorded> {
    let cutoff = match settings.filter {
        Filter::Butterworth { cutoff_hz } => Some(cutoff_hz),
        _ => None,
    };
    let mut rows = Rows::with_columns(levers.len(), (stage, &template.links));
    if let (Some(cutoff_hz), true, Some(needs)) = (cutoff, dry_only, reversal) {
        let dt = step(raw);
        let band = band::velocity(raw, settings, moving, needs)?;
        let samples = Pipeline::kept_samples(settings, raw.len(), dt);
        let inputs = Inputs {
            model,
            tilted,
            traj: None,
            band: &band,
            levers,
        };
        let keep = Keep {
            cutoff_hz: Some(cutoff_hz),
            dt,
            samples: &samples,
        };
        let signals = template.dry_signals();
        let bad = produce(
            &mut rows,
            &signals,
            &inputs,
            &keep,
            (memory, RAW_BUDGET_BYTES),
        )?;
        return Ok(Recorded {
            rows,
            rest: band.rest,
            samples,
            dt,
            non_finite: bad,
        });
    }
    // Parallel filtering (Butterworth): the whole equation tau = Y theta
    // passes the torque filter, so every column is compared exactly.
    let (traj, states) = match (cutoff, reversal) {
        (Some(_), Some(needs)) => band::states(model, raw, settings, needs)?,
        (Some(_), None) => (settings.states_at_full_rate(raw)?, settings.clone()),
        (None, _) => (settings.apply(raw)?, settings.clone()),
    };
    let dt = step(&traj);
    let band = match (cutoff, reversal) {
        (None, _) => Band::of(&traj, moving),
        (Some(_), None) => Band::of(&traj, &rest_velocities(raw, &traj, settings, moving)),
        (Some(_), Some(needs)) => band::velocity(raw, settings, moving, needs)?,
    };
    let samples: Vec<usize> = match cutoff {
        Some(_) => {
            let clear = Pipeline::clear_of_transients(&states, traj.len(), dt);
            let kept = Pipeline::kept_samples(settings, traj.len(), dt);
            kept.into_iter().filter(|s| clear.contains(s)).collect()
        }
        None => (0..traj.len()).collect(),
    };
    let inputs = Inputs {
        model,
        tilted,
        traj: Some(&traj),
        band: &band,
        levers,
    };
    let keep = Keep {
        cutoff_hz: cutoff,
        dt,
        samples: &samples,
    };
    let signals = template.signals();
    let bad = produce(
        &mut rows,
        &signals,
        &inputs,
        &keep,
        (memory, RAW_BUDGET_BYTES),
    )?;
    rows.measured_curvature = rate_over(&rows.measured_rate, &samples, dt, levers.len());
    Ok(Recorded {
        rows,
        rest: band.rest,
        samples,
        dt,
        non_finite: bad,
    })
}

/// The rate of a signal of kept rows (sample-major, `dof` per sample) over
/// the kept `samples` (numbered at the period `dt`, evenly spaced: a range
/// stepped by the decimation), by [`central_difference`] per joint.
fn rate_over(values: &[f64], samples: &[usize], dt: f64, dof: usize) -> Vec<f64> {
    let mut rate = vec![0.0; values.len()];
    let (Some(&first), Some(&second)) = (samples.first(), samples.get(1)) else {
        return rate;
    };
    let step = (second - first) as f64 * dt;
    for j in 0..dof {
        let column: Vec<f64> = values.iter().skip(j).step_by(dof).copied().collect();
        if let Ok(d) = central_difference(&column, step) {
            for (k, v) in d.into_iter().enumerate() {
                rate[k * dof + j] = v;
            }
        }
    }
    rate
}

/// What [`recording_rows`] gives.
struct Recorded {
    rows: Rows,
    /// Each joint's at-rest speed.
    rest: Vec<f64>,
    /// The kept samples, numbered at the period `dt`.
    samples: Vec<usize>,
    dt: f64,
    /// The first row where a checked signal is not finite.
    non_finite: Option<usize>,
}

/// Shortest and longest cross-validation segment, s.
pub const SEGMENT_SECONDS: (f64, f64) = (2.0, 30.0);
/// Segments aimed for over all recordings.
pub const TARGET_SEGMENTS: f64 = 12.0;

/// Segments per recording: about [`TARGET_SEGMENTS`] in all, each within
/// [`SEGMENT_SECONDS`] (shorter only when the recordings are too short for
/// four segments of 2 s), so one recording is cross-validated across its
/// own pieces and three give twelve groups for the jackknife.
pub fn segment_counts(durations: &[f64]) -> Vec<usize> {
    let total: f64 = durations.iter().sum();
    let shortest = SEGMENT_SECONDS.0.min(total / 4.0);
    let length = (total / TARGET_SEGMENTS).clamp(shortest, SEGMENT_SECONDS.1);
    durations
        .iter()
        .map(|d| ((d / length).round() as usize).max(1))
        .collect()
}

/// The model's value of joint effect `effect` (the index in
/// `codegen::EFFECT_NAMES`: 1 viscous, 2 Coulomb) of each joint.
fn effect_levels(model: &dyn Dynamics, effect: usize) -> Vec<f64> {
    let n = model.dof();
    let parameters = model.parameters();
    (0..n)
        .map(|j| {
            let at = 10 * n + codegen::EFFECTS_PER_JOINT * j + effect;
            parameters.get(at).copied().unwrap_or(0.0)
        })
        .collect()
}

/// A tilted base's candidate shape and its [`Tilted`] columns' model (the
/// gravity torque is linear in the gravity vector), or `None` without a
/// description or without gravity.
fn tilted_models(model: &dyn Dynamics) -> Option<(Shape, Tilted)> {
    let description = crate::dynamics::parsed_description(model).ok()?;
    let nominal = Model::from_description(&description);
    let down = nominal.gravity.try_normalize(1e-9)?;
    let across = tilt_directions(&down);
    let shape = Shape::Tilt {
        gravity: nominal.gravity,
        across,
    };
    let directions = [across[0], across[1], down];
    Some((
        shape,
        Tilted {
            model: nominal,
            directions,
        },
    ))
}

fn models(tilted: &Option<(Shape, Tilted)>) -> Option<&Tilted> {
    tilted.as_ref().map(|(_, models)| models)
}

/// Two unit vectors perpendicular to the unit vector `down` and to each
/// other: for gravity along -z, x and y of the base.
pub(super) fn tilt_directions(down: &Vector3<f64>) -> [Vector3<f64>; 2] {
    let helper = if down.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let first = (helper - down * down.dot(&helper)).normalize();
    [first, down.cross(&first)]
}

/// Raises each joint's largest at-rest speed over the recordings to `rest`.
fn widen(at_rest: &mut [f64], rest: &[f64]) {
    for (largest, r) in at_rest.iter_mut().zip(rest) {
        *largest = largest.max(*r);
    }
}

/// The at-rest speed of each joint for the Butterworth pipeline: three
/// standard deviations of the velocity noise left after filtering, at least
/// `moving` ([`MOVING`] scaled to the joint; slower joints stick or creep, where dry friction is not at
/// its sliding level). The
/// noise's deviation is that of the raw minus the filtered velocity (white
/// noise above the cut-off), scaled by the share of the band the filter
/// passes, sqrt(2 fc / fs).
fn rest_velocities(
    raw: &Trajectory,
    filtered: &Trajectory,
    settings: &Preprocess,
    moving: &[f64],
) -> Vec<f64> {
    let Filter::Butterworth { cutoff_hz } = settings.filter else {
        return moving.to_vec();
    };
    let passed = (2.0 * cutoff_hz * step(raw)).min(1.0).sqrt();
    (0..raw.dof())
        .map(|j| {
            let difference = raw.qd().column(j) - filtered.qd().column(j);
            let sigma = (difference.norm_squared() / raw.len().max(1) as f64).sqrt();
            (3.0 * sigma * passed).max(moving[j])
        })
        .collect()
}
