//! One recording's signals at every (sample, joint) row: the residual and
//! every candidate column, before the torque's filter and decimation
//! ([`super::data::stack`] filters, keeps and stacks them).

use nalgebra::{DMatrix, Vector3};

use super::band::{Band, Stage};
use super::search::{RESOLVED_REST_MULTIPLE, stribeck_velocities};
use super::stacked::GENERIC_FEATURES;
use crate::dynamics::{Dynamics, model_torques};
use crate::oracle::{self, Model, coulomb_sign};
use crate::preprocess::step;
use crate::trajectory::Trajectory;

/// With the thesis preprocessing, joints slower than this (rad/s; times
/// `dynamics::PRISMATIC_LEVER` in m/s on a prismatic joint) are taken
/// as at rest for the Coulomb fit: their friction is static, anywhere
/// between the Coulomb levels, and a measured velocity that small has an
/// unreliable sign (noise), which would bias the level low. Held-out errors
/// are still scored with the generated model's plain sign(qd)
/// (`Candidate::applied`).
pub const MOVING: f64 = 0.02;

/// Per-row signals of one recording, (sample, joint) rows, sample-major.
pub(super) struct Rows {
    pub(super) residual: Vec<f64>,
    pub(super) measured: Vec<f64>,
    pub(super) qd: Vec<f64>,
    pub(super) qdd: Vec<f64>,
    pub(super) gravity: Vec<f64>,
    pub(super) coulomb_applied: Vec<f64>,
    /// Fitted own-joint columns: qd, moving sign, qdd, 1, q.
    pub(super) own: [Vec<f64>; 5],
    /// The regressor's inertial columns.
    pub(super) inertial: Vec<Vec<f64>>,
    /// Own-joint features of the unexplained-structure check
    /// ([`GENERIC_FEATURES`]).
    pub(super) generic: Vec<Vec<f64>>,
    /// Gravity torques for unit gravity along two directions across the
    /// model's gravity and for unit gravity along it (a tilted base), zero
    /// without a description.
    pub(super) tilt: [Vec<f64>; 3],
    /// d/dt of the measured torque (a delay's column: a torque logged late
    /// is, to first order, the torque minus the delay times its rate).
    pub(super) measured_rate: Vec<f64>,
    /// Stribeck columns per velocity of `search::stribeck_velocities`
    /// (moving sign; the reversal stage only).
    pub(super) stribeck: Vec<Vec<f64>>,
}

impl Rows {
    /// Everything the torque filter applies to: residual, measured torque
    /// and every column.
    pub(super) fn filtered_mut(&mut self) -> impl Iterator<Item = &mut Vec<f64>> {
        self.parts_mut().1
    }

    /// Every signal, filtered or not.
    fn signals_mut(&mut self) -> impl Iterator<Item = &mut Vec<f64>> {
        let (states, filtered) = self.parts_mut();
        states.into_iter().chain(filtered)
    }

