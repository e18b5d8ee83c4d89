//! The rows the diagnosis fits: the residual and the signals of every
//! (sample, joint) pair, and the model's moving links the inertial
//! candidates correct.

use nalgebra::DVector;

/// Stacked data: rows are (sample, joint) pairs, sample-major.
pub(crate) struct Stacked {
    pub(super) residual: DVector<f64>,
    pub(super) measured: DVector<f64>,
    pub(super) qd: DVector<f64>,
    pub(super) qdd: DVector<f64>,
    /// The model's gravity torque.
    pub(super) gravity: DVector<f64>,
    /// Own-joint features ([`GENERIC_FEATURES`]), filtered like the columns.
    pub(super) generic: Vec<DVector<f64>>,
    pub(super) group: Vec<usize>,
    pub(super) dof: usize,
    /// Per joint the lever its speeds are scaled by (1 revolute,
    /// `dynamics::PRISMATIC_LEVER` prismatic): the Stribeck grid's.
    pub(super) levers: Vec<f64>,
}

impl Stacked {
    /// The rows of joint `joint` (rows are (sample, joint) pairs).
    pub(super) fn rows_of(&self, joint: usize) -> impl Iterator<Item = usize> + Clone + '_ {
        (joint..self.residual.len()).step_by(self.dof)
    }
}

/// A moving link of the model: its name and standard parameters.
pub(crate) struct Link {
    pub(super) name: String,
    pub(super) parameters: [f64; 10],
}
