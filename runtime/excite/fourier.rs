//! The excitation's shape: per joint a finite Fourier series (Swevers et
//! al. 1997) between two rests, scaled into the joint's limits.
//!
//! Joint j moves as q_j(t) = c_j + s_j sum_k [a_k sin(w_k u) + b_k (cos(w_k u) - 1)]
//! over its moving time u, w_k = k w, a whole number of base periods. The
//! `b` terms vanish at u = 0, so the motion starts at c_j; the
//! coefficients are projected so that the velocity and the acceleration
//! are zero at both ends of every period (the arm leaves and reaches its
//! rests smoothly) and at the joint's own pause, a point inside the span,
//! staggered from joint to joint, where it stops for [`Schedule::pause`]
//! seconds while the others move. Samples at rest tell a torque offset
//! from friction that depends on the direction of motion, and a joint
//! resting while the others move tells it without the other joints'
//! offsets confounding it.

use std::f64::consts::TAU;

/// The timing every joint shares.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Schedule {
    /// Whole length, s.
    pub duration: f64,
    /// Rest at each end, s (samples at rest tell a torque offset from
    /// friction that depends on the direction of motion).
    pub rest: f64,
    /// Each joint's pause inside the span, s.
    pub pause: f64,
    /// Base angular frequency, rad/s: a whole number of periods fills
    /// the moving time (the span less the pause).
    pub omega: f64,
    /// Joints (their pauses are spread over the span).
    pub joints: usize,
    /// Harmonics per joint.
    pub harmonics: usize,
}

impl Schedule {
    /// The schedule closest to `base_hz` (`None`: one period) that fits
    /// whole periods into the moving time (at least one period).
    pub fn new(
        duration: f64,
        (rest, pause): (f64, f64),
        base_hz: Option<f64>,
        harmonics: usize,
        joints: usize,
    ) -> Schedule {
        let moving = duration - 2.0 * rest - pause;
        let periods = base_hz.map_or(1.0, |hz| (moving * hz).round().max(1.0));
        Schedule {
            duration,
            rest,
            pause,
            omega: TAU * periods / moving,
            harmonics,
            joints,
        }
    }

    /// Each joint's moving time, s.
    pub fn moving(&self) -> f64 {
        self.duration - 2.0 * self.rest - self.pause
    }

    /// Where joint `j`'s pause falls in its moving time, s: spread evenly.
    pub fn pause_at(&self, j: usize) -> f64 {
        self.moving() * (j + 1) as f64 / (self.joints + 1) as f64
    }

    /// The base frequency actually used, Hz.
    pub fn base_hz(&self) -> f64 {
        self.omega / TAU
    }

    /// Raw coefficients per joint: a centre, then `harmonics` a's and b's.
    pub fn per_joint(&self) -> usize {
        1 + 2 * self.harmonics
    }

    /// `count` sample times evenly over the duration (cell centres).
    pub fn grid(&self, count: usize) -> Vec<f64> {
        let dt = self.duration / count as f64;
        (0..count).map(|i| (i as f64 + 0.5) * dt).collect()
    }
}

/// One joint's motion.
#[derive(Debug, Clone, PartialEq)]
pub struct JointSeries {
    pub centre: f64,
    pub a: Vec<f64>,
    pub b: Vec<f64>,
    /// Moving time at which the joint pauses, s.
    pub pause_at: f64,
}

impl JointSeries {
    /// From raw coefficients: `raw[0]` places the centre in the middle half
    /// of `range` (a hyperbolic tangent keeps it there: a centre near a
    /// limit leaves the joint no room to move), the rest, divided by
    /// k^1.5 for harmonic k (so that a draw of equal raw numbers asks
    /// comparable speed and acceleration of every harmonic), are projected
    /// onto the rest-to-rest constraints.
    pub fn from_raw(raw: &[f64], range: (f64, f64), schedule: &Schedule, j: usize) -> JointSeries {
        let n = schedule.harmonics;
        let mid = 0.5 * (range.0 + range.1);
        let half = 0.5 * (range.1 - range.0);
        let weighed: Vec<f64> = raw[1..=2 * n]
            .iter()
            .enumerate()
            .map(|(k, v)| v / ((k % n + 1) as f64).powf(1.5))
            .collect();
        let pause_at = schedule.pause_at(j);
        let x = project(&weighed, &constraints(schedule, pause_at));
        JointSeries {
            centre: mid + 0.5 * half * (0.5 * raw[0]).tanh(),
            a: x[..n].to_vec(),
            b: x[n..].to_vec(),
            pause_at,
        }
    }

