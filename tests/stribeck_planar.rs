//! Stribeck friction on recordings from a simulator written here, apart
//! from the tool's generator and virtual robot: a planar two-link arm in a
//! vertical plane (closed-form Lagrangian dynamics, checked against the
//! description the diagnosis reads), friction
//! tau_f = (Fc + (Fs - Fc) exp(-(qd/v_s)^2)) tanh(qd / 1 mrad/s) + b qd on
//! the shoulder, computed-torque tracking on the model without friction
//! (so the joint sticks at reversals until the PD term breaks it away),
//! RK4 at 0.25 ms, the torque held over each 1 ms period, noisy sensors.

use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sdnn::diagnose::{Diagnosis, Kind, Settings, diagnose};
use sdnn::dynamics::Dynamics;
use sdnn::preprocess::Pipeline;
use sdnn::trajectory::Trajectory;

use crate::util::Dir;

/// The arm as the diagnosis reads it (no joint effects).
const DESCRIPTION: &str = r#"
name = "planar arm of the Stribeck test"
gravity = [0.0, -9.81, 0.0]

[[links]]
name = "base"

[[links]]
name = "upper"
mass = 2.0
com = [0.35, 0.0, 0.0]
inertia = { ixx = 0.002, iyy = 0.12, izz = 0.12 }

[[links]]
name = "fore"
mass = 1.5
com = [0.4, 0.0, 0.0]
inertia = { ixx = 0.0015, iyy = 0.08, izz = 0.08 }

[[joints]]
name = "shoulder"
type = "revolute"
parent = "base"
child = "upper"
axis = [0.0, 0.0, 1.0]

[[joints]]
name = "elbow"
type = "revolute"
parent = "upper"
child = "fore"
origin = { xyz = [0.8, 0.0, 0.0] }
axis = [0.0, 0.0, 1.0]
"#;

const MASS: [f64; 2] = [2.0, 1.5];
const COM: [f64; 2] = [0.35, 0.4];
const INERTIA: [f64; 2] = [0.12, 0.08];
const UPPER: f64 = 0.8;
const G: f64 = 9.81;

/// Mass matrix and bias (Coriolis, centrifugal, gravity) of the arm, angles
/// from the x axis (the shoulder) and relative (the elbow), gravity -y.
fn dynamics(q: [f64; 2], qd: [f64; 2]) -> ([[f64; 2]; 2], [f64; 2]) {
    let (m, c, i) = (MASS, COM, INERTIA);
    let coupling = m[1] * UPPER * c[1];
    let m22 = i[1] + m[1] * c[1] * c[1];
    let m12 = m22 + coupling * q[1].cos();
    let m11 = i[0] + m[0] * c[0] * c[0] + m22 + m[1] * UPPER * UPPER + 2.0 * coupling * q[1].cos();
    let h = coupling * q[1].sin();
    let fore = m[1] * c[1] * G * (q[0] + q[1]).cos();
    let bias = [
        -h * (2.0 * qd[0] * qd[1] + qd[1] * qd[1])
            + (m[0] * c[0] + m[1] * UPPER) * G * q[0].cos()
            + fore,
        h * qd[0] * qd[0] + fore,
    ];
    ([[m11, m12], [m12, m22]], bias)
}

/// Shoulder friction: sliding level, static level, Stribeck velocity,
/// viscous coefficient.
#[derive(Clone, Copy)]
struct Friction {
    sliding: f64,
    static_: f64,
    velocity: f64,
    viscous: f64,
}

impl Friction {
    const NONE: Friction = Friction {
        sliding: 0.0,
        static_: 0.0,
        velocity: 1.0,
        viscous: 0.0,
    };

    fn torque(&self, qd: f64) -> f64 {
        let fading = (-(qd / self.velocity).powi(2)).exp();
        (self.sliding + (self.static_ - self.sliding) * fading) * (qd / 1e-3).tanh()
            + self.viscous * qd
    }
}

/// The reference of joint `j` at `t`: sums of sines with a seed's phases;
/// with `dwell` the shoulder's motion flattens at its turning points (a
/// squashed sine), so it rests there and breaks away.
fn reference(j: usize, t: f64, phase: f64, dwell: bool) -> f64 {
    let w = std::f64::consts::TAU;
    match (j, dwell) {
        (0, false) => -1.2 + 0.6 * (w * 0.23 * t + phase).sin() + 0.25 * (w * 0.61 * t).sin(),
        (0, true) => -1.2 + 0.7 * (3.0 * (w * 0.2 * t + phase).sin()).tanh() / 3f64.tanh(),
        _ => 0.8 + 0.5 * (w * 0.31 * t + 2.0 * phase).sin() + 0.2 * (w * 0.87 * t).sin(),
    }
}

/// Position, velocity and acceleration of the reference (central
/// differences of the closed form).
fn reference_state(j: usize, t: f64, phase: f64, dwell: bool) -> [f64; 3] {
    let h = 1e-4;
    let at = |t: f64| reference(j, t, phase, dwell);
    let (a, b, c) = (at(t - h), at(t), at(t + h));
    [b, (c - a) / (2.0 * h), (c - 2.0 * b + a) / (h * h)]
}

