//! The identified model: what a robotics engineer tries first. The
//! torques are linear in the model's parameters, tau = Y(q, qd, qdd) theta
//! (the generated regressor: ten inertial parameters per link and the joint
//! effects), so least squares on recordings gives the parameters that fit
//! them best, the model's kinematics kept. The fit is a correction of the
//! model's own parameters (its description is the prior, as CAD values are
//! for a real arm): directions of the parameters the data do not determine
//! (base-parameter combinations, unexcited columns, short recordings) keep
//! the model's values, through the minimum-norm correction: the
//! pseudo-inverse of the information matrix, eigenvalues below
//! [`RELATIVE_TOLERANCE`] of the largest taken as zero.

use anyhow::{Context, Result, bail};
use nalgebra::{DMatrix, DVector};

use crate::dynamics::Dynamics;
use crate::trajectory::Trajectory;

/// Relative eigenvalue of the (column-scaled) information matrix below which
/// a direction of the parameters is taken as unidentified.
pub const RELATIVE_TOLERANCE: f64 = 1e-4;

/// A model's regressor with parameters fitted to recordings.
pub struct Identified<'a> {
    model: &'a dyn Dynamics,
    theta: DVector<f64>,
    /// How many parameter directions the recordings determine.
    pub rank: usize,
}

impl<'a> Identified<'a> {
    /// Least squares of the measured torques of `recordings` (which need
    /// accelerations: preprocessed) on `model`'s regressor.
    pub fn fit(model: &'a dyn Dynamics, recordings: &[&Trajectory]) -> Result<Identified<'a>> {
        let prior = DVector::from_column_slice(model.parameters());
        let p = prior.len();
        let (mut information, mut moment) = (DMatrix::zeros(p, p), DVector::zeros(p));
        for traj in recordings {
            let qdd = traj
                .qdd()
                .context("identification needs accelerations: preprocess the recordings")?;
            for s in 0..traj.len() {
                let row = |m: &DMatrix<f64>| m.row(s).iter().copied().collect::<Vec<f64>>();
                let y = model.regressor(&row(traj.q()), &row(traj.qd()), &row(qdd))?;
                let tau = DVector::from_iterator(y.nrows(), traj.tau().row(s).iter().copied());
                let unexplained = tau - &y * &prior;
                information.gemm_tr(1.0, &y, &y, 1.0);
                moment.gemv_tr(1.0, &y, &unexplained, 1.0);
            }
        }
        let (correction, rank) = pseudo_solve(information, &moment)?;
        Ok(Identified {
            model,
            theta: prior + correction,
            rank,
        })
    }

    /// The identified model's torques along `traj` (samples x joints).
    pub fn torques(&self, traj: &Trajectory) -> Result<DMatrix<f64>> {
        let qdd = traj
            .qdd()
            .context("the identified model needs accelerations: preprocess the recording")?;
        let n = self.model.dof();
        let mut out = DMatrix::zeros(traj.len(), n);
        for s in 0..traj.len() {
            let row = |m: &DMatrix<f64>| m.row(s).iter().copied().collect::<Vec<f64>>();
            let y = self
                .model
                .regressor(&row(traj.q()), &row(traj.qd()), &row(qdd))?;
            out.set_row(s, &(y * &self.theta).transpose());
        }
        Ok(out)
    }
}

/// theta = A^+ b for the symmetric positive semi-definite `a`, scaled to a
/// unit diagonal first (the parameters' units differ by orders of
/// magnitude); the number of directions kept.
fn pseudo_solve(a: DMatrix<f64>, b: &DVector<f64>) -> Result<(DVector<f64>, usize)> {
    let scale: Vec<f64> = (0..a.nrows())
        .map(|k| {
            let d = a[(k, k)];
            if d > 0.0 { 1.0 / d.sqrt() } else { 0.0 }
        })
        .collect();
    let scaled = DMatrix::from_fn(a.nrows(), a.ncols(), |r, c| a[(r, c)] * scale[r] * scale[c]);
    let rhs = DVector::from_fn(b.len(), |k, _| b[k] * scale[k]);
    let Some(eigen) = crate::kernels::symmetric_eigen(scaled) else {
        bail!("the identification's information matrix could not be decomposed");
    };
    let largest = eigen.eigenvalues.max();
    if largest.is_nan() || largest <= 0.0 {
        bail!("the recordings do not excite any parameter of the model");
    }
    let mut theta = DVector::zeros(b.len());
    let mut rank = 0;
    for (k, &lambda) in eigen.eigenvalues.iter().enumerate() {
        if lambda > RELATIVE_TOLERANCE * largest {
            let v = eigen.eigenvectors.column(k);
            theta += v * (v.dot(&rhs) / lambda);
            rank += 1;
        }
    }
    Ok((theta.component_mul(&DVector::from_vec(scale)), rank))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_minimum_norm_solution_of_a_singular_system() {
        // x + y = 2 seen twice, z = 3: x and y are told apart only in sum.
        let a = DMatrix::from_row_slice(3, 3, &[2.0, 2.0, 0.0, 2.0, 2.0, 0.0, 0.0, 0.0, 1.0]);
        let b = DVector::from_vec(vec![4.0, 4.0, 3.0]);
        let (theta, rank) = pseudo_solve(a, &b).unwrap();
        assert_eq!(rank, 2);
        for (got, want) in theta.iter().zip([1.0, 1.0, 3.0]) {
            assert!((got - want).abs() < 1e-12, "{theta}");
        }
    }
}
