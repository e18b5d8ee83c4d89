//! The compiled models by name, and what the runtime derives from a model
//! (its parsed description, its joints' levers, torques on a recording).
//! The trait and the macro live in `sdnn-dynamics`; the compiled models in
//! `sdnn-models`, which the runtime does not depend on: the binary installs
//! them at start ([`install`]), so a description edit recompiles only the
//! models and the binary.

use std::sync::OnceLock;

use nalgebra::DMatrix;

pub use sdnn_dynamics::{DimensionError, Dynamics, Placement, fixed, fixed_mut};

/// The compiled models, installed by the binary (or a library user) once.
static COMPILED: OnceLock<&'static [&'static dyn Dynamics]> = OnceLock::new();

/// Makes `models` the compiled models [`model`] and [`model_names`] find
/// (the `sdnn` binary passes `sdnn_models::MODELS`). Later calls keep the
/// first set.
pub fn install(models: &'static [&'static dyn Dynamics]) {
    let _ = COMPILED.set(models);
}

/// The installed compiled models (none before [`install`]); the runtime's
/// own unit tests see the `sdnn-models` crate's directly.
pub fn compiled() -> &'static [&'static dyn Dynamics] {
    #[cfg(test)]
    if COMPILED.get().is_none() {
        install(sdnn_models::MODELS);
    }
    COMPILED.get().copied().unwrap_or(&[])
}

/// The compiled model with this name.
pub fn model(name: &str) -> Option<&'static dyn Dynamics> {
    compiled().iter().copied().find(|m| m.name() == name)
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
    compiled().iter().map(|m| m.name()).collect()
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
