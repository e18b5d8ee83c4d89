//! The chain's dynamics as structured straight-line programs over named
//! constants: what the generated file's functions compute.
//!
//! Same physics as `lagrangian.rs`, organised by body instead of expanded:
//! - `tau`, `gravity`, `coriolis`: the Euler-Lagrange equations of a serial
//!   chain regrouped body by body, i.e. the recursive Newton-Euler form
//!   (velocities and accelerations outwards, wrenches inwards), all in body
//!   axes, with gravity as a base acceleration (`newton_euler.rs`);
//! - `mass_matrix`: M = sum_k J_k^T M_k J_k from each body's Jacobian (the
//!   kinetic energy's Hessian), the joint twists expressed in body axes;
//! - regressor: Y_ik = J_ik^T W_k with W_k the body's wrench per unit
//!   inertial parameter (`jacobian.rs`).
//!
//! Each step is traced on a hash-consed `Dag` whose leaves are the inputs and
//! the description's named constants (`constants.rs`): zero and unit
//! rotation entries vanish, any other number stays a name, so the programs'
//! shape does not depend on the values and an edit of one number changes
//! one line of the generated file.

mod composite;
mod constants;
mod factor;
mod jacobian;
mod kinematics;
mod newton_euler;
mod regroup;
mod sensitivity;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_motion;

pub use constants::{Definition, Group, SNAP, ripple_cycles, stribeck_velocity};
pub use sensitivity::{Direction, pairs};

use crate::program::{Dag, NodeId};
use crate::reduce::Chain;
use constants::{JointLeaves, Leaves};
use newton_euler::{JointState, Rotation};
use regroup::BodyParameters;

/// Program input positions; the layout of `lagrangian::inputs`:
/// per joint sin, cos, qd, qdd, sign(qd), q, the Stribeck shape
/// sign(qd) exp(-(qd/v_s)^2), and sin and cos of the ripple's angle.
pub const INPUTS_PER_JOINT: usize = 9;
const SIN: usize = 0;
const COS: usize = 1;
const QD: usize = 2;
const QDD: usize = 3;
const SIGN: usize = 4;
const Q: usize = 5;
const STRIBECK: usize = 6;
const RIPPLE_SIN: usize = 7;
const RIPPLE_COS: usize = 8;

type V3 = [NodeId; 3];

/// The traced programs of one chain (one shared DAG; roots row-major).
pub struct Traced {
    pub dag: Dag,
    /// The named numbers the generated file starts with.
    pub groups: Vec<Group>,
    /// M qdd + c + g + effects.
    pub tau: Vec<NodeId>,
    /// n x n, armature on the diagonal.
    pub mass_matrix: Vec<NodeId>,
    pub gravity: Vec<NodeId>,
    pub coriolis: Vec<NodeId>,
    /// viscous qd + coulomb sign(qd) + coulomb_asymmetry |sign(qd)| +
    /// stribeck sign(qd) exp(-(qd/v_s)^2) + offset per joint.
    pub effects: Vec<NodeId>,
    /// dof x 19 bodies: ten inertial columns per moving body, then nine
    /// effect columns per moving body.
    pub regressor: Vec<NodeId>,
    /// tau at qdd = 0: c + g + effects.
    pub bias: Vec<NodeId>,
    /// M = L D L^T: L below the diagonal, 1/D on it (`factor.rs`).
    pub mass_factor: Vec<NodeId>,
    /// d tau / d q and d tau / d qd, dof x dof.
    pub tau_by_q: Vec<NodeId>,
    pub tau_by_qd: Vec<NodeId>,
    /// The same derivatives as a two-lane program, one group per `pairs`
    /// entry (what the generated `tau_derivatives` runs).
    pub tau_lanes: crate::lanes::LaneProgram,
    pub pairs: Vec<[Direction; 2]>,
    /// Per moving body its frame in the base frame: rotation row-major,
    /// then position (12 each).
    pub link_poses: Vec<NodeId>,
    /// The tip body (the last degree of freedom's).
    pub tip: usize,
    /// The tip's Jacobian (6 x dof) and J-dot qd (6).
    pub tip_jacobian: Vec<NodeId>,
    pub tip_jacobian_dot_qd: Vec<NodeId>,
    /// The tool frame's link, pose (12) and Jacobian (6 x dof), when the
    /// description has one.
    pub tool: Option<(String, Vec<NodeId>, Vec<NodeId>)>,
}

