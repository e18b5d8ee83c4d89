//! The symbolic Lagrangian of a serial chain and its Euler-Lagrange equations,
//! derived with Symbolica.
//!
//! Joint angles enter through `s_i = sin(q_i)` and `c_i = cos(q_i)` (a
//! prismatic joint's position through q_i itself), so every
//! quantity is a polynomial in `s, c, q, qd, qdd` and in the ten inertial
//! parameters of each body (m, m*c, inertia about the body origin), kept as
//! symbols. Kinematics and energies are built as Symbolica expressions;
//! the Lagrangian is then turned into an exact (rational) Symbolica
//! polynomial and differentiated:
//!
//!   tau_i = d/dt dL/dqd_i - dL/dq_i
//!         = sum_j (d/dq_j dL/dqd_i) qd_j + (d/dqd_j dL/dqd_i) qdd_j - dL/dq_i,
//!   d/dq_j = c_j d/ds_j - s_j d/dc_j   (chain rule through sin and cos;
//!                                       d/dq_j itself for a prismatic joint).
//!
//! The torque is linear in the parameters, so its coefficients are the
//! regressor columns. This module must only run on the Symbolica thread
//! (`session::run`).

use nalgebra::{Matrix3, Vector3};
use symbolica::atom::{Atom, AtomCore, Symbol};
use symbolica::domains::Ring;
use symbolica::domains::rational::{Q, Rational};
use symbolica::poly::PolyVariable;
use symbolica::poly::polynomial::MultivariatePolynomial;
use symbolica::symbol;

use crate::emit::Input;
use crate::program::Poly;
use crate::reduce::Chain;
use crate::schema::JointKind;

type V3 = [Atom; 3];
type M3 = [[Atom; 3]; 3];
type Polynomial = MultivariatePolynomial<Q, u16>;

/// The rigid-body torque as regressor polynomials: `regressor[i][k]` is
/// d tau_i / d parameter_k, over the program inputs of `inputs(dof)`.
pub struct RigidBodyTorque {
    pub regressor: Vec<Vec<Poly>>,
}

/// Program inputs of a chain with `dof` joints, in the order the polynomial
/// exponent vectors use: per joint sin, cos, qd, qdd, sign(qd), q, Stribeck shape, ripple sin and cos
/// (`recursive::INPUTS_PER_JOINT`).
pub fn inputs(dof: usize) -> Vec<Input> {
    (0..dof)
        .flat_map(|i| {
            [
                Input::Sin(i),
                Input::Cos(i),
                Input::Qd(i),
                Input::Qdd(i),
                Input::Sign(i),
                Input::Q(i),
                Input::Stribeck(i),
                Input::RippleSin(i),
                Input::RippleCos(i),
            ]
        })
        .collect()
}

/// Symbols of the derivation.
struct Symbols {
    sin: Vec<Symbol>,
    cos: Vec<Symbol>,
    q: Vec<Symbol>,
    qd: Vec<Symbol>,
    qdd: Vec<Symbol>,
    /// Ten inertial parameters per body.
    params: Vec<[Symbol; 10]>,
}

impl Symbols {
    fn new(dof: usize) -> Symbols {
        let per_joint = |prefix: &str| -> Vec<Symbol> {
            (1..=dof)
                .map(|i| symbol!(&format!("sdnn_{prefix}{i}")))
                .collect()
        };
        let names = [
            "m", "mx", "my", "mz", "ixx", "ixy", "iyy", "ixz", "iyz", "izz",
        ];
        Symbols {
            sin: per_joint("s"),
            cos: per_joint("c"),
            q: per_joint("q"),
            qd: per_joint("qd"),
            qdd: per_joint("qdd"),
            params: (1..=dof)
                .map(|i| names.map(|n| symbol!(&format!("sdnn_{n}{i}"))))
                .collect(),
        }
    }

    /// Polynomial variable order: s, c, q, qd, qdd per joint, then parameters.
    fn variables(&self) -> Vec<PolyVariable> {
        let joints = (0..self.sin.len())
            .flat_map(|i| [self.sin[i], self.cos[i], self.q[i], self.qd[i], self.qdd[i]]);
        joints
            .chain(self.params.iter().flatten().copied())
            .map(PolyVariable::from)
            .collect()
    }
}

/// Derives the rigid-body torque of `chain` (Symbolica thread only).
pub fn derive(chain: &Chain) -> Result<RigidBodyTorque, String> {
    let dof = chain.bodies.len();
    let symbols = Symbols::new(dof);
    let lagrangian = lagrangian(chain, &symbols)?;
    let variables = std::sync::Arc::new(symbols.variables());
    let l: Polynomial = lagrangian.to_polynomial(&Q, variables.clone());
    let prismatic = chain
        .bodies
        .iter()
        .map(|b| b.kind == JointKind::Prismatic)
        .collect();
    let index = VariableIndex { dof, prismatic };
    let mut regressor = Vec::with_capacity(dof);
    for i in 0..dof {
        let tau = euler_lagrange(&l, i, &index);
        regressor.push(split_by_parameter(&tau, &index));
    }
    Ok(RigidBodyTorque { regressor })
}

