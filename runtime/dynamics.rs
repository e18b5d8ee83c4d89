//! The compiled models behind one object-safe trait, selectable by name.
//!
//! Controllers that know their robot at compile time call the generated
//! functions directly (`sdnn::models::kinova_gen3_lite_3dof::tau(&q, &qd, &qdd)`,
//! fixed-size arrays, no allocation). Tools that pick a model at run time
//! (the CLI, the synthesizer, the diagnosis) go through [`Dynamics`], which
//! checks slice lengths once and returns an error instead of panicking.

use nalgebra::{DMatrix, DVector};

/// A slice had the wrong length for the model.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("model `{model}`: `{argument}` has {found} values, expected {expected}")]
pub struct DimensionError {
    pub model: &'static str,
    pub argument: &'static str,
    pub expected: usize,
    pub found: usize,
}

/// A model's dynamics, evaluated on slices.
pub trait Dynamics: Sync {
    /// The model name: its TOML file stem.
    fn name(&self) -> &'static str;
    /// Number of moving joints.
    fn dof(&self) -> usize;
    /// Names of the moving joints, base first.
    fn joint_names(&self) -> &'static [&'static str];
    /// The TOML description the model was generated from.
    fn description(&self) -> &'static str;
    /// Regressor parameters of the description (see `parameter_names`).
    fn parameters(&self) -> &'static [f64];
    fn parameter_names(&self) -> &'static [&'static str];
    /// tau = M(q) qdd + c(q, qd) + g(q) + effects(qd), N m.
    fn tau(&self, q: &[f64], qd: &[f64], qdd: &[f64]) -> Result<DVector<f64>, DimensionError>;
    /// M(q), armature included.
    fn mass_matrix(&self, q: &[f64]) -> Result<DMatrix<f64>, DimensionError>;
    /// g(q).
    fn gravity(&self, q: &[f64]) -> Result<DVector<f64>, DimensionError>;
    /// c(q, qd).
    fn coriolis(&self, q: &[f64], qd: &[f64]) -> Result<DVector<f64>, DimensionError>;
    /// viscous*qd + coulomb*sign(qd) + offset.
    fn effects(&self, qd: &[f64]) -> Result<DVector<f64>, DimensionError>;
    /// Y(q, qd, qdd) with tau = Y * parameters.
    fn regressor(&self, q: &[f64], qd: &[f64], qdd: &[f64])
    -> Result<DMatrix<f64>, DimensionError>;
    /// Forward dynamics qdd = M(q)^-1 (tau - c - g - effects), written into
    /// `qdd` (no allocation for a compiled model). A joint that moves no
    /// mass and has no armature makes M singular: non-finite values.
    fn forward_dynamics(
        &self,
        q: &[f64],
        qd: &[f64],
        tau: &[f64],
        qdd: &mut [f64],
    ) -> Result<(), DimensionError>;
    /// The tip frame (the last moving joint's link) in the base frame.
    fn tip_pose(&self, q: &[f64]) -> Result<Placement, DimensionError>;
}

/// A frame in the base frame: `rotation` takes its coordinates to the
/// base's, `position` is its origin (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    pub rotation: [[f64; 3]; 3],
    pub position: [f64; 3],
}

/// Checks an output slice's length like an input's.
pub fn fixed_mut<'a, const N: usize>(
    model: &'static str,
    argument: &'static str,
    values: &'a mut [f64],
) -> Result<&'a mut [f64; N], DimensionError> {
    let found = values.len();
    values.try_into().map_err(|_| DimensionError {
        model,
        argument,
        expected: N,
        found,
    })
}

/// Borrows a slice as a fixed-size array or says which argument is off.
pub fn fixed<'a, const N: usize>(
    model: &'static str,
    argument: &'static str,
    values: &'a [f64],
) -> Result<&'a [f64; N], DimensionError> {
    values.try_into().map_err(|_| DimensionError {
        model,
        argument,
        expected: N,
        found: values.len(),
    })
}

