//! One recording's signals at every (sample, joint) row: the residual and
//! every candidate column ([`super::produce`] builds them a batch of
//! columns at a time, filtered and decimated; [`super::data::stack`]
//! stacks the recordings).

use nalgebra::Vector3;

use super::band::Stage;
use super::search::stribeck_velocities;
use super::stacked::GENERIC_FEATURES;
use crate::oracle::Model;

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
    /// The model's joint effects in its torque (friction, offset), filtered
    /// like the residual: the sanity gate judges the rigid body's torque.
    pub(super) effects: Vec<f64>,
    pub(super) coulomb_applied: Vec<f64>,
    /// Fitted own-joint columns: qd, moving sign, qdd, 1, q.
    pub(super) own: [Vec<f64>; 5],
    /// The regressor's inertial columns, ten per link; those of a link not
    /// in `links` are left empty.
    pub(super) inertial: Vec<Vec<f64>>,
    /// The links whose inertial columns are built.
    pub(super) links: Vec<usize>,
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
    /// d2/dt2 of the measured torque (a delay's second-order term): the
    /// rate of `measured_rate` once filtered, not a produced signal (a
    /// second difference of the raw torque leaves edge transients of the
    /// raw noise over dt^2 that the filter's trim does not clear).
    pub(super) measured_curvature: Vec<f64>,
    /// Stribeck columns per velocity of `search::stribeck_velocities`
    /// (moving sign; the reversal stage only).
    pub(super) stribeck: Vec<Vec<f64>>,
}

/// One signal of [`Rows`]: a column of every (sample, joint) row.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Signal {
    Residual,
    Measured,
    Qd,
    Qdd,
    Gravity,
    Effects,
    CoulombApplied,
    Own(usize),
    Inertial(usize),
    Generic(usize),
    Tilt(usize),
    MeasuredRate,
    Stribeck(usize),
}

impl Signal {
    /// Whether the torque filter applies to it (velocity, acceleration and
    /// gravity load are already at the states' band).
    pub(super) fn filtered(self) -> bool {
        !matches!(self, Signal::Qd | Signal::Qdd | Signal::Gravity)
    }

    /// Whether a value that is not finite is an error (the signals the
    /// model's torque and regressor give, and the fitted columns).
    pub(super) fn checked(self) -> bool {
        self.filtered() && self != Signal::CoulombApplied
    }
}

impl Rows {
    /// Every signal these rows have a column for, in a fixed order: the
    /// regressor's columns first and together (a batch of
    /// [`super::produce`] that holds any of them computes the regressor,
    /// so they span as few batches as they can), the generic features
    /// together.
    pub(super) fn signals(&self) -> Vec<Signal> {
        use Signal::*;
        let fixed = [
            Residual,
            Measured,
            Qd,
            Qdd,
            Gravity,
            Effects,
            CoulombApplied,
        ];
        let own = (0..self.own.len()).map(Own);
        let inertial = self
            .links
            .iter()
            .flat_map(|k| 10 * k..10 * (k + 1))
            .map(Inertial);
        let generic = (0..self.generic.len()).map(Generic);
        let tilt = (0..self.tilt.len()).map(Tilt);
        let stribeck = (0..self.stribeck.len()).map(Stribeck);
        inertial
            .chain(fixed)
            .chain(own)
            .chain(generic)
            .chain(tilt)
            .chain([MeasuredRate])
            .chain(stribeck)
            .collect()
    }

    /// The dry-friction signals alone, as the reversal stage builds them
    /// at the motion band (see [`Rows::with_dry`]).
    pub(super) fn dry_signals(&self) -> Vec<Signal> {
        let stribeck = (0..self.stribeck.len()).map(Signal::Stribeck);
        [Signal::Qd, Signal::Own(1)]
            .into_iter()
            .chain(stribeck)
            .collect()
    }

    pub(super) fn signal_mut(&mut self, signal: Signal) -> &mut Vec<f64> {
        match signal {
            Signal::Residual => &mut self.residual,
            Signal::Measured => &mut self.measured,
            Signal::Qd => &mut self.qd,
            Signal::Qdd => &mut self.qdd,
            Signal::Gravity => &mut self.gravity,
            Signal::Effects => &mut self.effects,
            Signal::CoulombApplied => &mut self.coulomb_applied,
            Signal::Own(k) => &mut self.own[k],
            Signal::Inertial(k) => &mut self.inertial[k],
            Signal::Generic(k) => &mut self.generic[k],
            Signal::Tilt(k) => &mut self.tilt[k],
            Signal::MeasuredRate => &mut self.measured_rate,
            Signal::Stribeck(k) => &mut self.stribeck[k],
        }
    }