/// Positions of the symbols in the polynomial's variable list.
struct VariableIndex {
    dof: usize,
    /// Per joint: whether it slides (its position is the variable q).
    prismatic: Vec<bool>,
}

impl VariableIndex {
    fn sin(&self, i: usize) -> usize {
        5 * i
    }
    fn cos(&self, i: usize) -> usize {
        5 * i + 1
    }
    fn q(&self, i: usize) -> usize {
        5 * i + 2
    }
    fn qd(&self, i: usize) -> usize {
        5 * i + 3
    }
    fn qdd(&self, i: usize) -> usize {
        5 * i + 4
    }
    fn parameter(&self, body: usize, k: usize) -> usize {
        5 * self.dof + 10 * body + k
    }
}

/// tau_i by Euler-Lagrange with the total time derivative through q and qd.
fn euler_lagrange(l: &Polynomial, i: usize, at: &VariableIndex) -> Polynomial {
    let momentum = l.derivative(at.qd(i));
    let mut tau = -d_dq(l, i, at);
    for j in 0..at.dof {
        tau = tau + times_variable(&d_dq(&momentum, j, at), at.qd(j));
        tau = tau + times_variable(&momentum.derivative(at.qd(j)), at.qdd(j));
    }
    tau
}

/// d p / d q_j = c_j dp/ds_j - s_j dp/dc_j (dp/dq_j for a prismatic joint).
fn d_dq(p: &Polynomial, j: usize, at: &VariableIndex) -> Polynomial {
    if at.prismatic[j] {
        return p.derivative(at.q(j));
    }
    times_variable(&p.derivative(at.sin(j)), at.cos(j))
        - times_variable(&p.derivative(at.cos(j)), at.sin(j))
}

fn times_variable(p: &Polynomial, variable: usize) -> Polynomial {
    let mut exponents = vec![0u16; p.nvars()];
    exponents[variable] = 1;
    p.clone().mul_monomial(&p.ring().one(), &exponents)
}

/// Splits tau (linear in the parameters) into one polynomial per parameter,
/// over the program inputs (exponents re-indexed, coefficients rounded once).
fn split_by_parameter(tau: &Polynomial, at: &VariableIndex) -> Vec<Poly> {
    let dof = at.dof;
    let mut columns: Vec<Vec<(Vec<u32>, f64)>> = vec![Vec::new(); 10 * dof];
    for (t, coefficient) in tau.coefficients.iter().enumerate() {
        let exponents = tau.exponents(t);
        let parameter = (0..10 * dof).find(|&k| exponents[at.parameter(k / 10, k % 10)] > 0);
        let Some(k) = parameter else { continue };
        let per_joint = crate::recursive::INPUTS_PER_JOINT;
        let mut program = vec![0u32; per_joint * dof];
        for j in 0..dof {
            let at_joint = &mut program[per_joint * j..per_joint * (j + 1)];
            at_joint[0] = u32::from(exponents[at.sin(j)]);
            at_joint[1] = u32::from(exponents[at.cos(j)]);
            at_joint[2] = u32::from(exponents[at.qd(j)]);
            at_joint[3] = u32::from(exponents[at.qdd(j)]);
            at_joint[5] = u32::from(exponents[at.q(j)]);
        }
        columns[k].push((program, coefficient.to_f64()));
    }
    columns.into_iter().map(Poly::from_terms).collect()
}

