//! The stacked residual and the candidate columns built from trajectories.

use nalgebra::{DMatrix, DVector, Vector3};

use super::band::{self, Band, Needs, Stage};
use super::candidate::{Candidate, Columns, Shape, candidates};
use super::search::{RESOLVED_REST_MULTIPLE, stribeck_velocities};
use super::settings::Settings;
use super::stacked::{GENERIC_FEATURES, Layout, Link, Stacked};
use crate::dynamics::{Dynamics, model_torques};
use crate::oracle::{self, Model, coulomb_sign};
use crate::preprocess::{Filter, Pipeline, Preprocess, step};
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

/// Beyond the farthest of its child joints and its modelled centre of mass
/// by this much (m), a link's centre of mass is not plausible.
pub const EXTENT_MARGIN: f64 = 0.05;

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

/// Per-row signals of one recording, (sample, joint) rows, sample-major.
#[derive(Default)]
struct Rows {
    residual: Vec<f64>,
    measured: Vec<f64>,
    qd: Vec<f64>,
    qdd: Vec<f64>,
    gravity: Vec<f64>,
    coulomb_applied: Vec<f64>,
    /// Fitted own-joint columns: qd, moving sign, qdd, 1, q, and the
    /// Coulomb column's ramp at rest (`super::dry::rest_ramp`).
    own: [Vec<f64>; 6],
    /// The regressor's inertial columns.
    inertial: Vec<Vec<f64>>,
    /// Own-joint features of the unexplained-structure check
    /// ([`GENERIC_FEATURES`]).
    generic: Vec<Vec<f64>>,
    /// Gravity torques for unit gravity along two directions across the
    /// model's gravity and for unit gravity along it (a tilted base), zero
    /// without a description.
    tilt: [Vec<f64>; 3],
    /// d/dt of the measured torque (a delay's column: a torque logged late
    /// is, to first order, the torque minus the delay times its rate).
    measured_rate: Vec<f64>,
    /// Stribeck columns per velocity of `search::stribeck_velocities`
    /// (moving sign; the reversal stage only).
    stribeck: Vec<Vec<f64>>,
}

impl Rows {
    /// Everything the torque filter applies to: residual, measured torque
    /// and every column.
    fn filtered_mut(&mut self) -> impl Iterator<Item = &mut Vec<f64>> {
        [
            &mut self.residual,
            &mut self.measured,
            &mut self.coulomb_applied,
        ]
        .into_iter()
        .chain(self.own.iter_mut())
        .chain(self.inertial.iter_mut())
        .chain(self.generic.iter_mut())
        .chain(self.tilt.iter_mut())
        .chain([&mut self.measured_rate])
        .chain(self.stribeck.iter_mut())
    }

    /// The first row where any signal is not finite.
    fn first_non_finite(&self) -> Option<usize> {
        [&self.residual, &self.measured]
            .into_iter()
            .chain(self.own.iter())
            .chain(self.inertial.iter())
            .chain(self.generic.iter())
            .chain(self.tilt.iter())
            .chain([&self.measured_rate])
            .chain(self.stribeck.iter())
            .filter_map(|v| v.iter().position(|x| !x.is_finite()))
            .min()
    }

    /// The candidates' columns.
    fn columns_mut(&mut self) -> impl Iterator<Item = &mut Vec<f64>> {
        self.own
            .iter_mut()
            .chain(self.inertial.iter_mut())
            .chain(self.generic.iter_mut())
            .chain(self.tilt.iter_mut())
            .chain([&mut self.measured_rate])
            .chain(self.stribeck.iter_mut())
    }

    fn columns(&self) -> impl Iterator<Item = &Vec<f64>> {
        self.own
            .iter()
            .chain(&self.inertial)
            .chain(&self.generic)
            .chain(&self.tilt)
            .chain([&self.measured_rate])
            .chain(&self.stribeck)
    }

    /// Empty rows with every column of `stage`: Stribeck columns for each
    /// velocity of the grid at the reversal stage, the generic features of
    /// the unexplained-structure check at the motion stage; the links'
    /// inertial columns with `bodies`.
    fn with_columns(dof: usize, capacity: usize, (stage, bodies): (Stage, bool)) -> Rows {
        let (stribeck, generic) = match stage {
            Stage::Reversals => (stribeck_velocities().len(), 0),
            Stage::Motion => (0, GENERIC_FEATURES.len()),
        };
        Rows {
            inertial: vec![Vec::with_capacity(capacity); if bodies { 10 * dof } else { 0 }],
            generic: vec![Vec::with_capacity(capacity); generic],
            stribeck: vec![Vec::with_capacity(capacity); stribeck],
            ..Rows::default()
        }
    }

