//! A model read from a TOML description at run time, evaluated by the
//! numeric dynamics of [`crate::oracle`]: `--model path/to/arm.toml` works
//! without a rebuild (the compiled models stay the fast path, 10-100x
//! faster).

use std::path::Path;

use anyhow::{Context, Result};
use nalgebra::{DMatrix, DVector};

use crate::dynamics::{DimensionError, Dynamics, Placement};
use crate::oracle::{self, Model};

/// A description file's model. Its names live as long as the process (one
/// model per command), so it can stand behind [`Dynamics`]'s `'static`
/// strings.
pub struct Described {
    name: &'static str,
    text: &'static str,
    joint_names: &'static [&'static str],
    parameters: &'static [f64],
    parameter_names: &'static [&'static str],
    model: Model,
}

const INERTIAL_NAMES: [&str; 10] = [
    "m", "mx", "my", "mz", "ixx", "ixy", "iyy", "ixz", "iyz", "izz",
];
use codegen::EFFECT_NAMES;

impl Described {
    /// Reads and validates the description at `path` (named by its stem).
    pub fn load(path: &Path) -> Result<&'static Described> {
        crate::output::note_input(path);
        let text = crate::bounded::read_description(path)
            .with_context(|| format!("reading model description {}", path.display()))?;
        let stem = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let description = codegen::Description::parse(&text, &stem, path)?;
        let model = Model::from_description(&description);
        let leak = |s: String| -> &'static str { Box::leak(s.into_boxed_str()) };
        let joint_names: Vec<&'static str> = description
            .chain()
            .free_bodies()
            .map(|b| leak(b.joint.clone()))
            .collect();
        let names = (1..=model.bodies.len())
            .flat_map(|b| INERTIAL_NAMES.map(|p| format!("{p}{b}")))
            .chain((1..=model.bodies.len()).flat_map(|b| EFFECT_NAMES.map(|p| format!("{p}{b}"))))
            .map(leak)
            .collect::<Vec<_>>();
        let parameters = model.parameters().as_slice().to_vec();
        Ok(Box::leak(Box::new(Described {
            name: leak(path.display().to_string()),
            text: leak(text),
            joint_names: Box::leak(joint_names.into_boxed_slice()),
            parameters: Box::leak(parameters.into_boxed_slice()),
            parameter_names: Box::leak(names.into_boxed_slice()),
            model,
        })))
    }

    fn check(&self, argument: &'static str, values: &[f64]) -> Result<(), DimensionError> {
        if values.len() == self.model.dof() {
            Ok(())
        } else {
            Err(DimensionError {
                model: self.name,
                argument,
                expected: self.model.dof(),
                found: values.len(),
            })
        }
    }
}

impl Dynamics for Described {
    fn name(&self) -> &'static str {
        self.name
    }
    fn dof(&self) -> usize {
        self.model.dof()
    }
    fn joint_names(&self) -> &'static [&'static str] {
        self.joint_names
    }
    fn description(&self) -> &'static str {
        self.text
    }
    fn parameters(&self) -> &'static [f64] {
        self.parameters
    }
    fn parameter_names(&self) -> &'static [&'static str] {
        self.parameter_names
    }
    fn tau(&self, q: &[f64], qd: &[f64], qdd: &[f64]) -> Result<DVector<f64>, DimensionError> {
        self.check("q", q)?;
        self.check("qd", qd)?;
        self.check("qdd", qdd)?;
        Ok(oracle::rnea(&self.model, q, qd, qdd))
    }
    fn mass_matrix(&self, q: &[f64]) -> Result<DMatrix<f64>, DimensionError> {
        self.check("q", q)?;
        Ok(oracle::crba(&self.model, q))
    }
    fn gravity(&self, q: &[f64]) -> Result<DVector<f64>, DimensionError> {
        self.check("q", q)?;
        Ok(oracle::gravity(&self.model, q))
    }
    fn coriolis(&self, q: &[f64], qd: &[f64]) -> Result<DVector<f64>, DimensionError> {
        self.check("q", q)?;
        self.check("qd", qd)?;
        Ok(oracle::coriolis(&self.model, q, qd))
    }
    fn effects(&self, qd: &[f64]) -> Result<DVector<f64>, DimensionError> {
        self.check("qd", qd)?;
        let mut effects = DVector::zeros(qd.len());
        let zero = vec![0.0; qd.len()];
        for body in &self.model.bodies {
            let (d, m, _) = body.driver;
            let (_, v, _) = body.state(&zero, qd, &zero);
            effects[d] += m * oracle::effects_torque(&body.effects, v, 0.0);
        }
        Ok(effects)
    }
    fn regressor(
        &self,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
    ) -> Result<DMatrix<f64>, DimensionError> {
        self.check("q", q)?;
        self.check("qd", qd)?;
        self.check("qdd", qdd)?;
        Ok(oracle::regressor(&self.model, q, qd, qdd))
    }
    fn forward_dynamics(
        &self,
        q: &[f64],
        qd: &[f64],
        tau: &[f64],
        qdd: &mut [f64],
    ) -> Result<(), DimensionError> {
        self.check("q", q)?;
        self.check("qd", qd)?;
        self.check("tau", tau)?;
        self.check("qdd", qdd)?;
        match oracle::forward_dynamics(&self.model, q, qd, tau) {
            Some(solved) => qdd.copy_from_slice(solved.as_slice()),
            None => qdd.fill(f64::NAN),
        }
        Ok(())
    }
    fn tip_pose(&self, q: &[f64]) -> Result<Placement, DimensionError> {
        self.check("q", q)?;
        let (r, p) = oracle::placements(&self.model, q)[oracle::tip(&self.model)];
        Ok(Placement {
            rotation: std::array::from_fn(|i| std::array::from_fn(|j| r[(i, j)])),
            position: [p.x, p.y, p.z],
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_description_file_matches_its_compiled_model() {
        let compiled = crate::model("kinova_gen3_lite_3dof_plant").unwrap();
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../models/kinova_gen3_lite_3dof_plant.toml");
        let described = Described::load(&path).unwrap();
        let (q, qd, qdd) = ([0.3, -0.7, 1.1], [0.5, -0.2, 0.9], [1.0, 2.0, -3.0]);
        let a = compiled.tau(&q, &qd, &qdd).unwrap();
        let b = described.tau(&q, &qd, &qdd).unwrap();
        assert!((a - b).amax() < 1e-9);
        assert_eq!(described.joint_names(), compiled.joint_names());
        assert_eq!(described.parameter_names(), compiled.parameter_names());
        let (ya, yb) = (
            compiled.regressor(&q, &qd, &qdd).unwrap(),
            described.regressor(&q, &qd, &qdd).unwrap(),
        );
        assert!((ya - yb).amax() < 1e-9);
        assert!(described.tau(&q[..2], &qd, &qdd).is_err());
    }
}