/// L = K - U of the chain, with symbolic inertial parameters.
fn lagrangian(chain: &Chain, symbols: &Symbols) -> Result<Atom, String> {
    let zero = || [Atom::num(0), Atom::num(0), Atom::num(0)];
    // Body-frame angular velocity and origin velocity of the previous body.
    let (mut w, mut v) = (zero(), zero());
    // World orientation and origin position of the previous body frame.
    let mut world_rotation = numeric_matrix(&Matrix3::identity())?;
    let mut world_origin = zero();
    let gravity = numeric_vector(&chain.gravity)?;
    let mut kinetic = Atom::num(0);
    let mut potential = Atom::num(0);
    for (i, body) in chain.bodies.iter().enumerate() {
        let qd = Atom::var(symbols.qd[i]);
        let axis = numeric_vector(&body.axis)?;
        let fixed = numeric_matrix(&body.rotation)?;
        let mut p = numeric_vector(&body.translation)?;
        let r = if body.kind == JointKind::Prismatic {
            let travel = scale(&mat_vec(&fixed, &axis), &Atom::var(symbols.q[i]));
            p = expand_vector(&add(&p, &travel));
            fixed
        } else {
            let joint = rotation(&body.axis, symbols.sin[i], symbols.cos[i])?;
            expand_matrix(&mat_mul(&fixed, &joint))
        };
        let rt = transpose(&r);
        v = expand_vector(&mat_vec(&rt, &add(&v, &cross(&w, &p))));
        w = expand_vector(&mat_vec(&rt, &w));
        if body.kind == JointKind::Prismatic {
            v = expand_vector(&add(&v, &scale(&axis, &qd)));
        } else {
            w = expand_vector(&add(&w, &scale(&axis, &qd)));
        }
        world_origin = expand_vector(&add(&world_origin, &mat_vec(&world_rotation, &p)));
        world_rotation = expand_matrix(&mat_mul(&world_rotation, &r));

        let [m, mx, my, mz, ixx, ixy, iyy, ixz, iyz, izz] = symbols.params[i].map(Atom::var);
        let h = [mx, my, mz];
        let inertia = [
            [ixx.clone(), ixy.clone(), ixz.clone()],
            [ixy, iyy, iyz.clone()],
            [ixz, iyz, izz],
        ];
        // K = 1/2 m v.v + v.(w x h) + 1/2 w.(I w), all in body axes.
        let half = Atom::num(1) / Atom::num(2);
        kinetic = kinetic
            + &half * &m * dot(&v, &v)
            + dot(&v, &cross(&w, &h))
            + &half * dot(&w, &mat_vec(&inertia, &w));
        // U = -g.(m o + W h): the full COM position, not only its height.
        potential -= dot(
            &gravity,
            &add(&scale(&world_origin, &m), &mat_vec(&world_rotation, &h)),
        );
    }
    Ok((kinetic - potential).expand())
}

/// Rodrigues: I + s S + (1 - c) S^2 with S the cross-product matrix of `axis`.
fn rotation(axis: &Vector3<f64>, sin: Symbol, cos: Symbol) -> Result<M3, String> {
    let s = skew(axis);
    let s2 = s * s;
    let (sin, cos) = (Atom::var(sin), Atom::var(cos));
    let one_minus_cos = Atom::num(1) - &cos;
    let mut out = numeric_matrix(&Matrix3::identity())?;
    for r in 0..3 {
        for c in 0..3 {
            out[r][c] = &out[r][c] + exact(s[(r, c)])? * &sin + exact(s2[(r, c)])? * &one_minus_cos;
        }
    }
    Ok(expand_matrix(&out))
}

fn skew(a: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -a.z, a.y, a.z, 0.0, -a.x, -a.y, a.x, 0.0)
}

/// The exact rational value of a finite f64.
fn exact(x: f64) -> Result<Atom, String> {
    let rational = Rational::try_from(x).map_err(|e| format!("cannot use {x} exactly: {e}"))?;
    Ok(Atom::num(rational))
}

fn numeric_vector(v: &Vector3<f64>) -> Result<V3, String> {
    Ok([exact(v.x)?, exact(v.y)?, exact(v.z)?])
}

fn numeric_matrix(m: &Matrix3<f64>) -> Result<M3, String> {
    let row = |r: usize| -> Result<V3, String> {
        Ok([exact(m[(r, 0)])?, exact(m[(r, 1)])?, exact(m[(r, 2)])?])
    };
    Ok([row(0)?, row(1)?, row(2)?])
}

fn add(a: &V3, b: &V3) -> V3 {
    [&a[0] + &b[0], &a[1] + &b[1], &a[2] + &b[2]]
}

fn scale(a: &V3, k: &Atom) -> V3 {
    [&a[0] * k, &a[1] * k, &a[2] * k]
}

fn dot(a: &V3, b: &V3) -> Atom {
    &a[0] * &b[0] + &a[1] * &b[1] + &a[2] * &b[2]
}

fn cross(a: &V3, b: &V3) -> V3 {
    [
        &a[1] * &b[2] - &a[2] * &b[1],
        &a[2] * &b[0] - &a[0] * &b[2],
        &a[0] * &b[1] - &a[1] * &b[0],
    ]
}

fn mat_vec(m: &M3, v: &V3) -> V3 {
    [dot(&m[0], v), dot(&m[1], v), dot(&m[2], v)]
}

fn mat_mul(a: &M3, b: &M3) -> M3 {
    let column = |c: usize| [b[0][c].clone(), b[1][c].clone(), b[2][c].clone()];
    let cols = [column(0), column(1), column(2)];
    [0, 1, 2].map(|r| [0, 1, 2].map(|c| dot(&a[r], &cols[c])))
}

fn transpose(m: &M3) -> M3 {
    [0, 1, 2].map(|r| [0, 1, 2].map(|c| m[c][r].clone()))
}

fn expand_vector(v: &V3) -> V3 {
    [v[0].expand(), v[1].expand(), v[2].expand()]
}

fn expand_matrix(m: &M3) -> M3 {
    [0, 1, 2].map(|r| [0, 1, 2].map(|c| m[r][c].expand()))
}
