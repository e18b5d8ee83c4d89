//! One set of raw coefficients made into a motion inside the limits, and
//! the criterion the search minimizes for it.

use nalgebra::DMatrix;

use super::fourier::{self, Basis, Bounds, JointSeries, Schedule, Track, kinematic_scale};
use super::information::{Parameters, Samples, unit_diagonal};
use super::spectrum;
use crate::dynamics::Dynamics;

/// The evaluation of raw coefficients on the design grid.
pub struct Problem<'a> {
    pub model: &'a dyn Dynamics,
    pub parameters: &'a Parameters,
    pub bounds: &'a Bounds,
    pub schedule: Schedule,
    /// The series' terms at the design grid's times.
    pub basis: Basis,
    pub grid_len: usize,
    /// Base parameters whose variance inflation the criterion adds.
    pub focus: &'a [usize],
    /// Share of each effort limit the planned torque may use.
    pub share: f64,
}

/// Factor by which every amplitude shrinks while the torque is too high,
/// and how often it may.
const SHRINK: f64 = 0.85;
const SHRINKS: usize = 14;

/// Joints' series with their tracks at some times.
pub type Sampled = (Vec<JointSeries>, Vec<Track>);

impl Problem<'_> {
    /// The motion of raw coefficients `x` on the design grid: each joint
    /// scaled to its limits there, then all shrunk until the torque fits;
    /// `None` if it never does.
    pub fn motion(&self, x: &[f64]) -> Option<Sampled> {
        let per = self.schedule.per_joint();
        let (joints, tracks) = (0..self.model.dof())
            .map(|j| {
                let series = JointSeries::from_raw(
                    &x[j * per..(j + 1) * per],
                    self.bounds.position[j],
                    &self.schedule,
                    j,
                );
                let track = self.basis.track(j, &series);
                let f = kinematic_scale(&track, series.centre, self.bounds, j);
                (series.scaled(f), track.scaled(series.centre, f))
            })
            .unzip();
        self.within_torque((joints, tracks))
    }

    /// The motion shrunk until the torque fits on its tracks' samples.
    fn within_torque(&self, (mut joints, mut tracks): Sampled) -> Option<Sampled> {
        for _ in 0..=SHRINKS {
            if self.torque_ratio(&tracks)? <= 1.0 {
                return Some((joints, tracks));
            }
            tracks = tracks
                .iter()
                .zip(&joints)
                .map(|(t, s)| t.scaled(s.centre, SHRINK))
                .collect();
            joints = joints.iter().map(|s| s.scaled(SHRINK)).collect();
        }
        None
    }

    /// The design checked at the written sample `times`: amplitudes
    /// lowered where a peak between the design grid's samples passes a
    /// limit, then shrunk until the torque fits there too.
    pub fn refine(&self, designed: Vec<JointSeries>, times: &[f64]) -> Option<Vec<JointSeries>> {
        let (joints, tracks) = designed
            .iter()
            .enumerate()
            .map(|(j, s)| {
                let track = Track::new(s, &self.schedule, times);
                let f =
                    kinematic_scale(&track, s.centre, self.bounds, j) / fourier::KINEMATIC_SHARE;
                if f < 1.0 {
                    let f = f * fourier::KINEMATIC_SHARE;
                    (s.scaled(f), track.scaled(s.centre, f))
                } else {
                    (s.clone(), track)
                }
            })
            .unzip();
        self.within_torque((joints, tracks))
            .map(|(joints, _)| joints)
    }

    /// Largest |tau| / (share x effort) over joints and samples.
    fn torque_ratio(&self, tracks: &[Track]) -> Option<f64> {
        if self.bounds.effort.iter().all(Option::is_none) {
            return Some(0.0);
        }
        let mut worst = 0.0_f64;
        for i in 0..tracks.first().map_or(0, |t| t.q.len()) {
            let (q, qd, qdd) = state_at(tracks, i);
            let tau = self.model.tau(&q, &qd, &qdd).ok()?;
            for (j, limit) in self.bounds.effort.iter().enumerate() {
                if let Some(l) = limit {
                    worst = worst.max(tau[j].abs() / (self.share * l));
                }
            }
        }
        worst.is_finite().then_some(worst)
    }

    /// The information matrix of raw coefficients `x` on the design grid,
    /// scaled to a unit diagonal; `None` where no motion fits the limits.
    pub fn information(&self, x: &[f64]) -> Option<DMatrix<f64>> {
        let (_, tracks) = self.motion(x)?;
        let samples = samples(&tracks);
        let f = self
            .parameters
            .information(self.model, &samples, 1.0 / self.grid_len as f64)
            .ok()?;
        Some(unit_diagonal(&f))
    }

    /// ln of the condition number, plus (with `--from`) ln of the weighted
    /// base parameters' mean variance inflation: their variance relative to
    /// what it would be were their columns orthogonal to all others.
    pub fn cost(&self, x: &[f64]) -> f64 {
        let Some(f) = self.information(x) else {
            return f64::INFINITY;
        };
        let Some((low, high)) = spectrum::extremes(&f) else {
            return f64::INFINITY;
        };
        if low <= 0.0 {
            return f64::INFINITY;
        }
        let cond = (high / low).ln();
        if self.focus.is_empty() {
            return cond;
        }
        match inflation(&f, self.focus) {
            Some(v) => cond + v.ln(),
            None => f64::INFINITY,
        }
    }
}

/// The mean of the `focus` diagonal entries of unit-diagonal `f`'s inverse.
fn inflation(f: &DMatrix<f64>, focus: &[usize]) -> Option<f64> {
    let inverse = f.clone().cholesky()?.inverse();
    Some(focus.iter().map(|&k| inverse[(k, k)]).sum::<f64>() / focus.len() as f64)
}

/// All joints' (q, qd, qdd) at sample i of their tracks.
fn state_at(tracks: &[Track], i: usize) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    (
        tracks.iter().map(|t| t.q[i]).collect(),
        tracks.iter().map(|t| t.qd[i]).collect(),
        tracks.iter().map(|t| t.qdd[i]).collect(),
    )
}

/// The tracks' samples, sample by sample.
pub fn samples(tracks: &[Track]) -> Samples {
    let n = tracks.first().map_or(0, |t| t.q.len());
    let mut s = Samples {
        q: Vec::with_capacity(n),
        qd: Vec::with_capacity(n),
        qdd: Vec::with_capacity(n),
    };
    for i in 0..n {
        let (q, qd, qdd) = state_at(tracks, i);
        s.q.push(q);
        s.qd.push(qd);
        s.qdd.push(qdd);
    }
    s
}
