//! tau, gravity and Coriolis by the recursive Newton-Euler form: joint
//! rotations, motions outwards from the base, wrenches inwards from the tip.
//! A revolute joint turns its body about the axis; a prismatic joint keeps
//! the joint frame's orientation and moves the body's origin along the
//! axis by q, and takes the force's axis component instead of the moment's.

use super::{COS, Q, QD, QDD, RIPPLE_COS, RIPPLE_SIN, SIGN, SIN, STRIBECK, Tracer, V3, constants};
use crate::program::{Dag, NodeId};
use crate::schema::JointKind;

/// A joint rotation as a product of stages (rows each), parent-most first.
pub struct Rotation(Vec<[V3; 3]>);

impl Rotation {
    /// The stages' rows, parent-most first: R = stages[0] stages[1] ...
    pub fn stages(&self) -> &[[V3; 3]] {
        &self.0
    }
}

/// Motion of one body frame, in its own axes.
#[derive(Clone, Copy)]
pub struct Motion {
    pub w: V3,
    pub wd: V3,
    /// Linear acceleration of the frame origin (gravity included).
    pub a: V3,
}

/// Joint state inputs, possibly replaced by constant zeros.
#[derive(Clone, Copy)]
pub struct JointState {
    pub qd: NodeId,
    pub qdd: NodeId,
}