fn accelerations(q: [f64; 2], qd: [f64; 2], tau: [f64; 2], friction: Friction) -> [f64; 2] {
    let (m, bias) = dynamics(q, qd);
    let r = [tau[0] - bias[0] - friction.torque(qd[0]), tau[1] - bias[1]];
    let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
    [
        (m[1][1] * r[0] - m[0][1] * r[1]) / det,
        (m[0][0] * r[1] - m[1][0] * r[0]) / det,
    ]
}

/// One RK4 step of `h` with the torque held.
fn step(q: &mut [f64; 2], qd: &mut [f64; 2], tau: [f64; 2], friction: Friction, h: f64) {
    let derivative = |q: [f64; 2], qd: [f64; 2]| (qd, accelerations(q, qd, tau, friction));
    let shift = |x: [f64; 2], dx: [f64; 2], s: f64| [x[0] + s * dx[0], x[1] + s * dx[1]];
    let (k1q, k1v) = derivative(*q, *qd);
    let (k2q, k2v) = derivative(shift(*q, k1q, h / 2.0), shift(*qd, k1v, h / 2.0));
    let (k3q, k3v) = derivative(shift(*q, k2q, h / 2.0), shift(*qd, k2v, h / 2.0));
    let (k4q, k4v) = derivative(shift(*q, k3q, h), shift(*qd, k3v, h));
    for j in 0..2 {
        q[j] += h / 6.0 * (k1q[j] + 2.0 * k2q[j] + 2.0 * k3q[j] + k4q[j]);
        qd[j] += h / 6.0 * (k1v[j] + 2.0 * k2v[j] + 2.0 * k3v[j] + k4v[j]);
    }
}

/// A standard normal draw (Box-Muller).
fn normal(rng: &mut ChaCha8Rng) -> f64 {
    let u: f64 = rng.random::<f64>().max(1e-300);
    let v: f64 = rng.random();
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// 20 s at 1 kHz: computed torque on the frictionless model plus PD,
/// noise q 1e-5 rad, qd 0.02 rad/s, torque 0.05 N m.
fn record(friction: Friction, seed: u64, dwell: bool) -> Trajectory {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let phase = rng.random::<f64>() * std::f64::consts::TAU;
    let (kp, kd, period, substeps) = (100.0, 20.0, 1e-3, 4);
    let samples = 20_000;
    let state = |t: f64| [0, 1].map(|j| reference_state(j, t, phase, dwell));
    let start = state(0.0);
    let (mut q, mut qd) = ([start[0][0], start[1][0]], [start[0][1], start[1][1]]);
    let mut columns = [vec![], vec![], vec![]];
    for k in 0..samples {
        let r = state(k as f64 * period);
        let (m, bias) = dynamics(q, qd);
        let a: [f64; 2] =
            std::array::from_fn(|j| r[j][2] + kp * (r[j][0] - q[j]) + kd * (r[j][1] - qd[j]));
        let tau: [f64; 2] = std::array::from_fn(|j| m[j][0] * a[0] + m[j][1] * a[1] + bias[j]);
        for j in 0..2 {
            columns[0].push(q[j] + 1e-5 * normal(&mut rng));
            columns[1].push(qd[j] + 0.02 * normal(&mut rng));
            columns[2].push(tau[j] + 0.05 * normal(&mut rng));
        }
        for _ in 0..substeps {
            step(&mut q, &mut qd, tau, friction, period / substeps as f64);
        }
    }
    let matrix = |v: &Vec<f64>| DMatrix::from_row_slice(samples, 2, v);
    let t = (0..samples).map(|k| k as f64 * period).collect();
    let [q, qd, tau] = &columns;
    Trajectory::new(t, matrix(q), matrix(qd), None, matrix(tau)).unwrap()
}

/// 20 s at 1 kHz of the reference itself, its torque the inverse
/// dynamics plus friction (a motion that does not react to its friction,
/// as an inverse-dynamics simulator gives it); positions with noise of
/// 1e-4 rad, velocities their central differences, torque noise 0.05 N m.
fn record_prescribed(friction: Friction, seed: u64) -> Trajectory {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let phase = rng.random::<f64>() * std::f64::consts::TAU;
    let (period, samples) = (1e-3, 20_000);
    let mut q = DMatrix::zeros(samples, 2);
    let mut tau = DMatrix::zeros(samples, 2);
    for k in 0..samples {
        let r = [0, 1].map(|j| reference_state(j, k as f64 * period, phase, false));
        let (m, bias) = dynamics([r[0][0], r[1][0]], [r[0][1], r[1][1]]);
        for j in 0..2 {
            let inertial = m[j][0] * r[0][2] + m[j][1] * r[1][2];
            let friction = if j == 0 {
                friction.torque(r[0][1])
            } else {
                0.0
            };
            q[(k, j)] = r[j][0] + 1e-4 * normal(&mut rng);
            tau[(k, j)] = inertial + bias[j] + friction + 0.05 * normal(&mut rng);
        }
    }
    let mut qd = DMatrix::zeros(samples, 2);
    for k in 0..samples {
        let (a, b) = (k.saturating_sub(1), (k + 1).min(samples - 1));
        for j in 0..2 {
            qd[(k, j)] = (q[(b, j)] - q[(a, j)]) / ((b - a) as f64 * period);
        }
    }
    let t = (0..samples).map(|k| k as f64 * period).collect();
    Trajectory::new(t, q, qd, None, tau).unwrap()
}

fn model(dir: &Dir) -> &'static dyn Dynamics {
    sdnn::described::Described::load(&dir.write("planar_stribeck.toml", DESCRIPTION)).unwrap()
}

