//! The inertial parameters the dynamics use: each body's standard
//! parameters with every part that cannot feel its own joint moved to the
//! parent body, as derived constants of the description's numbers.
//!
//! Moved are the mass and the first moment along the joint axis (they sit
//! on the axis) and an inertia b (1 - z z^T) about the axis (it sees only
//! the parent's rotation), with b chosen to zero one diagonal entry when the
//! axis is a coordinate axis. Kinetic and potential energy are unchanged, so
//! tau, M, g and c are the same (the classical base-parameter regrouping for
//! revolute joints); the regressor keeps the description's parameters.
//! A body behind a prismatic joint keeps all its parameters.

use super::{SNAP, Tracer, V3};
use crate::program::NodeId;

/// Mass, first moment m*c and inertia about the body origin, as program
/// nodes (named derived constants where regrouping changed them).
#[derive(Clone, Copy)]
pub struct BodyParameters {
    pub m: NodeId,
    pub h: V3,
    pub inertia: [V3; 3],
}

const QUANTITIES: [&str; 10] = [
    "MASS", "MX", "MY", "MZ", "IXX", "IXY", "IYY", "IXZ", "IYZ", "IZZ",
];

impl Tracer<'_> {
    /// Every body's regrouped parameters, tip first, each named
    /// `LINKi_REGROUPED_...` where it differs from the standard parameter.
    pub(super) fn regrouped(&mut self) -> Vec<BodyParameters> {
        let n = self.chain.bodies.len();
        let mut parameters: Vec<BodyParameters> = (0..n).map(|i| self.standard(i)).collect();
        for j in (0..n).rev() {
            if self.prismatic(j) {
                // A sliding body's mass and first moment feel its joint;
                // it keeps its parameters.
                continue;
            }
            let BodyParameters { m, h, inertia } = parameters[j];
            let z = self.joint(j).axis;
            let along = self.dot(h, z);
            let b = match coordinate_axis(&self.chain.bodies[j].axis) {
                Some(k) => inertia[(k + 1) % 3][(k + 1) % 3],
                None => self.dag.constant(0.0),
            };
            let ring = self.ring(z);
            let on_axis = self.scale(z, along);
            let kept_h = self.subtract(h, on_axis);
            let moved_ring = self.mat_scale(&ring, b);
            let kept_inertia = self.mat_subtract(&inertia, &moved_ring);
            let zero = self.dag.constant(0.0);
            parameters[j] = BodyParameters {
                m: zero,
                h: kept_h,
                inertia: kept_inertia,
            };
            let Some(p) = self.chain.bodies[j].parent else {
                continue;
            };
            let added = self.moved_to_parent(j, m, along, b);
            let parent = parameters[p];
            parameters[p] = BodyParameters {
                m: self.dag.sum2(parent.m, added.m),
                h: self.add(parent.h, added.h),
                inertia: self.mat_add(&parent.inertia, &added.inertia),
            };
        }
        for (i, p) in parameters.iter().enumerate() {
            let entries = [
                p.m,
                p.h[0],
                p.h[1],
                p.h[2],
                p.inertia[0][0],
                p.inertia[0][1],
                p.inertia[1][1],
                p.inertia[0][2],
                p.inertia[1][2],
                p.inertia[2][2],
            ];
            for (entry, quantity) in entries.into_iter().zip(QUANTITIES) {
                self.dag
                    .name(entry, &format!("LINK{}_REGROUPED_{quantity}", i + 1));
            }
        }
        parameters
    }

    fn standard(&mut self, i: usize) -> BodyParameters {
        let [m, hx, hy, hz, xx, xy, yy, xz, yz, zz] = self.leaves.standard[i];
        BodyParameters {
            m,
            h: [hx, hy, hz],
            inertia: [[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]],
        }
    }

    /// 1 - z z^T.
    fn ring(&mut self, z: V3) -> [V3; 3] {
        let one = self.dag.constant(1.0);
        let identity = self.diagonal(one);
        let zz = self.outer(z, z);
        self.mat_subtract(&identity, &zz)
    }

    /// Body `j`'s on-axis mass `m`, first moment `along` z and inertia
    /// b (1 - z z^T), in the parent's axes about the parent's origin.
    fn moved_to_parent(&mut self, j: usize, m: NodeId, along: NodeId, b: NodeId) -> BodyParameters {
        let joint = self.joint(j);
        let (p, rotation, z) = (joint.translation, joint.rotation, joint.axis);
        let zp = self.mat_vec(&rotation, z);
        let moment = self.scale(zp, along);
        let ring = self.ring(zp);
        let about_p = self.mat_scale(&ring, b);
        self.translated(
            BodyParameters {
                m,
                h: moment,
                inertia: about_p,
            },
            p,
        )
    }

    /// A body's parameters given in axes parallel to the parent's, about a
    /// point at `p` in the parent frame, moved to the parent's origin:
    /// h + m p and the parallel-axis terms
    /// m (|p|^2 1 - p p^T) + 2 (p . h) 1 - p h^T - h p^T.
    pub(super) fn translated(&mut self, body: BodyParameters, p: V3) -> BodyParameters {
        let BodyParameters { m, h, inertia } = body;
        let p2 = self.dot(p, p);
        let p2_one = self.diagonal(p2);
        let pp = self.outer(p, p);
        let point = self.mat_subtract(&p2_one, &pp);
        let point = self.mat_scale(&point, m);
        let two = self.dag.constant(2.0);
        let ph = self.dot(p, h);
        let ph2 = self.dag.product2(two, ph);
        let cross_terms = self.diagonal(ph2);
        let p_h = self.outer(p, h);
        let h_p = self.outer(h, p);
        let inertia = self.mat_add(&inertia, &point);
        let inertia = self.mat_add(&inertia, &cross_terms);
        let inertia = self.mat_subtract(&inertia, &p_h);
        let inertia = self.mat_subtract(&inertia, &h_p);
        let mp = self.scale(p, m);
        BodyParameters {
            m,
            h: self.add(mp, h),
            inertia,
        }
    }
}

/// k when `z` is +-e_k.
fn coordinate_axis(z: &nalgebra::Vector3<f64>) -> Option<usize> {
    (0..3).find(|&k| (z[k].abs() - 1.0).abs() < SNAP && z.norm_squared() - z[k] * z[k] < SNAP)
}
