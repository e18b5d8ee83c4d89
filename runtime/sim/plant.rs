//! The dynamics interface of the virtual robot and its forward/inverse
//! dynamics helpers.

use nalgebra::{DMatrix, DVector};
use thiserror::Error;

/// Errors from evaluating a [`Plant`].
#[derive(Debug, Clone, PartialEq, Error)]
pub enum DynamicsError {
    /// An input vector does not have the plant's joint count.
    #[error("{what} has {found} entries, the plant has {dof} joints")]
    Dimension {
        what: &'static str,
        dof: usize,
        found: usize,
    },
    /// The plant returned a mass matrix or bias of the wrong shape.
    #[error("plant returned {what} of shape {rows}x{cols}, expected {dof}x{expected_cols}")]
    PlantShape {
        what: &'static str,
        dof: usize,
        expected_cols: usize,
        rows: usize,
        cols: usize,
    },
    /// Cholesky factorisation of M(q) failed.
    #[error("mass matrix is not positive definite at q = {q:?}")]
    NotPositiveDefinite { q: Vec<f64> },
}

/// Rigid-body dynamics with joint effects: tau = M(q) qdd + c(q, qd) + g(q) + effects(qd),
/// M including armature (reflected rotor inertia).
pub trait Plant {
    fn dof(&self) -> usize;
    /// M(q), dof x dof, symmetric positive definite.
    fn mass_matrix(&self, q: &[f64]) -> DMatrix<f64>;
    /// c(q, qd) + g(q) + effects(qd): every torque term except M qdd.
    fn bias(&self, q: &[f64], qd: &[f64]) -> DVector<f64>;
    /// qdd = M(q)^-1 (tau - bias(q, qd)) into `qdd` (slices of the plant's
    /// length). By default a Cholesky solve of `mass_matrix` and `bias`;
    /// a plant with its own forward dynamics (a compiled model) overrides
    /// it.
    fn accelerations(
        &self,
        q: &[f64],
        qd: &[f64],
        tau: &[f64],
        qdd: &mut [f64],
    ) -> Result<(), DynamicsError> {
        let solved = solve_by_cholesky(self, q, qd, tau)?;
        qdd.copy_from_slice(solved.as_slice());
        Ok(())
    }
}

/// Joint accelerations qdd = M(q)^-1 (tau - bias(q, qd)), by the plant's
/// own forward dynamics.
pub fn forward_dynamics(
    plant: &dyn Plant,
    q: &[f64],
    qd: &[f64],
    tau: &[f64],
) -> Result<DVector<f64>, DynamicsError> {
    let dof = plant.dof();
    check_len("q", q, dof)?;
    check_len("qd", qd, dof)?;
    check_len("tau", tau, dof)?;
    let mut qdd = DVector::zeros(dof);
    plant.accelerations(q, qd, tau, qdd.as_mut_slice())?;
    Ok(qdd)
}

/// qdd by a Cholesky solve of M and the bias. Only the lower triangle of M
/// is read, so an asymmetric M is not detected.
pub fn solve_by_cholesky<P: Plant + ?Sized>(
    plant: &P,
    q: &[f64],
    qd: &[f64],
    tau: &[f64],
) -> Result<DVector<f64>, DynamicsError> {
    let dof = plant.dof();
    let m = plant.mass_matrix(q);
    check_shape("mass matrix", m.shape(), dof, dof)?;
    let bias = plant.bias(q, qd);
    check_shape("bias", bias.shape(), dof, 1)?;
    let chol = m
        .cholesky()
        .ok_or_else(|| DynamicsError::NotPositiveDefinite { q: q.to_vec() })?;
    Ok(chol.solve(&(DVector::from_column_slice(tau) - bias)))
}

/// Joint torques tau = M(q) qdd + bias(q, qd).
pub fn inverse_dynamics(
    plant: &dyn Plant,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
) -> Result<DVector<f64>, DynamicsError> {
    let dof = plant.dof();
    check_len("q", q, dof)?;
    check_len("qd", qd, dof)?;
    check_len("qdd", qdd, dof)?;
    let (m, bias) = evaluate(plant, q, qd)?;
    Ok(m * DVector::from_column_slice(qdd) + bias)
}

/// M and bias with their shapes checked, so a faulty plant cannot make
/// nalgebra panic on a dimension mismatch.
fn evaluate(
    plant: &dyn Plant,
    q: &[f64],
    qd: &[f64],
) -> Result<(DMatrix<f64>, DVector<f64>), DynamicsError> {
    let dof = plant.dof();
    let m = plant.mass_matrix(q);
    check_shape("mass matrix", m.shape(), dof, dof)?;
    let bias = plant.bias(q, qd);
    check_shape("bias", bias.shape(), dof, 1)?;
    Ok((m, bias))
}

