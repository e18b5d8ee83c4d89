//! The virtual robot: a computed-torque controller tracking a [`Reference`]
//! on a [`Plant`] integrated with RK4, recorded through noisy sensors.
//!
//! Coulomb friction makes the plant's bias discontinuous at qd = 0. RK4 then
//! loses its fourth order across a velocity reversal, but at a 1 ms step the
//! local error stays tiny, so no event handling is done.

use crate::trajectory::{Trajectory, TrajectoryError};
use nalgebra::{DMatrix, DVector};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use super::plant::{DynamicsError, Plant, forward_dynamics, inverse_dynamics};
use super::reference::Reference;

/// Upper bound on recorded samples, so a typo in the rate cannot exhaust memory.
pub const MAX_SAMPLES: f64 = 1.0e8;

/// Errors from configuring or running a simulation.
#[derive(Debug, Error)]
pub enum SimError {
    /// Evaluating the plant or nominal model failed.
    #[error(transparent)]
    Dynamics(#[from] DynamicsError),
    /// Building an output trajectory failed.
    #[error(transparent)]
    Trajectory(#[from] TrajectoryError),
    /// Plant, nominal model, reference or input disagree in joint count.
    #[error("{what} has {found} joints, the plant has {dof}")]
    DofMismatch {
        what: &'static str,
        dof: usize,
        found: usize,
    },
    /// A configuration value is out of range.
    #[error("invalid configuration: {what} = {value} ({reason})")]
    Config {
        what: &'static str,
        value: f64,
        reason: &'static str,
    },
    /// The state blew up (non-finite, or faster than the divergence bound).
    #[error("simulation diverged at t = {time} s: joint {joint} (0-based) has q = {q}, qd = {qd}")]
    Diverged {
        time: f64,
        joint: usize,
        q: f64,
        qd: f64,
    },
}

/// Gains and saturation of the [`Controller`].
///
/// `kp`, `kd` and `effort_limit` hold one value per joint, or a single value
/// applied to every joint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ControllerConfig {
    /// Proportional gain in 1/s^2 (100: natural frequency 10 rad/s).
    pub kp: Vec<f64>,
    /// Derivative gain in 1/s (20 = 2 * 10: critically damped).
    pub kd: Vec<f64>,
    /// Symmetric torque saturation in N m; `None` for none.
    pub effort_limit: Option<Vec<f64>>,
}

impl Default for ControllerConfig {
    fn default() -> Self {
        Self {
            kp: vec![100.0],
            kd: vec![20.0],
            effort_limit: None,
        }
    }
}

/// Computed torque on a nominal model plus PD feedback:
/// tau = M_nom(q) (qdd_ref + Kp e + Kd e_dot) + bias_nom(q, qd), saturated.
///
/// Coulomb compensation in `bias_nom` follows the sign of the fed-back qd, so
/// at a velocity reversal a joint can stick for tens of ms (a few mrad of
/// error) until the PD term pushes it through, much like a real arm.
pub struct Controller<'a> {
    nominal: &'a dyn Plant,
    kp: DVector<f64>,
    kd: DVector<f64>,
    effort_limit: Option<DVector<f64>>,
}

impl<'a> Controller<'a> {
    /// Checks the gains against the nominal model's joint count.
    pub fn new(nominal: &'a dyn Plant, config: &ControllerConfig) -> Result<Self, SimError> {
        let dof = nominal.dof();
        let effort_limit = match &config.effort_limit {
            Some(limit) => Some(per_joint("effort_limit", limit, dof, true)?),
            None => None,
        };
        Ok(Self {
            nominal,
            kp: per_joint("kp", &config.kp, dof, false)?,
            kd: per_joint("kd", &config.kd, dof, false)?,
            effort_limit,
        })
    }

    /// Torque for the state (q, qd) tracking (q_ref, qd_ref, qdd_ref).
    pub fn torque(
        &self,
        (q, qd): (&DVector<f64>, &DVector<f64>),
        (q_ref, qd_ref, qdd_ref): (&DVector<f64>, &DVector<f64>, &DVector<f64>),
    ) -> Result<DVector<f64>, SimError> {
        let dof = self.kp.len();
        for (what, v) in [
            ("q", q),
            ("qd", qd),
            ("q_ref", q_ref),
            ("qd_ref", qd_ref),
            ("qdd_ref", qdd_ref),
        ] {
            check_dof(what, v.len(), dof)?;
        }
        let e = q_ref - q;
        let e_dot = qd_ref - qd;
        let command = qdd_ref + self.kp.component_mul(&e) + self.kd.component_mul(&e_dot);
        let tau = inverse_dynamics(
            self.nominal,
            q.as_slice(),
            qd.as_slice(),
            command.as_slice(),
        )?;
        Ok(self.saturate(tau))
    }

