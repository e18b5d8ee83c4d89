//! `sdnn-dynamics`: the object-safe trait behind which every compiled
//! model (crate `sdnn-models`) and every description read at run time
//! stands, and the macro that implements it over a generated file.
//!
//! Controllers that know their robot at compile time call the generated
//! functions directly (`sdnn::models::kinova_gen3_lite_3dof::tau(&q, &qd, &qdd)`,
//! fixed-size arrays, no allocation). Tools that pick a model at run time
//! (the CLI, the synthesizer, the diagnosis) go through [`Dynamics`], which
//! checks slice lengths once and returns an error instead of panicking.
//! A crate of its own so that the runtime does not depend on the compiled
//! models: a description edit recompiles only them and the binary.

pub use nalgebra;
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
        /// This model behind the `Dynamics` trait.
        pub struct Model;

        /// The model instance for the registry.
        pub static MODEL: Model = Model;

        impl $crate::Dynamics for Model {
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
                    "/../models/",
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
            ) -> Result<$crate::nalgebra::DVector<f64>, $crate::DimensionError> {
                use $crate::fixed;
                let out = tau(
                    fixed::<DOF>($name, "q", q)?,
                    fixed::<DOF>($name, "qd", qd)?,
                    fixed::<DOF>($name, "qdd", qdd)?,
                );
                Ok($crate::nalgebra::DVector::from_row_slice(&out))
            }
            fn mass_matrix(
                &self,
                q: &[f64],
            ) -> Result<$crate::nalgebra::DMatrix<f64>, $crate::DimensionError> {
                let m = mass_matrix($crate::fixed::<DOF>($name, "q", q)?);
                Ok($crate::nalgebra::DMatrix::from_fn(DOF, DOF, |r, c| m[r][c]))
            }
            fn gravity(
                &self,
                q: &[f64],
            ) -> Result<$crate::nalgebra::DVector<f64>, $crate::DimensionError> {
                let g = gravity($crate::fixed::<DOF>($name, "q", q)?);
                Ok($crate::nalgebra::DVector::from_row_slice(&g))
            }
            fn coriolis(
                &self,
                q: &[f64],
                qd: &[f64],
            ) -> Result<$crate::nalgebra::DVector<f64>, $crate::DimensionError> {
                use $crate::fixed;
                let c = coriolis(fixed::<DOF>($name, "q", q)?, fixed::<DOF>($name, "qd", qd)?);
                Ok($crate::nalgebra::DVector::from_row_slice(&c))
            }
            fn effects(
                &self,
                qd: &[f64],
            ) -> Result<$crate::nalgebra::DVector<f64>, $crate::DimensionError> {
                let e = effects($crate::fixed::<DOF>($name, "qd", qd)?);
                Ok($crate::nalgebra::DVector::from_row_slice(&e))
            }
            fn regressor(
                &self,
                q: &[f64],
                qd: &[f64],
                qdd: &[f64],
            ) -> Result<$crate::nalgebra::DMatrix<f64>, $crate::DimensionError> {
                use $crate::fixed;
                let y = regressor(
                    fixed::<DOF>($name, "q", q)?,
                    fixed::<DOF>($name, "qd", qd)?,
                    fixed::<DOF>($name, "qdd", qdd)?,
                );
                Ok($crate::nalgebra::DMatrix::from_fn(
                    DOF,
                    NUM_PARAMETERS,
                    |r, c| y[r][c],
                ))
            }
            fn forward_dynamics(
                &self,
                q: &[f64],
                qd: &[f64],
                tau: &[f64],
                qdd: &mut [f64],
            ) -> Result<(), $crate::DimensionError> {
                use $crate::{fixed, fixed_mut};
                *fixed_mut::<DOF>($name, "qdd", qdd)? = forward_dynamics(
                    fixed::<DOF>($name, "q", q)?,
                    fixed::<DOF>($name, "qd", qd)?,
                    fixed::<DOF>($name, "tau", tau)?,
                );
                Ok(())
            }
            fn tip_pose(&self, q: &[f64]) -> Result<$crate::Placement, $crate::DimensionError> {
                let pose = tip_pose($crate::fixed::<DOF>($name, "q", q)?);
                Ok($crate::Placement {
                    rotation: pose.rotation,
                    position: pose.position,
                })
            }
        }
    };
}
