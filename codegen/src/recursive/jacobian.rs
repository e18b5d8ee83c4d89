//! The regressor from the joint twists in body axes: Y_ik = J_ik^T W_k.

use super::newton_euler::{Motion, Rotation};
use super::{QD, QDD, RIPPLE_COS, RIPPLE_SIN, SIGN, STRIBECK, Tracer, V3};
use crate::program::NodeId;
use crate::schema::{EFFECTS_PER_JOINT, PARAMETERS_PER_JOINT};

impl Tracer<'_> {
    /// `twists[k][j]`: the unit twist of joint j in body k's axes, for the
    /// joints j that move body k (its own and its ancestors'), else `None`.
    pub(super) fn twists(&mut self, rotations: &[Rotation]) -> Vec<Vec<Option<(V3, V3)>>> {
        let n = rotations.len();
        let zero = self.dag.constant(0.0);
        let mut twists: Vec<Vec<Option<(V3, V3)>>> = Vec::with_capacity(n);
        for (k, rotation) in rotations.iter().enumerate() {
            let p = self.origin(k);
            let mut row = vec![None; n];
            if let Some(parent) = self.chain.bodies[k].parent {
                for j in 0..n {
                    let Some((w, v)) = twists[parent][j] else {
                        continue;
                    };
                    let wxp = self.cross(w, p);
                    let v = self.add(v, wxp);
                    row[j] = Some((
                        self.in_body_axes(rotation, w),
                        self.in_body_axes(rotation, v),
                    ));
                }
            }
            let z = self.joint(k).axis;
            row[k] = Some(if self.prismatic(k) {
                ([zero; 3], z)
            } else {
                (z, [zero; 3])
            });
            twists.push(row);
        }
        twists
    }

    /// Rigid-body columns from the body wrenches per unit parameter, then the
    /// joint-effect columns (qdd, qd, sign(qd), 1 on the joint's own row).
    pub(super) fn regressor(
        &mut self,
        twists: &[Vec<Option<(V3, V3)>>],
        motions: &[Motion],
    ) -> Vec<NodeId> {
        let n = motions.len();
        let zero = self.dag.constant(0.0);
        let one = self.dag.constant(1.0);
        let width = PARAMETERS_PER_JOINT * n;
        let mut y = vec![zero; n * width];
        for (k, motion) in motions.iter().enumerate() {
            for (p, (force, moment)) in self.unit_wrenches(motion).into_iter().enumerate() {
                for (i, twist) in twists[k].iter().enumerate() {
                    let Some((w, v)) = *twist else { continue };
                    let a = self.dot(v, force);
                    let b = self.dot(w, moment);
                    y[i * width + 10 * k + p] = self.dag.sum2(a, b);
                }
            }
        }
        for i in 0..n {
            let row = i * width + 10 * n + EFFECTS_PER_JOINT * i;
            let sign = self.input(i, SIGN);
            y[row] = self.input(i, QDD);
            y[row + 1] = self.input(i, QD);
            y[row + 2] = sign;
            y[row + 3] = one;
            y[row + 4] = self.dag.product2(sign, sign);
            y[row + 5] = self.spring_stretch(i);
            y[row + 6] = self.input(i, STRIBECK);
            y[row + 7] = self.input(i, RIPPLE_SIN);
            y[row + 8] = self.input(i, RIPPLE_COS);
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
