//! A planned motion read from a file (`sdnn excite`'s trajectory, or any
//! `t,q,qd,qdd` table) as a [`Reference`] the virtual robot tracks:
//! between samples, q is the cubic Hermite curve through the samples' q
//! and qd (so q and qd agree), qd its derivative and qdd linear. Before
//! the first sample and after the last the motion holds the end sample's
//! position at rest.

use nalgebra::{DMatrix, DVector};

use super::reference::Reference;
use crate::trajectory::Trajectory;

/// A sampled plan; `t` strictly increasing (the trajectory's invariant).
#[derive(Debug, Clone)]
pub struct Planned {
    t: Vec<f64>,
    q: DMatrix<f64>,
    qd: DMatrix<f64>,
    qdd: DMatrix<f64>,
}

impl Planned {
    /// The plan of `traj` (its accelerations, or zeros without them),
    /// shifted to start at t = 0.
    pub fn new(traj: &Trajectory) -> Planned {
        let start = traj.t().first().copied().unwrap_or(0.0);
        Planned {
            t: traj.t().iter().map(|t| t - start).collect(),
            q: traj.q().clone(),
            qd: traj.qd().clone(),
            qdd: traj
                .qdd()
                .cloned()
                .unwrap_or_else(|| DMatrix::zeros(traj.len(), traj.dof())),
        }
    }

    fn row(m: &DMatrix<f64>, i: usize) -> DVector<f64> {
        m.row(i).transpose()
    }
}

impl Reference for Planned {
    fn dof(&self) -> usize {
        self.q.ncols()
    }

    fn duration(&self) -> f64 {
        self.t.last().copied().unwrap_or(0.0)
    }

    fn sample(&self, t: f64) -> (DVector<f64>, DVector<f64>, DVector<f64>) {
        let n = self.t.len();
        let rest = |i: usize| {
            (
                Self::row(&self.q, i),
                DVector::zeros(self.dof()),
                DVector::zeros(self.dof()),
            )
        };
        if n == 0 {
            return (
                DVector::zeros(self.dof()),
                DVector::zeros(self.dof()),
                DVector::zeros(self.dof()),
            );
        }
        if t.is_nan() {
            let nan = DVector::from_element(self.dof(), f64::NAN);
            return (nan.clone(), nan.clone(), nan);
        }
        if t <= self.t[0] || n == 1 {
            return if t < self.t[0] {
                rest(0)
            } else {
                (
                    Self::row(&self.q, 0),
                    Self::row(&self.qd, 0),
                    Self::row(&self.qdd, 0),
                )
            };
        }
        if t >= self.t[n - 1] {
            return if t > self.t[n - 1] {
                rest(n - 1)
            } else {
                (
                    Self::row(&self.q, n - 1),
                    Self::row(&self.qd, n - 1),
                    Self::row(&self.qdd, n - 1),
                )
            };
        }
        let i = self.t.partition_point(|&s| s <= t) - 1;
        let h = self.t[i + 1] - self.t[i];
        let s = (t - self.t[i]) / h;
        let (q0, q1) = (Self::row(&self.q, i), Self::row(&self.q, i + 1));
        let (v0, v1) = (Self::row(&self.qd, i) * h, Self::row(&self.qd, i + 1) * h);
        // Hermite basis and its first derivative in s.
        let (s2, s3) = (s * s, s * s * s);
        let (h00, h10, h01, h11) = (
            2.0 * s3 - 3.0 * s2 + 1.0,
            s3 - 2.0 * s2 + s,
            -2.0 * s3 + 3.0 * s2,
            s3 - s2,
        );
        let (d00, d10, d01, d11) = (
            6.0 * s2 - 6.0 * s,
            3.0 * s2 - 4.0 * s + 1.0,
            -6.0 * s2 + 6.0 * s,
            3.0 * s2 - 2.0 * s,
        );
        let q = &q0 * h00 + &v0 * h10 + &q1 * h01 + &v1 * h11;
        let qd = (&q0 * d00 + &v0 * d10 + &q1 * d01 + &v1 * d11) / h;
        let qdd = Self::row(&self.qdd, i) * (1.0 - s) + Self::row(&self.qdd, i + 1) * s;
        (q, qd, qdd)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plan(rate: f64) -> Trajectory {
        let n = (2.0 * rate) as usize + 1;
        let t: Vec<f64> = (0..n).map(|i| 1.0 + i as f64 / rate).collect();
        let q = DMatrix::from_fn(n, 1, |i, _| (t[i] * 2.0).sin());
        let qd = DMatrix::from_fn(n, 1, |i, _| 2.0 * (t[i] * 2.0).cos());
        let qdd = DMatrix::from_fn(n, 1, |i, _| -4.0 * (t[i] * 2.0).sin());
        Trajectory::new(t, q, qd, Some(qdd), DMatrix::zeros(n, 1)).unwrap()
    }

    #[test]
    fn between_samples_the_motion_follows_the_sampled_curve() {
        let p = Planned::new(&plan(100.0));
        assert!((p.duration() - 2.0).abs() < 1e-12);
        for k in 0..200 {
            let u = 0.0037 + k as f64 * 0.00991;
            let (q, qd, qdd) = p.sample(u);
            let t = u + 1.0;
            assert!((q[0] - (2.0 * t).sin()).abs() < 1e-7, "q at {u}");
            assert!((qd[0] - 2.0 * (2.0 * t).cos()).abs() < 1e-4, "qd at {u}");
            assert!((qdd[0] + 4.0 * (2.0 * t).sin()).abs() < 1e-3, "qdd at {u}");
        }
    }

    #[test]
    fn before_and_after_the_plan_the_arm_rests_at_its_ends() {
        let p = Planned::new(&plan(10.0));
        let (q, qd, qdd) = p.sample(-1.0);
        assert!((q[0] - 2f64.sin()).abs() < 1e-12 && qd[0] == 0.0 && qdd[0] == 0.0);
        let (q, qd, _) = p.sample(5.0);
        assert!((q[0] - 6f64.sin()).abs() < 1e-12 && qd[0] == 0.0);
        assert!(p.sample(f64::NAN).0[0].is_nan());
    }
}
