//! Independent numeric dynamics: recursive Newton-Euler on the parsed and
//! reduced description, never on generated code. It is the reference the
//! generated functions are tested against, and a fallback for any model.
//!
//! The model is constant; every algorithm is a free function
//! `algorithm(&model, args..)` returning its result (Pinocchio's layout).
//! Forces are taken about each body frame's origin, with the ten standard
//! inertial parameters (m, m*c, inertia about the origin), so the same pass
//! computes torques and, with unit parameters, the regressor.

use codegen::{Chain, Description, JointEffects, JointKind};
use nalgebra::{DMatrix, DVector, Matrix3, Rotation3, Unit, Vector3};

mod regressor;
pub use regressor::regressor;

/// Number of standard inertial parameters per body.
pub const INERTIAL_PARAMETERS: usize = 10;
/// Number of joint-effect parameters per joint: armature, viscous, coulomb,
/// offset, coulomb_asymmetry, spring, stribeck, ripple_sin, ripple_cos
/// (`JointEffects::parameters`).
pub const EFFECT_PARAMETERS: usize = codegen::EFFECTS_PER_JOINT;

/// A serial chain ready for numeric dynamics.
#[derive(Debug, Clone)]
pub struct Model {
    pub name: String,
    pub gravity: Vector3<f64>,
    pub bodies: Vec<OracleBody>,
}

/// One moving body in origin-referenced standard parameters.
#[derive(Debug, Clone)]
pub struct OracleBody {
    pub rotation: Matrix3<f64>,
    pub translation: Vector3<f64>,
    /// Revolute (turns about `axis`) or prismatic (slides along it).
    pub kind: JointKind,
    pub axis: Unit<Vector3<f64>>,
    /// m, m*c, inertia about the body origin (Pinocchio order).
    pub parameters: [f64; INERTIAL_PARAMETERS],
    pub effects: JointEffects,
    /// The degree of freedom that moves this body's joint, and its
    /// multiplier and offset (1 and 0 unless the joint is a mimic).
    pub driver: (usize, f64, f64),
    /// Set for a mimic joint: no degree of freedom of its own.
    pub coupled: bool,
    /// The moving body it hangs from (smaller index); `None` for the base.
    pub parent: Option<usize>,
}

impl Model {
    /// Builds the model from a validated description.
    pub fn from_description(description: &Description) -> Model {
        Model::from_chain(&description.name, description.chain())
    }

    pub fn from_chain(name: &str, chain: &Chain) -> Model {
        let bodies = chain
            .bodies
            .iter()
            .enumerate()
            .map(|(k, b)| OracleBody {
                rotation: b.rotation,
                translation: b.translation,
                kind: b.kind,
                axis: Unit::new_normalize(b.axis),
                parameters: b.inertial.standard_parameters(),
                effects: b.effects,
                driver: chain.driver(k),
                coupled: b.coupling.is_some(),
                parent: b.parent,
            })
            .collect();
        Model {
            name: name.to_string(),
            gravity: chain.gravity,
            bodies,
        }
    }

    /// Degrees of freedom (dim q): the bodies not coupled to another's.
    pub fn dof(&self) -> usize {
        self.free().count()
    }

    /// The bodies of the degrees of freedom, base first.
    pub fn free(&self) -> impl Iterator<Item = &OracleBody> {
        self.bodies.iter().filter(|b| !b.is_coupled())
    }

    /// All parameters in the generated regressor's order: per body the ten
    /// inertial parameters, then per degree of freedom its effects
    /// ([`JointEffects::parameters`]).
    pub fn parameters(&self) -> DVector<f64> {
        let inertial = self.bodies.iter().flat_map(|b| b.parameters);
        let effects = self.bodies.iter().flat_map(|b| b.effects.parameters());
        DVector::from_iterator(self.parameter_count(), inertial.chain(effects))
    }

    /// 19 per moving body (per degree of freedom without mimic joints).
    pub fn parameter_count(&self) -> usize {
        self.bodies.len() * (INERTIAL_PARAMETERS + EFFECT_PARAMETERS)
    }
}

