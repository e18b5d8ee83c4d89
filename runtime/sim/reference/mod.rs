//! Planned joint trajectories with exact derivatives: random minimum-jerk
//! waypoints (how the thesis data were recorded, §2.1) and a Fourier
//! excitation (the "fully theoretical trajectory" of thesis §4.3.1).

use nalgebra::DVector;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Peak of the minimum-jerk velocity profile, in units of |dq| / T.
pub const MIN_JERK_PEAK_VELOCITY: f64 = 1.875;
/// Peak of the minimum-jerk acceleration profile (10 / sqrt 3), in units of |dq| / T^2.
pub const MIN_JERK_PEAK_ACCELERATION: f64 = 5.773_502_691_896_258;
/// Upper bound on segments per joint, so a typo cannot exhaust memory.
pub const MAX_SEGMENTS: f64 = 1.0e6;
/// Upper bound on harmonics per joint, for the same reason.
pub const MAX_HARMONICS: usize = 1000;

/// Errors from invalid reference configurations.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ReferenceError {
    /// No joints were configured.
    #[error("joint limits list no joints")]
    NoJoints,
    /// Per-joint lists disagree in length.
    #[error("{what} lists {found} joints, the position limits list {dof}")]
    LengthMismatch {
        what: &'static str,
        dof: usize,
        found: usize,
    },
    /// A joint's usable range [lower + margin, upper - margin] is empty.
    #[error(
        "joint {joint} (0-based): range [{lower}, {upper}] minus margin {margin} on each side is empty"
    )]
    EmptyRange {
        joint: usize,
        lower: f64,
        upper: f64,
        margin: f64,
    },
    /// A value that must be positive and finite is not.
    #[error("{what} must be positive and finite, got {value}")]
    NotPositive { what: &'static str, value: f64 },
    /// A min/max pair is out of order.
    #[error("{what}: minimum {min} exceeds maximum {max}")]
    Order {
        what: &'static str,
        min: f64,
        max: f64,
    },
    /// The harmonic count is zero or above [`MAX_HARMONICS`].
    #[error("harmonics must be between 1 and {MAX_HARMONICS}, got {value}")]
    Harmonics { value: usize },
    /// The configuration would need too many segments.
    #[error(
        "duration {duration} s with segments of {min_segment} s needs more than {MAX_SEGMENTS} segments"
    )]
    TooLong { duration: f64, min_segment: f64 },
}

/// A planned trajectory with exact derivatives.
pub trait Reference {
    /// Number of joints.
    fn dof(&self) -> usize;
    /// Length of the trajectory in seconds (it starts at t = 0).
    fn duration(&self) -> f64;
    /// Planned (q, qd, qdd) at time `t`.
    fn sample(&self, t: f64) -> (DVector<f64>, DVector<f64>, DVector<f64>);
}

/// Per-joint limits.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct JointLimits {
    /// (lower, upper) joint angle in rad.
    pub position: Vec<(f64, f64)>,
    /// Maximum |qd| in rad/s.
    pub velocity: Vec<f64>,
    /// Maximum |qdd| in rad/s^2.
    pub acceleration: Vec<f64>,
}

impl Default for JointLimits {
    /// Gen3 Lite joints 1-3: range ±2.69 rad (ros2_kortex URDF), MoveIt caps
    /// 0.5 rad/s and 1.0/0.5/0.4 rad/s^2 (ros_kortex joint_limits.yaml).
    fn default() -> Self {
        Self {
            position: vec![(-2.69, 2.69); 3],
            velocity: vec![0.5; 3],
            acceleration: vec![1.0, 0.5, 0.4],
        }
    }
}

impl JointLimits {
    /// The same limits on `dof` joints.
    pub fn uniform(dof: usize, position: (f64, f64), velocity: f64, acceleration: f64) -> Self {
        Self {
            position: vec![position; dof],
            velocity: vec![velocity; dof],
            acceleration: vec![acceleration; dof],
        }
    }

    /// Number of joints.
    pub fn dof(&self) -> usize {
        self.position.len()
    }

    /// The margin kept inside joint `j`'s range: `margin`, or a quarter of
    /// a shorter range (a gripper's few centimetres of stroke).
    pub fn margin(&self, j: usize, margin: f64) -> f64 {
        let (lower, upper) = self.position[j];
        margin.min(0.25 * (upper - lower)).max(0.0)
    }

