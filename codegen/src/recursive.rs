//! The chain's dynamics as structured straight-line programs, for arms whose
//! expanded Lagrangian is too large (six joints and more).
//!
//! Same physics as `lagrangian.rs`, organised by body instead of expanded:
//! - `tau`, `gravity`, `coriolis`: the Euler-Lagrange equations of a serial
//!   chain regrouped body by body, i.e. the recursive Newton-Euler form
//!   (velocities and accelerations outwards, wrenches inwards), all in body
//!   axes, with gravity as a base acceleration;
//! - `mass_matrix`: M = sum_k J_k^T M_k J_k from each body's Jacobian (the
//!   kinetic energy's Hessian), the joint twists expressed in body axes;
//! - regressor: Y_ik = J_ik^T W_k with W_k the body's wrench per unit
//!   inertial parameter.
//!
//! Each step is traced on a hash-consed `Dag` whose constants fold (zero and
//! unit rotation entries vanish), so the output is flat code with shared
//! subexpressions, linear in the chain length for `tau`.

use nalgebra::{Matrix3, Vector3};

use crate::program::{Dag, NodeId};
use crate::reduce::{Body, Chain};

/// Program input positions; the layout of `lagrangian::inputs`:
/// per joint sin, cos, qd, qdd, sign(qd).
pub const INPUTS_PER_JOINT: usize = 5;
const SIN: usize = 0;
const COS: usize = 1;
const QD: usize = 2;
const QDD: usize = 3;
const SIGN: usize = 4;

/// Rotation entries closer than this to 0 or +-1 are taken as exact (they
/// come from angles like pi/2 in floating point).
const SNAP: f64 = 1e-15;

type V3 = [NodeId; 3];

/// The traced programs of one chain (one shared DAG; roots row-major).
pub struct Traced {
    pub dag: Dag,
    /// M qdd + c + g + effects.
    pub tau: Vec<NodeId>,
    /// n x n, armature on the diagonal.
    pub mass_matrix: Vec<NodeId>,
    pub gravity: Vec<NodeId>,
    pub coriolis: Vec<NodeId>,
    /// n x 14n: ten inertial columns per body, then four effect columns per joint.
    pub regressor: Vec<NodeId>,
}

/// A joint rotation as a product of stages (rows each), parent-most first.
struct Rotation(Vec<[V3; 3]>);

/// Motion of one body frame, in its own axes.
#[derive(Clone, Copy)]
struct Motion {
    w: V3,
    wd: V3,
    /// Linear acceleration of the frame origin (gravity included).
    a: V3,
}

/// A body's inertial parameters as constants: mass, first moment m*c and
/// inertia about the body origin.
struct Inertia {
    m: NodeId,
    h: V3,
    i: [V3; 3],
}

/// Joint state inputs, possibly replaced by constant zeros.
#[derive(Clone, Copy)]
struct JointState {
    qd: NodeId,
    qdd: NodeId,
}

/// Traces every function of `chain`.
pub fn trace(chain: &Chain) -> Traced {
    let mut t = Tracer {
        dag: Dag::default(),
        chain,
        parameters: regrouped(chain),
    };
    let n = chain.bodies.len();
    let rotations: Vec<Rotation> = (0..n).map(|i| t.rotation(i)).collect();
    let zero = t.dag.constant(0.0);
    let gravity_off = [zero; 3];
    let base_acceleration = t.constants(&(-chain.gravity));
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
    let rigid = t.backward(&rotations, &motions);
    let tau = (0..n)
        .map(|i| {
            let effects = t.effects(i, true);
            t.dag.sum2(rigid[i], effects)
        })
        .collect();
    let rest = t.forward(&rotations, &at_rest, base_acceleration);
    let gravity = t.backward(&rotations, &rest);
    let moving = t.forward(&rotations, &no_acceleration, gravity_off);
    let coriolis = t.backward(&rotations, &moving);
    let twists = t.twists(&rotations);
    let mass_matrix = t.mass_matrix(&twists);
    let regressor = t.regressor(&twists, &motions);
    Traced {
        dag: t.dag,
        tau,
        mass_matrix,
        gravity,
        coriolis,
        regressor,
    }
}

