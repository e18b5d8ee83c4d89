//! The mass matrix by the composite-rigid-body algorithm: each body's
//! inertia with everything it carries (tip first), then per joint the
//! momentum its unit motion gives that composite, carried inwards; M_ij is
//! joint i's axis component of joint j's momentum. Every body is in its own
//! axes, so a joint's motion and its row of M are axis components.

use super::newton_euler::Rotation;
use super::regroup::BodyParameters;
use super::{Tracer, V3};
use crate::program::NodeId;

impl Tracer<'_> {
    /// M per moving body (n x n, row-major), armature on the diagonal.
    pub(super) fn composite_mass_matrix(&mut self, rotations: &[Rotation]) -> Vec<NodeId> {
        let n = self.chain.bodies.len();
        let mut composite = self.parameters.clone();
        for c in (0..n).rev() {
            if let Some(p) = self.chain.bodies[c].parent {
                let carried = self.in_parent_frame(c, &rotations[c], composite[c]);
                composite[p] = self.sum_bodies(composite[p], carried);
            }
        }
        let zero = self.dag.constant(0.0);
        let mut mass = vec![zero; n * n];
        for j in 0..n {
            let (mut force, mut moment) = self.unit_momentum(j, composite[j]);
            let mut k = j;
            loop {
                let mut entry = self.axis_component(k, force, moment);
                if k == j {
                    let armature = self.joint(j).effects[0];
                    entry = self.dag.sum2(entry, armature);
                }
                mass[k * n + j] = entry;
                mass[j * n + k] = entry;
                let Some(parent) = self.chain.bodies[k].parent else {
                    break;
                };
                (force, moment) = self.wrench_in_parent_frame(k, &rotations[k], force, moment);
                k = parent;
            }
        }
        mass
    }

    /// Body `c`'s parameters in its parent's axes about the parent's origin.
    fn in_parent_frame(
        &mut self,
        c: usize,
        rotation: &Rotation,
        body: BodyParameters,
    ) -> BodyParameters {
        let h = self.in_parent_axes(rotation, body.h);
        // R I R^T, column by column: R (R I)^T since I is symmetric.
        let ri = [0, 1, 2].map(|k| {
            let column = [body.inertia[0][k], body.inertia[1][k], body.inertia[2][k]];
            self.in_parent_axes(rotation, column)
        });
        // ri[k] is column k of R I, so row k of (R I)^T = I R^T.
        let rir = [0, 1, 2].map(|k| {
            let column = [ri[0][k], ri[1][k], ri[2][k]];
            self.in_parent_axes(rotation, column)
        });
        // rir[k] is column k of R I R^T; keep the upper triangle, mirrored.
        let inertia = [0, 1, 2].map(|r| [0, 1, 2].map(|c| rir[r.max(c)][r.min(c)]));
        let origin = self.origin(c);
        self.translated(
            BodyParameters {
                m: body.m,
                h,
                inertia,
            },
            origin,
        )
    }

    fn sum_bodies(&mut self, a: BodyParameters, b: BodyParameters) -> BodyParameters {
        BodyParameters {
            m: self.dag.sum2(a.m, b.m),
            h: self.add(a.h, b.h),
            inertia: self.mat_add(&a.inertia, &b.inertia),
        }
    }

    /// The momentum (linear, angular about the origin) of a body moving
    /// with joint `j`'s unit motion: (z x h, I z) turning, (m z, h x z)
    /// sliding.
    fn unit_momentum(&mut self, j: usize, body: BodyParameters) -> (V3, V3) {
        let z = self.joint(j).axis;
        if self.prismatic(j) {
            (self.scale(z, body.m), self.cross(body.h, z))
        } else {
            (self.cross(z, body.h), self.mat_vec(&body.inertia, z))
        }
    }

    /// What joint `k` feels of a wrench or momentum in its body's axes.
    fn axis_component(&mut self, k: usize, force: V3, moment: V3) -> NodeId {
        let z = self.joint(k).axis;
        let along = if self.prismatic(k) { force } else { moment };
        self.dot(z, along)
    }

    /// A wrench in body `k`'s axes about its origin, in the parent's axes
    /// about the parent's origin.
    pub(super) fn wrench_in_parent_frame(
        &mut self,
        k: usize,
        rotation: &Rotation,
        force: V3,
        moment: V3,
    ) -> (V3, V3) {
        let force = self.in_parent_axes(rotation, force);
        let moment = self.in_parent_axes(rotation, moment);
        let origin = self.origin(k);
        let lever = self.cross(origin, force);
        (force, self.add(moment, lever))
    }
}
