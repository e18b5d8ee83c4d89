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

/// Bracketing steps of the amplitude factor that brings the torque down
/// to its limit: the bracket shrinks superlinearly, so after these the
/// factor is within rounding of the largest that fits.
const TORQUE_STEPS: usize = 12;

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

    /// The motion with every amplitude scaled by the largest factor (at
    /// most 1) that keeps the torque within its limits on the tracks'
    /// samples; `None` if even the motion's centre posture does not.
    /// Found by regula falsi (Illinois) on the factor, keeping the
    /// bracket's feasible end: a smooth function of the coefficients,
    /// where shrinking by fixed steps made the criterion jump.
    fn within_torque(&self, (joints, tracks): Sampled) -> Option<Sampled> {
        let excess = |f: f64| -> Option<f64> {
            let scaled: Vec<Track> = tracks
                .iter()
                .zip(&joints)
                .map(|(t, s)| t.scaled(s.centre, f))
                .collect();
            Some(self.torque_ratio(&scaled)? - 1.0)
        };
        let high = excess(1.0)?;
        let f = if high <= 0.0 {
            1.0
        } else {
            let low = excess(0.0)?;
            if low > 0.0 {
                return None;
            }
            largest_feasible((0.0, low), (1.0, high), excess)?
        };
        let tracks = tracks
            .iter()
            .zip(&joints)
            .map(|(t, s)| t.scaled(s.centre, f))
            .collect();
        Some((joints.iter().map(|s| s.scaled(f)).collect(), tracks))
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

    /// The information matrix of raw coefficients `x` on the design grid
    /// (per sample) scaled to a unit diagonal, and that diagonal; `None`
    /// where no motion fits the limits.
    fn information(&self, x: &[f64]) -> Option<(DMatrix<f64>, Vec<f64>)> {
        let (_, tracks) = self.motion(x)?;
        let samples = samples(&tracks);
        let f = self
            .parameters
            .information(self.model, &samples, 1.0 / self.grid_len as f64)
            .ok()?;
        let diagonal = f.diagonal().iter().copied().collect();
        Some((unit_diagonal(&f), diagonal))
    }

    /// The criterion: ln of the condition number, plus (with `--from`) ln
    /// of the weighted parameters' mean predicted variance ([`focus`]).
    pub fn cost(&self, x: &[f64]) -> f64 {
        self.criterion(x, |f| {
            let (low, high) = spectrum::extremes(f)?;
            (low > 0.0).then(|| (high / low).ln())
        })
    }

    /// The criterion with the condition number replaced by a smooth
    /// stand-in: (tr F^8)^(1/8) (tr F^-8)^(1/8), the ratio of the 8-norms
    /// of the eigenvalues and of their inverses. It exceeds the condition
    /// number by at most the parameter count to the 1/8 (1.7 for 76
    /// parameters) and, unlike it, rewards lifting any small eigenvalue,
    /// not only the smallest: the search's progress no longer stalls where
    /// several are equal.
    pub fn smooth_cost(&self, x: &[f64]) -> f64 {
        self.criterion(x, |f| {
            let inverse = f.clone().cholesky()?.inverse();
            let v = eighth_norm(f) + eighth_norm(&inverse);
            v.is_finite().then_some(v)
        })
    }

    fn criterion(&self, x: &[f64], log_condition: impl Fn(&DMatrix<f64>) -> Option<f64>) -> f64 {
        let Some((f, diagonal)) = self.information(x) else {
            return f64::INFINITY;
        };
        let Some(condition) = log_condition(&f) else {
            return f64::INFINITY;
        };
        if self.focus.is_empty() {
            return condition;
        }
        match focus(&f, &diagonal, &self.parameters.typical, self.focus) {
            Some(v) => condition + v.ln(),
            None => f64::INFINITY,
        }
    }
}

/// ln of (tr M^8)^(1/8) for symmetric M, by squaring (scaled first so the
/// powers stay finite).
fn eighth_norm(m: &DMatrix<f64>) -> f64 {
    let norm = m.norm();
    let m = m / norm;
    let square = &m * &m;
    let fourth = &square * &square;
    // tr M^8 = |M^4|_F^2.
    norm.ln() + 0.25 * fourth.norm().ln()
}

/// The mean, over the `focus` parameters, of their predicted variance
/// relative to that of a parameter whose column is orthogonal to all others
/// and as large as random states inside the limits make it (`typical`,
/// RMS per sample): the variance inflation of unit-diagonal `f` over the
/// column's mean square (`diagonal`). Both count: a diagnosis that found a
/// parameter poorly determined asks for a motion that moves it more, not
/// only one that tells it from the others.
fn focus(f: &DMatrix<f64>, diagonal: &[f64], typical: &[f64], focus: &[usize]) -> Option<f64> {
    let inverse = f.clone().cholesky()?.inverse();
    let total: f64 = focus
        .iter()
        .map(|&k| inverse[(k, k)] * typical[k] * typical[k] / diagonal[k])
        .sum();
    Some(total / focus.len() as f64)
}

/// Regula falsi (Illinois) between a feasible (g <= 0) and an infeasible
/// point of `g`; the feasible end of the last bracket.
fn largest_feasible(
    mut good: (f64, f64),
    mut bad: (f64, f64),
    g: impl Fn(f64) -> Option<f64>,
) -> Option<f64> {
    let mut side = 0;
    for _ in 0..TORQUE_STEPS {
        let x = (good.0 * bad.1 - bad.0 * good.1) / (bad.1 - good.1);
        let y = g(x)?;
        if y <= 0.0 {
            good = (x, y);
            // Two steps on the same side: halve the other end's value so
            // the bracket keeps closing from both sides (Illinois).
            if side == -1 {
                bad.1 *= 0.5;
            }
            side = -1;
        } else {
            bad = (x, y);
            if side == 1 {
                good.1 *= 0.5;
            }
            side = 1;
        }
    }
    Some(good.0)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_largest_feasible_factor_is_found_from_the_feasible_side() {
        // Torque ratio less one, growing with the amplitude factor: 0 at 0.5.
        let g = |f: f64| Some(f * f - 0.25);
        let f = largest_feasible((0.0, -0.25), (1.0, 0.75), g).unwrap();
        assert!(g(f).unwrap() <= 0.0 && f > 0.5 - 1e-9, "{f}");
    }

    #[test]
    fn a_failed_torque_evaluation_is_no_factor() {
        let g = |f: f64| (f < 0.3).then_some(f - 0.5);
        assert_eq!(largest_feasible((0.0, -0.5), (1.0, 0.5), g), None);
    }
}
