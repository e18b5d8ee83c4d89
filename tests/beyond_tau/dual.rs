//! Forward-mode dual numbers and a recursive Newton-Euler written over
//! them from the oracle's model data, sharing no code with the generator
//! or the oracle's algorithms: d tau / d x to rounding, the independent
//! second computation the generated derivatives are checked against.

use std::ops::{Add, Mul, Neg, Sub};

use codegen::JointKind;
use sdnn::oracle::Model;

/// v + d eps with eps^2 = 0.
#[derive(Debug, Clone, Copy)]
pub struct Dual {
    pub v: f64,
    pub d: f64,
}

impl Dual {
    pub fn constant(v: f64) -> Dual {
        Dual { v, d: 0.0 }
    }
    fn sin(self) -> Dual {
        Dual {
            v: self.v.sin(),
            d: self.d * self.v.cos(),
        }
    }
    fn cos(self) -> Dual {
        Dual {
            v: self.v.cos(),
            d: -self.d * self.v.sin(),
        }
    }
    fn exp(self) -> Dual {
        let e = self.v.exp();
        Dual {
            v: e,
            d: self.d * e,
        }
    }
}

impl Add for Dual {
    type Output = Dual;
    fn add(self, o: Dual) -> Dual {
        Dual {
            v: self.v + o.v,
            d: self.d + o.d,
        }
    }
}
impl Sub for Dual {
    type Output = Dual;
    fn sub(self, o: Dual) -> Dual {
        Dual {
            v: self.v - o.v,
            d: self.d - o.d,
        }
    }
}
impl Mul for Dual {
    type Output = Dual;
    fn mul(self, o: Dual) -> Dual {
        Dual {
            v: self.v * o.v,
            d: self.d * o.v + self.v * o.d,
        }
    }
}
impl Mul<Dual> for f64 {
    type Output = Dual;
    fn mul(self, o: Dual) -> Dual {
        Dual {
            v: self * o.v,
            d: self * o.d,
        }
    }
}
impl Neg for Dual {
    type Output = Dual;
    fn neg(self) -> Dual {
        Dual {
            v: -self.v,
            d: -self.d,
        }
    }
}

type V = [Dual; 3];
type M = [[Dual; 3]; 3];

fn c(x: f64) -> Dual {
    Dual::constant(x)
}
fn vec(x: [f64; 3]) -> V {
    x.map(c)
}
fn add(a: V, b: V) -> V {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn scale(a: V, s: Dual) -> V {
    a.map(|x| x * s)
}
fn cross(a: V, b: V) -> V {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn dot(a: V, b: V) -> Dual {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn times(m: &M, v: V) -> V {
    [dot(m[0], v), dot(m[1], v), dot(m[2], v)]
}
fn transposed_times(m: &M, v: V) -> V {
    let column = |k: usize| [m[0][k], m[1][k], m[2][k]];
    [dot(column(0), v), dot(column(1), v), dot(column(2), v)]
}

/// R_fixed (I + sin K + (1 - cos) K^2), K the axis's cross matrix.
fn joint_rotation(fixed: &nalgebra::Matrix3<f64>, axis: [f64; 3], angle: Dual) -> M {
    let k = [
        [0.0, -axis[2], axis[1]],
        [axis[2], 0.0, -axis[0]],
        [-axis[1], axis[0], 0.0],
    ];
    let (s, one_minus_c) = (angle.sin(), c(1.0) - angle.cos());
    let rot: M = std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            let kk: f64 = (0..3).map(|l| k[i][l] * k[l][j]).sum();
            c(if i == j { 1.0 } else { 0.0 }) + k[i][j] * s + kk * one_minus_c
        })
    });
    std::array::from_fn(|i| {
        std::array::from_fn(|j| (0..3).fold(c(0.0), |acc, l| acc + fixed[(i, l)] * rot[l][j]))
    })
}

