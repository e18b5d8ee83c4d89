//! d tau / d q and d tau / d qd: the traced tau differentiated exactly,
//! forward mode, one joint variable at a time (`derivative.rs`). What the
//! chain rule needs of each program input: d sin(q) = cos(q) dq,
//! d cos(q) = -sin(q) dq, a ripple's sin and cos likewise times its cycles,
//! a coupled body's sin and cos times its multiplier, and the Stribeck
//! shape's slope -2 qd / v_s^2 times the shape. sign(qd) is piecewise
//! constant: its derivative is taken as 0 (also at qd = 0, where the
//! torque jumps).

use super::{COS, INPUTS_PER_JOINT, Q, QD, RIPPLE_COS, RIPPLE_SIN, SIN, STRIBECK, Tracer};
use crate::derivative::derivative;
use crate::lanes::LaneProgram;
use crate::program::NodeId;

/// A direction of differentiation: a joint's angle or its speed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    Angle(usize),
    Speed(usize),
}

/// The directions paired on two lanes: each joint's angle with its speed.
/// Both start at the joint's body and move the same subtree, so their
/// tangents overlap most. Counted on the Panda (before like terms were
/// combined): 3,249 lane operations this way, 3,581 with neighbouring
/// angles and neighbouring speeds paired (q1 q2, ..., q7 qd1, ...), 3,692
/// with angle j and speed 8 - j; 5,439 - 599 = 4,840 scalar ones.
pub fn pairs(dof: usize) -> Vec<[Direction; 2]> {
    (0..dof)
        .map(|d| [Direction::Angle(d), Direction::Speed(d)])
        .collect()
}

impl Tracer<'_> {
    /// (d tau / d q, d tau / d qd), each dof x dof row-major: row i is
    /// output i, column j input j.
    pub(super) fn tau_derivatives(&mut self, tau: &[NodeId]) -> (Vec<NodeId>, Vec<NodeId>) {
        let n = self.chain.dof();
        let mut by_q = Vec::with_capacity(n);
        let mut by_qd = Vec::with_capacity(n);
        for d in 0..n {
            let seeds = self.position_seeds(d);
            by_q.push(derivative(&mut self.dag, tau, |_, i| seeds[i]));
            let seeds = self.velocity_seeds(d);
            by_qd.push(derivative(&mut self.dag, tau, |_, i| seeds[i]));
        }
        let row_major = |columns: Vec<Vec<NodeId>>| -> Vec<NodeId> {
            (0..n * n).map(|k| columns[k % n][k / n]).collect()
        };
        (row_major(by_q), row_major(by_qd))
    }

    /// The same derivatives as `tau_derivatives`, two directions per
    /// group (`pairs`), as a two-lane tangent program.
    pub(super) fn tau_lanes(&mut self, tau: &[NodeId], pairs: &[[Direction; 2]]) -> LaneProgram {
        let mut lanes = LaneProgram::default();
        for pair in pairs {
            let seeds = pair.map(|direction| match direction {
                Direction::Angle(d) => self.position_seeds(d),
                Direction::Speed(d) => self.velocity_seeds(d),
            });
            lanes.push_group(&mut self.dag, tau, &seeds);
        }
        lanes
    }

    fn input_count(&self) -> usize {
        INPUTS_PER_JOINT * self.chain.dof() + 2 * super::coupled_bodies(self.chain).len()
    }

    /// Each program input's derivative with respect to q_d.
    fn position_seeds(&mut self, d: usize) -> Vec<Option<NodeId>> {
        let mut seeds = vec![None; self.input_count()];
        let base = INPUTS_PER_JOINT * d;
        let body = self.chain.dof_bodies()[d];
        let cycles = self.joint(body).ripple_cycles;
        let one = self.dag.constant(1.0);
        seeds[base + Q] = Some(one);
        let turns = [(SIN, COS, one), (RIPPLE_SIN, RIPPLE_COS, cycles)];
        for (sin, cos, rate) in turns {
            let [s, c] = [base + sin, base + cos];
            seeds[s] = Some(self.rate_of_sine(c, rate));
            seeds[c] = Some(self.rate_of_cosine(s, rate));
        }
        let first = INPUTS_PER_JOINT * self.chain.dof();
        for (slot, b) in super::coupled_bodies(self.chain).into_iter().enumerate() {
            if self.chain.driver(b).0 != d {
                continue;
            }
            let multiplier = self.joint(b).coupling[0];
            let [s, c] = [first + 2 * slot, first + 2 * slot + 1];
            seeds[s] = Some(self.rate_of_sine(c, multiplier));
            seeds[c] = Some(self.rate_of_cosine(s, multiplier));
        }
        seeds
    }

    /// d sin(k q) = k cos(k q) dq, with input `cos` holding cos(k q).
    fn rate_of_sine(&mut self, cos: usize, k: NodeId) -> NodeId {
        let c = self.dag.input(cos);
        self.dag.product2(k, c)
    }

    /// d cos(k q) = -k sin(k q) dq.
    fn rate_of_cosine(&mut self, sin: usize, k: NodeId) -> NodeId {
        let s = self.dag.input(sin);
        let ks = self.dag.product2(k, s);
        self.dag.negate(ks)
    }

    /// Each program input's derivative with respect to qd_d.
    fn velocity_seeds(&mut self, d: usize) -> Vec<Option<NodeId>> {
        let mut seeds = vec![None; self.input_count()];
        let base = INPUTS_PER_JOINT * d;
        seeds[base + QD] = Some(self.dag.constant(1.0));
        let velocity = self.joint(self.chain.dof_bodies()[d]).stribeck_velocity;
        if self.dag.is_literal_zero(velocity) {
            return seeds;
        }
        // d/dqd [sign(qd) exp(-(qd/v_s)^2)] = -2 qd / v_s^2 times the shape.
        let square = self.dag.product2(velocity, velocity);
        let inverse = self.dag.reciprocal(square);
        let minus_two = self.dag.constant(-2.0);
        let rate = self.dag.product2(minus_two, inverse);
        let qd = self.dag.input(base + QD);
        let shape = self.dag.input(base + STRIBECK);
        let slope = self.dag.product2(qd, shape);
        seeds[base + STRIBECK] = Some(self.dag.product2(rate, slope));
        seeds
    }
}