    /// The signals the torque filter leaves alone (velocity, acceleration
    /// and gravity load, already at the states' band) and those it filters.
    fn parts_mut(&mut self) -> ([&mut Vec<f64>; 3], impl Iterator<Item = &mut Vec<f64>>) {
        let filtered = [
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
        .chain(self.stribeck.iter_mut());
        ([&mut self.qd, &mut self.qdd, &mut self.gravity], filtered)
    }

    /// Every signal emptied, its memory kept.
    pub(super) fn clear(&mut self) {
        self.signals_mut().for_each(Vec::clear);
    }

    /// Appends the rows of `tile` (built with the same columns), which is
    /// emptied.
    fn append(&mut self, tile: &mut Rows) {
        for (to, from) in self.signals_mut().zip(tile.signals_mut()) {
            to.extend_from_slice(from);
            from.clear();
        }
    }

    /// The first row where any signal is not finite.
    pub(super) fn first_non_finite(&self) -> Option<usize> {
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
    pub(super) fn columns_mut(&mut self) -> impl Iterator<Item = &mut Vec<f64>> {
        self.own
            .iter_mut()
            .chain(self.inertial.iter_mut())
            .chain(self.generic.iter_mut())
            .chain(self.tilt.iter_mut())
            .chain([&mut self.measured_rate])
            .chain(self.stribeck.iter_mut())
    }

    pub(super) fn columns(&self) -> impl Iterator<Item = &Vec<f64>> {
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
    /// Every column holds `capacity` rows without growing (a grown vector
    /// is copied, and its pages touched twice).
    pub(super) fn with_columns(
        dof: usize,
        capacity: usize,
        (stage, bodies): (Stage, bool),
    ) -> Rows {
        let (stribeck, generic) = match stage {
            Stage::Reversals => (stribeck_velocities().len(), 0),
            Stage::Motion => (0, GENERIC_FEATURES.len()),
        };
        let column = |_: usize| Vec::with_capacity(capacity);
        let columns = |count: usize| (0..count).map(column).collect();
        Rows {
            residual: column(0),
            measured: column(0),
            qd: column(0),
            qdd: column(0),
            gravity: column(0),
            coulomb_applied: column(0),
            own: std::array::from_fn(column),
            inertial: columns(if bodies { 10 * dof } else { 0 }),
            generic: columns(generic),
            tilt: std::array::from_fn(column),
            measured_rate: column(0),
            stribeck: columns(stribeck),
        }
    }

    pub(super) fn keep(&self, dof: usize, samples: &[usize]) -> Rows {
        // A signal not built (only the dry-friction ones, see `fill_dry`)
        // stays empty.
        let pick = |v: &Vec<f64>| -> Vec<f64> {
            if v.is_empty() {
                return Vec::new();
            }
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

    /// The motion stage's kept rows of a recording (`self`) with the
    /// dry-friction signals of `dry` (kept from [`fill_dry`] at the same
    /// pipeline and samples): what [`fill`] builds for the reversal stage's
    /// pass at the motion band, every other signal being the same numbers.
    /// A link's columns only with `bodies`; the tilt's zero without `tilt`.
    pub(super) fn with_dry(&self, dry: Rows, (bodies, tilt): (bool, bool)) -> Rows {
        let own = |k: usize| match k {
            1 => dry.own[1].clone(),
            _ => self.own[k].clone(),
        };
        Rows {
            residual: self.residual.clone(),
            measured: self.measured.clone(),
            qd: dry.qd,
            qdd: self.qdd.clone(),
            gravity: self.gravity.clone(),
            coulomb_applied: self.coulomb_applied.clone(),
            own: std::array::from_fn(own),
            inertial: if bodies {
                self.inertial.clone()
            } else {
                Vec::new()
            },
            generic: Vec::new(),
            tilt: std::array::from_fn(|k| match tilt {
                true => self.tilt[k].clone(),
                false => vec![0.0; self.tilt[k].len()],
            }),
            measured_rate: self.measured_rate.clone(),
            stribeck: dry.stribeck,
        }
    }
}

/// The model whose gravity torque is taken along each direction of a
/// tilted base's columns.
pub(super) struct Tilted {
    pub(super) model: Model,
    /// Unit gravity along two directions across the model's gravity, and
    /// along it.
    pub(super) directions: [Vector3<f64>; 3],
}

/// Fills `rows` (cleared first) with the model's residual and candidate
/// columns at every sample of `traj`.
/// The dry-friction columns (Coulomb's moving sign, Stribeck's for each
/// velocity of the grid at the reversal stage) follow `band`'s velocity and
/// at-rest speeds (see [`rest_velocities`]).
pub(super) fn fill(
    rows: &mut Rows,
    (model, tilted): (&dyn Dynamics, Option<&Tilted>),
    traj: &Trajectory,
    band: &Band,
    (stage, bodies): (Stage, bool),
    levers: &[f64],
) -> anyhow::Result<()> {
    let n = model.dof();
    let predicted = model_torques(model, traj)?;
    let accel = traj
        .qdd()
        .ok_or_else(|| anyhow::anyhow!("a preprocessed recording has no accelerations"))?;
    rows.clear();
    let velocities = match stage {
        Stage::Reversals => stribeck_velocities(),
        Stage::Motion => Vec::new(),
    };
    let rate = torque_rate(&predicted, step(traj));
    let measured_rate = torque_rate(traj.tau(), step(traj));
    let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    // Rows are built a few samples at a time in a tile that stays in the
    // cache, then appended column by column: written sample by sample, the
    // fifty-odd long columns took most of this function's time.
    let mut tile = Rows::with_columns(n, TILE_SAMPLES * n, (stage, bodies));
    for s in 0..traj.len() {
        if s % TILE_SAMPLES == 0 {
            rows.append(&mut tile);
        }
        let rows = &mut tile;
        for i in 0..n {
            (q[i], qd[i], qdd[i]) = (traj.q()[(s, i)], traj.qd()[(s, i)], accel[(s, i)]);
        }
        let y = match bodies {
            true => model.regressor(&q, &qd, &qdd)?,
            false => DMatrix::zeros(0, 0),
        };
        let load = model.gravity(&q)?;
        let tilt = tilted.map(|t| oracle::gravity_along(&t.model, &q, &t.directions));
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
            for (k, v) in [qd[i], sign, qdd[i], 1.0, q[i]].into_iter().enumerate() {
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
            push_stribeck(&mut rows.stribeck, &velocities, (sign, resolved), levers[i]);
        }
    }
    rows.append(&mut tile);
    Ok(())
}

/// Samples per tile of [`fill`].
const TILE_SAMPLES: usize = 16;

/// Fills `rows` (cleared first) with the dry-friction signals alone, as
/// [`fill`] builds them at the reversal stage: the velocity that resolves
/// reversals, Coulomb's moving sign and the Stribeck columns (the others
/// stay empty; see [`Rows::with_dry`]).
pub(super) fn fill_dry(rows: &mut Rows, band: &Band, levers: &[f64]) {
    rows.clear();
    let velocities = stribeck_velocities();
    for s in 0..band.qd.nrows() {
        for (i, (&rest, &lever)) in band.rest.iter().zip(levers).enumerate() {
            let resolved = band.qd[(s, i)];
            rows.qd.push(resolved);
            let sign = moving_sign(resolved, rest);
            rows.own[1].push(sign);
            push_stribeck(&mut rows.stribeck, &velocities, (sign, resolved), lever);
        }
    }
}

/// One row of the Stribeck columns, one per velocity of the grid, for a
/// joint moving with `sign` at the `resolved` velocity.
fn push_stribeck(
    columns: &mut [Vec<f64>],
    velocities: &[f64],
    (sign, resolved): (f64, f64),
    lever: f64,
) {
    for (fitted, v) in columns.iter_mut().zip(velocities) {
        // Velocities below the least at-rest speed's resolved multiple are
        // never searched: a zero column, not filtered.
        let shape = if *v < RESOLVED_REST_MULTIPLE * MOVING {
            0.0
        } else {
            sign * (-(resolved / (v * lever)).powi(2)).exp()
        };
        fitted.push(shape);
    }
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

pub(super) fn moving_sign(qd: f64, rest: f64) -> f64 {
    if qd.abs() > rest { qd.signum() } else { 0.0 }
}