    fn saturate(&self, tau: DVector<f64>) -> DVector<f64> {
        match &self.effort_limit {
            Some(limit) => tau.zip_map(limit, |t, l| t.clamp(-l, l)),
            None => tau,
        }
    }
}

/// Expands a per-joint list (or one broadcast value) after checking it.
fn per_joint(
    what: &'static str,
    values: &[f64],
    dof: usize,
    strictly_positive: bool,
) -> Result<DVector<f64>, SimError> {
    let v = match values.len() {
        1 => DVector::from_element(dof, values[0]),
        n if n == dof => DVector::from_column_slice(values),
        n => {
            return Err(SimError::DofMismatch {
                what,
                dof,
                found: n,
            });
        }
    };
    for &x in v.iter() {
        let ok = x.is_finite() && (x > 0.0 || (!strictly_positive && x == 0.0));
        if !ok {
            let reason = if strictly_positive {
                "must be positive"
            } else {
                "must be non-negative"
            };
            return Err(SimError::Config {
                what,
                value: x,
                reason,
            });
        }
    }
    Ok(v)
}

fn check_dof(what: &'static str, found: usize, dof: usize) -> Result<(), SimError> {
    if found == dof {
        Ok(())
    } else {
        Err(SimError::DofMismatch { what, dof, found })
    }
}

/// Sensor model of the recorded data.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct NoiseConfig {
    /// Std-dev of additive torque noise in N m (current-based estimate).
    pub torque_sigma: f64,
    /// Std-dev of a per-joint torque gain error, drawn once per recording
    /// (torque-constant error of the current estimate): recorded =
    /// (1 + e_j) applied + noise.
    pub torque_scale_sigma: f64,
    /// Std-dev of additive velocity noise in rad/s.
    pub velocity_sigma: f64,
    /// Std-dev of additive angle noise in rad.
    pub angle_sigma: f64,
    /// Encoder resolution in rad: recorded angles are rounded to multiples of
    /// it; `None` for none.
    pub angle_resolution: Option<f64>,
    /// Per joint, metres per radian of the noise (see
    /// `dynamics::PRISMATIC_LEVER`): a prismatic joint's
    /// position and velocity noise is the revolute sigma times this lever,
    /// its force noise the torque sigma divided by it. Empty: 1 for every
    /// joint.
    pub lever: Vec<f64>,
}

impl Default for NoiseConfig {
    fn default() -> Self {
        Self {
            torque_sigma: 0.05,
            torque_scale_sigma: 0.0,
            velocity_sigma: 0.02,
            angle_sigma: 1e-5,
            angle_resolution: None,
            lever: Vec::new(),
        }
    }
}

impl NoiseConfig {
    /// Perfect sensors.
    pub fn none() -> Self {
        Self {
            torque_sigma: 0.0,
            torque_scale_sigma: 0.0,
            velocity_sigma: 0.0,
            angle_sigma: 0.0,
            angle_resolution: None,
            lever: Vec::new(),
        }
    }

    fn validate(&self) -> Result<(), SimError> {
        non_negative("torque_sigma", self.torque_sigma)?;
        non_negative("torque_scale_sigma", self.torque_scale_sigma)?;
        non_negative("velocity_sigma", self.velocity_sigma)?;
        non_negative("angle_sigma", self.angle_sigma)?;
        match self.angle_resolution {
            Some(r) if !(r.is_finite() && r > 0.0) => Err(SimError::Config {
                what: "angle_resolution",
                value: r,
                reason: "must be positive",
            }),
            _ => {
                for &lever in &self.lever {
                    positive("noise lever", lever)?;
                }
                Ok(())
            }
        }
    }

    /// Joint j's lever (1 when none is given).
    fn lever(&self, j: usize) -> f64 {
        self.lever.get(j).copied().unwrap_or(1.0)
    }
}