struct Tracer<'a> {
    dag: Dag,
    chain: &'a Chain,
    /// Per body the standard parameters the dynamics use: regrouped (see
    /// [`regrouped`]), the same torques with fewer non-zero constants.
    parameters: Vec<[f64; 10]>,
}

/// The bodies' standard parameters with every part that cannot feel its own
/// joint moved to the parent body (the base keeps nothing): the mass and the
/// first moment along the joint axis (they sit on the axis) and an inertia
/// b (1 - z z^T) about the axis (it sees only the parent's rotation), with b
/// chosen to zero one diagonal entry when the axis is a coordinate axis.
/// Kinetic and potential energy are unchanged, so tau, M, g and c are the
/// same (the classical base-parameter regrouping for revolute joints);
/// the regressor keeps the description's parameters.
fn regrouped(chain: &Chain) -> Vec<[f64; 10]> {
    let mut parameters: Vec<[f64; 10]> = chain
        .bodies
        .iter()
        .map(|b| b.inertial.standard_parameters())
        .collect();
    for j in (0..chain.bodies.len()).rev() {
        let body = &chain.bodies[j];
        let z = body.axis;
        let [m, hx, hy, hz, xx, xy, yy, xz, yz, zz] = parameters[j];
        let h = Vector3::new(hx, hy, hz);
        let inertia = Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz);
        let along = h.dot(&z);
        let b = coordinate_axis(&z).map_or(0.0, |k| inertia[((k + 1) % 3, (k + 1) % 3)]);
        let ring = Matrix3::identity() - z * z.transpose();
        let kept_h = h - along * z;
        let kept_i = inertia - b * ring;
        parameters[j] = pack(0.0, &kept_h, &kept_i);
        if j == 0 {
            continue;
        }
        // The moved part in the parent's axes, about the joint origin p.
        let p = body.translation;
        let zp = body.rotation * z;
        let moment = along * zp;
        let about_p = b * (Matrix3::identity() - zp * zp.transpose());
        let about_origin = about_p
            + m * (p.norm_squared() * Matrix3::identity() - p * p.transpose())
            + 2.0 * p.dot(&moment) * Matrix3::identity()
            - p * moment.transpose()
            - moment * p.transpose();
        let added = pack(m, &(m * p + moment), &about_origin);
        for (total, extra) in parameters[j - 1].iter_mut().zip(added) {
            *total += extra;
        }
    }
    parameters
}

/// k when `z` is +-e_k.
fn coordinate_axis(z: &Vector3<f64>) -> Option<usize> {
    (0..3).find(|&k| (z[k].abs() - 1.0).abs() < SNAP && z.norm_squared() - z[k] * z[k] < SNAP)
}

/// Standard parameters (Pinocchio's order) from mass, first moment and
/// inertia about the origin.
fn pack(m: f64, h: &Vector3<f64>, i: &Matrix3<f64>) -> [f64; 10] {
    [
        m,
        h.x,
        h.y,
        h.z,
        i[(0, 0)],
        i[(0, 1)],
        i[(1, 1)],
        i[(0, 2)],
        i[(1, 2)],
        i[(2, 2)],
    ]
}

impl<'a> Tracer<'a> {
    fn input(&mut self, joint: usize, which: usize) -> NodeId {
        self.dag.input(INPUTS_PER_JOINT * joint + which)
    }

    fn constant(&mut self, x: f64) -> NodeId {
        let snapped = [0.0, 1.0, -1.0]
            .into_iter()
            .find(|exact| (x - exact).abs() < SNAP)
            .unwrap_or(x);
        self.dag.constant(snapped)
    }