    fn keep(&self, dof: usize, samples: &[usize]) -> Rows {
        let pick = |v: &Vec<f64>| -> Vec<f64> {
            samples
                .iter()
                .flat_map(|&s| v[s * dof..(s + 1) * dof].iter().copied())
                .collect()
        };
        Rows {
            residual: pick(&self.residual),
            measured: pick(&self.measured),
            qd: pick(&self.qd),
            qdd: pick(&self.qdd),
            gravity: pick(&self.gravity),
            coulomb_applied: pick(&self.coulomb_applied),
            own: std::array::from_fn(|k| pick(&self.own[k])),
            inertial: self.inertial.iter().map(pick).collect(),
            generic: self.generic.iter().map(pick).collect(),
            tilt: std::array::from_fn(|k| pick(&self.tilt[k])),
            measured_rate: pick(&self.measured_rate),
            stribeck: self.stribeck.iter().map(pick).collect(),
        }
    }
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
pub(super) fn stack(
    model: &dyn Dynamics,
    recordings: &[Trajectory],
    pipeline: &Pipeline,
    settings: &Settings,
    reversal: Option<&Needs>,
) -> anyhow::Result<(Stacked, Vec<Candidate>, Layout)> {
    let n = model.dof();
    let stage = match reversal {
        Some(_) => Stage::Reversals,
        None => Stage::Motion,
    };
    let bodies = reversal.is_none_or(|r| r.bodies);
    let tilted = tilted_models(model).filter(|_| reversal.is_none_or(|r| r.tilt));
    let levers = crate::dynamics::joint_levers(model);
    let moving: Vec<f64> = levers.iter().map(|lever| MOVING * lever).collect();
    let mut kept = Vec::new();
    let mut durations = Vec::new();
    let mut at_rest = vec![0.0_f64; n];
    let mut trimmed = 0;
    for (g, raw) in recordings.iter().enumerate() {
        if raw.dof() != n {
            anyhow::bail!(
                "recording {} has {} joints, model `{}` has {n}",
                g + 1,
                raw.dof(),
                model.name()
            );
        }
        let settings = pipeline.for_recording(raw);
        let (rows, samples, dt) = match settings.filter {
            Filter::Butterworth { .. } => {
                // Parallel filtering: the whole equation tau = Y theta passes
                // the torque filter, so every column is compared exactly.
                let traj = settings.states_at_full_rate(raw)?;
                let dt = step(&traj);
                let band = match stage {
                    Stage::Motion => {
                        Band::of(&traj, &rest_velocities(raw, &traj, &settings, &moving))
                    }
                    Stage::Reversals => {
                        let band_hz = reversal.map_or(0.0, |r| r.band_hz);
                        band::velocity(raw, &settings, &moving, band_hz)?
                    }
                };
                for (largest, r) in at_rest.iter_mut().zip(&band.rest) {
                    *largest = largest.max(*r);
                }
                let mut rows = rows(
                    model,
                    models(&tilted),
                    &traj,
                    &band,
                    (stage, bodies),
                    &levers,
                )?;
                // A column of zeros (a tilt or Stribeck velocity not built
                // at this stage) stays zero through any linear filter.
                for column in rows.filtered_mut().filter(|c| c.iter().any(|x| *x != 0.0)) {
                    smooth_per_joint(column, n, |x| settings.smooth(x, dt))?;
                }
                (rows, Pipeline::kept_samples(&settings, traj.len(), dt), dt)
            }
            _ => {
                let traj = settings.apply(raw)?;
                let dt = step(&traj);
                for (largest, r) in at_rest.iter_mut().zip(&moving) {
                    *largest = largest.max(*r);
                }
                let band = Band::of(&traj, &moving);
                (
                    rows(
                        model,
                        models(&tilted),
                        &traj,
                        &band,
                        (stage, bodies),
                        &levers,
                    )?,
                    (0..traj.len()).collect(),
                    dt,
                )
            }
        };
        if let Some(at) = rows.first_non_finite() {
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
        kept.push(rows.keep(n, &samples));
    }
    let counts = match settings.segments {
        Some(k) => vec![k; kept.len()],
        None => segment_counts(&durations),
    };
    let mut all = Rows::with_columns(n, 0, (stage, bodies));
    let mut group = Vec::new();
    for ((rows, &count), &seconds) in kept.iter().zip(&counts).zip(&durations) {
        let samples = rows.residual.len() / n;
        // A segment of under a second validates nothing and multiplies the
        // folds: a requested count is cut to whole seconds (the report
        // states the segments used).
        let whole_seconds = (seconds / MIN_SEGMENT_SECONDS).floor().max(1.0) as usize;
        let count = count.clamp(1, samples.max(1).min(whole_seconds));
        let first = group.last().map_or(0, |g| g + 1);
        for s in 0..samples {
            group.extend(std::iter::repeat_n(first + s * count / samples, n));
        }
        all.residual.extend(&rows.residual);
        all.measured.extend(&rows.measured);
        all.qd.extend(&rows.qd);
        all.qdd.extend(&rows.qdd);
        all.gravity.extend(&rows.gravity);
        all.coulomb_applied.extend(&rows.coulomb_applied);
        for (to, from) in all.columns_mut().zip(rows.columns()) {
            to.extend(from);
        }
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
        qd: vector(all.qd),
        qdd: vector(all.qdd),
        gravity: vector(all.gravity),
        generic: all.generic.into_iter().map(DVector::from_vec).collect(),
        group,
        dof: n,
        levers,
        rest: at_rest.clone(),
    };
    let columns = Columns {
        own: all.own.map(DVector::from_vec),
        coulomb_applied: DVector::from_vec(all.coulomb_applied),
        inertial: all.inertial.into_iter().map(DVector::from_vec).collect(),
        tilt: tilted.map(|(shape, _)| (shape, all.tilt.map(DVector::from_vec))),
        measured_rate: DVector::from_vec(all.measured_rate),
        coulomb_levels: coulomb_levels(model),
        sample_period: recordings.iter().map(step).fold(0.0, f64::max),
        stribeck: stribeck_pairs(all.stribeck),
        rest: at_rest,
        modelled_ripple: super::modelled::ripple_cycles(&super::modelled::joint_effects(model)),
        ripple_given: reversal.map(|r| r.ripple.clone()),
    };
    let candidates = candidates(&data, columns, &links(model));
    Ok((data, candidates, layout))
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

/// The model's residual and candidate columns at every sample of `traj`.
/// The dry-friction columns (Coulomb's moving sign, Stribeck's for each
/// velocity of the grid at the reversal stage) follow `band`'s velocity and
/// at-rest speeds (see [`rest_velocities`]).
fn rows(
    model: &dyn Dynamics,
    tilted: Option<&[Model; 3]>,
    traj: &Trajectory,
    band: &Band,
    (stage, bodies): (Stage, bool),
    levers: &[f64],
) -> anyhow::Result<Rows> {
    let n = model.dof();
    let predicted = model_torques(model, traj)?;
    let accel = traj
        .qdd()
        .ok_or_else(|| anyhow::anyhow!("a preprocessed recording has no accelerations"))?;
    let mut rows = Rows::with_columns(n, traj.len() * n, (stage, bodies));
    let velocities = match stage {
        Stage::Reversals => stribeck_velocities(),
        Stage::Motion => Vec::new(),
    };
    let rate = torque_rate(&predicted, step(traj));
    let measured_rate = torque_rate(traj.tau(), step(traj));
    // The reversal stage fits on the moving rows only and judges a
    // breakaway, which lives next to rest: there the Coulomb column stays
    // the moving sign (a zero ramp), or its share at rest would take the
    // breakaway's place.
    let ramps = match stage {
        Stage::Motion => super::dry::rest_ramps(&band.qd, &band.rest),
        Stage::Reversals => vec![vec![0.0; traj.len()]; n],
    };
    for s in 0..traj.len() {
        let row = |m: &DMatrix<f64>| m.row(s).iter().copied().collect::<Vec<f64>>();
        let (q, qd, qdd) = (row(traj.q()), row(traj.qd()), row(accel));
        let y = match bodies {
            true => model.regressor(&q, &qd, &qdd)?,
            false => DMatrix::zeros(0, 0),
        };
        let load = model.gravity(&q)?;
        let tilt = tilted.map(|m| m.each_ref().map(|m| oracle::gravity(m, &q)));
        for i in 0..n {
            let tau = traj.tau()[(s, i)];
            rows.residual.push(tau - predicted[(s, i)]);
            rows.measured.push(tau);
            // The dry-friction columns follow the velocity that resolves
            // reversals (the states' own at the motion stage).
            let resolved = band.qd[(s, i)];
            rows.qd.push(resolved);
            rows.qdd.push(qdd[i]);
            rows.gravity.push(load[i]);
            rows.coulomb_applied.push(coulomb_sign(qd[i]));
            let sign = moving_sign(resolved, band.rest[i]);
            let ramp = ramps[i][s];
            for (k, v) in [qd[i], sign, qdd[i], 1.0, q[i], ramp]
                .into_iter()
                .enumerate()
            {
                rows.own[k].push(v);
            }
            for (k, column) in rows.inertial.iter_mut().enumerate() {
                column.push(y[(i, k)]);
            }
            let features = generic_features(q[i], qd[i], sign, qdd[i], load[i], rate[(s, i)]);
            for (column, v) in rows.generic.iter_mut().zip(features) {
                column.push(v);
            }
            for (k, column) in rows.tilt.iter_mut().enumerate() {
                column.push(tilt.as_ref().map_or(0.0, |t| t[k][i]));
            }
            rows.measured_rate.push(measured_rate[(s, i)]);
            for (fitted, v) in rows.stribeck.iter_mut().zip(&velocities) {
                // Velocities below the least at-rest speed's resolved
                // multiple are never searched: a zero column, not filtered.
                let shape = if *v < RESOLVED_REST_MULTIPLE * MOVING {
                    0.0
                } else {
                    sign * (-(resolved / (v * levers[i])).powi(2)).exp()
                };
                fitted.push(shape);
            }
        }
    }
    Ok(rows)
}

/// The stacked Stribeck columns as (fitted, applied) pairs per velocity.
/// The reversal stage scores the fitted columns only (it names what the
/// physics explains; the report says how the generated model applies it),
/// so both are the fitted one.
fn stribeck_pairs(columns: Vec<Vec<f64>>) -> Vec<(DVector<f64>, DVector<f64>)> {
    columns
        .into_iter()
        .map(|f| {
            let f = DVector::from_vec(f);
            (f.clone(), f)
        })
        .collect()
}

/// The model's Coulomb friction level of each joint (its regressor
/// parameter `coulomb{j}`).
fn coulomb_levels(model: &dyn Dynamics) -> Vec<f64> {
    let n = model.dof();
    let parameters = model.parameters();
    (0..n)
        .map(|j| {
            let at = 10 * n + codegen::EFFECTS_PER_JOINT * j + 2;
            parameters.get(at).copied().unwrap_or(0.0)
        })
        .collect()
}

/// A tilted base's candidate shape and the model with unit gravity along
/// each of its two directions across the model's gravity (the gravity
/// torque is linear in the gravity vector), or `None` without a
/// description or without gravity.
fn tilted_models(model: &dyn Dynamics) -> Option<(Shape, [Model; 3])> {
    let description = crate::dynamics::parsed_description(model).ok()?;
    let nominal = Model::from_description(&description);
    let down = nominal.gravity.try_normalize(1e-9)?;
    let across = tilt_directions(&down);
    let models = [across[0], across[1], down].map(|direction| Model {
        gravity: direction,
        ..nominal.clone()
    });
    let shape = Shape::Tilt {
        gravity: nominal.gravity,
        across,
    };
    Some((shape, models))
}

fn models(tilted: &Option<(Shape, [Model; 3])>) -> Option<&[Model; 3]> {
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

fn generic_features(q: f64, qd: f64, sign: f64, qdd: f64, load: f64, rate: f64) -> [f64; 12] {
    [
        qd,
        qd * qd.abs(),
        sign,
        sign * (-qd.abs() / 0.1).exp(),
        qdd,
        load,
        q.sin(),
        q.cos(),
        (2.0 * q).sin(),
        (2.0 * q).cos(),
        1.0,
        rate,
    ]
}

/// Time derivative of every column of `tau` (central differences).
fn torque_rate(tau: &DMatrix<f64>, dt: f64) -> DMatrix<f64> {
    let mut rate = DMatrix::zeros(tau.nrows(), tau.ncols());
    for j in 0..tau.ncols() {
        let x: Vec<f64> = tau.column(j).iter().copied().collect();
        if let Ok(d) = crate::preprocess::central_difference(&x, dt) {
            rate.column_mut(j).copy_from_slice(&d);
        }
    }
    rate
}

/// Applies `smooth` to each joint's time series of a (sample, joint) column.
fn smooth_per_joint(
    column: &mut [f64],
    dof: usize,
    smooth: impl Fn(&[f64]) -> Result<Vec<f64>, crate::preprocess::PreprocessError>,
) -> anyhow::Result<()> {
    for j in 0..dof {
        let series: Vec<f64> = column.iter().skip(j).step_by(dof).copied().collect();
        for (at, v) in smooth(&series)?.into_iter().enumerate() {
            column[at * dof + j] = v;
        }
    }
    Ok(())
}

/// With the thesis preprocessing, joints slower than this (rad/s; times
/// `dynamics::PRISMATIC_LEVER` in m/s on a prismatic joint) are taken
/// as at rest for the Coulomb fit: their friction is static, anywhere
/// between the Coulomb levels, and a measured velocity that small has an
/// unreliable sign (noise), which would bias the level low. Held-out errors
/// are still scored with the generated model's plain sign(qd)
/// (`Candidate::applied`).
pub const MOVING: f64 = 0.02;

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

pub(super) fn moving_sign(qd: f64, rest: f64) -> f64 {
    if qd.abs() > rest { qd.signum() } else { 0.0 }
}