/// Implements [`Dynamics`] as `MODEL` for the generated functions in scope.
#[doc(hidden)]
#[macro_export]
macro_rules! compiled_model {
    ($name:literal) => {
        /// This model behind the [`Dynamics`](crate::dynamics::Dynamics) trait.
        pub struct Model;

        /// The model instance for the registry.
        pub static MODEL: Model = Model;

        impl $crate::dynamics::Dynamics for Model {
            fn name(&self) -> &'static str {
                $name
            }
            fn dof(&self) -> usize {
                DOF
            }
            fn joint_names(&self) -> &'static [&'static str] {
                &JOINT_NAMES
            }
            fn description(&self) -> &'static str {
                include_str!(concat!(
                    env!("CARGO_MANIFEST_DIR"),
                    "/models/",
                    $name,
                    ".toml"
                ))
            }
            fn parameters(&self) -> &'static [f64] {
                &PARAMETERS
            }
            fn parameter_names(&self) -> &'static [&'static str] {
                &PARAMETER_NAMES
            }
            fn tau(
                &self,
                q: &[f64],
                qd: &[f64],
                qdd: &[f64],
            ) -> Result<nalgebra::DVector<f64>, $crate::dynamics::DimensionError> {
                use $crate::dynamics::fixed;
                let out = tau(
                    fixed::<DOF>($name, "q", q)?,
                    fixed::<DOF>($name, "qd", qd)?,
                    fixed::<DOF>($name, "qdd", qdd)?,
                );
                Ok(nalgebra::DVector::from_row_slice(&out))
            }
            fn mass_matrix(
                &self,
                q: &[f64],
            ) -> Result<nalgebra::DMatrix<f64>, $crate::dynamics::DimensionError> {
                let m = mass_matrix($crate::dynamics::fixed::<DOF>($name, "q", q)?);
                Ok(nalgebra::DMatrix::from_fn(DOF, DOF, |r, c| m[r][c]))
            }
            fn gravity(
                &self,
                q: &[f64],
            ) -> Result<nalgebra::DVector<f64>, $crate::dynamics::DimensionError> {
                let g = gravity($crate::dynamics::fixed::<DOF>($name, "q", q)?);
                Ok(nalgebra::DVector::from_row_slice(&g))
            }
            fn coriolis(
                &self,
                q: &[f64],
                qd: &[f64],
            ) -> Result<nalgebra::DVector<f64>, $crate::dynamics::DimensionError> {
                use $crate::dynamics::fixed;
                let c = coriolis(fixed::<DOF>($name, "q", q)?, fixed::<DOF>($name, "qd", qd)?);
                Ok(nalgebra::DVector::from_row_slice(&c))
            }
            fn effects(
                &self,
                qd: &[f64],
            ) -> Result<nalgebra::DVector<f64>, $crate::dynamics::DimensionError> {
                let e = effects($crate::dynamics::fixed::<DOF>($name, "qd", qd)?);
                Ok(nalgebra::DVector::from_row_slice(&e))
            }
            fn regressor(
                &self,
                q: &[f64],
                qd: &[f64],
                qdd: &[f64],
            ) -> Result<nalgebra::DMatrix<f64>, $crate::dynamics::DimensionError> {
                use $crate::dynamics::fixed;
                let y = regressor(
                    fixed::<DOF>($name, "q", q)?,
                    fixed::<DOF>($name, "qd", qd)?,
                    fixed::<DOF>($name, "qdd", qdd)?,
                );
                Ok(nalgebra::DMatrix::from_fn(DOF, NUM_PARAMETERS, |r, c| {
                    y[r][c]
                }))
            }
            fn forward_dynamics(
                &self,
                q: &[f64],
                qd: &[f64],
                tau: &[f64],
                qdd: &mut [f64],
            ) -> Result<(), $crate::dynamics::DimensionError> {
                use $crate::dynamics::{fixed, fixed_mut};
                *fixed_mut::<DOF>($name, "qdd", qdd)? = forward_dynamics(
                    fixed::<DOF>($name, "q", q)?,
                    fixed::<DOF>($name, "qd", qd)?,
                    fixed::<DOF>($name, "tau", tau)?,
                );
                Ok(())
            }
            fn tip_pose(
                &self,
                q: &[f64],
            ) -> Result<$crate::dynamics::Placement, $crate::dynamics::DimensionError> {
                let pose = tip_pose($crate::dynamics::fixed::<DOF>($name, "q", q)?);
                Ok($crate::dynamics::Placement {
                    rotation: pose.rotation,
                    position: pose.position,
                })
            }
        }
    };
}

/// The compiled model with this name.
pub fn model(name: &str) -> Option<&'static dyn Dynamics> {
    crate::models::MODELS
        .iter()
        .copied()
        .find(|m| m.name() == name)
}

/// The parsed description of a compiled model (limits, effects, links).
pub fn parsed_description(
    model: &dyn Dynamics,
) -> Result<codegen::Description, codegen::DescriptionError> {
    let label = format!("models/{}.toml", model.name());
    codegen::Description::parse(
        model.description(),
        model.name(),
        std::path::Path::new(&label),
    )
}

/// Metres per radian at which a prismatic joint's motion compares with a
/// revolute joint's: a linear axis sensed and moved like a revolute joint's
/// point 0.1 m from its axis. Speed thresholds and sensor noise given in
/// rad and rad/s are scaled by it on prismatic joints.
pub const PRISMATIC_LEVER: f64 = 0.1;

/// Per joint 1 (revolute) or [`PRISMATIC_LEVER`] (prismatic); 1 for every
/// joint when the model's description cannot be read.
pub fn joint_levers(model: &dyn Dynamics) -> Vec<f64> {
    match parsed_description(model) {
        Ok(d) => d
            .chain()
            .free_bodies()
            .map(|b| match b.kind {
                codegen::JointKind::Prismatic => PRISMATIC_LEVER,
                _ => 1.0,
            })
            .collect(),
        Err(_) => vec![1.0; model.dof()],
    }
}

/// Names of every compiled model, sorted.
pub fn model_names() -> Vec<&'static str> {
    crate::models::MODELS.iter().map(|m| m.name()).collect()
}

/// Torques of a compiled model on a trajectory's (q, qd, qdd).
pub fn model_torques(
    model: &dyn Dynamics,
    traj: &crate::trajectory::Trajectory,
) -> anyhow::Result<DMatrix<f64>> {
    let qdd = traj.qdd().ok_or_else(|| {
        anyhow::anyhow!("the trajectory has no accelerations; preprocess it first")
    })?;
    let mut tau = DMatrix::zeros(traj.len(), model.dof());
    for r in 0..traj.len() {
        let row = |m: &DMatrix<f64>| m.row(r).iter().copied().collect::<Vec<f64>>();
        let t = model.tau(&row(traj.q()), &row(traj.qd()), &row(qdd))?;
        tau.set_row(r, &t.transpose());
    }
    Ok(tau)
}