    /// Checks list lengths, positive caps and non-empty usable ranges.
    pub fn validate(&self, margin: f64) -> Result<(), ReferenceError> {
        let dof = self.dof();
        if dof == 0 {
            return Err(ReferenceError::NoJoints);
        }
        check_len("velocity limits", self.velocity.len(), dof)?;
        check_len("acceleration limits", self.acceleration.len(), dof)?;
        check_non_negative("margin", margin)?;
        for (joint, &(lower, upper)) in self.position.iter().enumerate() {
            let margin = self.margin(joint, margin);
            let usable = upper - margin - (lower + margin);
            if !(lower.is_finite() && upper.is_finite() && usable >= 0.0) {
                return Err(ReferenceError::EmptyRange {
                    joint,
                    lower,
                    upper,
                    margin,
                });
            }
        }
        self.velocity
            .iter()
            .try_for_each(|&v| check_positive("velocity limit", v))?;
        self.acceleration
            .iter()
            .try_for_each(|&a| check_positive("acceleration limit", a))
    }
}

/// (q, qd, qdd) of `dof` joints from each joint's own.
fn per_joint(
    dof: usize,
    joint: impl Fn(usize) -> (f64, f64, f64),
) -> (DVector<f64>, DVector<f64>, DVector<f64>) {
    let (mut q, mut qd, mut qdd) = (
        DVector::zeros(dof),
        DVector::zeros(dof),
        DVector::zeros(dof),
    );
    for j in 0..dof {
        (q[j], qd[j], qdd[j]) = joint(j);
    }
    (q, qd, qdd)
}

fn check_len(what: &'static str, found: usize, dof: usize) -> Result<(), ReferenceError> {
    if found == dof {
        Ok(())
    } else {
        Err(ReferenceError::LengthMismatch { what, dof, found })
    }
}

fn check_positive(what: &'static str, value: f64) -> Result<(), ReferenceError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(ReferenceError::NotPositive { what, value })
    }
}

fn check_non_negative(what: &'static str, value: f64) -> Result<(), ReferenceError> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(ReferenceError::NotPositive { what, value })
    }
}

fn check_order(what: &'static str, min: f64, max: f64) -> Result<(), ReferenceError> {
    if min <= max {
        Ok(())
    } else {
        Err(ReferenceError::Order { what, min, max })
    }
}

/// Configuration of a [`WaypointTrajectory`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct WaypointConfig {
    /// Trajectory length in s (thesis: 20 s).
    pub duration: f64,
    /// Joint limits; waypoints stay `margin` inside the position limits.
    pub limits: JointLimits,
    /// Distance in rad kept from each position limit.
    pub margin: f64,
    /// Shortest drawn segment duration in s.
    pub min_segment: f64,
    /// Longest drawn segment duration in s (segments may be lengthened beyond
    /// it to respect the velocity and acceleration caps).
    pub max_segment: f64,
}

impl Default for WaypointConfig {
    fn default() -> Self {
        Self {
            duration: 20.0,
            limits: JointLimits::default(),
            margin: 0.1,
            min_segment: 1.5,
            max_segment: 4.0,
        }
    }
}

impl WaypointConfig {
    fn validate(&self) -> Result<(), ReferenceError> {
        self.limits.validate(self.margin)?;
        check_positive("duration", self.duration)?;
        check_positive("min_segment", self.min_segment)?;
        check_positive("max_segment", self.max_segment)?;
        check_order("segment duration", self.min_segment, self.max_segment)?;
        if self.duration / self.min_segment > MAX_SEGMENTS {
            return Err(ReferenceError::TooLong {
                duration: self.duration,
                min_segment: self.min_segment,
            });
        }
        Ok(())
    }
}

/// One minimum-jerk move from `q0` to `q0 + dq` over [start, start + length].
#[derive(Debug, Clone, PartialEq)]
struct Segment {
    start: f64,
    length: f64,
    q0: f64,
    dq: f64,
}