    fn constants(&mut self, v: &Vector3<f64>) -> V3 {
        [self.constant(v.x), self.constant(v.y), self.constant(v.z)]
    }

    fn body(&self, i: usize) -> &'a Body {
        &self.chain.bodies[i]
    }

    /// R_i = R_fixed Rot(axis, q_i), as one matrix or in two stages,
    /// whichever costs fewer operations per rotated vector: a signed
    /// permutation or a rotation about a coordinate axis as R_fixed makes
    /// the stages nearly free, a dense R_fixed favours one matrix.
    fn rotation(&mut self, i: usize) -> Rotation {
        let mut scratch = Tracer {
            dag: Dag::default(),
            chain: self.chain,
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
        let body = self.body(i);
        let z = body.axis;
        let zz = z * z.transpose();
        let skew = Matrix3::new(0.0, -z.z, z.y, z.z, 0.0, -z.x, -z.y, z.x, 0.0);
        // Rot(axis, q) = K0 + K1 sin + K2 cos.
        let k = [zz, skew, Matrix3::identity() - zz];
        let fixed = body.rotation;
        if staged {
            let zero = Matrix3::zeros();
            let fixed = self.rows(i, [fixed, zero, zero]);
            let joint = self.rows(i, k);
            Rotation(vec![fixed, joint])
        } else {
            let combined = self.rows(i, k.map(|k| fixed * k));
            Rotation(vec![combined])
        }
    }

    /// Rows of K0 + K1 sin(q_i) + K2 cos(q_i).
    fn rows(&mut self, i: usize, k: [Matrix3<f64>; 3]) -> [V3; 3] {
        let (s, c) = (self.input(i, SIN), self.input(i, COS));
        [0, 1, 2].map(|r| {
            [0, 1, 2].map(|col| {
                let terms = [
                    self.constant(k[0][(r, col)]),
                    self.scaled(k[1][(r, col)], s),
                    self.scaled(k[2][(r, col)], c),
                ];
                self.sum(&terms)
            })
        })
    }

    /// R^T v: from the parent's axes into the body's.
    fn in_body_axes(&mut self, rotation: &Rotation, v: V3) -> V3 {
        rotation
            .0
            .iter()
            .fold(v, |v, stage| self.inverse_rotate(stage, v))
    }

    /// R v: from the body's axes into the parent's.
    fn in_parent_axes(&mut self, rotation: &Rotation, v: V3) -> V3 {
        rotation
            .0
            .iter()
            .rev()
            .fold(v, |v, stage| self.mat_vec(stage, v))
    }

    fn scaled(&mut self, k: f64, x: NodeId) -> NodeId {
        let k = self.constant(k);
        self.dag.product2(k, x)
    }

    fn sum(&mut self, terms: &[NodeId]) -> NodeId {
        let zero = self.dag.constant(0.0);
        terms.iter().fold(zero, |acc, &t| self.dag.sum2(acc, t))
    }

    fn add(&mut self, a: V3, b: V3) -> V3 {
        [0, 1, 2].map(|k| self.dag.sum2(a[k], b[k]))
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

    fn inertia(&mut self, i: usize) -> Inertia {
        let [m, hx, hy, hz, ixx, ixy, iyy, ixz, iyz, izz] = self.parameters[i];
        let h = [hx, hy, hz].map(|x| self.dag.constant(x));
        let k = [ixx, ixy, iyy, ixz, iyz, izz].map(|x| self.dag.constant(x));
        let [xx, xy, yy, xz, yz, zz] = k;
        Inertia {
            m: self.dag.constant(m),
            h,
            i: [[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]],
        }
    }

    /// Velocities and accelerations outwards from the base.
    fn forward(&mut self, rotations: &[Rotation], state: &[JointState], base: V3) -> Vec<Motion> {
        let zero = self.dag.constant(0.0);
        let mut parent = Motion {
            w: [zero; 3],
            wd: [zero; 3],
            a: base,
        };
        let mut motions = Vec::with_capacity(state.len());
        for (i, s) in state.iter().enumerate() {
            let p = self.constants(&self.body(i).translation);
            let z = self.constants(&self.body(i).axis);
            // Acceleration of the joint origin, parent axes.
            let relative = self.point_acceleration(&parent, p);
            let a = self.add(parent.a, relative);
            let a = self.in_body_axes(&rotations[i], a);
            let w_in = self.in_body_axes(&rotations[i], parent.w);
            let wd_in = self.in_body_axes(&rotations[i], parent.wd);
            let spin = self.scale(z, s.qd);
            let w = self.add(w_in, spin);
            let transport = self.cross(w_in, spin);
            let joint_acceleration = self.scale(z, s.qdd);
            let wd = self.add(wd_in, joint_acceleration);
            let wd = self.add(wd, transport);
            parent = Motion { w, wd, a };
            motions.push(parent);
        }
        motions
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
    /// of forming I wd, I w and w x I w; its diagonal enters only as
    /// U_kk - U_jj = w_k^2 - w_j^2, and U_kj P_jj - U_jk P_kk as
    /// w_j w_k (P_jj - P_kk) + wd_i (P_jj + P_kk), which folds when w or wd
    /// has zero components (bodies near the base).
    fn wrench(&mut self, i: usize, motion: &Motion) -> (V3, V3) {
        let (m, h, p) = self.moments(i);
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
            let products = [
                (diagonal, p[(j, k)]),
                (ww[j][k], p[(j, j)] - p[(k, k)]),
                (motion.wd[i], p[(j, j)] + p[(k, k)]),
                (u[k][i], p[(i, j)]),
                (u[j][i], -p[(i, k)]),
            ]
            .map(|(x, c)| {
                // Inertial numbers stay unsnapped, like `inertia`.
                let c = self.dag.constant(c);
                self.dag.product2(c, x)
            });
            let sum = self.sum(&products);
            self.dag.sum2(sum, hxa[i])
        });
        (force, moment)
    }

    /// Mass, first moment and second moment P = int r r^T dm of body `i`
    /// about its origin, the latter as numbers.
    fn moments(&mut self, i: usize) -> (NodeId, V3, Matrix3<f64>) {
        let [m, hx, hy, hz, xx, xy, yy, xz, yz, zz] = self.parameters[i];
        let inertia = Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz);
        let p = Matrix3::identity() * (inertia.trace() / 2.0) - inertia;
        let h = [hx, hy, hz].map(|x| self.dag.constant(x));
        (self.dag.constant(m), h, p)
    }

    /// Wrenches inwards from the tip; each joint takes its axis component.
    fn backward(&mut self, rotations: &[Rotation], motions: &[Motion]) -> Vec<NodeId> {
        let n = motions.len();
        let mut tau = vec![0; n];
        let mut outer: Option<(V3, V3)> = None;
        for i in (0..n).rev() {
            let (mut force, mut moment) = self.wrench(i, &motions[i]);
            if let Some((f, m)) = outer {
                let f = self.in_parent_axes(&rotations[i + 1], f);
                let m = self.in_parent_axes(&rotations[i + 1], m);
                let p = self.constants(&self.body(i + 1).translation);
                let lever = self.cross(p, f);
                force = self.add(force, f);
                moment = self.add(moment, m);
                moment = self.add(moment, lever);
            }
            let z = self.constants(&self.body(i).axis);
            tau[i] = self.dot(z, moment);
            outer = Some((force, moment));
        }
        tau
    }

    /// armature*qdd (optional) + viscous*qd + coulomb*sign(qd) + offset.
    fn effects(&mut self, i: usize, with_armature: bool) -> NodeId {
        let e = self.body(i).effects;
        let armature = if with_armature { e.armature } else { 0.0 };
        let terms = [
            (armature, self.input(i, QDD)),
            (e.viscous, self.input(i, QD)),
            (e.coulomb, self.input(i, SIGN)),
        ]
        .map(|(k, x)| self.scaled(k, x));
        let offset = self.dag.constant(e.offset);
        let sum = self.sum(&terms);
        self.dag.sum2(sum, offset)
    }

    /// `twists[k][j]`, j <= k: the unit twist of joint j in body k's axes,
    /// (angular, linear velocity of body k's origin).
    fn twists(&mut self, rotations: &[Rotation]) -> Vec<Vec<(V3, V3)>> {
        let n = rotations.len();
        let zero = self.dag.constant(0.0);
        let mut twists: Vec<Vec<(V3, V3)>> = Vec::with_capacity(n);
        for (k, rotation) in rotations.iter().enumerate() {
            let p = self.constants(&self.body(k).translation);
            let mut row = Vec::with_capacity(k + 1);
            for &(w, v) in twists.last().into_iter().flatten() {
                let wxp = self.cross(w, p);
                let v = self.add(v, wxp);
                row.push((
                    self.in_body_axes(rotation, w),
                    self.in_body_axes(rotation, v),
                ));
            }
            row.push((self.constants(&self.body(k).axis), [zero; 3]));
            twists.push(row);
        }
        twists
    }

    /// M_ij = sum over bodies k >= i, j of twist_ik . (momentum of twist_jk).
    fn mass_matrix(&mut self, twists: &[Vec<(V3, V3)>]) -> Vec<NodeId> {
        let n = twists.len();
        let mut momenta: Vec<Vec<(V3, V3)>> = Vec::with_capacity(n);
        for (k, row) in twists.iter().enumerate() {
            let Inertia { m, h, i: inertia } = self.inertia(k);
            let per_joint = row
                .iter()
                .map(|&(w, v)| {
                    let mv = self.scale(v, m);
                    let wxh = self.cross(w, h);
                    let iw = self.mat_vec(&inertia, w);
                    let hxv = self.cross(h, v);
                    (self.add(mv, wxh), self.add(iw, hxv))
                })
                .collect();
            momenta.push(per_joint);
        }
        let mut mass = vec![0; n * n];
        for i in 0..n {
            for j in i..n {
                let terms: Vec<NodeId> = (j..n)
                    .map(|k| {
                        let (w, v) = twists[k][i];
                        let (linear, angular) = momenta[k][j];
                        let a = self.dot(v, linear);
                        let b = self.dot(w, angular);
                        self.dag.sum2(a, b)
                    })
                    .collect();
                let mut entry = self.sum(&terms);
                if i == j {
                    let armature = self.dag.constant(self.body(i).effects.armature);
                    entry = self.dag.sum2(entry, armature);
                }
                mass[i * n + j] = entry;
                mass[j * n + i] = entry;
            }
        }
        mass
    }

    /// Rigid-body columns from the body wrenches per unit parameter, then the
    /// joint-effect columns (qdd, qd, sign(qd), 1 on the joint's own row).
    fn regressor(&mut self, twists: &[Vec<(V3, V3)>], motions: &[Motion]) -> Vec<NodeId> {
        let n = motions.len();
        let zero = self.dag.constant(0.0);
        let one = self.dag.constant(1.0);
        let mut y = vec![zero; n * 14 * n];
        for (k, motion) in motions.iter().enumerate() {
            for (p, (force, moment)) in self.unit_wrenches(motion).into_iter().enumerate() {
                for (i, &(w, v)) in twists[k].iter().enumerate() {
                    let a = self.dot(v, force);
                    let b = self.dot(w, moment);
                    y[i * 14 * n + 10 * k + p] = self.dag.sum2(a, b);
                }
            }
        }
        for i in 0..n {
            let row = i * 14 * n + 10 * n + 4 * i;
            y[row] = self.input(i, QDD);
            y[row + 1] = self.input(i, QD);
            y[row + 2] = self.input(i, SIGN);
            y[row + 3] = one;
        }
        y
    }

    /// The body wrench per unit value of each standard parameter, in the
    /// order m, m*c (x, y, z), Ixx, Ixy, Iyy, Ixz, Iyz, Izz.
    fn unit_wrenches(&mut self, motion: &Motion) -> Vec<(V3, V3)> {
        let zero = self.dag.constant(0.0);
        let one = self.dag.constant(1.0);
        let none = [zero; 3];
        let unit = |k: usize| {
            let mut e = [zero; 3];
            e[k] = one;
            e
        };
        let mut wrenches = vec![(motion.a, none)];
        for k in 0..3 {
            let e = unit(k);
            let wdxe = self.cross(motion.wd, e);
            let wxe = self.cross(motion.w, e);
            let wxwxe = self.cross(motion.w, wxe);
            let force = self.add(wdxe, wxwxe);
            let moment = self.cross(e, motion.a);
            wrenches.push((force, moment));
        }
        for (r, c) in [(0, 0), (0, 1), (1, 1), (0, 2), (1, 2), (2, 2)] {
            let mut inertia = [[zero; 3]; 3];
            inertia[r][c] = one;
            inertia[c][r] = one;
            let iwd = self.mat_vec(&inertia, motion.wd);
            let iw = self.mat_vec(&inertia, motion.w);
            let gyroscopic = self.cross(motion.w, iw);
            wrenches.push((none, self.add(iwd, gyroscopic)));
        }
        wrenches
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::description::Description;
    use std::path::Path;

    const PLANAR: &str = r#"
        gravity = [0.0, -9.81, 0.0]
        [[links]]
        name = "base"
        [[links]]
        name = "upper"
        mass = 2.0
        com = [0.35, 0.0, 0.0]
        inertia = { ixx = 0.002, iyy = 0.12, izz = 0.12 }
        [[links]]
        name = "fore"
        mass = 1.5
        com = [0.4, 0.0, 0.0]
        inertia = { ixx = 0.0015, iyy = 0.08, izz = 0.08 }
        [[joints]]
        name = "shoulder"
        type = "revolute"
        parent = "base"
        child = "upper"
        effects = { viscous = 0.3, coulomb = 0.2, offset = -0.1, armature = 0.01 }
        [[joints]]
        name = "elbow"
        type = "revolute"
        parent = "upper"
        child = "fore"
        origin = { xyz = [0.8, 0.0, 0.0] }
    "#;

    fn inputs(q: &[f64], qd: &[f64], qdd: &[f64]) -> Vec<f64> {
        (0..q.len())
            .flat_map(|i| [q[i].sin(), q[i].cos(), qd[i], qdd[i], qd[i].signum()])
            .collect()
    }

    /// The textbook closed form of the planar two-link arm (gravity along -y).
    fn closed_form(q: &[f64], qd: &[f64], qdd: &[f64]) -> [f64; 2] {
        let (m1, m2, l1, c1, c2, g) = (2.0, 1.5, 0.8, 0.35, 0.4, 9.81);
        let (i1, i2) = (0.12 + m1 * c1 * c1, 0.08 + m2 * c2 * c2);
        let cos2 = q[1].cos();
        let m11 = i1 + i2 + m2 * l1 * l1 + 2.0 * m2 * l1 * c2 * cos2;
        let m12 = i2 + m2 * l1 * c2 * cos2;
        let h = -m2 * l1 * c2 * q[1].sin();
        let g1 = (m1 * c1 + m2 * l1) * g * q[0].cos() + m2 * c2 * g * (q[0] + q[1]).cos();
        let g2 = m2 * c2 * g * (q[0] + q[1]).cos();
        [
            m11 * qdd[0] + m12 * qdd[1] + h * (2.0 * qd[0] * qd[1] + qd[1] * qd[1]) + g1,
            m12 * qdd[0] + i2 * qdd[1] - h * qd[0] * qd[0] + g2,
        ]
    }

    /// A plain numeric recursive Newton-Euler for per-body standard
    /// parameters (no joint effects), the reference for the traced programs.
    fn rnea(
        chain: &Chain,
        params: &[[f64; 10]],
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        g: bool,
    ) -> Vec<f64> {
        type V = Vector3<f64>;
        let n = chain.bodies.len();
        let (mut w, mut wd) = (V::zeros(), V::zeros());
        let mut a = if g { -chain.gravity } else { V::zeros() };
        let mut frames = Vec::new();
        let mut wrenches = Vec::new();
        for (i, body) in chain.bodies.iter().enumerate() {
            let r = body.rotation * crate::reduce::axis_angle(&body.axis, q[i]);
            let z = body.axis;
            a = r.transpose()
                * (a + wd.cross(&body.translation) + w.cross(&w.cross(&body.translation)));
            let w_in = r.transpose() * w;
            w = w_in + z * qd[i];
            wd = r.transpose() * wd + z * qdd[i] + w_in.cross(&(z * qd[i]));
            let [m, hx, hy, hz, xx, xy, yy, xz, yz, zz] = params[i];
            let h = V::new(hx, hy, hz);
            let inertia = Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz);
            let force = m * a + wd.cross(&h) + w.cross(&w.cross(&h));
            let moment = inertia * wd + w.cross(&(inertia * w)) + h.cross(&a);
            frames.push(r);
            wrenches.push((force, moment));
        }
        let mut tau = vec![0.0; n];
        for i in (0..n).rev() {
            if i + 1 < n {
                let (f, m) = wrenches[i + 1];
                let (f, m) = (frames[i + 1] * f, frames[i + 1] * m);
                let p = chain.bodies[i + 1].translation;
                wrenches[i].0 += f;
                wrenches[i].1 += m + p.cross(&f);
            }
            tau[i] = chain.bodies[i].axis.dot(&wrenches[i].1);
        }
        tau
    }

    /// A deterministic pseudo-random number in [-1, 1).
    fn uniform(state: &mut u64) -> f64 {
        *state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (*state >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    fn assert_close(what: &str, got: &[f64], want: &[f64]) {
        let scale = want.iter().fold(1.0_f64, |s, x| s.max(x.abs()));
        for (k, (g, w)) in got.iter().zip(want).enumerate() {
            assert!((g - w).abs() <= 1e-12 * scale, "{what}[{k}]: {g} vs {w}");
        }
    }

    /// Every traced function against the numeric reference, on random states.
    fn check_against_reference(model: &str, samples: usize) {
        let path = format!("{}/../models/{model}.toml", env!("CARGO_MANIFEST_DIR"));
        let description = Description::load(&path).unwrap();
        let chain = description.chain();
        let traced = trace(chain);
        let n = chain.bodies.len();
        let params: Vec<[f64; 10]> = chain
            .bodies
            .iter()
            .map(|b| b.inertial.standard_parameters())
            .collect();
        let effects: Vec<_> = chain.bodies.iter().map(|b| b.effects).collect();
        let mut state = 7;
        for sample in 0..samples {
            let mut random =
                |scale: f64| -> Vec<f64> { (0..n).map(|_| scale * uniform(&mut state)).collect() };
            let (q, qd, qdd) = (random(std::f64::consts::PI), random(3.0), random(10.0));
            let x = inputs(&q, &qd, &qdd);
            let eval = |roots: &[NodeId]| traced.dag.evaluate(roots, &x);
            let zeros = vec![0.0; n];
            let mut tau = rnea(chain, &params, &q, &qd, &qdd, true);
            for (i, e) in effects.iter().enumerate() {
                tau[i] +=
                    e.armature * qdd[i] + e.viscous * qd[i] + e.coulomb * qd[i].signum() + e.offset;
            }
            assert_close("tau", &eval(&traced.tau), &tau);
            let gravity = rnea(chain, &params, &q, &zeros, &zeros, true);
            assert_close("gravity", &eval(&traced.gravity), &gravity);
            let coriolis = rnea(chain, &params, &q, &qd, &zeros, false);
            assert_close("coriolis", &eval(&traced.coriolis), &coriolis);
            if sample % 10 != 0 {
                continue;
            }
            let mut mass = vec![0.0; n * n];
            for j in 0..n {
                let mut unit = zeros.clone();
                unit[j] = 1.0;
                let column = rnea(chain, &params, &q, &zeros, &unit, false);
                for i in 0..n {
                    mass[i * n + j] = column[i] + if i == j { effects[i].armature } else { 0.0 };
                }
            }
            assert_close("mass_matrix", &eval(&traced.mass_matrix), &mass);
            let y = eval(&traced.regressor);
            for (k, p) in (0..n).flat_map(|k| (0..10).map(move |p| (k, p))) {
                let mut unit = vec![[0.0; 10]; n];
                unit[k][p] = 1.0;
                let column = rnea(chain, &unit, &q, &qd, &qdd, true);
                let got: Vec<f64> = (0..n).map(|i| y[i * 14 * n + 10 * k + p]).collect();
                assert_close("regressor", &got, &column);
            }
        }
    }

    #[test]
    fn panda_matches_the_numeric_reference() {
        check_against_reference("panda", 1000);
    }

    #[test]
    fn gen3_lite_matches_the_numeric_reference() {
        check_against_reference("kinova_gen3_lite", 1000);
        check_against_reference("kinova_gen3_lite_3dof", 1000);
    }

    #[test]
    fn planar_arm_matches_its_closed_form() {
        let description = Description::parse(PLANAR, "planar", Path::new("planar.toml")).unwrap();
        let traced = trace(description.chain());
        let (q, qd, qdd) = ([0.3, -1.1], [0.7, -0.4], [1.3, 0.5]);
        let x = inputs(&q, &qd, &qdd);
        let tau = traced.dag.evaluate(&traced.tau, &x);
        let rigid = closed_form(&q, &qd, &qdd);
        let effects = 0.01 * qdd[0] + 0.3 * qd[0] + 0.2 - 0.1;
        assert!(
            (tau[0] - rigid[0] - effects).abs() < 1e-12,
            "{tau:?} {rigid:?}"
        );
        assert!((tau[1] - rigid[1]).abs() < 1e-12);
    }

    #[test]
    fn functions_are_consistent() {
        let description = Description::parse(PLANAR, "planar", Path::new("planar.toml")).unwrap();
        let traced = trace(description.chain());
        let params: Vec<f64> = description
            .chain()
            .bodies
            .iter()
            .flat_map(|b| b.inertial.standard_parameters())
            .chain(description.chain().bodies.iter().flat_map(|b| {
                let e = b.effects;
                [e.armature, e.viscous, e.coulomb, e.offset]
            }))
            .collect();
        let (q, qd, qdd) = ([-0.6, 2.0], [1.5, 0.9], [-0.2, 0.8]);
        let x = inputs(&q, &qd, &qdd);
        let eval = |roots: &[NodeId]| traced.dag.evaluate(roots, &x);
        let (tau, m, g, c) = (
            eval(&traced.tau),
            eval(&traced.mass_matrix),
            eval(&traced.gravity),
            eval(&traced.coriolis),
        );
        let y = eval(&traced.regressor);
        for i in 0..2 {
            let effects = if i == 0 { 0.3 * qd[0] + 0.2 - 0.1 } else { 0.0 };
            let split = m[2 * i] * qdd[0] + m[2 * i + 1] * qdd[1] + c[i] + g[i] + effects;
            let regressed: f64 = (0..28).map(|k| y[28 * i + k] * params[k]).sum();
            assert!(
                (tau[i] - split).abs() < 1e-12,
                "joint {i}: {} vs {split}",
                tau[i]
            );
            assert!((tau[i] - regressed).abs() < 1e-12);
        }
        assert_eq!(m[1], m[2]);
    }
}
