//! Placements and the tip's velocity Jacobian, traced on q: each moving
//! body's frame in the base frame, the tip's Jacobian in the base axes at
//! the tip frame's origin (Pinocchio's LOCAL_WORLD_ALIGNED), and its drift
//! J-dot qd, the tip's classical acceleration at qdd = 0 without gravity.

use super::newton_euler::{Motion, Rotation};
use super::{Tracer, V3};
use crate::program::NodeId;

/// A frame in the base frame: rotation rows and origin.
#[derive(Clone, Copy)]
pub struct Placement {
    pub rotation: [V3; 3],
    pub position: V3,
}

impl Placement {
    /// Rotation row-major, then position: the generated `Pose`'s order.
    pub fn entries(&self) -> Vec<NodeId> {
        let mut out: Vec<NodeId> = self.rotation.iter().flatten().copied().collect();
        out.extend(self.position);
        out
    }
}

impl Tracer<'_> {
    /// Every moving body's frame in the base frame.
    pub(super) fn placements(&mut self, rotations: &[Rotation]) -> Vec<Placement> {
        let zero = self.dag.constant(0.0);
        let one = self.dag.constant(1.0);
        let base = Placement {
            rotation: self.diagonal(one),
            position: [zero; 3],
        };
        let mut placements: Vec<Placement> = Vec::with_capacity(rotations.len());
        for (i, rotation) in rotations.iter().enumerate() {
            let parent = match self.chain.bodies[i].parent {
                Some(p) => placements[p],
                None => base,
            };
            let origin = self.origin(i);
            let offset = self.mat_vec(&parent.rotation, origin);
            let position = self.add(parent.position, offset);
            let rotation = rotation
                .stages()
                .iter()
                .fold(parent.rotation, |r, stage| self.mat_mul(&r, stage));
            placements.push(Placement { rotation, position });
        }
        placements
    }

    /// A frame fixed to `body` (rotation rows and origin in its axes) in
    /// the base frame.
    pub(super) fn attached(
        &mut self,
        body: &Placement,
        rotation: &[V3; 3],
        origin: V3,
    ) -> Placement {
        let offset = self.mat_vec(&body.rotation, origin);
        Placement {
            rotation: self.mat_mul(&body.rotation, rotation),
            position: self.add(body.position, offset),
        }
    }

    /// The Jacobian of a frame fixed to `tip` with origin `point` (6 x dof
    /// row-major: linear velocity of that origin, then angular velocity,
    /// base axes). A body coupled to a degree of freedom adds its motion
    /// times its multiplier.
    pub(super) fn jacobian(
        &mut self,
        placements: &[Placement],
        tip: usize,
        point: V3,
    ) -> Vec<NodeId> {
        let n = self.chain.dof();
        let zero = self.dag.constant(0.0);
        let mut columns = vec![[zero; 6]; n];
        let mut body = Some(tip);
        while let Some(b) = body {
            let (d, _, _) = self.chain.driver(b);
            let axis = self.mat_vec(&placements[b].rotation, self.joint(b).axis);
            let (linear, angular) = if self.prismatic(b) {
                (axis, [zero; 3])
            } else {
                let lever = self.subtract(point, placements[b].position);
                (self.cross(axis, lever), axis)
            };
            let multiplier = self.joint(b).coupling[0];
            for (k, &v) in linear.iter().chain(&angular).enumerate() {
                let scaled = self.dag.product2(multiplier, v);
                columns[d][k] = self.dag.sum2(columns[d][k], scaled);
            }
            body = self.chain.bodies[b].parent;
        }
        (0..6 * n).map(|k| columns[k % n][k / n]).collect()
    }

    /// J-dot qd of `tip`: its origin's acceleration and its angular
    /// acceleration in base axes, from motions traced at qdd = 0 without
    /// gravity.
    pub(super) fn jacobian_drift(
        &mut self,
        placements: &[Placement],
        motions: &[Motion],
        tip: usize,
    ) -> Vec<NodeId> {
        let rotation = placements[tip].rotation;
        let linear = self.mat_vec(&rotation, motions[tip].a);
        let angular = self.mat_vec(&rotation, motions[tip].wd);
        linear.into_iter().chain(angular).collect()
    }
}