fn non_negative(what: &'static str, value: f64) -> Result<(), SimError> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(SimError::Config {
            what,
            value,
            reason: "must be finite and non-negative",
        })
    }
}

/// Configuration of [`simulate`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SimConfig {
    /// Control and recording period in s (1 ms: the arm's 1 kHz feedback).
    pub control_dt: f64,
    /// RK4 steps per control period.
    pub substeps: usize,
    /// Controller gains and saturation.
    pub controller: ControllerConfig,
    /// Sensor model.
    pub noise: NoiseConfig,
    /// |qd| in rad/s above which the run counts as diverged.
    pub divergence_velocity: f64,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            control_dt: 1e-3,
            substeps: 1,
            controller: ControllerConfig::default(),
            noise: NoiseConfig::default(),
            divergence_velocity: 100.0,
        }
    }
}

impl SimConfig {
    /// Number of control periods covering `duration`.
    fn steps(&self, duration: f64) -> Result<usize, SimError> {
        if !(duration.is_finite() && duration >= 0.0) {
            return Err(SimError::Config {
                what: "reference duration",
                value: duration,
                reason: "must be finite and non-negative",
            });
        }
        positive("control_dt", self.control_dt)?;
        positive("divergence_velocity", self.divergence_velocity)?;
        positive("substeps", self.substeps as f64)?;
        self.noise.validate()?;
        let steps = (duration / self.control_dt - 1e-9).ceil().max(0.0);
        if !(steps.is_finite() && steps < MAX_SAMPLES) {
            return Err(SimError::Config {
                what: "duration / control_dt",
                value: steps,
                reason: "too many samples",
            });
        }
        Ok(steps as usize)
    }
}

fn positive(what: &'static str, value: f64) -> Result<(), SimError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(SimError::Config {
            what,
            value,
            reason: "must be positive and finite",
        })
    }
}

/// Output of [`simulate`]; all three share the time grid k * control_dt.
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    /// What the robot logs: noisy q, qd, tau; no qdd.
    pub measured: Trajectory,
    /// True q, qd, qdd and applied tau (qdd is the plant's response to tau).
    pub truth: Trajectory,
    /// Planned q, qd, qdd; tau is the nominal model's inverse dynamics.
    pub reference: Trajectory,
}

/// Runs the virtual robot over the reference's duration, starting at the
/// reference's initial state, and records at the control rate.
///
/// The controller sees the measured (noisy) state, as the real arm's does;
/// its torque is held constant over each control period.
pub fn simulate(
    plant: &dyn Plant,
    nominal: &dyn Plant,
    reference: &dyn Reference,
    config: &SimConfig,
    seed: u64,
) -> Result<Recording, SimError> {
    let dof = plant.dof();
    check_dof("nominal model", nominal.dof(), dof)?;
    check_dof("reference", reference.dof(), dof)?;
    let steps = config.steps(reference.duration())?;
    let controller = Controller::new(nominal, &config.controller)?;
    let mut sensors = Sensors::new(&config.noise, dof, seed);
    let mut log = Log::new(steps + 1, dof);
    let (mut q, mut qd, _) = reference.sample(0.0);
    let h = config.control_dt / config.substeps as f64;
    check_state(0.0, &q, &qd, config.divergence_velocity)?;
    for k in 0..=steps {
        let t = k as f64 * config.control_dt;
        let (q_ref, qd_ref, qdd_ref) = reference.sample(t);
        let (q_meas, qd_meas) = sensors.state(&q, &qd);
        let tau = controller.torque((&q_meas, &qd_meas), (&q_ref, &qd_ref, &qdd_ref))?;
        let qdd = forward_dynamics(plant, q.as_slice(), qd.as_slice(), tau.as_slice())?;
        let tau_ref = inverse_dynamics(
            nominal,
            q_ref.as_slice(),
            qd_ref.as_slice(),
            qdd_ref.as_slice(),
        )?;
        log.push(
            k,
            [&q_meas, &qd_meas, &sensors.torque(&tau)],
            [&q, &qd, &qdd, &tau],
            [&q_ref, &qd_ref, &qdd_ref, &tau_ref],
        );
        if k < steps {
            for _ in 0..config.substeps {
                (q, qd) = rk4_step(plant, &q, &qd, &tau, h)?;
            }
            check_state(t + config.control_dt, &q, &qd, config.divergence_velocity)?;
        }
    }
    log.finish(config.control_dt)
}