/// Traces every function of `chain`.
///
/// Everything is traced per moving body, as if each had its own joint; a
/// body coupled to another joint (a mimic) takes that joint's position
/// times its multiplier plus its offset, and its rows are projected onto
/// the degrees of freedom (tau_d = sum over the bodies b it drives of
/// multiplier_b tau_b, M = G^T M_b G): the coupled system's equations.
pub fn trace(chain: &Chain) -> Traced {
    trace_with_tool(chain, None)
}

/// `trace`, with the tool frame's pose and Jacobian when there is one.
pub fn trace_with_tool(chain: &Chain, tool: Option<&crate::tool::ToolFrame>) -> Traced {
    let mut dag = Dag::default();
    let leaves = constants::leaves(&mut dag, chain);
    let mut t = Tracer {
        dag,
        chain,
        leaves,
        parameters: Vec::new(),
    };
    t.parameters = t.regrouped();
    let n = chain.bodies.len();
    let rotations: Vec<Rotation> = (0..n).map(|i| t.rotation(i)).collect();
    let zero = t.dag.constant(0.0);
    let gravity_off = [zero; 3];
    let base_acceleration = t.leaves.gravity.map(|g| t.dag.negate(g));
    let full: Vec<JointState> = (0..n)
        .map(|i| JointState {
            qd: t.input(i, QD),
            qdd: t.input(i, QDD),
        })
        .collect();
    let at_rest: Vec<JointState> = (0..n)
        .map(|_| JointState {
            qd: zero,
            qdd: zero,
        })
        .collect();
    let no_acceleration: Vec<JointState> = full
        .iter()
        .map(|s| JointState { qdd: zero, ..*s })
        .collect();

    let motions = t.forward(&rotations, &full, base_acceleration);
    // Each body's joint torque (rigid body, effects, position), then the
    // degrees of freedom's.
    let rigid = t.backward(&rotations, &motions);
    let tau = t.with_joint_effects(rigid, true);
    let (tau_by_q, tau_by_qd) = t.tau_derivatives(&tau);
    let pairs = sensitivity::pairs(chain.dof());
    let tau_lanes = t.tau_lanes(&tau, &pairs);
    let coasting = t.forward(&rotations, &no_acceleration, base_acceleration);
    let rigid = t.backward(&rotations, &coasting);
    let bias = t.with_joint_effects(rigid, false);
    let rest = t.forward(&rotations, &at_rest, base_acceleration);
    let at_rest: Vec<NodeId> = t
        .backward(&rotations, &rest)
        .into_iter()
        .enumerate()
        .map(|(b, g)| {
            let position = t.position_torque(b);
            t.dag.sum2(g, position)
        })
        .collect();
    let gravity = t.project(&at_rest, 1);
    let moving = t.forward(&rotations, &no_acceleration, gravity_off);
    let coriolis = t.backward(&rotations, &moving);
    let coriolis = t.project(&coriolis, 1);
    let effects: Vec<NodeId> = (0..n).map(|b| t.effects(b, false)).collect();
    let effects = t.project(&effects, 1);
    let twists = t.twists(&rotations);
    let mass_matrix = t.composite_mass_matrix(&rotations);
    let mass_matrix = t.project_both(&mass_matrix);
    let regressor = t.regressor(&twists, &motions);
    let regressor = t.project_regressor(&regressor);
    let mass_factor = factor::ldlt(&mut t.dag, &mass_matrix, chain.dof());
    let placements = t.placements(&rotations);
    let link_poses = placements.iter().flat_map(|p| p.entries()).collect();
    let tip = *chain.dof_bodies().last().expect("a chain moves");
    let tip_jacobian = t.jacobian(&placements, tip, placements[tip].position);
    let tip_jacobian_dot_qd = t.jacobian_drift(&placements, &moving, tip);
    let tool = tool.map(|frame| {
        let (group, rotation, translation) = constants::tool(&mut t.dag, frame);
        t.leaves.groups.push(group);
        let placement = t.attached(&placements[tip], &rotation, translation);
        let jacobian = t.jacobian(&placements, tip, placement.position);
        (frame.link.clone(), placement.entries(), jacobian)
    });
    Traced {
        dag: t.dag,
        groups: t.leaves.groups,
        tau,
        mass_matrix,
        gravity,
        coriolis,
        effects,
        regressor,
        bias,
        mass_factor,
        tau_by_q,
        tau_by_qd,
        tau_lanes,
        pairs,
        link_poses,
        tip,
        tip_jacobian,
        tip_jacobian_dot_qd,
        tool,
    }
}