impl Segment {
    /// Quintic with zero velocity and acceleration at both ends.
    fn eval(&self, t: f64) -> (f64, f64, f64) {
        let s = ((t - self.start) / self.length).clamp(0.0, 1.0);
        let (s2, s3) = (s * s, s * s * s);
        let pos = s3 * (10.0 - 15.0 * s + 6.0 * s2);
        let vel = 30.0 * s2 * (1.0 - 2.0 * s + s2);
        let acc = 60.0 * s * (1.0 - 3.0 * s + 2.0 * s2);
        let (dq, len) = (self.dq, self.length);
        (self.q0 + dq * pos, dq * vel / len, dq * acc / (len * len))
    }
}

/// Random joint waypoints joined by minimum-jerk segments, drawn
/// independently per joint as in the thesis experiments (§2.1).
#[derive(Debug, Clone, PartialEq)]
pub struct WaypointTrajectory {
    duration: f64,
    joints: Vec<Vec<Segment>>,
}

impl WaypointTrajectory {
    /// Draws a trajectory from `seed` (ChaCha8, deterministic).
    pub fn new(config: &WaypointConfig, seed: u64) -> Result<Self, ReferenceError> {
        config.validate()?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let joints = (0..config.limits.dof())
            .map(|j| joint_segments(config, j, &mut rng))
            .collect();
        Ok(Self {
            duration: config.duration,
            joints,
        })
    }
}

/// Segments of joint `j` until they cover the duration.
fn joint_segments(config: &WaypointConfig, j: usize, rng: &mut ChaCha8Rng) -> Vec<Segment> {
    let (lower, upper) = config.limits.position[j];
    let margin = config.limits.margin(j, config.margin);
    let (lo, hi) = (lower + margin, upper - margin);
    let (vmax, amax) = (config.limits.velocity[j], config.limits.acceleration[j]);
    let mut q = rng.random_range(lo..=hi);
    let mut start = 0.0;
    let mut segments = Vec::new();
    while start < config.duration {
        let next = rng.random_range(lo..=hi);
        let drawn = rng.random_range(config.min_segment..=config.max_segment);
        let length = capped_length(drawn, (next - q).abs(), vmax, amax);
        segments.push(Segment {
            start,
            length,
            q0: q,
            dq: next - q,
        });
        start += length;
        q = next;
    }
    segments
}

/// Lengthens a segment until its minimum-jerk peaks respect the caps.
fn capped_length(drawn: f64, distance: f64, vmax: f64, amax: f64) -> f64 {
    let for_velocity = MIN_JERK_PEAK_VELOCITY * distance / vmax;
    let for_acceleration = (MIN_JERK_PEAK_ACCELERATION * distance / amax).sqrt();
    drawn.max(for_velocity).max(for_acceleration)
}

impl Reference for WaypointTrajectory {
    fn dof(&self) -> usize {
        self.joints.len()
    }

    fn duration(&self) -> f64 {
        self.duration
    }

    /// Before t = 0 and after the last segment the joints rest at the first or
    /// last waypoint. A NaN `t` yields NaN.
    fn sample(&self, t: f64) -> (DVector<f64>, DVector<f64>, DVector<f64>) {
        per_joint(self.dof(), |j| {
            let segments = &self.joints[j];
            // Last segment starting at or before t (the first one for t < 0).
            let idx = segments.partition_point(|s| s.start <= t).saturating_sub(1);
            segments[idx].eval(t)
        })
    }
}

/// Configuration of an [`ExcitationTrajectory`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ExcitationConfig {
    /// Trajectory length in s.
    pub duration: f64,
    /// Joint limits; the motion stays `margin` inside the position limits.
    pub limits: JointLimits,
    /// Distance in rad kept from each position limit.
    pub margin: f64,
    /// Harmonics per joint (Swevers et al. use 5).
    pub harmonics: usize,
    /// Lowest base frequency in Hz.
    pub min_base_hz: f64,
    /// Highest base frequency in Hz.
    pub max_base_hz: f64,
}

impl Default for ExcitationConfig {
    fn default() -> Self {
        Self {
            duration: 20.0,
            limits: JointLimits::default(),
            margin: 0.1,
            harmonics: 5,
            min_base_hz: 0.05,
            max_base_hz: 0.1,
        }
    }
}