fn check_len(what: &'static str, v: &[f64], dof: usize) -> Result<(), DynamicsError> {
    if v.len() == dof {
        Ok(())
    } else {
        Err(DynamicsError::Dimension {
            what,
            dof,
            found: v.len(),
        })
    }
}

fn check_shape(
    what: &'static str,
    (rows, cols): (usize, usize),
    dof: usize,
    expected_cols: usize,
) -> Result<(), DynamicsError> {
    if rows == dof && cols == expected_cols {
        Ok(())
    } else {
        Err(DynamicsError::PlantShape {
            what,
            dof,
            expected_cols,
            rows,
            cols,
        })
    }
}

/// Closed-form plants for tests.
#[cfg(test)]
pub(crate) mod test_plants {
    use super::*;

    const G: f64 = 9.81;

    /// Coulomb friction sign with sign(0) = 0, so a resting joint feels none.
    fn sign(x: f64) -> f64 {
        if x == 0.0 { 0.0 } else { x.signum() }
    }

    /// Planar two-link arm, joints about z, gravity along -y, angles from +x.
    #[derive(Debug, Clone)]
    pub(crate) struct TwoLink {
        pub m: [f64; 2],
        pub l1: f64,
        pub lc: [f64; 2],
        pub inertia: [f64; 2],
        pub armature: [f64; 2],
        pub viscous: [f64; 2],
        pub coulomb: [f64; 2],
    }

    impl TwoLink {
        /// Roughly the size of the Gen3 Lite's upper arm and forearm.
        pub fn new() -> Self {
            Self {
                m: [1.2, 1.9],
                l1: 0.28,
                lc: [0.2, 0.2],
                inertia: [0.011, 0.02],
                armature: [0.01, 0.01],
                viscous: [0.0; 2],
                coulomb: [0.0; 2],
            }
        }

        pub fn with_friction(mut self, viscous: f64, coulomb: f64) -> Self {
            self.viscous = [viscous; 2];
            self.coulomb = [coulomb; 2];
            self
        }

        /// Scales the distal link's mass and inertia (an unmodelled payload).
        pub fn heavier(mut self, factor: f64) -> Self {
            self.m[1] *= factor;
            self.inertia[1] *= factor;
            self
        }

        /// Kinetic plus potential energy.
        pub fn energy(&self, q: &[f64], qd: &[f64]) -> f64 {
            let m = self.mass_matrix(q);
            let v = DVector::from_column_slice(qd);
            let kinetic = 0.5 * v.dot(&(m * &v));
            let (m1, m2) = (self.m[0], self.m[1]);
            let height1 = self.lc[0] * q[0].sin();
            let height2 = self.l1 * q[0].sin() + self.lc[1] * (q[0] + q[1]).sin();
            kinetic + G * (m1 * height1 + m2 * height2)
        }
    }

    impl Plant for TwoLink {
        fn dof(&self) -> usize {
            2
        }

        fn mass_matrix(&self, q: &[f64]) -> DMatrix<f64> {
            let (m1, m2, l1) = (self.m[0], self.m[1], self.l1);
            let (c1, c2) = (self.lc[0], self.lc[1]);
            let (i1, i2) = (self.inertia[0], self.inertia[1]);
            let k = m2 * l1 * c2 * q[1].cos();
            let m11 = i1 + i2 + m1 * c1 * c1 + m2 * (l1 * l1 + c2 * c2) + 2.0 * k;
            let m12 = i2 + m2 * c2 * c2 + k;
            let m22 = i2 + m2 * c2 * c2;
            DMatrix::from_row_slice(
                2,
                2,
                &[m11 + self.armature[0], m12, m12, m22 + self.armature[1]],
            )
        }

        fn bias(&self, q: &[f64], qd: &[f64]) -> DVector<f64> {
            let (m1, m2, l1) = (self.m[0], self.m[1], self.l1);
            let (c1, c2) = (self.lc[0], self.lc[1]);
            let h = m2 * l1 * c2 * q[1].sin();
            let cor = [
                -h * (2.0 * qd[0] * qd[1] + qd[1] * qd[1]),
                h * qd[0] * qd[0],
            ];
            let c12 = (q[0] + q[1]).cos();
            let grav = [
                G * ((m1 * c1 + m2 * l1) * q[0].cos() + m2 * c2 * c12),
                G * m2 * c2 * c12,
            ];
            DVector::from_fn(2, |i, _| {
                cor[i] + grav[i] + self.viscous[i] * qd[i] + self.coulomb[i] * sign(qd[i])
            })
        }
    }

