//! The regressor Y(q, qd, qdd), `Y * model.parameters() == rnea(q, qd, qdd)`:
//! one forward pass for the bodies' motions, then each body's ten unit
//! wrenches carried towards the base alone (a parameter moves only its
//! own body's wrench, so the other bodies' are zero and need no pass).

use nalgebra::{DMatrix, Matrix3, SMatrix, Vector3};

use super::{
    INERTIAL_PARAMETERS, JointKind, Model, Motion, coulomb_sign, frames, motions, stribeck_shape,
};

/// Regressor Y(q, qd, qdd) with Y * model.parameters() == rnea(q, qd, qdd)
/// (dim dof x 19 per moving body).
pub fn regressor(model: &Model, q: &[f64], qd: &[f64], qdd: &[f64]) -> DMatrix<f64> {
    let (n, bodies) = (model.dof(), model.bodies.len());
    let mut y = DMatrix::zeros(n, model.parameter_count());
    let frames = frames(model, q, qd, qdd);
    for (b, &motion) in motions(model, model.gravity, &frames, (q, qd, qdd))
        .iter()
        .enumerate()
    {
        let columns = b * INERTIAL_PARAMETERS..(b + 1) * INERTIAL_PARAMETERS;
        towards_base(model, &frames, b, unit_wrenches(motion), |d, row| {
            let mut y = y.view_mut((d, columns.start), (1, columns.len()));
            y += row;
        });
    }
    // Each joint's effect columns at its own state, on its degree of
    // freedom's row times the multiplier.
    for (b, body) in model.bodies.iter().enumerate() {
        let (d, m, _) = body.driver;
        let e = &body.effects;
        let (q, qd, qdd) = body.state(q, qd, qdd);
        let sign = coulomb_sign(qd);
        let angle = e.ripple_cycles * q;
        let columns = [
            qdd,
            qd,
            sign,
            1.0,
            sign * sign,
            q - e.spring_rest,
            stribeck_shape(e, qd),
            angle.sin(),
            angle.cos(),
        ];
        let base = bodies * INERTIAL_PARAMETERS + b * super::EFFECT_PARAMETERS;
        for (k, column) in columns.into_iter().enumerate() {
            y[(d, base + k)] = m * column;
        }
    }
    y
}

/// The force and the moment about its origin of a body moving with
/// `motion`, one column per unit standard parameter ([`super::wrench`] with
/// that parameter 1 and the others 0, term by term). Only the mass and the
/// first moment move a force: the inertia's six columns have none.
fn unit_wrenches((w, wd, vd): Motion) -> Wrenches {
    let mut forces = Forces::zeros();
    let mut moments = Moments::zeros();
    forces.set_column(0, &vd);
    for (i, e) in [Vector3::x(), Vector3::y(), Vector3::z()]
        .iter()
        .enumerate()
    {
        forces.set_column(1 + i, &(wd.cross(e) + w.cross(&w.cross(e))));
        moments.set_column(1 + i, &e.cross(&vd));
    }
    // The inertia's six entries in `unpack`'s order (xx, xy, yy, xz, yz, zz).
    let pairs = [(0, 0), (0, 1), (1, 1), (0, 2), (1, 2), (2, 2)];
    for (k, &(a, b)) in pairs.iter().enumerate() {
        let mut inertia = Matrix3::zeros();
        inertia[(a, b)] = 1.0;
        inertia[(b, a)] = 1.0;
        moments.set_column(4 + k, &(inertia * wd + w.cross(&(inertia * w))));
    }
    Wrenches { forces, moments }
}

/// The backward pass of the RNEA for body `b`'s wrenches alone: their
/// joint torques on each joint from `b` to the base, given to `add` as
/// (degree of freedom, one torque per parameter), in the order the full
/// pass adds them.
fn towards_base(
    model: &Model,
    frames: &[(Matrix3<f64>, Vector3<f64>)],
    b: usize,
    Wrenches {
        mut forces,
        mut moments,
    }: Wrenches,
    mut add: impl FnMut(usize, RowTorques),
) {
    let mut i = b;
    loop {
        let body = &model.bodies[i];
        let (d, multiplier, _) = body.driver;
        let axis = body.axis.transpose() * multiplier;
        let torques = match body.kind {
            JointKind::Prismatic => {
                let mut row = RowTorques::zeros();
                row.fixed_columns_mut::<FORCE_COLUMNS>(0)
                    .copy_from(&(axis * forces));
                row
            }
            _ => axis * moments,
        };
        add(d, torques);
        let Some(parent) = body.parent else {
            return;
        };
        let (r, p) = frames[i];
        forces = r * forces;
        moments = r * moments;
        let mut first = moments.fixed_columns_mut::<FORCE_COLUMNS>(0);
        first += p.cross_matrix() * forces;
        i = parent;
    }
}

/// The parameters that move a force: the mass and the first moment.
const FORCE_COLUMNS: usize = 4;
type Forces = SMatrix<f64, 3, FORCE_COLUMNS>;
type Moments = SMatrix<f64, 3, INERTIAL_PARAMETERS>;

/// One body's unit-parameter wrenches: forces (of the first
/// [`FORCE_COLUMNS`] parameters; the others' are zero) and moments about
/// the body origin, a column per standard parameter.
struct Wrenches {
    forces: Forces,
    moments: Moments,
}

/// A joint's torque of each parameter.
type RowTorques = SMatrix<f64, 1, INERTIAL_PARAMETERS>;

#[cfg(test)]
mod tests {
    use super::super::{Description, rigid_body_torque};
    use super::*;

    fn model(name: &str) -> Model {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../models")
            .join(format!("{name}.toml"));
        let source = std::fs::read_to_string(&path).unwrap();
        Model::from_description(&Description::parse(&source, name, &path).unwrap())
    }

    /// Each inertial column is the full RNEA with that one parameter set
    /// to 1 and every other zero: on a serial arm, one with a prismatic
    /// joint, and a gripper whose fingers branch and mimic a joint.
    #[test]
    fn each_inertial_column_is_the_rnea_of_its_unit_parameter() {
        for name in ["panda", "lift_arm", "kinova_gen3_lite_finger"] {
            let model = model(name);
            let (n, bodies) = (model.dof(), model.bodies.len());
            for s in 0..20 {
                let wave = |k: usize, scale: f64| -> Vec<f64> {
                    (0..n)
                        .map(|j| ((s * 11 + j * 5 + k) as f64 * 0.61).sin() * scale)
                        .collect()
                };
                let (q, qd, qdd) = (wave(0, 1.5), wave(1, 2.0), wave(2, 4.0));
                let y = regressor(&model, &q, &qd, &qdd);
                for b in 0..bodies {
                    for k in 0..INERTIAL_PARAMETERS {
                        let mut params = vec![[0.0; INERTIAL_PARAMETERS]; bodies];
                        params[b][k] = 1.0;
                        let full = rigid_body_torque(&model, &params, model.gravity, &q, &qd, &qdd);
                        let column = y.column(b * INERTIAL_PARAMETERS + k);
                        let scale = 1.0 + full.amax();
                        assert!(
                            (column - &full).amax() <= 1e-14 * scale,
                            "{name}, body {b}, parameter {k}: {column} vs {full}"
                        );
                    }
                }
            }
        }
    }
}
