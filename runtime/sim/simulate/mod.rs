//! The virtual robot: a computed-torque controller tracking a [`Reference`]
//! on a [`Plant`] integrated with RK4, recorded through noisy sensors.
//!
//! Coulomb friction makes the plant's bias discontinuous at qd = 0. RK4 then
//! loses its fourth order across a velocity reversal, but at a 1 ms step the
//! local error stays tiny, so no event handling is done.

use crate::trajectory::{Trajectory, TrajectoryError};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use super::plant::{DynamicsError, Plant, forward_dynamics, inverse_dynamics};
use super::reference::Reference;

mod sensors;
#[cfg(test)]
mod tests;

pub use sensors::NoiseConfig;
use sensors::Sensors;

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
    #[error(
        "simulation diverged at t = {time} s: joint {} has q = {q}, qd = {qd} (a reference \
         beyond what the drives' effort limits can follow, or gains too high for the plant)",
        .joint + 1
    )]
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

/// Most RK4 steps per control period [`stable_substeps`] asks for.
const MOST_SUBSTEPS: usize = 1000;

/// RK4 steps per control period that keep the plant's fastest velocity
/// decay, lambda = -d qdd_j / d qd_j (viscous friction over a small
/// inertia: an imported wrist with 2 N m s/rad on 1.3e-4 kg m^2 decays at
/// 15,000 1/s), within h lambda <= 1, well inside RK4's stability bound of
/// 2.78; at one step per millisecond such a plant diverges in one step.
/// Measured at `q` moving at 1 rad/s on every joint (central differences,
/// away from Coulomb friction's step at rest).
fn stable_substeps(plant: &dyn Plant, q: &DVector<f64>, dt: f64) -> Result<usize, SimError> {
    let dof = q.len();
    let tau = vec![0.0; dof];
    let step = 1e-4;
    let mut fastest: f64 = 0.0;
    for j in 0..dof {
        let at = |v: f64| {
            let mut qd = vec![1.0; dof];
            qd[j] = v;
            forward_dynamics(plant, q.as_slice(), &qd, &tau).map(|qdd| qdd[j])
        };
        let decay = -(at(1.0 + step)? - at(1.0 - step)?) / (2.0 * step);
        if decay.is_finite() {
            fastest = fastest.max(decay);
        }
    }
    Ok(((dt * fastest).ceil() as usize).clamp(1, MOST_SUBSTEPS))
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

impl Recording {
    /// The joint (0-based) that left its planned motion most, by how much
    /// (rad or m) and when (s).
    pub fn worst_tracking(&self) -> Option<(usize, f64, f64)> {
        let error = self.truth.q() - self.reference.q();
        let (row, joint) = error.iamax_full();
        let worst = error.get((row, joint))?.abs();
        Some((joint, worst, self.truth.t()[row]))
    }
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
    let substeps = config
        .substeps
        .max(stable_substeps(plant, &q, config.control_dt)?);
    let h = config.control_dt / substeps as f64;
    let mut rk4 = Rk4::new(dof);
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
            for _ in 0..substeps {
                rk4.step(
                    plant,
                    q.as_mut_slice(),
                    qd.as_mut_slice(),
                    tau.as_slice(),
                    h,
                )?;
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
    let mut rk4 = Rk4::new(dof);
    for k in 0..torques.nrows() {
        out.set_row(k, &q.transpose());
        let tau = torques.row(k).transpose();
        rk4.step(
            plant,
            q.as_mut_slice(),
            qd.as_mut_slice(),
            tau.as_slice(),
            dt,
        )?;
        check_state((k + 1) as f64 * dt, &q, &qd, f64::INFINITY)?;
    }
    Ok(out)
}

/// The classic RK4 integrator's stage buffers, allocated once per run so
/// that a step allocates nothing (with a plant whose forward dynamics do
/// not: a compiled model's).
pub(crate) struct Rk4 {
    /// Stage positions and velocities.
    q: Vec<f64>,
    v: [Vec<f64>; 3],
    /// Stage accelerations.
    a: [Vec<f64>; 4],
}

impl Rk4 {
    pub(crate) fn new(dof: usize) -> Rk4 {
        let zeros = || vec![0.0; dof];
        Rk4 {
            q: zeros(),
            v: [zeros(), zeros(), zeros()],
            a: [zeros(), zeros(), zeros(), zeros()],
        }
    }

    /// Advances (q, qd) by h under the held torque `tau`, in place.
    pub(crate) fn step(
        &mut self,
        plant: &dyn Plant,
        q: &mut [f64],
        qd: &mut [f64],
        tau: &[f64],
        h: f64,
    ) -> Result<(), SimError> {
        let Rk4 { q: stage, v, a } = self;
        plant.accelerations(q, qd, tau, &mut a[0])?;
        // Stage k + 1 starts from (q + c v_k, qd + c a_k), v_0 = qd.
        for (k, c) in [h / 2.0, h / 2.0, h].into_iter().enumerate() {
            let from = if k == 0 { &*qd } else { &v[k - 1] };
            for j in 0..q.len() {
                stage[j] = q[j] + c * from[j];
            }
            let (done, next) = a.split_at_mut(k + 1);
            for j in 0..q.len() {
                v[k][j] = qd[j] + c * done[k][j];
            }
            plant.accelerations(stage, &v[k], tau, &mut next[0])?;
        }
        for j in 0..q.len() {
            q[j] += h / 6.0 * (qd[j] + 2.0 * v[0][j] + 2.0 * v[1][j] + v[2][j]);
            qd[j] += h / 6.0 * (a[0][j] + 2.0 * a[1][j] + 2.0 * a[2][j] + a[3][j]);
        }
        Ok(())
    }
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
