//! The rows the diagnosis fits: the residual and the signals of every
//! (sample, joint) pair, and the model's moving links the inertial
//! candidates correct.

use std::ops::Range;

use nalgebra::DVector;

/// Stacked data: rows are (sample, joint) pairs, sample-major.
#[derive(Clone)]
pub(crate) struct Stacked {
    pub(super) residual: DVector<f64>,
    pub(super) measured: DVector<f64>,
    /// Each row's joint position, velocity and acceleration (filtered).
    pub(super) angle: DVector<f64>,
    pub(super) qd: DVector<f64>,
    pub(super) qdd: DVector<f64>,
    /// The model's gravity torque.
    pub(super) gravity: DVector<f64>,
    /// The model's joint effects (friction, offset) in its torque,
    /// filtered like the residual.
    pub(super) effects: DVector<f64>,
    /// d2/dt2 of the measured torque (a delay's second-order term, see
    /// `super::delay`).
    pub(super) measured_curvature: DVector<f64>,
    /// Own-joint features ([`GENERIC_FEATURES`]), filtered like the columns.
    pub(super) generic: Vec<DVector<f64>>,
    pub(super) group: Vec<usize>,
    /// Each recording's rows and groups, in order.
    pub(super) recordings: Vec<Span>,
    pub(super) dof: usize,
    /// Per joint the lever its speeds are scaled by (1 revolute,
    /// `dynamics::PRISMATIC_LEVER` prismatic): the Stribeck grid's.
    pub(super) levers: Vec<f64>,
    /// Per joint the speed below which it counts as at rest (the largest
    /// over the recordings; see `rows::MOVING`).
    pub(super) rest: Vec<f64>,
    /// Per joint the description's viscous and Coulomb friction.
    pub(super) friction: Vec<[f64; 2]>,
}

impl Stacked {
    /// Rows of `dof` joints with `residual` (also the measured torque) and
    /// every signal zero, in four groups of equal length (unit tests).
    #[cfg(test)]
    pub(super) fn of_residual(residual: DVector<f64>, dof: usize) -> Stacked {
        let rows = residual.len();
        Stacked {
            measured: residual.clone(),
            residual,
            angle: DVector::zeros(rows),
            qd: DVector::zeros(rows),
            qdd: DVector::zeros(rows),
            gravity: DVector::zeros(rows),
            effects: DVector::zeros(rows),
            measured_curvature: DVector::zeros(rows),
            generic: Vec::new(),
            group: (0..rows).map(|r| r * 4 / rows).collect(),
            recordings: vec![Span {
                rows: 0..rows,
                alone: 4,
            }],
            dof,
            levers: vec![1.0; dof],
            rest: vec![0.02; dof],
            friction: vec![[0.0; 2]; dof],
        }
    }

    /// The rows of joint `joint` (rows are (sample, joint) pairs).
    pub(super) fn rows_of(&self, joint: usize) -> impl Iterator<Item = usize> + Clone + '_ {
        (joint..self.residual.len()).step_by(self.dof)
    }
}

/// One recording's place in the stacked rows.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Span {
    /// Its rows (contiguous: recordings are stacked one after another).
    pub(super) rows: Range<usize>,
    /// The segments it would be cut into if it were diagnosed alone: a
    /// check that judges each recording alone folds its jackknife alike.
    pub(super) alone: usize,
}

/// Beyond the farthest of its child joints and its modelled centre of mass
/// by this much (m), a link's centre of mass is not plausible.
pub const EXTENT_MARGIN: f64 = 0.05;

/// A moving link of the model: its name, standard parameters and extent.
pub(crate) struct Link {
    pub(super) name: String,
    pub(super) parameters: [f64; 10],
    /// How far from its origin a centre of mass of this link is plausible,
    /// m (see `data::links`); infinite for the last link.
    pub(super) extent: f64,
}

/// How recordings became the diagnosed rows (reported).
#[derive(Debug, Clone, serde::Serialize)]
pub struct Layout {
    /// Cross-validation groups: contiguous segments of the recordings.
    pub segments: usize,
    /// Seconds per segment (mean).
    pub segment_seconds: f64,
    /// Samples dropped at each end of a recording against filter transients.
    pub trimmed_samples: usize,
}

/// Features of the unexplained-structure check, by regime: what a
/// residual that no candidate explains may still depend on.
pub const GENERIC_FEATURES: [(&str, &str); 12] = [
    ("velocity", "qd"),
    ("velocity", "qd |qd|"),
    ("velocity sign", "sign(qd)"),
    ("velocity sign", "sign(qd) exp(-|qd| / 0.1 rad/s)"),
    ("acceleration", "qdd"),
    ("gravity load", "model gravity torque"),
    ("position", "sin q"),
    ("position", "cos q"),
    ("position", "sin 2q"),
    ("position", "cos 2q"),
    ("constant", "1"),
    ("torque rate", "d/dt model torque"),
];