fn diagnosed(friction: Friction, dwell: bool, count: u64) -> Diagnosis {
    let recordings: Vec<Trajectory> = (0..count).map(|s| record(friction, 7 + s, dwell)).collect();
    diagnosed_from(&recordings)
}

fn diagnosed_from(recordings: &[Trajectory]) -> Diagnosis {
    let dir = Dir::new();
    let pipeline = Pipeline::auto(recordings, None, None).unwrap();
    diagnose(model(&dir), recordings, &pipeline, Settings::default()).unwrap()
}

fn named(d: &Diagnosis) -> Vec<(Kind, Option<usize>)> {
    d.effects.iter().map(|e| (e.kind, e.joint)).collect()
}

#[test]
fn the_simulator_is_the_described_arm() {
    let dir = Dir::new();
    let arm = model(&dir);
    for k in 0..50 {
        let x = k as f64;
        let (q, qd, qdd) = (
            [(0.7 * x).sin() * 2.0, (1.3 * x).cos()],
            [(0.3 * x).cos(), (0.9 * x).sin()],
            [(1.1 * x).sin() * 3.0, (0.4 * x).cos()],
        );
        let (m, bias) = dynamics(q, qd);
        let tau = arm.tau(&q, &qd, &qdd).unwrap();
        for j in 0..2 {
            let mine = m[j][0] * qdd[0] + m[j][1] * qdd[1] + bias[j];
            assert!((mine - tau[j]).abs() < 1e-9, "{mine} vs {}", tau[j]);
        }
    }
}

/// `d` names the breakaway of `friction` on the shoulder (velocity within
/// 20%, the grid's step being 1.4; excess within 25%) and only friction
/// there.
#[track_caller]
fn assert_breakaway(d: &Diagnosis, friction: Friction) {
    let stribeck = d
        .effects
        .iter()
        .find(|e| e.kind == Kind::StribeckFriction && e.joint == Some(1))
        .unwrap_or_else(|| panic!("{:?}\n{:#?}", named(d), d.notes));
    let value = |name: &str| stribeck.parameters[name].as_f64().unwrap();
    let excess = friction.static_ - friction.sliding;
    assert!(
        (value("velocity") / friction.velocity - 1.0).abs() <= 0.2,
        "{stribeck:?}"
    );
    assert!(
        (value("excess") / excess - 1.0).abs() <= 0.25,
        "{stribeck:?}"
    );
    assert!(
        d.effects.iter().all(|e| matches!(
            e.kind,
            Kind::CoulombFriction | Kind::ViscousFriction | Kind::StribeckFriction
        ) && e.joint == Some(1)),
        "{:?}",
        named(d)
    );
}

#[test]
fn a_breakaway_on_the_shoulder_is_named() {
    let friction = Friction {
        sliding: 0.16,
        static_: 0.39,
        velocity: 0.08,
        viscous: 0.1,
    };
    assert_breakaway(&diagnosed(friction, false, 3), friction);
}

/// The same kind of breakaway where the motion does not react to it: the
/// reversal band's acceleration is then the noise of twice-differentiated
/// positions (about 1 rad/s^2 here, times the shoulder's inertia), and the
/// reversal stage computes the model's torque on the motion band's states.
/// Before, the excess was not significant there (|t| <= 3.5).
#[test]
fn a_breakaway_under_a_prescribed_motion_is_named() {
    let friction = Friction {
        sliding: 0.16,
        static_: 0.39,
        velocity: 0.15,
        viscous: 0.1,
    };
    let recordings: Vec<Trajectory> = (0..3).map(|s| record_prescribed(friction, 7 + s)).collect();
    assert_breakaway(&diagnosed_from(&recordings), friction);
}

#[test]
fn dry_friction_that_rests_and_breaks_away_is_not_stribeck() {
    let friction = Friction {
        sliding: 0.39,
        static_: 0.39,
        ..Friction::NONE
    };
    for dwell in [true, false] {
        let d = diagnosed(friction, dwell, 3);
        assert_eq!(named(&d), [(Kind::CoulombFriction, Some(1))], "{d:#?}");
    }
}

#[test]
fn clean_data_name_nothing() {
    let d = diagnosed(Friction::NONE, true, 3);
    assert!(d.effects.is_empty(), "{:?}", named(&d));
}