impl ExcitationConfig {
    fn validate(&self) -> Result<(), ReferenceError> {
        self.limits.validate(self.margin)?;
        check_positive("duration", self.duration)?;
        if self.harmonics == 0 || self.harmonics > MAX_HARMONICS {
            return Err(ReferenceError::Harmonics {
                value: self.harmonics,
            });
        }
        check_positive("min_base_hz", self.min_base_hz)?;
        check_positive("max_base_hz", self.max_base_hz)?;
        check_order("base frequency", self.min_base_hz, self.max_base_hz)
    }
}

/// One joint's finite Fourier series:
/// q = offset + sum_k a_k/(w k) sin(w k t) - b_k/(w k) cos(w k t).
#[derive(Debug, Clone, PartialEq)]
struct FourierJoint {
    offset: f64,
    a: Vec<f64>,
    b: Vec<f64>,
}

/// Swevers-style periodic excitation: per joint a finite Fourier series with
/// a common base frequency, scaled to respect position, velocity and
/// acceleration limits by construction (triangle-inequality bounds).
#[derive(Debug, Clone, PartialEq)]
pub struct ExcitationTrajectory {
    duration: f64,
    /// Base angular frequency in rad/s.
    omega: f64,
    joints: Vec<FourierJoint>,
}

impl ExcitationTrajectory {
    /// Draws a trajectory from `seed` (ChaCha8, deterministic).
    pub fn new(config: &ExcitationConfig, seed: u64) -> Result<Self, ReferenceError> {
        config.validate()?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let hz = rng.random_range(config.min_base_hz..=config.max_base_hz);
        let omega = std::f64::consts::TAU * hz;
        let joints = (0..config.limits.dof())
            .map(|j| fourier_joint(config, j, omega, &mut rng))
            .collect();
        Ok(Self {
            duration: config.duration,
            omega,
            joints,
        })
    }

    /// Base frequency in Hz.
    pub fn base_hz(&self) -> f64 {
        self.omega / std::f64::consts::TAU
    }
}

/// Random coefficients in [-1, 1], scaled so the tightest bound is just met.
fn fourier_joint(
    config: &ExcitationConfig,
    j: usize,
    omega: f64,
    rng: &mut ChaCha8Rng,
) -> FourierJoint {
    let n = config.harmonics;
    let a: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..=1.0)).collect();
    let b: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..=1.0)).collect();
    let (lower, upper) = config.limits.position[j];
    let half_range = 0.5 * (upper - lower) - config.limits.margin(j, config.margin);
    let (mut pos, mut vel, mut acc) = (0.0, 0.0, 0.0);
    for k in 0..n {
        let wk = omega * (k + 1) as f64;
        let amplitude = a[k].hypot(b[k]);
        pos += amplitude / wk;
        vel += amplitude;
        acc += amplitude * wk;
    }
    let scale = [
        ratio(half_range, pos),
        ratio(config.limits.velocity[j], vel),
        ratio(config.limits.acceleration[j], acc),
    ]
    .into_iter()
    .fold(f64::INFINITY, f64::min);
    let scale = if scale.is_finite() { scale } else { 0.0 };
    FourierJoint {
        offset: 0.5 * (lower + upper),
        a: a.iter().map(|x| x * scale).collect(),
        b: b.iter().map(|x| x * scale).collect(),
    }
}

fn ratio(limit: f64, bound: f64) -> f64 {
    if bound > 0.0 {
        limit / bound
    } else {
        f64::INFINITY
    }
}

impl FourierJoint {
    fn eval(&self, omega: f64, t: f64) -> (f64, f64, f64) {
        let (mut q, mut qd, mut qdd) = (self.offset, 0.0, 0.0);
        for (k, (a, b)) in self.a.iter().zip(&self.b).enumerate() {
            let wk = omega * (k + 1) as f64;
            let (s, c) = (wk * t).sin_cos();
            q += (a * s - b * c) / wk;
            qd += a * c + b * s;
            qdd += wk * (b * c - a * s);
        }
        (q, qd, qdd)
    }
}

impl Reference for ExcitationTrajectory {
    fn dof(&self) -> usize {
        self.joints.len()
    }

    fn duration(&self) -> f64 {
        self.duration
    }

    /// Defined (periodic) for every finite `t`.
    fn sample(&self, t: f64) -> (DVector<f64>, DVector<f64>, DVector<f64>) {
        per_joint(self.dof(), |j| self.joints[j].eval(self.omega, t))
    }
}

#[cfg(test)]
mod tests;