/// Feeds `torques` (rows = samples, columns = joints) open-loop, each row held
/// for `dt` (zero-order hold, one RK4 step), and returns the joint angles at
/// the start of each period (row 0 = `q0`), aligned with the torque rows.
pub fn open_loop(
    plant: &dyn Plant,
    q0: &[f64],
    qd0: &[f64],
    torques: &DMatrix<f64>,
    dt: f64,
) -> Result<DMatrix<f64>, SimError> {
    let dof = plant.dof();
    check_dof("q0", q0.len(), dof)?;
    check_dof("qd0", qd0.len(), dof)?;
    check_dof("torques", torques.ncols(), dof)?;
    positive("dt", dt)?;
    let mut q = DVector::from_column_slice(q0);
    let mut qd = DVector::from_column_slice(qd0);
    let mut out = DMatrix::zeros(torques.nrows(), dof);
    for k in 0..torques.nrows() {
        out.set_row(k, &q.transpose());
        let tau = torques.row(k).transpose();
        (q, qd) = rk4_step(plant, &q, &qd, &tau, dt)?;
        check_state((k + 1) as f64 * dt, &q, &qd, f64::INFINITY)?;
    }
    Ok(out)
}

/// One classic RK4 step of qdd = f(q, qd, tau) with tau held constant.
pub(crate) fn rk4_step(
    plant: &dyn Plant,
    q: &DVector<f64>,
    qd: &DVector<f64>,
    tau: &DVector<f64>,
    h: f64,
) -> Result<(DVector<f64>, DVector<f64>), SimError> {
    let accel = |q: &DVector<f64>, qd: &DVector<f64>| {
        forward_dynamics(plant, q.as_slice(), qd.as_slice(), tau.as_slice())
    };
    let a1 = accel(q, qd)?;
    let (q2, v2) = (q + qd * (h / 2.0), qd + &a1 * (h / 2.0));
    let a2 = accel(&q2, &v2)?;
    let (q3, v3) = (q + &v2 * (h / 2.0), qd + &a2 * (h / 2.0));
    let a3 = accel(&q3, &v3)?;
    let (q4, v4) = (q + &v3 * h, qd + &a3 * h);
    let a4 = accel(&q4, &v4)?;
    let q_next = q + (qd + &v2 * 2.0 + &v3 * 2.0 + &v4) * (h / 6.0);
    let qd_next = qd + (a1 + a2 * 2.0 + a3 * 2.0 + a4) * (h / 6.0);
    Ok((q_next, qd_next))
}

/// Fails on a non-finite state or a joint faster than `max_velocity`.
fn check_state(
    time: f64,
    q: &DVector<f64>,
    qd: &DVector<f64>,
    max_velocity: f64,
) -> Result<(), SimError> {
    for (joint, (&qj, &vj)) in q.iter().zip(qd.iter()).enumerate() {
        if !(qj.is_finite() && vj.is_finite() && vj.abs() <= max_velocity) {
            return Err(SimError::Diverged {
                time,
                joint,
                q: qj,
                qd: vj,
            });
        }
    }
    Ok(())
}

/// Standard normal draw by Box-Muller (keeps the dependency list short).
fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    // 1 - u lies in (0, 1], so the logarithm is finite.
    let u1 = 1.0 - rng.random::<f64>();
    let u2 = rng.random::<f64>();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Seeded sensor noise; every channel draws every sample so the stream does
/// not depend on which sigmas are zero.
struct Sensors {
    rng: ChaCha8Rng,
    config: NoiseConfig,
    torque_gain: DVector<f64>,
}

impl Sensors {
    fn new(config: &NoiseConfig, dof: usize, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let torque_gain = DVector::from_fn(dof, |_, _| {
            1.0 + config.torque_scale_sigma * gaussian(&mut rng)
        });
        Self {
            rng,
            config: config.clone(),
            torque_gain,
        }
    }

    /// Noise of joint j's sigma times `scale(lever_j)`.
    fn noise(&mut self, len: usize, sigma: f64, scale: fn(f64) -> f64) -> DVector<f64> {
        let config = &self.config;
        let rng = &mut self.rng;
        DVector::from_fn(len, |j, _| sigma * scale(config.lever(j)) * gaussian(rng))
    }