    /// Point-mass pendulum about z, gravity along -y, angle from +x.
    #[derive(Debug, Clone)]
    pub(crate) struct Pendulum {
        pub mass: f64,
        pub length: f64,
        pub viscous: f64,
    }

    impl Plant for Pendulum {
        fn dof(&self) -> usize {
            1
        }

        fn mass_matrix(&self, _q: &[f64]) -> DMatrix<f64> {
            DMatrix::from_element(1, 1, self.mass * self.length * self.length)
        }

        fn bias(&self, q: &[f64], qd: &[f64]) -> DVector<f64> {
            let gravity = self.mass * G * self.length * q[0].cos();
            DVector::from_element(1, gravity + self.viscous * qd[0])
        }
    }

    /// A plant whose mass matrix is singular, to exercise the error path.
    pub(crate) struct Degenerate;

    impl Plant for Degenerate {
        fn dof(&self) -> usize {
            2
        }

        fn mass_matrix(&self, _q: &[f64]) -> DMatrix<f64> {
            DMatrix::from_row_slice(2, 2, &[1.0, 1.0, 1.0, 1.0])
        }

        fn bias(&self, _q: &[f64], _qd: &[f64]) -> DVector<f64> {
            DVector::zeros(2)
        }
    }

    /// A plant returning a bias of the wrong length.
    pub(crate) struct Broken;

    impl Plant for Broken {
        fn dof(&self) -> usize {
            2
        }

        fn mass_matrix(&self, _q: &[f64]) -> DMatrix<f64> {
            DMatrix::identity(2, 2)
        }

        fn bias(&self, _q: &[f64], _qd: &[f64]) -> DVector<f64> {
            DVector::zeros(3)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::test_plants::*;
    use super::*;

    #[test]
    fn pendulum_forward_dynamics_matches_closed_form() {
        let p = Pendulum {
            mass: 2.0,
            length: 0.5,
            viscous: 0.3,
        };
        let (q, qd, tau) = (0.4_f64, -1.2, 0.7);
        let qdd = forward_dynamics(&p, &[q], &[qd], &[tau]).unwrap();
        let expected = (tau - 2.0 * 9.81 * 0.5 * q.cos() - 0.3 * qd) / (2.0 * 0.25);
        assert!((qdd[0] - expected).abs() < 1e-12);
    }

    #[test]
    fn forward_and_inverse_dynamics_are_inverse() {
        let arm = TwoLink::new().with_friction(0.1, 0.2);
        let (q, qd, qdd) = ([0.3, -1.1], [0.5, -0.7], [2.0, -3.0]);
        let tau = inverse_dynamics(&arm, &q, &qd, &qdd).unwrap();
        let back = forward_dynamics(&arm, &q, &qd, tau.as_slice()).unwrap();
        assert!((back - DVector::from_column_slice(&qdd)).amax() < 1e-10);
    }

    #[test]
    fn two_link_holds_still_with_gravity_torque_at_rest() {
        let arm = TwoLink::new();
        let q = [0.7, 0.2];
        let g = inverse_dynamics(&arm, &q, &[0.0; 2], &[0.0; 2]).unwrap();
        let qdd = forward_dynamics(&arm, &q, &[0.0; 2], g.as_slice()).unwrap();
        assert!(qdd.amax() < 1e-12);
    }

    #[test]
    fn singular_mass_matrix_names_configuration() {
        let err = forward_dynamics(&Degenerate, &[0.1, 0.2], &[0.0; 2], &[0.0; 2]).unwrap_err();
        assert_eq!(
            err,
            DynamicsError::NotPositiveDefinite { q: vec![0.1, 0.2] }
        );
        assert!(err.to_string().contains("0.1"));
    }

    #[test]
    fn wrong_lengths_are_errors() {
        let arm = TwoLink::new();
        let err = forward_dynamics(&arm, &[0.0], &[0.0; 2], &[0.0; 2]).unwrap_err();
        assert!(matches!(err, DynamicsError::Dimension { what: "q", .. }));
        let err = inverse_dynamics(&arm, &[0.0; 2], &[0.0; 2], &[0.0; 3]).unwrap_err();
        assert!(matches!(err, DynamicsError::Dimension { what: "qdd", .. }));
    }

    #[test]
    fn faulty_plant_shape_is_an_error() {
        let err = inverse_dynamics(&Broken, &[0.0; 2], &[0.0; 2], &[0.0; 2]).unwrap_err();
        assert!(matches!(
            err,
            DynamicsError::PlantShape { what: "bias", .. }
        ));
    }
}