/// Coulomb friction direction: sign(qd) with sign(0) = 0, as the generated code.
pub fn coulomb_sign(qd: f64) -> f64 {
    if qd > 0.0 {
        1.0
    } else if qd < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// Joint torques tau = M(q) qdd + c(q, qd) + g(q) + effects (dim model.dof()).
pub fn rnea(model: &Model, q: &[f64], qd: &[f64], qdd: &[f64]) -> DVector<f64> {
    let params: Vec<[f64; INERTIAL_PARAMETERS]> =
        model.bodies.iter().map(|b| b.parameters).collect();
    let mut tau = rigid_body_torque(model, &params, model.gravity, q, qd, qdd);
    for body in &model.bodies {
        let (d, m, _) = body.driver;
        let (q, qd, qdd) = body.state(q, qd, qdd);
        tau[d] += m * (effects_torque(&body.effects, qd, qdd) + position_torque(&body.effects, q));
    }
    tau
}

/// Joint-effect torque of one joint, its torque of the position aside (see
/// [`position_torque`]).
pub fn effects_torque(e: &JointEffects, qd: f64, qdd: f64) -> f64 {
    let sign = coulomb_sign(qd);
    e.armature * qdd
        + e.viscous * qd
        + e.coulomb * sign
        + e.coulomb_asymmetry * sign * sign
        + e.stribeck * stribeck_shape(e, qd)
        + e.offset
}

/// sign(qd) exp(-(qd/v_s)^2), 0 without a Stribeck velocity.
fn stribeck_shape(e: &JointEffects, qd: f64) -> f64 {
    if e.stribeck_velocity > 0.0 {
        coulomb_sign(qd) * (-(qd / e.stribeck_velocity).powi(2)).exp()
    } else {
        0.0
    }
}

/// A joint's torque of its position alone (spring and ripple), part of
/// [`gravity`].
pub fn position_torque(e: &JointEffects, q: f64) -> f64 {
    let angle = e.ripple_cycles * q;
    e.spring * (q - e.spring_rest) + e.ripple_sin * angle.sin() + e.ripple_cos * angle.cos()
}

/// Joint-space inertia matrix M(q), armature included, column by column
/// from RNEA with zero velocity and gravity.
pub fn crba(model: &Model, q: &[f64]) -> DMatrix<f64> {
    let n = model.dof();
    let params: Vec<_> = model.bodies.iter().map(|b| b.parameters).collect();
    let zero = vec![0.0; n];
    let mut m = DMatrix::zeros(n, n);
    for j in 0..n {
        let mut unit = vec![0.0; n];
        unit[j] = 1.0;
        let column = rigid_body_torque(model, &params, Vector3::zeros(), q, &zero, &unit);
        m.set_column(j, &column);
    }
    for body in &model.bodies {
        let (d, multiplier, _) = body.driver;
        m[(d, d)] += multiplier * multiplier * body.effects.armature;
    }
    m
}

/// Torque of the position g(q): the rigid-body torque at rest plus the
/// joint springs and ripples, without the other effects.
pub fn gravity(model: &Model, q: &[f64]) -> DVector<f64> {
    let params: Vec<_> = model.bodies.iter().map(|b| b.parameters).collect();
    let zero = vec![0.0; model.dof()];
    let mut g = rigid_body_torque(model, &params, model.gravity, q, &zero, &zero);
    for body in &model.bodies {
        let (d, m, _) = body.driver;
        let (q, _, _) = body.state(q, &zero, &zero);
        g[d] += m * position_torque(&body.effects, q);
    }
    g
}

/// [`gravity`] of `model` with its gravity vector replaced by each of
/// `directions` in turn (the same numbers as `gravity` of each such
/// model, but for the sign of an exact zero), the bodies' frames computed
/// once for all of them and the directions carried through one recursion
/// side by side (each direction's operations are its own, in the same
/// order).
pub fn gravity_along<const K: usize>(
    model: &Model,
    q: &[f64],
    directions: &[Vector3<f64>; K],
) -> [DVector<f64>; K] {
    let zero = vec![0.0; model.dof()];
    let frames = frames(model, q, &zero, &zero);
    let mut g = torques_at_rest(model, directions, &frames);
    for body in &model.bodies {
        let (d, m, _) = body.driver;
        let (q, _, _) = body.state(q, &zero, &zero);
        let position = m * position_torque(&body.effects, q);
        for g in &mut g {
            g[d] += position;
        }
    }
    g
}

/// Coriolis and centrifugal vector c(q, qd), without gravity or effects.
pub fn coriolis(model: &Model, q: &[f64], qd: &[f64]) -> DVector<f64> {
    let params: Vec<_> = model.bodies.iter().map(|b| b.parameters).collect();
    let zero = vec![0.0; model.dof()];
    rigid_body_torque(model, &params, Vector3::zeros(), q, qd, &zero)
}

/// Kinetic energy 0.5 qd^T M(q) qd of the rigid bodies (no armature).
pub fn kinetic_energy(model: &Model, q: &[f64], qd: &[f64]) -> f64 {
    let mut m = crba(model, q);
    for body in &model.bodies {
        let (d, multiplier, _) = body.driver;
        m[(d, d)] -= multiplier * multiplier * body.effects.armature;
    }
    let v = DVector::from_column_slice(qd);
    0.5 * v.dot(&(m * &v))
}

/// RNEA about body origins with given per-body standard parameters.
fn rigid_body_torque(
    model: &Model,
    params: &[[f64; INERTIAL_PARAMETERS]],
    gravity: Vector3<f64>,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
) -> DVector<f64> {
    let frames = frames(model, q, qd, qdd);
    torque_in_frames(model, params, gravity, &frames, (q, qd, qdd))
}

/// Every body's frame in its parent's at the state (rotation, origin).
fn frames(model: &Model, q: &[f64], qd: &[f64], qdd: &[f64]) -> Vec<(Matrix3<f64>, Vector3<f64>)> {
    model
        .bodies
        .iter()
        .map(|body| body.placement(body.state(q, qd, qdd).0))
        .collect()
}

/// [`rigid_body_torque`] with the bodies' `frames` given.
fn torque_in_frames(
    model: &Model,
    params: &[[f64; INERTIAL_PARAMETERS]],
    gravity: Vector3<f64>,
    frames: &[(Matrix3<f64>, Vector3<f64>)],
    state: (&[f64], &[f64], &[f64]),
) -> DVector<f64> {
    let motions = motions(model, gravity, frames, state);
    let (forces, moments) = motions
        .iter()
        .zip(params)
        .map(|(&motion, p)| wrench(p, motion))
        .unzip();
    joint_torques(model, frames, forces, moments)
}

/// A body's angular velocity, angular acceleration and its origin's linear
/// acceleration (gravity's included, as the base accelerating upwards), in
/// its own frame.
type Motion = (Vector3<f64>, Vector3<f64>, Vector3<f64>);

/// The forward pass of the RNEA: every body's [`Motion`] at the state.
fn motions(
    model: &Model,
    gravity: Vector3<f64>,
    frames: &[(Matrix3<f64>, Vector3<f64>)],
    (q, qd, qdd): (&[f64], &[f64], &[f64]),
) -> Vec<Motion> {
    let base = (Vector3::zeros(), Vector3::zeros(), -gravity);
    let mut motions: Vec<Motion> = Vec::with_capacity(model.bodies.len());
    for (i, body) in model.bodies.iter().enumerate() {
        let (mut w, mut wd, mut vd) = body.parent.map_or(base, |p| motions[p]);
        let a = body.axis.into_inner();
        let (_, qd, qdd) = body.state(q, qd, qdd);
        let (r, p) = frames[i];
        let rt = r.transpose();
        vd = rt * (vd + wd.cross(&p) + w.cross(&w.cross(&p)));
        let w_parent = rt * w;
        wd = rt * wd;
        if body.kind == JointKind::Prismatic {
            w = w_parent;
            vd += a * qdd + 2.0 * w_parent.cross(&a) * qd;
        } else {
            w = w_parent + a * qd;
            wd += a * qdd + w_parent.cross(&a) * qd;
        }
        motions.push((w, wd, vd));
    }
    motions
}

/// The force and the moment about its origin (in its frame) that move a
/// body of standard parameters `p` with `motion`: linear in `p`.
fn wrench(p: &[f64; INERTIAL_PARAMETERS], (w, wd, vd): Motion) -> (Vector3<f64>, Vector3<f64>) {
    let (m, h, inertia) = unpack(p);
    (
        m * vd + wd.cross(&h) + w.cross(&w.cross(&h)),
        inertia * wd + w.cross(&(inertia * w)) + h.cross(&vd),
    )
}

/// [`torque_in_frames`] at rest (zero velocities and accelerations) for
/// each of the gravity vectors `directions`, where every term of the
/// bodies' rates of turn is an exact zero: without them, the same numbers
/// but for the sign of a result that is exactly zero. The directions go
/// through the recursion side by side, each with its own operations in
/// [`joint_torques`]' order: one set of buffers for all of them.
fn torques_at_rest<const K: usize>(
    model: &Model,
    directions: &[Vector3<f64>; K],
    frames: &[(Matrix3<f64>, Vector3<f64>)],
) -> [DVector<f64>; K] {
    let n = model.bodies.len();
    let mut forces: Vec<[Vector3<f64>; K]> = Vec::with_capacity(n);
    let mut moments: Vec<[Vector3<f64>; K]> = Vec::with_capacity(n);
    // Base: accelerating upwards to emulate gravity.
    let mut accelerations: Vec<[Vector3<f64>; K]> = Vec::with_capacity(n);
    for (i, body) in model.bodies.iter().enumerate() {
        let rt = frames[i].0.transpose();
        let vd: [Vector3<f64>; K] = std::array::from_fn(|k| {
            rt * body.parent.map_or(-directions[k], |p| accelerations[p][k])
        });
        let (m, h, _) = unpack(&body.parameters);
        forces.push(vd.map(|vd| m * vd));
        moments.push(vd.map(|vd| h.cross(&vd)));
        accelerations.push(vd);
    }
    let mut tau = std::array::from_fn(|_| DVector::zeros(model.dof()));
    for i in (0..n).rev() {
        let body = &model.bodies[i];
        for k in 0..K {
            if let Some(parent) = body.parent {
                let (r, p) = frames[i];
                let force = r * forces[i][k];
                let moment = r * moments[i][k] + p.cross(&force);
                forces[parent][k] += force;
                moments[parent][k] += moment;
            }
            let along = match body.kind {
                JointKind::Prismatic => forces[i][k],
                _ => moments[i][k],
            };
            let (d, multiplier, _) = body.driver;
            tau[k][d] += multiplier * body.axis.dot(&along);
        }
    }
    tau
}

/// The backward pass of the RNEA: each body's force and moment about its
/// origin (in its frame) gathered towards the base, projected on its axis.
fn joint_torques(
    model: &Model,
    frames: &[(Matrix3<f64>, Vector3<f64>)],
    mut forces: Vec<Vector3<f64>>,
    mut moments: Vec<Vector3<f64>>,
) -> DVector<f64> {
    let n = model.bodies.len();
    let mut tau = DVector::zeros(model.dof());
    for i in (0..n).rev() {
        let body = &model.bodies[i];
        if let Some(parent) = body.parent {
            let (r, p) = frames[i];
            let force = r * forces[i];
            let moment = r * moments[i] + p.cross(&force);
            forces[parent] += force;
            moments[parent] += moment;
        }
        let along = match body.kind {
            JointKind::Prismatic => forces[i],
            _ => moments[i],
        };
        let (d, multiplier, _) = body.driver;
        tau[d] += multiplier * body.axis.dot(&along);
    }
    tau
}

/// Every moving body's frame in the base frame (rotation, origin).
pub fn placements(model: &Model, q: &[f64]) -> Vec<(Matrix3<f64>, Vector3<f64>)> {
    let zero = vec![0.0; q.len()];
    let mut out: Vec<(Matrix3<f64>, Vector3<f64>)> = Vec::with_capacity(model.bodies.len());
    for body in &model.bodies {
        let (x, _, _) = body.state(q, &zero, &zero);
        let (r, p) = body.placement(x);
        let (r0, p0) = body
            .parent
            .map_or((Matrix3::identity(), Vector3::zeros()), |k| out[k]);
        out.push((r0 * r, p0 + r0 * p));
    }
    out
}

/// The tip body: the last degree of freedom's (the generated `TIP_LINK`).
pub fn tip(model: &Model) -> usize {
    model
        .bodies
        .iter()
        .rposition(|b| !b.coupled)
        .unwrap_or(model.bodies.len().saturating_sub(1))
}

/// qdd = M^-1 (tau - bias) by Cholesky; `None` when M is not positive
/// definite (a joint that moves no mass and has no armature).
pub fn forward_dynamics(model: &Model, q: &[f64], qd: &[f64], tau: &[f64]) -> Option<DVector<f64>> {
    let bias = rnea(model, q, qd, &vec![0.0; q.len()]);
    let rhs = DVector::from_column_slice(tau) - bias;
    crba(model, q).cholesky().map(|c| c.solve(&rhs))
}

impl OracleBody {
    /// The body's joint position, velocity and acceleration from the
    /// degrees of freedom's.
    pub fn state(&self, q: &[f64], qd: &[f64], qdd: &[f64]) -> (f64, f64, f64) {
        let (d, m, offset) = self.driver;
        (m * q[d] + offset, m * qd[d], m * qdd[d])
    }

    /// Whether the joint follows another one's degree of freedom.
    pub fn is_coupled(&self) -> bool {
        self.coupled
    }

    /// The body frame in the previous one at joint position q: rotation
    /// and origin.
    pub fn placement(&self, q: f64) -> (Matrix3<f64>, Vector3<f64>) {
        match self.kind {
            JointKind::Prismatic => (
                self.rotation,
                self.translation + self.rotation * self.axis.into_inner() * q,
            ),
            _ => (
                self.rotation * Rotation3::from_axis_angle(&self.axis, q).into_inner(),
                self.translation,
            ),
        }
    }
}

fn unpack(p: &[f64; INERTIAL_PARAMETERS]) -> (f64, Vector3<f64>, Matrix3<f64>) {
    let h = Vector3::new(p[1], p[2], p[3]);
    let inertia = Matrix3::new(p[4], p[5], p[7], p[5], p[6], p[8], p[7], p[8], p[9]);
    (p[0], h, inertia)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pendulum() -> Model {
        let source = r#"
            [[links]]
            name = "base"
            [[links]]
            name = "rod"
            mass = 2.0
            com = [0.5, 0.0, 0.0]
            inertia = { ixx = 0.001, iyy = 0.05, izz = 0.05 }
            [[joints]]
            name = "pivot"
            type = "revolute"
            parent = "base"
            child = "rod"
            axis = [0.0, -1.0, 0.0]
            effects = { viscous = 0.3, coulomb = 0.2, armature = 0.01, offset = 0.05 }
        "#;
        let d = Description::parse(source, "pendulum", std::path::Path::new("p.toml")).unwrap();
        Model::from_description(&d)
    }

    /// A rod in the x-z plane turning about -y: tau = (I + m l^2 + a) qdd
    /// + m g l cos(q) + effects.
    #[test]
    fn single_pendulum_matches_closed_form() {
        let model = pendulum();
        for &(q, qd, qdd) in &[(0.3, 1.2, -0.5), (-2.0, -0.4, 3.0), (1.0, 0.0, 0.0)] {
            let tau = rnea(&model, &[q], &[qd], &[qdd])[0];
            let inertia = 0.05 + 2.0 * 0.25 + 0.01;
            let expected = inertia * qdd
                + 2.0 * 9.81 * 0.5 * f64::cos(q)
                + 0.3 * qd
                + 0.2 * coulomb_sign(qd)
                + 0.05;
            assert!((tau - expected).abs() < 1e-12, "{tau} vs {expected}");
        }
    }

    #[test]
    fn regressor_times_parameters_is_rnea() {
        let model = pendulum();
        let (q, qd, qdd) = ([0.4], [-0.7], [2.0]);
        let y = regressor(&model, &q, &qd, &qdd);
        let tau = rnea(&model, &q, &qd, &qdd);
        assert!((y * model.parameters() - tau).norm() < 1e-12);
    }

    #[test]
    fn gravity_along_directions_is_gravity_of_each_model() {
        let source = std::fs::read_to_string(
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../models/panda.toml"),
        )
        .unwrap();
        let d = Description::parse(&source, "panda", std::path::Path::new("panda.toml")).unwrap();
        let model = Model::from_description(&d);
        let directions = [Vector3::x(), -Vector3::y(), Vector3::new(0.3, -0.2, -0.93)];
        for k in 0..50 {
            let q: Vec<f64> = (0..model.dof())
                .map(|j| ((k * 7 + j * 3) as f64 * 0.37).sin() * 2.5)
                .collect();
            let along = gravity_along(&model, &q, &directions);
            for (g, &direction) in along.iter().zip(&directions) {
                let alone = Model {
                    gravity: direction,
                    ..model.clone()
                };
                // Equal as numbers (an exact zero may differ in sign).
                assert_eq!(g, &gravity(&alone, &q), "q = {q:?}");
            }
        }
    }

    #[test]
    fn coulomb_sign_of_zero_is_zero() {
        assert_eq!(coulomb_sign(0.0), 0.0);
        assert_eq!(coulomb_sign(-0.0), 0.0);
        assert_eq!(coulomb_sign(1e-300), 1.0);
    }
}