/// tau of `model` at dual (q, qd, qdd): rigid body and every joint effect.
pub fn rnea(model: &Model, q: &[Dual], qd: &[Dual], qdd: &[Dual]) -> Vec<Dual> {
    let n = model.bodies.len();
    let zero = vec([0.0; 3]);
    let gravity = vec([-model.gravity.x, -model.gravity.y, -model.gravity.z]);
    let mut frames: Vec<(M, V)> = Vec::with_capacity(n);
    let mut motions: Vec<(V, V, V)> = Vec::with_capacity(n);
    let mut wrenches: Vec<(V, V)> = Vec::with_capacity(n);
    let mut own = Vec::with_capacity(n);
    for body in &model.bodies {
        let (d, multiplier, offset) = body.driver;
        let x = multiplier * q[d] + c(offset);
        let (v, a) = (multiplier * qd[d], multiplier * qdd[d]);
        let z = [body.axis.x, body.axis.y, body.axis.z];
        let t = [body.translation.x, body.translation.y, body.translation.z];
        let sliding = body.kind == JointKind::Prismatic;
        let (rotation, origin) = if sliding {
            let along = body.rotation * body.axis.into_inner();
            let travel = scale(vec([along.x, along.y, along.z]), x);
            (
                joint_rotation(&body.rotation, z, c(0.0)),
                add(vec(t), travel),
            )
        } else {
            (joint_rotation(&body.rotation, z, x), vec(t))
        };
        let (w0, wd0, a0) = body.parent.map_or((zero, zero, gravity), |p| motions[p]);
        let relative = add(cross(wd0, origin), cross(w0, cross(w0, origin)));
        let mut lin = transposed_times(&rotation, add(a0, relative));
        let (w_in, wd_in) = (
            transposed_times(&rotation, w0),
            transposed_times(&rotation, wd0),
        );
        let zv = vec(z);
        let (w, wd) = if sliding {
            lin = add(lin, add(scale(cross(w_in, zv), c(2.0) * v), scale(zv, a)));
            (w_in, wd_in)
        } else {
            let w = add(w_in, scale(zv, v));
            (w, add(add(wd_in, scale(zv, a)), scale(cross(w_in, zv), v)))
        };
        let [m, hx, hy, hz, xx, xy, yy, xz, yz, zz] = body.parameters.map(c);
        let h = [hx, hy, hz];
        let inertia: M = [[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]];
        let force = add(add(scale(lin, m), cross(wd, h)), cross(w, cross(w, h)));
        let moment = add(
            add(times(&inertia, wd), cross(w, times(&inertia, w))),
            cross(h, lin),
        );
        frames.push((rotation, origin));
        motions.push((w, wd, lin));
        wrenches.push((force, moment));
        own.push((x, v, a, sliding));
    }
    let mut tau = vec![c(0.0); model.dof()];
    for b in (0..n).rev() {
        let body = &model.bodies[b];
        let (force, moment) = wrenches[b];
        if let Some(p) = body.parent {
            let (rotation, origin) = frames[b];
            let f = times(&rotation, force);
            let m = add(times(&rotation, moment), cross(origin, f));
            wrenches[p] = (add(wrenches[p].0, f), add(wrenches[p].1, m));
        }
        let (x, v, a, sliding) = own[b];
        let z = vec([body.axis.x, body.axis.y, body.axis.z]);
        let rigid = dot(z, if sliding { force } else { moment });
        let (d, multiplier, _) = body.driver;
        tau[d] = tau[d] + multiplier * (rigid + effects(&body.effects, x, v, a));
    }
    tau
}

/// The joint effects of the description format, on the joint's own state.
fn effects(e: &codegen::JointEffects, q: Dual, qd: Dual, qdd: Dual) -> Dual {
    let sign = if qd.v > 0.0 {
        1.0
    } else if qd.v < 0.0 {
        -1.0
    } else {
        0.0
    };
    let breakaway = if e.stribeck_velocity > 0.0 {
        let x = (1.0 / e.stribeck_velocity) * qd;
        sign * (-(x * x)).exp()
    } else {
        c(0.0)
    };
    let angle = e.ripple_cycles * q;
    e.armature * qdd
        + e.viscous * qd
        + c(e.coulomb * sign + e.coulomb_asymmetry * sign * sign + e.offset)
        + e.stribeck * breakaway
        + e.spring * (q - c(e.spring_rest))
        + e.ripple_sin * angle.sin()
        + e.ripple_cos * angle.cos()
}

/// (d tau / d q, d tau / d qd), row i output i, column j input j.
pub fn tau_derivatives(model: &Model, q: &[f64], qd: &[f64], qdd: &[f64]) -> [Vec<Vec<f64>>; 2] {
    let n = q.len();
    let seeded = |x: &[f64], j: Option<usize>| -> Vec<Dual> {
        (0..n)
            .map(|k| Dual {
                v: x[k],
                d: if Some(k) == j { 1.0 } else { 0.0 },
            })
            .collect()
    };
    let column = |by_q: bool, j: usize| -> Vec<f64> {
        let (dq, dqd) = if by_q {
            (Some(j), None)
        } else {
            (None, Some(j))
        };
        rnea(model, &seeded(q, dq), &seeded(qd, dqd), &seeded(qdd, None))
            .iter()
            .map(|t| t.d)
            .collect()
    };
    [true, false].map(|by_q| {
        let columns: Vec<Vec<f64>> = (0..n).map(|j| column(by_q, j)).collect();
        (0..n)
            .map(|i| (0..n).map(|j| columns[j][i]).collect())
            .collect()
    })
}