    /// (q, qd, qdd) at time t.
    pub fn eval(&self, schedule: &Schedule, t: f64) -> (f64, f64, f64) {
        let (u, still) = moving_time(schedule, self.pause_at, t);
        let (q, qd, qdd) = self.series(schedule, u);
        if still { (q, 0.0, 0.0) } else { (q, qd, qdd) }
    }

    /// The series at moving time u.
    fn series(&self, schedule: &Schedule, u: f64) -> (f64, f64, f64) {
        let (mut q, mut qd, mut qdd) = (self.centre, 0.0, 0.0);
        for (k, (a, b)) in self.a.iter().zip(&self.b).enumerate() {
            let w = schedule.omega * (k + 1) as f64;
            let (s, c) = (w * u).sin_cos();
            q += a * s + b * (c - 1.0);
            qd += w * (a * c - b * s);
            qdd -= w * w * (a * s + b * c);
        }
        (q, qd, qdd)
    }

    /// The series with every amplitude multiplied by `factor` (centre kept).
    pub fn scaled(&self, factor: f64) -> JointSeries {
        JointSeries {
            centre: self.centre,
            a: self.a.iter().map(|x| x * factor).collect(),
            b: self.b.iter().map(|x| x * factor).collect(),
            pause_at: self.pause_at,
        }
    }
}

/// A joint's moving time at time t (its pause at `pause_at` taken out),
/// and whether it is still there: at a rest it is at u = 0 (the centre,
/// as the series starts there), in its pause at the pause's start.
fn moving_time(schedule: &Schedule, pause_at: f64, t: f64) -> (f64, bool) {
    let mut u = t - schedule.rest;
    if u > pause_at {
        if u < pause_at + schedule.pause {
            return (pause_at, true);
        }
        u -= schedule.pause;
    }
    if (0.0..=schedule.moving()).contains(&u) {
        (u, false)
    } else {
        (0.0, true)
    }
}

/// One joint's motion at a list of times.
#[derive(Debug, Clone, PartialEq)]
pub struct Track {
    pub q: Vec<f64>,
    pub qd: Vec<f64>,
    pub qdd: Vec<f64>,
}

impl Track {
    /// `series` evaluated at `times`.
    pub fn new(series: &JointSeries, schedule: &Schedule, times: &[f64]) -> Track {
        let mut track = Track {
            q: Vec::with_capacity(times.len()),
            qd: Vec::with_capacity(times.len()),
            qdd: Vec::with_capacity(times.len()),
        };
        for &t in times {
            let (q, qd, qdd) = series.eval(schedule, t);
            track.q.push(q);
            track.qd.push(qd);
            track.qdd.push(qdd);
        }
        track
    }

    /// The track of the series scaled by `factor` about `centre`
    /// ([`JointSeries::scaled`]).
    pub fn scaled(&self, centre: f64, factor: f64) -> Track {
        Track {
            q: self
                .q
                .iter()
                .map(|q| centre + factor * (q - centre))
                .collect(),
            qd: self.qd.iter().map(|v| factor * v).collect(),
            qdd: self.qdd.iter().map(|a| factor * a).collect(),
        }
    }
}

/// The series' sines and cosines at fixed times, computed once: the search
/// evaluates thousands of coefficient sets on the same grid, and computing
/// them afresh took a third of its time.
pub struct Basis {
    omega: f64,
    harmonics: usize,
    /// Per joint: per time whether the joint is still, and sin, cos of
    /// w_k u (time-major, `harmonics` per time).
    joints: Vec<(Vec<bool>, Vec<f64>, Vec<f64>)>,
}

