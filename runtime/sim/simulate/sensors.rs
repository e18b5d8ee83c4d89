//! The virtual robot's sensors: additive Gaussian noise on angles,
//! velocities and torques, a per-recording torque gain error and encoder
//! rounding, scaled per joint by its lever (a prismatic joint's metres).

use nalgebra::DVector;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::{SimError, non_negative, positive};

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

    pub(super) fn validate(&self) -> Result<(), SimError> {
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

/// Standard normal draw by Box-Muller (keeps the dependency list short).
fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    // 1 - u lies in (0, 1], so the logarithm is finite.
    let u1 = 1.0 - rng.random::<f64>();
    let u2 = rng.random::<f64>();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Seeded sensor noise; every channel draws every sample so the stream does
/// not depend on which sigmas are zero.
pub(super) struct Sensors {
    rng: ChaCha8Rng,
    config: NoiseConfig,
    torque_gain: DVector<f64>,
}

impl Sensors {
    pub(super) fn new(config: &NoiseConfig, dof: usize, seed: u64) -> Self {
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

    pub(super) fn state(
        &mut self,
        q: &DVector<f64>,
        qd: &DVector<f64>,
    ) -> (DVector<f64>, DVector<f64>) {
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

    pub(super) fn torque(&mut self, tau: &DVector<f64>) -> DVector<f64> {
        let noise = self.noise(tau.len(), self.config.torque_sigma, |lever| 1.0 / lever);
        tau.component_mul(&self.torque_gain) + noise
    }
}