    fn state(&mut self, q: &DVector<f64>, qd: &DVector<f64>) -> (DVector<f64>, DVector<f64>) {
        let along = |lever: f64| lever;
        let mut q_meas = q + self.noise(q.len(), self.config.angle_sigma, along);
        if let Some(res) = self.config.angle_resolution {
            q_meas.iter_mut().enumerate().for_each(|(j, x)| {
                let step = res * self.config.lever(j);
                *x = (*x / step).round() * step
            });
        }
        let qd_meas = qd + self.noise(qd.len(), self.config.velocity_sigma, along);
        (q_meas, qd_meas)
    }

    fn torque(&mut self, tau: &DVector<f64>) -> DVector<f64> {
        let noise = self.noise(tau.len(), self.config.torque_sigma, |lever| 1.0 / lever);
        tau.component_mul(&self.torque_gain) + noise
    }
}

/// Row-per-sample buffers of the three recorded trajectories.
struct Log {
    measured: [DMatrix<f64>; 3],
    truth: [DMatrix<f64>; 4],
    reference: [DMatrix<f64>; 4],
}

impl Log {
    fn new(rows: usize, dof: usize) -> Self {
        let zeros = || DMatrix::zeros(rows, dof);
        Self {
            measured: [zeros(), zeros(), zeros()],
            truth: [zeros(), zeros(), zeros(), zeros()],
            reference: [zeros(), zeros(), zeros(), zeros()],
        }
    }

    fn push(
        &mut self,
        k: usize,
        measured: [&DVector<f64>; 3],
        truth: [&DVector<f64>; 4],
        reference: [&DVector<f64>; 4],
    ) {
        let rows = self.measured.iter_mut().zip(measured);
        let rows = rows.chain(self.truth.iter_mut().zip(truth));
        for (m, v) in rows.chain(self.reference.iter_mut().zip(reference)) {
            m.set_row(k, &v.transpose());
        }
    }