impl Tracer<'_> {
    /// R_i = R_fixed Rot(axis, q_i), as one matrix or in two stages,
    /// whichever costs fewer run-time operations per rotated vector: a
    /// signed permutation or a rotation about a coordinate axis as R_fixed
    /// makes the stages nearly free, a dense R_fixed favours one matrix.
    /// The choice depends on which entries are 0 or +-1 only.
    pub(super) fn rotation(&mut self, i: usize) -> Rotation {
        if self.prismatic(i) {
            return Rotation(vec![self.joint(i).rotation]);
        }
        let mut dag = Dag::default();
        let leaves = constants::leaves(&mut dag, self.chain);
        let mut scratch = Tracer {
            dag,
            chain: self.chain,
            leaves,
            parameters: Vec::new(),
        };
        let [one, staged] = [false, true].map(|stage| {
            let rotation = scratch.rotation_in(i, stage);
            let v = [1, 2, 3].map(|k| scratch.dag.input(usize::MAX - k));
            let rotated = scratch.in_body_axes(&rotation, v);
            scratch.dag.operation_count(&rotated)
        });
        self.rotation_in(i, staged < one)
    }

    fn rotation_in(&mut self, i: usize, staged: bool) -> Rotation {
        let joint = self.joint(i);
        let (z, fixed) = (joint.axis, joint.rotation);
        let zero = self.dag.constant(0.0);
        let one = self.dag.constant(1.0);
        let zz = self.outer(z, z);
        let minus = z.map(|x| self.dag.negate(x));
        let skew = [
            [zero, minus[2], z[1]],
            [z[2], zero, minus[0]],
            [minus[1], z[0], zero],
        ];
        let identity = self.diagonal(one);
        let ring = self.mat_subtract(&identity, &zz);
        // Rot(axis, q) = K0 + K1 sin + K2 cos.
        let k = [zz, skew, ring];
        if staged {
            let none = [[zero; 3]; 3];
            let fixed = self.rows(i, [fixed, none, none]);
            let joint = self.rows(i, k);
            Rotation(vec![fixed, joint])
        } else {
            let combined = k.map(|k| self.mat_mul(&fixed, &k));
            Rotation(vec![self.rows(i, combined)])
        }
    }

    /// Rows of K0 + K1 sin(q_i) + K2 cos(q_i).
    fn rows(&mut self, i: usize, k: [[V3; 3]; 3]) -> [V3; 3] {
        let (s, c) = (self.input(i, SIN), self.input(i, COS));
        [0, 1, 2].map(|r| {
            [0, 1, 2].map(|col| {
                let terms = [
                    k[0][r][col],
                    self.dag.product2(k[1][r][col], s),
                    self.dag.product2(k[2][r][col], c),
                ];
                self.sum(&terms)
            })
        })
    }

    /// R^T v: from the parent's axes into the body's.
    pub(super) fn in_body_axes(&mut self, rotation: &Rotation, v: V3) -> V3 {
        rotation
            .0
            .iter()
            .fold(v, |v, stage| self.inverse_rotate(stage, v))
    }

    /// R v: from the body's axes into the parent's.
    pub(super) fn in_parent_axes(&mut self, rotation: &Rotation, v: V3) -> V3 {
        rotation
            .0
            .iter()
            .rev()
            .fold(v, |v, stage| self.mat_vec(stage, v))
    }

    /// Velocities and accelerations outwards from the base.
    pub(super) fn forward(
        &mut self,
        rotations: &[Rotation],
        state: &[JointState],
        base: V3,
    ) -> Vec<Motion> {
        let zero = self.dag.constant(0.0);
        let base = Motion {
            w: [zero; 3],
            wd: [zero; 3],
            a: base,
        };
        let mut motions: Vec<Motion> = Vec::with_capacity(state.len());
        for (i, s) in state.iter().enumerate() {
            let parent = match self.chain.bodies[i].parent {
                Some(p) => motions[p],
                None => base,
            };
            let z = self.joint(i).axis;
            let origin = self.origin(i);
            // Acceleration of the body origin, parent axes.
            let relative = self.point_acceleration(&parent, origin);
            let a = self.add(parent.a, relative);
            let mut a = self.in_body_axes(&rotations[i], a);
            let w_in = self.in_body_axes(&rotations[i], parent.w);
            let wd_in = self.in_body_axes(&rotations[i], parent.wd);
            let (w, wd) = if self.prismatic(i) {
                // Coriolis 2 w x (z qd) and the sliding acceleration z qdd.
                let slide = self.scale(z, s.qd);
                let two = self.dag.constant(2.0);
                let w_twice = self.scale(w_in, two);
                let coriolis = self.cross(w_twice, slide);
                let sliding = self.scale(z, s.qdd);
                a = self.add(a, coriolis);
                a = self.add(a, sliding);
                (w_in, wd_in)
            } else {
                let spin = self.scale(z, s.qd);
                let w = self.add(w_in, spin);
                let transport = self.cross(w_in, spin);
                let joint_acceleration = self.scale(z, s.qdd);
                let wd = self.add(wd_in, joint_acceleration);
                (w, self.add(wd, transport))
            };
            motions.push(Motion { w, wd, a });
        }
        motions
    }

    /// Whether joint `i` slides.
    pub(super) fn prismatic(&self, i: usize) -> bool {
        self.chain.bodies[i].kind == JointKind::Prismatic
    }

    /// Body `i`'s origin in the previous body's axes: the joint origin p,
    /// plus R z q for a prismatic joint.
    pub(super) fn origin(&mut self, i: usize) -> V3 {
        let p = self.joint(i).translation;
        if !self.prismatic(i) {
            return p;
        }
        let (rotation, z) = (self.joint(i).rotation, self.joint(i).axis);
        let direction = self.mat_vec(&rotation, z);
        let q = self.input(i, Q);
        let travel = self.scale(direction, q);
        self.add(p, travel)
    }

    /// wd x r + w x (w x r) = U r, the acceleration of a body point at r
    /// relative to the origin.
    fn point_acceleration(&mut self, motion: &Motion, r: V3) -> V3 {
        let u = self.spin_matrix(motion);
        self.mat_vec(&u, r)
    }

    /// U = [wd]x + w w^T - |w|^2 1, built once per body (hash-consed): it
    /// serves the force, the moment and the child's origin acceleration.
    fn spin_matrix(&mut self, motion: &Motion) -> [V3; 3] {
        let (w, wd) = (motion.w, motion.wd);
        let ww = self.squares(w);
        [0, 1, 2].map(|i| {
            [0, 1, 2].map(|j| {
                if i == j {
                    let (k, l) = ((i + 1) % 3, (i + 2) % 3);
                    let sum = self.dag.sum2(ww[k][k], ww[l][l]);
                    self.dag.negate(sum)
                } else {
                    // [wd]x at (i, j): -wd_k for j = i + 1, +wd_k for j = i + 2.
                    let k = 3 - i - j;
                    let spin = if j == (i + 1) % 3 {
                        self.dag.negate(wd[k])
                    } else {
                        wd[k]
                    };
                    self.dag.sum2(ww[i][j], spin)
                }
            })
        })
    }

    /// w w^T, each product once.
    fn squares(&mut self, w: V3) -> [V3; 3] {
        [0, 1, 2].map(|i| [0, 1, 2].map(|j| self.dag.product2(w[i.min(j)], w[i.max(j)])))
    }

    /// The wrench (force, moment about the origin) body `i` needs for its
    /// motion. Its points accelerate by a + U r, so with the first and
    /// second moments h and P = int r r^T dm (P = tr(I)/2 - I):
    /// f = m a + U h and n = h x a + int r x U r dm = h x a + axial(U P),
    /// axial(X)_i = X_kj - X_jk for (i, j, k) cyclic. This reuses U instead
    /// of forming I wd, I w and w x I w; written with the inertia I about
    /// the origin, component i is (w_k^2 - w_j^2) (-I_jk) +
    /// w_j w_k (I_kk - I_jj) + wd_i I_ii + U_ki (-I_ij) + U_ji I_ik, which
    /// folds when w or wd has zero components (bodies near the base).
    fn wrench(&mut self, i: usize, motion: &Motion) -> (V3, V3) {
        let body = self.parameters[i];
        let (m, h, inertia) = (body.m, body.h, body.inertia);
        let u = self.spin_matrix(motion);
        let ma = self.scale(motion.a, m);
        let uh = self.mat_vec(&u, h);
        let force = self.add(ma, uh);
        let ww = self.squares(motion.w);
        let hxa = self.cross(h, motion.a);
        let moment = [0, 1, 2].map(|i| {
            let (j, k) = ((i + 1) % 3, (i + 2) % 3);
            let minus = self.dag.negate(ww[j][j]);
            let diagonal = self.dag.sum2(ww[k][k], minus);
            let minus_jj = self.dag.negate(inertia[j][j]);
            let kk_minus_jj = self.dag.sum2(inertia[k][k], minus_jj);
            let minus_ij = self.dag.negate(inertia[i][j]);
            let minus_jk = self.dag.negate(inertia[j][k]);
            let products = [
                (diagonal, minus_jk),
                (ww[j][k], kk_minus_jj),
                (motion.wd[i], inertia[i][i]),
                (u[k][i], minus_ij),
                (u[j][i], inertia[i][k]),
            ]
            .map(|(x, c)| self.dag.product2(c, x));
            let sum = self.sum(&products);
            self.dag.sum2(sum, hxa[i])
        });
        (force, moment)
    }

    /// Wrenches inwards from the tip; each joint takes its axis component.
    pub(super) fn backward(&mut self, rotations: &[Rotation], motions: &[Motion]) -> Vec<NodeId> {
        let n = motions.len();
        let mut tau = vec![0; n];
        // Each body's wrench with its children's, in its own axes.
        let mut total: Vec<(V3, V3)> = Vec::with_capacity(n);
        for i in (0..n).rev() {
            let (mut force, mut moment) = self.wrench(i, &motions[i]);
            let children = (i + 1..n).filter(|&c| self.chain.bodies[c].parent == Some(i));
            for c in children.collect::<Vec<_>>() {
                let (f, m) = total[n - 1 - c];
                let (f, m) = self.wrench_in_parent_frame(c, &rotations[c], f, m);
                force = self.add(force, f);
                moment = self.add(moment, m);
            }
            let z = self.joint(i).axis;
            let along = if self.prismatic(i) { force } else { moment };
            tau[i] = self.dot(z, along);
            total.push((force, moment));
        }
        tau
    }

    /// armature*qdd (optional) + viscous*qd + coulomb*sign(qd) +
    /// coulomb_asymmetry*sign(qd)^2 + stribeck*stribeck_shape + offset.
    pub(super) fn effects(&mut self, i: usize, with_armature: bool) -> NodeId {
        let [
            armature,
            viscous,
            coulomb,
            offset,
            asymmetry,
            _,
            stribeck,
            _,
            _,
        ] = self.joint(i).effects;
        let zero = self.dag.constant(0.0);
        let armature = if with_armature { armature } else { zero };
        let sign = self.input(i, SIGN);
        let moving = self.dag.product2(sign, sign);
        let terms = [
            (armature, self.input(i, QDD)),
            (viscous, self.input(i, QD)),
            (coulomb, sign),
            (asymmetry, moving),
            (stribeck, self.input(i, STRIBECK)),
        ]
        .map(|(k, x)| self.dag.product2(k, x));
        let sum = self.sum(&terms);
        self.dag.sum2(sum, offset)
    }

    /// The torque of the position alone: the joint spring
    /// spring*(q - spring_rest) and the ripple
    /// ripple_sin*sin(cycles*q) + ripple_cos*cos(cycles*q).
    pub(super) fn position_torque(&mut self, i: usize) -> NodeId {
        let stretch = self.spring_stretch(i);
        let [.., stiffness, _, ripple_sin, ripple_cos] = self.joint(i).effects;
        let terms = [
            (stiffness, stretch),
            (ripple_sin, self.input(i, RIPPLE_SIN)),
            (ripple_cos, self.input(i, RIPPLE_COS)),
        ]
        .map(|(k, x)| self.dag.product2(k, x));
        self.sum(&terms)
    }

    /// q - spring_rest: the regressor's spring column.
    pub(super) fn spring_stretch(&mut self, i: usize) -> NodeId {
        let q = self.input(i, Q);
        let rest = self.joint(i).spring_rest;
        let minus_rest = self.dag.negate(rest);
        self.dag.sum2(q, minus_rest)
    }
}