    /// The number of (sample, joint) rows.
    pub(super) fn len(&self) -> usize {
        self.residual.len()
    }

    /// The rows of `parts` (with the same columns as `self`, which is
    /// filled) one after the other, each column allocated once at its
    /// length. With `consume`, each part's column is freed once copied: at
    /// most one signal's columns are in memory twice.
    pub(super) fn concat(mut self, parts: &mut [Rows], consume: bool) -> Rows {
        for signal in self.signals() {
            let length = parts.iter().map(|p| p.signal(signal).len()).sum();
            let mut column = Vec::with_capacity(length);
            for part in parts.iter_mut() {
                column.extend_from_slice(part.signal(signal));
                if consume {
                    *part.signal_mut(signal) = Vec::new();
                }
            }
            *self.signal_mut(signal) = column;
        }
        let curvature = parts.iter_mut().flat_map(|part| match consume {
            true => std::mem::take(&mut part.measured_curvature),
            false => part.measured_curvature.clone(),
        });
        self.measured_curvature = curvature.collect();
        self
    }

    fn signal(&self, signal: Signal) -> &Vec<f64> {
        match signal {
            Signal::Residual => &self.residual,
            Signal::Measured => &self.measured,
            Signal::Qd => &self.qd,
            Signal::Qdd => &self.qdd,
            Signal::Gravity => &self.gravity,
            Signal::Effects => &self.effects,
            Signal::CoulombApplied => &self.coulomb_applied,
            Signal::Own(k) => &self.own[k],
            Signal::Inertial(k) => &self.inertial[k],
            Signal::Generic(k) => &self.generic[k],
            Signal::Tilt(k) => &self.tilt[k],
            Signal::MeasuredRate => &self.measured_rate,
            Signal::Stribeck(k) => &self.stribeck[k],
        }
    }

    /// Empty rows with every column of `stage`: Stribeck columns for each
    /// velocity of the grid at the reversal stage, the generic features of
    /// the unexplained-structure check at the motion stage; the inertial
    /// columns of `links`.
    pub(super) fn with_columns(dof: usize, (stage, links): (Stage, &[usize])) -> Rows {
        let (stribeck, generic) = match stage {
            Stage::Reversals => (stribeck_velocities().len(), 0),
            Stage::Motion => (0, GENERIC_FEATURES.len()),
        };
        let column = |_: usize| Vec::new();
        let columns = |count: usize| (0..count).map(column).collect();
        Rows {
            residual: column(0),
            measured: column(0),
            qd: column(0),
            qdd: column(0),
            gravity: column(0),
            effects: column(0),
            coulomb_applied: column(0),
            own: std::array::from_fn(column),
            inertial: columns(if links.is_empty() { 0 } else { 10 * dof }),
            links: links.to_vec(),
            generic: columns(generic),
            tilt: std::array::from_fn(column),
            measured_rate: column(0),
            measured_curvature: column(0),
            stribeck: columns(stribeck),
        }
    }

    /// The motion stage's kept rows of a recording (`self`) with the
    /// dry-friction signals of `dry` (kept from [`fill_dry`] at the same
    /// pipeline and samples): what [`fill`] builds for the reversal stage's
    /// pass at the motion band, every other signal being the same numbers.
    /// The inertial columns of `links` only; the tilt's zero without `tilt`.
    pub(super) fn with_dry(&self, dry: Rows, (links, tilt): (&[usize], bool)) -> Rows {
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
            effects: self.effects.clone(),
            coulomb_applied: self.coulomb_applied.clone(),
            own: std::array::from_fn(own),
            inertial: match links.is_empty() {
                true => Vec::new(),
                false => (0..self.inertial.len())
                    .map(|k| match links.contains(&(k / 10)) {
                        true => self.inertial[k].clone(),
                        false => Vec::new(),
                    })
                    .collect(),
            },
            links: links.to_vec(),
            generic: Vec::new(),
            tilt: std::array::from_fn(|k| match tilt {
                true => self.tilt[k].clone(),
                false => vec![0.0; self.tilt[k].len()],
            }),
            measured_rate: self.measured_rate.clone(),
            measured_curvature: self.measured_curvature.clone(),
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

/// The sign of a joint's velocity `qd` where it moves (faster than its
/// at-rest speed `rest`), zero at rest.
pub(super) fn moving_sign(qd: f64, rest: f64) -> f64 {
    if qd.abs() > rest { qd.signum() } else { 0.0 }
}
