//! Plants from compiled models and from descriptions (numeric oracle).

use nalgebra::{DMatrix, DVector};

use super::plant::{DynamicsError, Plant};
use crate::dynamics::Dynamics;
use crate::oracle::{self, Model};

/// A compiled model as a plant. Wrong slice lengths cannot occur: the
/// simulator checks every vector against `dof()` before calling.
pub struct Compiled<'a>(pub &'a dyn Dynamics);

impl Plant for Compiled<'_> {
    fn dof(&self) -> usize {
        self.0.dof()
    }

    fn mass_matrix(&self, q: &[f64]) -> DMatrix<f64> {
        self.0
            .mass_matrix(q)
            .unwrap_or_else(|_| DMatrix::from_element(self.dof(), self.dof(), f64::NAN))
    }

    fn bias(&self, q: &[f64], qd: &[f64]) -> DVector<f64> {
        let n = self.dof();
        let parts = (
            self.0.coriolis(q, qd),
            self.0.gravity(q),
            self.0.effects(qd),
        );
        match parts {
            (Ok(c), Ok(g), Ok(e)) => c + g + e,
            _ => DVector::from_element(n, f64::NAN),
        }
    }

    /// The model's generated forward dynamics: no matrix is allocated.
    fn accelerations(
        &self,
        q: &[f64],
        qd: &[f64],
        tau: &[f64],
        qdd: &mut [f64],
    ) -> Result<(), DynamicsError> {
        self.0
            .forward_dynamics(q, qd, tau, qdd)
            .map_err(|e| DynamicsError::Dimension {
                what: e.argument,
                dof: e.expected,
                found: e.found,
            })?;
        if qdd.iter().all(|x| x.is_finite()) {
            Ok(())
        } else {
            Err(DynamicsError::NotPositiveDefinite { q: q.to_vec() })
        }
    }
}

impl Plant for Model {
    fn dof(&self) -> usize {
        Model::dof(self)
    }

    fn mass_matrix(&self, q: &[f64]) -> DMatrix<f64> {
        oracle::crba(self, q)
    }

    fn bias(&self, q: &[f64], qd: &[f64]) -> DVector<f64> {
        oracle::rnea(self, q, qd, &vec![0.0; Model::dof(self)])
    }
}