    fn finish(self, dt: f64) -> Result<Recording, SimError> {
        let t: Vec<f64> = (0..self.measured[0].nrows())
            .map(|k| k as f64 * dt)
            .collect();
        let [mq, mqd, mtau] = self.measured;
        let [tq, tqd, tqdd, ttau] = self.truth;
        let [rq, rqd, rqdd, rtau] = self.reference;
        Ok(Recording {
            measured: Trajectory::new(t.clone(), mq, mqd, None, mtau)?,
            truth: Trajectory::new(t.clone(), tq, tqd, Some(tqdd), ttau)?,
            reference: Trajectory::new(t, rq, rqd, Some(rqdd), rtau)?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::plant::test_plants::{Pendulum, TwoLink};
    use crate::sim::reference::{
        ExcitationConfig, ExcitationTrajectory, JointLimits, WaypointConfig, WaypointTrajectory,
    };

    fn two_link_waypoints(seed: u64) -> WaypointTrajectory {
        let cfg = WaypointConfig {
            limits: JointLimits::uniform(2, (-2.5, 2.5), 1.0, 2.0),
            ..Default::default()
        };
        WaypointTrajectory::new(&cfg, seed).unwrap()
    }

    fn quiet() -> SimConfig {
        SimConfig {
            noise: NoiseConfig::none(),
            ..Default::default()
        }
    }

    fn rms(m: &DMatrix<f64>) -> f64 {
        (m.norm_squared() / m.len() as f64).sqrt()
    }

    /// Relative drift of total energy of the free double pendulum over 20 s.
    fn energy_drift(h: f64) -> f64 {
        let arm = TwoLink::new();
        let (mut q, mut qd) = (DVector::from_vec(vec![0.3, 0.8]), DVector::zeros(2));
        let tau = DVector::zeros(2);
        let e0 = arm.energy(q.as_slice(), qd.as_slice());
        let scale = e0.abs().max(
            arm.energy(&[-std::f64::consts::FRAC_PI_2, 0.0], &[0.0; 2])
                .abs(),
        );
        let mut worst: f64 = 0.0;
        for _ in 0..(20.0 / h).round() as usize {
            (q, qd) = rk4_step(&arm, &q, &qd, &tau, h).unwrap();
            worst = worst.max((arm.energy(q.as_slice(), qd.as_slice()) - e0).abs());
        }
        worst / scale
    }

    #[test]
    fn rk4_conserves_energy_of_free_double_pendulum() {
        let drift = energy_drift(1e-3);
        eprintln!("max relative energy drift over 20 s at 1 ms: {drift:e}");
        // Measured 1.65e-8.
        assert!(drift < 3e-8, "drift {drift:e}");
        // Fourth order: halving the step shrinks the drift about 16-fold.
        let coarse = energy_drift(2e-3);
        eprintln!("at 2 ms: {coarse:e}");
        assert!(coarse > 8.0 * drift);
    }

    #[test]
    fn perfect_model_without_noise_tracks_closely() {
        let arm = TwoLink::new().with_friction(0.05, 0.0);
        let rec = simulate(&arm, &arm, &two_link_waypoints(1), &quiet(), 0).unwrap();
        assert_eq!(rec.truth.len(), 20_001);
        // Residual from the zero-order hold (half-period delay), measured 3.5e-4.
        let err = (rec.truth.q() - rec.reference.q()).amax();
        assert!(err < 1e-3, "tracking error {err:e}");
        assert_eq!(rec.measured.q(), rec.truth.q());
        assert!(rec.measured.qdd().is_none());
    }

    #[test]
    fn coulomb_friction_sticks_briefly_at_reversals() {
        let arm = TwoLink::new().with_friction(0.05, 0.1);
        let rec = simulate(&arm, &arm, &two_link_waypoints(1), &quiet(), 0).unwrap();
        // Compensation follows sign(qd) at the sample, so a reversal can stick
        // for tens of ms until the PD term pushes through (measured 6.7e-3).
        let err = (rec.truth.q() - rec.reference.q()).amax();
        assert!(err > 1e-3 && err < 2e-2, "tracking error {err:e}");
    }

    #[test]
    fn perfect_model_tracks_excitation() {
        let arm = TwoLink::new();
        let cfg = ExcitationConfig {
            limits: JointLimits::uniform(2, (-2.5, 2.5), 1.0, 2.0),
            ..Default::default()
        };
        let reference = ExcitationTrajectory::new(&cfg, 4).unwrap();
        let rec = simulate(&arm, &arm, &reference, &quiet(), 0).unwrap();
        assert!((rec.truth.q() - rec.reference.q()).amax() < 1e-3);
    }

    #[test]
    fn heavier_plant_shows_in_recorded_torque() {
        let nominal = TwoLink::new();
        let plant = TwoLink::new().heavier(1.5);
        let rec = simulate(
            &plant,
            &nominal,
            &two_link_waypoints(2),
            &SimConfig::default(),
            9,
        )
        .unwrap();
        let mismatch = rms(&(rec.truth.tau() - rec.reference.tau()));
        let recorded = rms(&(rec.measured.tau() - rec.reference.tau()));
        assert!(mismatch > 0.5, "applied vs nominal torque rms {mismatch}");
        assert!(recorded > 0.5, "recorded vs nominal torque rms {recorded}");
        // Feedback still holds the heavier arm near the plan.
        // (Steady error ~ gravity mismatch / (M Kp), about 0.2 rad here.)
        assert!((rec.truth.q() - rec.reference.q()).amax() < 0.3);
    }

    #[test]
    fn truth_satisfies_plant_dynamics() {
        let plant = TwoLink::new().heavier(1.3).with_friction(0.1, 0.2);
        let rec = simulate(
            &plant,
            &TwoLink::new(),
            &two_link_waypoints(3),
            &SimConfig::default(),
            1,
        )
        .unwrap();
        let qdd = rec.truth.qdd().unwrap();
        for k in (0..rec.truth.len()).step_by(997) {
            let row = |m: &DMatrix<f64>| m.row(k).iter().copied().collect::<Vec<_>>();
            let tau =
                inverse_dynamics(&plant, &row(rec.truth.q()), &row(rec.truth.qd()), &row(qdd))
                    .unwrap();
            assert!((tau.transpose() - rec.truth.tau().row(k)).amax() < 1e-9);
        }
    }

    #[test]
    fn same_seed_same_recording() {
        let arm = TwoLink::new();
        let reference = two_link_waypoints(5);
        let cfg = SimConfig::default();
        let a = simulate(&arm, &arm, &reference, &cfg, 42).unwrap();
        assert_eq!(a, simulate(&arm, &arm, &reference, &cfg, 42).unwrap());
        let b = simulate(&arm, &arm, &reference, &cfg, 43).unwrap();
        assert_ne!(a.measured, b.measured);
    }

    #[test]
    fn measured_velocity_is_visibly_noisy() {
        let arm = TwoLink::new();
        let rec = simulate(&arm, &arm, &two_link_waypoints(6), &SimConfig::default(), 3).unwrap();
        let noise = rms(&(rec.measured.qd() - rec.truth.qd()));
        assert!((noise - 0.02).abs() < 0.002, "velocity noise rms {noise}");
        let tau_noise = rms(&(rec.measured.tau() - rec.truth.tau()));
        assert!(
            (tau_noise - 0.05).abs() < 0.005,
            "torque noise rms {tau_noise}"
        );
        assert!(rms(&(rec.measured.q() - rec.truth.q())) < 2e-5);
    }

    #[test]
    fn torque_scale_error_and_quantization() {
        let arm = TwoLink::new();
        let mut cfg = quiet();
        cfg.noise.torque_scale_sigma = 0.1;
        cfg.noise.angle_resolution = Some(1e-3);
        let rec = simulate(&arm, &arm, &two_link_waypoints(7), &cfg, 8).unwrap();
        let ratio = rec.measured.tau()[(100, 0)] / rec.truth.tau()[(100, 0)];
        let ratio_late = rec.measured.tau()[(9000, 0)] / rec.truth.tau()[(9000, 0)];
        assert!((ratio - ratio_late).abs() < 1e-9 && (ratio - 1.0).abs() > 1e-6);
        let q = rec.measured.q()[(123, 1)];
        assert!(((q / 1e-3).round() * 1e-3 - q).abs() < 1e-12);
    }

    #[test]
    fn effort_limit_saturates_torque() {
        let arm = TwoLink::new();
        let mut cfg = quiet();
        cfg.controller.effort_limit = Some(vec![1.0]);
        match simulate(&arm, &arm, &two_link_waypoints(8), &cfg, 0) {
            Ok(rec) => assert!(rec.truth.tau().amax() <= 1.0),
            Err(SimError::Diverged { .. }) => {}
            Err(e) => panic!("unexpected error {e}"),
        }
    }

    #[test]
    fn divergence_reports_time() {
        // A pendulum with negative damping gains energy until it trips the bound.
        let plant = Pendulum {
            mass: 1.0,
            length: 0.5,
            viscous: -2.0,
        };
        let limits = JointLimits::uniform(1, (-1.0, 1.0), 1.0, 1.0);
        let reference = WaypointTrajectory::new(
            &WaypointConfig {
                limits,
                ..Default::default()
            },
            0,
        )
        .unwrap();
        let mut cfg = quiet();
        cfg.controller.kp = vec![0.0];
        cfg.controller.kd = vec![0.0];
        cfg.controller.effort_limit = Some(vec![1e-9]);
        cfg.divergence_velocity = 5.0;
        let err = simulate(&plant, &plant, &reference, &cfg, 0).unwrap_err();
        let SimError::Diverged {
            time, joint: 0, qd, ..
        } = err
        else {
            panic!("{err}")
        };
        assert!(time > 0.0 && time < 20.0 && qd.abs() > 5.0);
        assert!(err.to_string().contains("diverged at t ="));
    }

    #[test]
    fn bad_inputs_are_errors() {
        let arm = TwoLink::new();
        let pendulum = Pendulum {
            mass: 1.0,
            length: 1.0,
            viscous: 0.0,
        };
        let reference = two_link_waypoints(0);
        let err = simulate(&arm, &pendulum, &reference, &quiet(), 0).unwrap_err();
        assert!(matches!(
            err,
            SimError::DofMismatch {
                what: "nominal model",
                ..
            }
        ));
        let mut cfg = quiet();
        cfg.controller.kp = vec![1.0, 2.0, 3.0];
        assert!(matches!(
            simulate(&arm, &arm, &reference, &cfg, 0),
            Err(SimError::DofMismatch { what: "kp", .. })
        ));
        let cfg = SimConfig {
            control_dt: 0.0,
            ..quiet()
        };
        assert!(matches!(
            simulate(&arm, &arm, &reference, &cfg, 0),
            Err(SimError::Config { .. })
        ));
        let cfg = SimConfig {
            control_dt: 1e-12,
            ..quiet()
        };
        assert!(matches!(
            simulate(&arm, &arm, &reference, &cfg, 0),
            Err(SimError::Config { .. })
        ));
        let cfg = SimConfig {
            substeps: 0,
            ..quiet()
        };
        assert!(simulate(&arm, &arm, &reference, &cfg, 0).is_err());
        let mut cfg = quiet();
        cfg.noise.velocity_sigma = -1.0;
        assert!(simulate(&arm, &arm, &reference, &cfg, 0).is_err());
        let torques = DMatrix::zeros(10, 3);
        assert!(open_loop(&arm, &[0.0; 2], &[0.0; 2], &torques, 1e-3).is_err());
        assert!(open_loop(&arm, &[0.0; 2], &[0.0; 2], &DMatrix::zeros(10, 2), f64::NAN).is_err());
    }

    #[test]
    fn config_defaults_fill_missing_fields() {
        use serde::de::value::{Error, MapDeserializer};
        let empty: Vec<(&str, f64)> = Vec::new();
        let cfg =
            SimConfig::deserialize(MapDeserializer::<_, Error>::new(empty.into_iter())).unwrap();
        assert_eq!(cfg, SimConfig::default());
        assert_eq!(cfg.controller.kp, vec![100.0]);
    }

    #[test]
    fn controller_is_computed_torque_plus_pd() {
        let arm = TwoLink::new();
        let cfg = ControllerConfig {
            kp: vec![4.0, 9.0],
            kd: vec![1.0],
            effort_limit: None,
        };
        let ctrl = Controller::new(&arm, &cfg).unwrap();
        let (q, qd) = (
            DVector::from_vec(vec![0.1, 0.2]),
            DVector::from_vec(vec![0.3, -0.1]),
        );
        let (qr, qdr, qddr) = (
            DVector::from_vec(vec![0.2, 0.0]),
            DVector::zeros(2),
            DVector::from_vec(vec![1.0, 1.0]),
        );
        let tau = ctrl.torque((&q, &qd), (&qr, &qdr, &qddr)).unwrap();
        let command = [1.0 + 4.0 * 0.1 - 0.3, 1.0 - 9.0 * 0.2 + 0.1];
        let expected = inverse_dynamics(&arm, q.as_slice(), qd.as_slice(), &command).unwrap();
        assert!((tau - expected).amax() < 1e-12);
    }

    #[test]
    fn open_loop_reproduces_simulated_motion() {
        let arm = TwoLink::new().with_friction(0.05, 0.0);
        let rec = simulate(&arm, &arm, &two_link_waypoints(10), &quiet(), 0).unwrap();
        let q0: Vec<f64> = rec.truth.q().row(0).iter().copied().collect();
        let qd0: Vec<f64> = rec.truth.qd().row(0).iter().copied().collect();
        // Same torques, same hold, same integrator: the same motion.
        let q = open_loop(&arm, &q0, &qd0, rec.truth.tau(), 1e-3).unwrap();
        assert!((&q - rec.truth.q()).amax() < 1e-6);
        // Nominal inverse-dynamics torques follow the plan open-loop for a while.
        let short = rec.reference.tau().rows(0, 1000).into_owned();
        let planned = open_loop(&arm, &q0, &qd0, &short, 1e-3).unwrap();
        // Open loop drifts (unstable under gravity): measured 2.1e-4 after 1 s.
        assert!((planned - rec.reference.q().rows(0, 1000)).amax() < 1e-3);
    }

    #[test]
    fn substeps_agree_with_single_step() {
        let arm = TwoLink::new();
        let reference = two_link_waypoints(12);
        let one = simulate(&arm, &arm, &reference, &quiet(), 0).unwrap();
        let four = simulate(
            &arm,
            &arm,
            &reference,
            &SimConfig {
                substeps: 4,
                ..quiet()
            },
            0,
        )
        .unwrap();
        assert!((one.truth.q() - four.truth.q()).amax() < 1e-8);
    }
}