impl Basis {
    /// The basis of every joint of `schedule` at `times`.
    pub fn new(schedule: &Schedule, times: &[f64]) -> Basis {
        let n = schedule.harmonics;
        let joints = (0..schedule.joints)
            .map(|j| {
                let pause_at = schedule.pause_at(j);
                let (mut still, mut sin, mut cos) = (Vec::new(), Vec::new(), Vec::new());
                for &t in times {
                    let (u, at_rest) = moving_time(schedule, pause_at, t);
                    still.push(at_rest);
                    for k in 0..n {
                        let (s, c) = (schedule.omega * (k + 1) as f64 * u).sin_cos();
                        sin.push(s);
                        cos.push(c);
                    }
                }
                (still, sin, cos)
            })
            .collect();
        Basis {
            omega: schedule.omega,
            harmonics: n,
            joints,
        }
    }

    /// Joint `j`'s `series` at the basis's times (as [`Track::new`]).
    pub fn track(&self, j: usize, series: &JointSeries) -> Track {
        let (still, sin, cos) = &self.joints[j];
        let n = self.harmonics;
        let mut track = Track {
            q: Vec::with_capacity(still.len()),
            qd: Vec::with_capacity(still.len()),
            qdd: Vec::with_capacity(still.len()),
        };
        for (i, &at_rest) in still.iter().enumerate() {
            let (mut q, mut qd, mut qdd) = (series.centre, 0.0, 0.0);
            for k in 0..n {
                let (s, c) = (sin[i * n + k], cos[i * n + k]);
                let (a, b) = (series.a[k], series.b[k]);
                let w = self.omega * (k + 1) as f64;
                q += a * s + b * (c - 1.0);
                qd += w * (a * c - b * s);
                qdd -= w * w * (a * s + b * c);
            }
            track.q.push(q);
            track.qd.push(if at_rest { 0.0 } else { qd });
            track.qdd.push(if at_rest { 0.0 } else { qdd });
        }
        track
    }
}

/// The rows c with c . [a, b] = velocity and acceleration at u = 0 and at
/// the pause (u = `pause_at`); the pause's rows only when it lies inside a
/// period (at a period's end they repeat the first two) and three or more
/// harmonics leave the motion some freedom.
fn constraints(schedule: &Schedule, pause_at: f64) -> Vec<Vec<f64>> {
    let n = schedule.harmonics;
    let w = |k: usize| schedule.omega * (k + 1) as f64;
    // Velocity and acceleration at u of a and b (sin and cos terms).
    let velocity = |u: f64| -> Vec<f64> {
        (0..2 * n)
            .map(|i| {
                if i < n {
                    w(i) * (w(i) * u).cos()
                } else {
                    -w(i - n) * (w(i - n) * u).sin()
                }
            })
            .collect()
    };
    let acceleration = |u: f64| -> Vec<f64> {
        (0..2 * n)
            .map(|i| {
                if i < n {
                    w(i).powi(2) * (w(i) * u).sin()
                } else {
                    w(i - n).powi(2) * (w(i - n) * u).cos()
                }
            })
            .collect()
    };
    let mut rows = vec![velocity(0.0), acceleration(0.0)];
    let phase = (pause_at * schedule.omega / TAU).fract();
    if schedule.pause > 0.0 && phase > 1e-6 && phase < 1.0 - 1e-6 && n >= 3 {
        rows.push(velocity(pause_at));
        rows.push(acceleration(pause_at));
    }
    rows
}

/// `x` projected onto the null space of the rows: afterwards every
/// row . x = 0 (least change, through the rows' Gram matrix).
fn project(x: &[f64], rows: &[Vec<f64>]) -> Vec<f64> {
    let m = rows.len();
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(u, v)| u * v).sum::<f64>();
    let gram = nalgebra::DMatrix::from_fn(m, m, |r, c| dot(&rows[r], &rows[c]));
    let rhs = nalgebra::DVector::from_fn(m, |r, _| dot(&rows[r], x));
    let Some(lambda) = gram.cholesky().map(|c| c.solve(&rhs)) else {
        return x.to_vec();
    };
    (0..x.len())
        .map(|i| x[i] - (0..m).map(|r| lambda[r] * rows[r][i]).sum::<f64>())
        .collect()
}