/// Program inputs of a state of `chain` (q, qd, qdd per degree of
/// freedom): per degree of freedom the `INPUTS_PER_JOINT` inputs, then per
/// coupled body the sine and cosine of its angle.
pub fn program_inputs(chain: &Chain, q: &[f64], qd: &[f64], qdd: &[f64]) -> Vec<f64> {
    let dofs = chain.dof_bodies();
    let mut x: Vec<f64> = dofs
        .iter()
        .enumerate()
        .flat_map(|(d, &b)| {
            let e = &chain.bodies[b].effects;
            let (ripple_sin, ripple_cos) = (e.ripple_cycles * q[d]).sin_cos();
            [
                q[d].sin(),
                q[d].cos(),
                qd[d],
                qdd[d],
                crate::schema::sign(qd[d]),
                q[d],
                e.stribeck_shape(qd[d]),
                ripple_sin,
                ripple_cos,
            ]
        })
        .collect();
    for b in coupled_bodies(chain) {
        let (d, multiplier, offset) = chain.driver(b);
        let (s, c) = (multiplier * q[d] + offset).sin_cos();
        x.extend([s, c]);
    }
    x
}

/// The coupled bodies, base first.
pub fn coupled_bodies(chain: &Chain) -> Vec<usize> {
    (0..chain.bodies.len())
        .filter(|&b| chain.bodies[b].coupling.is_some())
        .collect()
}

struct Tracer<'a> {
    dag: Dag,
    chain: &'a Chain,
    leaves: Leaves,
    /// Per body the inertial parameters the dynamics use (regrouped).
    parameters: Vec<BodyParameters>,
}