/// Per joint the limits the motion must keep.
#[derive(Debug, Clone, PartialEq)]
pub struct Bounds {
    /// Usable position range (the margin already taken off), rad or m.
    pub position: Vec<(f64, f64)>,
    pub velocity: Vec<f64>,
    pub acceleration: Vec<f64>,
    /// Torque (force) the motion may ask of each joint through the model,
    /// `None` where the description gives no effort limit.
    pub effort: Vec<Option<f64>>,
}

/// Share of a limit the scaled motion reaches at the sampled peaks: the
/// peaks between samples, a little higher, stay inside.
pub const KINEMATIC_SHARE: f64 = 0.98;

/// [`KINEMATIC_SHARE`] of the largest factor by which a joint's motion
/// about `centre`, sampled as `track`, can be scaled and keep joint `j`'s
/// position, velocity and acceleration limits at the track's samples.
pub fn kinematic_scale(track: &Track, centre: f64, bounds: &Bounds, j: usize) -> f64 {
    let (lo, hi) = bounds.position[j];
    let (mut up, mut down, mut v, mut a) = (0.0_f64, 0.0_f64, 0.0_f64, 0.0_f64);
    for ((q, qd), qdd) in track.q.iter().zip(&track.qd).zip(&track.qdd) {
        let d = q - centre;
        up = up.max(d);
        down = down.max(-d);
        v = v.max(qd.abs());
        a = a.max(qdd.abs());
    }
    let ratio = |limit: f64, peak: f64| {
        if peak > 0.0 {
            limit / peak
        } else {
            f64::INFINITY
        }
    };
    let factor = [
        ratio(hi - centre, up),
        ratio(centre - lo, down),
        ratio(bounds.velocity[j], v),
        ratio(bounds.acceleration[j], a),
    ]
    .into_iter()
    .fold(f64::INFINITY, f64::min);
    if factor.is_finite() {
        KINEMATIC_SHARE * factor.max(0.0)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn schedule() -> Schedule {
        Schedule::new(20.0, (1.0, 3.0), Some(0.1), 5, 1)
    }

    #[test]
    fn whole_periods_fill_the_span() {
        let s = schedule();
        let periods = s.moving() * s.base_hz();
        assert!((periods - periods.round()).abs() < 1e-12 && periods >= 1.0);
    }

    #[test]
    fn the_motion_leaves_and_reaches_its_rests_smoothly() {
        let s = schedule();
        let raw: Vec<f64> = (0..s.per_joint())
            .map(|k| ((k * 7) % 5) as f64 - 2.0)
            .collect();
        let series = JointSeries::from_raw(&raw, (-1.0, 1.0), &s, 0);
        for t in [0.0, 0.5, 1.0, 19.0, 19.5, 20.0] {
            let (q, qd, qdd) = series.eval(&s, t);
            assert!((q - series.centre).abs() < 1e-9, "q at {t}");
            assert!(
                qd.abs() < 1e-9 && qdd.abs() < 1e-9,
                "at rest at {t}: {qd} {qdd}"
            );
        }
        // The pause: halfway through the moving time, 3 s long, entered
        // and left smoothly.
        let start = 1.0 + s.pause_at(0);
        let (q0, _, _) = series.eval(&s, start + 1.5);
        for t in [
            start - 1e-4,
            start,
            start + 1.0,
            start + 3.0,
            start + 3.0 + 1e-4,
        ] {
            let (q, qd, qdd) = series.eval(&s, t);
            assert!(
                (q - q0).abs() < 1e-6 && qd.abs() < 1e-3 && qdd.abs() < 1e-2,
                "pause at {t}: {q} {qd} {qdd}"
            );
        }
        // Just inside the span the motion is continuous with the rest.
        let (q, qd, _) = series.eval(&s, 1.0 + 1e-4);
        assert!((q - series.centre).abs() < 1e-6 && qd.abs() < 1e-3);
    }

    #[test]
    fn derivatives_are_exact() {
        let s = schedule();
        let raw: Vec<f64> = (0..s.per_joint())
            .map(|k| (k as f64 * 0.37).sin())
            .collect();
        let series = JointSeries::from_raw(&raw, (-2.0, 2.0), &s, 0);
        let h = 1e-5;
        for i in 0..200 {
            let t = 1.3 + i as f64 * 0.087;
            let (_, qd, qdd) = series.eval(&s, t);
            let (qp, qdp, _) = series.eval(&s, t + h);
            let (qm, qdm, _) = series.eval(&s, t - h);
            assert!(((qp - qm) / (2.0 * h) - qd).abs() < 1e-6);
            assert!(((qdp - qdm) / (2.0 * h) - qdd).abs() < 1e-6);
        }
    }

    #[test]
    fn the_basis_gives_what_the_series_gives() {
        let s = Schedule::new(20.0, (1.0, 3.0), None, 5, 3);
        let raw: Vec<f64> = (0..s.per_joint())
            .map(|k| (k as f64 * 0.71).cos())
            .collect();
        let times = s.grid(500);
        let basis = Basis::new(&s, &times);
        for j in 0..3 {
            let series = JointSeries::from_raw(&raw, (-1.0, 2.0), &s, j);
            let (fast, direct) = (basis.track(j, &series), Track::new(&series, &s, &times));
            for (x, y) in [
                (&fast.q, &direct.q),
                (&fast.qd, &direct.qd),
                (&fast.qdd, &direct.qdd),
            ] {
                assert!(x.iter().zip(y).all(|(a, b)| (a - b).abs() < 1e-12));
            }
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(48))]

        /// Whatever the coefficients, the scaled motion keeps its limits on
        /// the grid it was scaled on, and rests at both ends.
        #[test]
        fn any_coefficients_scale_into_the_limits(
            raw in proptest::collection::vec(-5.0f64..5.0, 13),
            pause in 0.0f64..4.0,
        ) {
            let s = Schedule::new(12.0, (0.5, pause), None, 6, 2);
            let bounds = Bounds {
                position: vec![(-0.3, 2.0)],
                velocity: vec![0.8],
                acceleration: vec![1.5],
                effort: vec![None],
            };
            let series = JointSeries::from_raw(&raw, bounds.position[0], &s, 1);
            let grid = s.grid(1200);
            let f = kinematic_scale(&Track::new(&series, &s, &grid), series.centre, &bounds, 0);
            let scaled = series.scaled(f);
            for &t in &grid {
                let (q, qd, qdd) = scaled.eval(&s, t);
                proptest::prop_assert!((-0.3..=2.0).contains(&q) && qd.abs() <= 0.8 && qdd.abs() <= 1.5);
            }
            for t in [0.0, 12.0] {
                let (_, qd, qdd) = scaled.eval(&s, t);
                proptest::prop_assert!(qd.abs() < 1e-9 && qdd.abs() < 1e-9);
            }
        }
    }

    #[test]
    fn scaling_keeps_every_limit_on_the_grid() {
        let s = schedule();
        let bounds = Bounds {
            position: vec![(-0.5, 1.5)],
            velocity: vec![0.7],
            acceleration: vec![1.1],
            effort: vec![None],
        };
        let raw: Vec<f64> = (0..s.per_joint()).map(|k| 3.0 * (k as f64).cos()).collect();
        let series = JointSeries::from_raw(&raw, bounds.position[0], &s, 0);
        let grid = s.grid(4000);
        let f = kinematic_scale(&Track::new(&series, &s, &grid), series.centre, &bounds, 0);
        let scaled = series.scaled(f);
        for &t in &grid {
            let (q, qd, qdd) = scaled.eval(&s, t);
            assert!((-0.5..=1.5).contains(&q) && qd.abs() <= 0.7 && qdd.abs() <= 1.1);
        }
    }
}