impl Tracer<'_> {
    /// Input `which` of body `b`: its degree of freedom's, or for a
    /// coupled body its own angle's sine and cosine and the multiplied
    /// position, velocity and acceleration.
    fn input(&mut self, b: usize, which: usize) -> NodeId {
        let (d, _, _) = self.chain.driver(b);
        let own = self.dag.input(INPUTS_PER_JOINT * d + which);
        let Some(slot) = coupled_bodies(self.chain).iter().position(|&c| c == b) else {
            return own;
        };
        let dof = self.chain.dof();
        let [multiplier, offset] = self.joint(b).coupling;
        match which {
            SIN | COS => self
                .dag
                .input(INPUTS_PER_JOINT * dof + 2 * slot + which - SIN),
            Q => {
                let scaled = self.dag.product2(multiplier, own);
                self.dag.sum2(scaled, offset)
            }
            QD | QDD => self.dag.product2(multiplier, own),
            SIGN => {
                let (_, m, _) = self.chain.driver(b);
                let turn = self.dag.constant(crate::schema::sign(m));
                self.dag.product2(turn, own)
            }
            // Stribeck and ripple are refused on a coupled joint: their
            // coefficients are the literal 0 and this input is never used.
            _ => own,
        }
    }

    /// Each body's rigid-body torque plus its joint's effects (armature
    /// with `with_armature`) and torque of the position, projected onto the
    /// degrees of freedom.
    fn with_joint_effects(&mut self, rigid: Vec<NodeId>, with_armature: bool) -> Vec<NodeId> {
        let torques: Vec<NodeId> = rigid
            .into_iter()
            .enumerate()
            .map(|(b, rigid)| {
                let effects = self.effects(b, with_armature);
                let position = self.position_torque(b);
                let with_effects = self.dag.sum2(rigid, effects);
                self.dag.sum2(with_effects, position)
            })
            .collect();
        self.project(&torques, 1)
    }

    /// Rows per body projected onto the degrees of freedom, each row
    /// `width` entries wide: row d = sum over the bodies b it drives of
    /// multiplier_b row_b.
    fn project(&mut self, rows: &[NodeId], width: usize) -> Vec<NodeId> {
        if !self.chain.is_coupled() {
            return rows.to_vec();
        }
        let n = self.chain.dof();
        let zero = self.dag.constant(0.0);
        let mut out = vec![zero; n * width];
        for b in 0..self.chain.bodies.len() {
            let (d, _, _) = self.chain.driver(b);
            let scale = self.chain.bodies[b]
                .coupling
                .as_ref()
                .map(|_| self.joint(b).coupling[0]);
            for k in 0..width {
                let term = match scale {
                    Some(m) => self.dag.product2(m, rows[b * width + k]),
                    None => rows[b * width + k],
                };
                out[d * width + k] = self.dag.sum2(out[d * width + k], term);
            }
        }
        out
    }

    /// G^T M G for a body-by-body matrix M.
    fn project_both(&mut self, m: &[NodeId]) -> Vec<NodeId> {
        if !self.chain.is_coupled() {
            return m.to_vec();
        }
        let (nb, n) = (self.chain.bodies.len(), self.chain.dof());
        let rows = self.project(m, nb);
        let transposed: Vec<NodeId> = (0..nb * n).map(|k| rows[(k % n) * nb + k / n]).collect();
        let both = self.project(&transposed, n);
        (0..n * n).map(|k| both[(k % n) * n + k / n]).collect()
    }

    /// The regressor's rows projected onto the degrees of freedom (its
    /// columns stay per moving body: ten inertial and nine effects each).
    fn project_regressor(&mut self, y: &[NodeId]) -> Vec<NodeId> {
        let width = crate::schema::PARAMETERS_PER_JOINT * self.chain.bodies.len();
        self.project(y, width)
    }

    fn joint(&self, i: usize) -> &JointLeaves {
        &self.leaves.joints[i]
    }

    fn sum(&mut self, terms: &[NodeId]) -> NodeId {
        let zero = self.dag.constant(0.0);
        terms.iter().fold(zero, |acc, &t| self.dag.sum2(acc, t))
    }

    fn add(&mut self, a: V3, b: V3) -> V3 {
        [0, 1, 2].map(|k| self.dag.sum2(a[k], b[k]))
    }

    fn subtract(&mut self, a: V3, b: V3) -> V3 {
        [0, 1, 2].map(|k| {
            let minus = self.dag.negate(b[k]);
            self.dag.sum2(a[k], minus)
        })
    }

    fn scale(&mut self, v: V3, s: NodeId) -> V3 {
        v.map(|x| self.dag.product2(x, s))
    }

    fn dot(&mut self, a: V3, b: V3) -> NodeId {
        let products = [0, 1, 2].map(|k| self.dag.product2(a[k], b[k]));
        self.sum(&products)
    }

    fn cross(&mut self, a: V3, b: V3) -> V3 {
        [(1, 2), (2, 0), (0, 1)].map(|(j, k)| {
            let plus = self.dag.product2(a[j], b[k]);
            let minus = self.dag.product2(a[k], b[j]);
            let minus = self.dag.negate(minus);
            self.dag.sum2(plus, minus)
        })
    }

    fn mat_vec(&mut self, rows: &[V3; 3], v: V3) -> V3 {
        [0, 1, 2].map(|r| self.dot(rows[r], v))
    }

    /// M^T v for the rows of M.
    fn inverse_rotate(&mut self, rows: &[V3; 3], v: V3) -> V3 {
        let columns = [0, 1, 2].map(|c| [rows[0][c], rows[1][c], rows[2][c]]);
        self.mat_vec(&columns, v)
    }

    /// The rows of A B.
    fn mat_mul(&mut self, a: &[V3; 3], b: &[V3; 3]) -> [V3; 3] {
        let columns = [0, 1, 2].map(|c| [b[0][c], b[1][c], b[2][c]]);
        [0, 1, 2].map(|r| [0, 1, 2].map(|c| self.dot(a[r], columns[c])))
    }

    /// u v^T.
    fn outer(&mut self, u: V3, v: V3) -> [V3; 3] {
        [0, 1, 2].map(|r| [0, 1, 2].map(|c| self.dag.product2(u[r], v[c])))
    }

    /// The identity scaled by `s`, literal zeros off the diagonal.
    fn diagonal(&mut self, s: NodeId) -> [V3; 3] {
        let zero = self.dag.constant(0.0);
        [0, 1, 2].map(|r| [0, 1, 2].map(|c| if r == c { s } else { zero }))
    }

    fn mat_add(&mut self, a: &[V3; 3], b: &[V3; 3]) -> [V3; 3] {
        [0, 1, 2].map(|r| self.add(a[r], b[r]))
    }

    fn mat_subtract(&mut self, a: &[V3; 3], b: &[V3; 3]) -> [V3; 3] {
        [0, 1, 2].map(|r| self.subtract(a[r], b[r]))
    }

    fn mat_scale(&mut self, a: &[V3; 3], s: NodeId) -> [V3; 3] {
        [0, 1, 2].map(|r| self.scale(a[r], s))
    }
}
