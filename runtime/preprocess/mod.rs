//! Preprocessing of measured recordings: smoothing, differentiation for
//! acceleration, and decimation.
//!
//! Two presets:
//! - **auto** (every command's default but `reproduce`): settings chosen from
//!   the data ([`auto::choose`]): a zero-phase Butterworth low-pass of
//!   positions, velocities and torque at one cut-off in Hz (parallel
//!   filtering: the torque keeps no more bandwidth than the states that
//!   explain it), acceleration by central differences of the filtered
//!   velocity, then decimation to ten times the cut-off. Filtering comes
//!   before decimation, so nothing aliases.
//! - **thesis** (thesis section 2.4, `reproduce`'s default): keep every 10th
//!   sample, a 40-sample centred moving average on the velocity, central
//!   differences, the same average on the acceleration; torque unfiltered.
//!
//! Every filter returns as many samples as it is given.

pub mod auto;
pub mod butterworth;
mod filters;
mod pipeline;

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

pub use butterworth::ZeroPhaseLowPass;
pub use filters::{
    Centering, PreprocessError, central_difference, downsample, moving_average, savitzky_golay,
};
pub use pipeline::{Compared, Pipeline, Preset};

use crate::trajectory::Trajectory;

/// Velocity smoothing used by [`Preprocess`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Filter {
    /// No smoothing; acceleration by plain central differences.
    None,
    /// Thesis pipeline: SMA on velocity, central difference, SMA again.
    Sma { window: usize, centered: bool },
    /// Zero-phase alternative: velocity and acceleration from one local
    /// polynomial fit of the raw velocity (derivatives 0 and 1).
    SavitzkyGolay { window: usize, order: usize },
    /// Zero-phase Butterworth low-pass of q, qd (and the torque, with
    /// `filter_torque`) at the original rate, before decimation;
    /// acceleration by central differences of the filtered velocity.
    Butterworth { cutoff_hz: f64 },
}

/// Preprocessing configuration ([`Default`]: the thesis's).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Preprocess {
    /// Keep every n-th sample (10: 1 kHz -> 100 Hz).
    pub downsample: usize,
    /// Velocity filter (SMA, window 40 = 0.4 s at 100 Hz, centred).
    pub filter: Filter,
    /// Also low-pass the measured torque with the acceleration's filter
    /// ("parallel filtering" of identification): the torque then carries no
    /// more high-frequency content than the smoothed states that explain it.
    /// Off in the thesis pipeline.
    pub filter_torque: bool,
}

impl Default for Preprocess {
    fn default() -> Self {
        Self::thesis()
    }
}

impl Preprocess {
    /// Thesis section 2.4.2.
    pub fn thesis() -> Self {
        Self {
            downsample: 10,
            filter: Filter::Sma {
                window: 40,
                centered: true,
            },
            filter_torque: false,
        }
    }

    /// The identification-grade pipeline for a data-driven [`auto::Choice`]:
    /// zero-phase low-pass of states and torque, decimation to the chosen
    /// rate of a recording sampled at `sample_rate_hz`.
    pub fn identification(choice: &auto::Choice, sample_rate_hz: f64) -> Self {
        Self {
            downsample: ((sample_rate_hz / choice.decimated_rate_hz).floor() as usize).max(1),
            filter: Filter::Butterworth {
                cutoff_hz: choice.cutoff_hz,
            },
            filter_torque: true,
        }
    }

    /// Smooths the velocity, recomputes the acceleration and decimates;
    /// `q` and `tau` are kept as measured (unless the filter is a
    /// Butterworth or `filter_torque` is set), any `qdd` is replaced.
    /// Assumes uniform sampling (as [`crate::trajectory::read_csv`] guarantees).
    pub fn apply(&self, traj: &Trajectory) -> Result<Trajectory, PreprocessError> {
        if let Filter::Butterworth { .. } = self.filter {
            return downsample(&self.filter_at_full_rate(traj)?, self.downsample);
        }
        let traj = downsample(traj, self.downsample)?;
        let n = traj.len();
        let needed = match self.filter {
            Filter::Sma { window, .. } | Filter::SavitzkyGolay { window, .. } => window.max(2),
            _ => 2,
        };
        if n < needed {
            return Err(PreprocessError::TooFewSamples {
                what: "preprocessing after downsampling",
                needed,
                found: n,
            });
        }
        let dt = step(&traj);
        let mut qd = traj.qd().clone();
        let mut qdd = DMatrix::zeros(n, traj.dof());
        for j in 0..traj.dof() {
            let raw: Vec<f64> = traj.qd().column(j).iter().copied().collect();
            let (v, a) = self.filter_velocity(&raw, dt)?;
            qd.column_mut(j).copy_from_slice(&v);
            qdd.column_mut(j).copy_from_slice(&a);
        }
        let tau = if self.filter_torque {
            self.smooth_columns(traj.tau(), dt)?
        } else {
            traj.tau().clone()
        };
        let t = traj.t().to_vec();
        Ok(Trajectory::new(t, traj.q().clone(), qd, Some(qdd), tau)?)
    }

    /// The Butterworth pipeline without its decimation: filtered q, qd and
    /// (with `filter_torque`) tau, qdd from the filtered qd, all samples kept.
    pub fn filter_at_full_rate(&self, traj: &Trajectory) -> Result<Trajectory, PreprocessError> {
        if traj.len() < 3 {
            return Err(PreprocessError::TooFewSamples {
                what: "preprocessing",
                needed: 3,
                found: traj.len(),
            });
        }
        let dt = step(traj);
        let mut qd = self.smooth_columns(traj.qd(), dt)?;
        let mut qdd = DMatrix::zeros(traj.len(), traj.dof());
        for j in 0..traj.dof() {
            let v: Vec<f64> = qd.column(j).iter().copied().collect();
            qdd.column_mut(j)
                .copy_from_slice(&central_difference(&v, dt)?);
        }
        still_where_logged_still(&mut qd, traj.qd());
        let q = match self.filter {
            Filter::Butterworth { .. } => self.smooth_columns(traj.q(), dt)?,
            _ => traj.q().clone(),
        };
        let tau = if self.filter_torque {
            self.smooth_columns(traj.tau(), dt)?
        } else {
            traj.tau().clone()
        };
        Ok(Trajectory::new(traj.t().to_vec(), q, qd, Some(qdd), tau)?)
    }

    /// [`Preprocess::filter_at_full_rate`] with the torque left as measured
    /// (for a comparison that filters both torques alike afterwards).
    pub fn states_at_full_rate(&self, traj: &Trajectory) -> Result<Trajectory, PreprocessError> {
        Self {
            filter_torque: false,
            ..self.clone()
        }
        .filter_at_full_rate(traj)
    }

    /// Every column of `m` through [`Preprocess::smooth`].
    pub fn smooth_columns(
        &self,
        m: &DMatrix<f64>,
        dt: f64,
    ) -> Result<DMatrix<f64>, PreprocessError> {
        let mut out = m.clone();
        if let (Filter::Butterworth { cutoff_hz }, rows @ 1.., 1..) =
            (&self.filter, m.nrows(), m.ncols())
        {
            // The columns side by side: the same numbers as one at a time.
            let filter = ZeroPhaseLowPass::new(*cutoff_hz, dt)?;
            let mut columns: Vec<&mut [f64]> = out.as_mut_slice().chunks_mut(rows).collect();
            filter.apply_interleaved(&mut columns, 1);
            return Ok(out);
        }
        for j in 0..m.ncols() {
            let raw: Vec<f64> = m.column(j).iter().copied().collect();
            out.column_mut(j).copy_from_slice(&self.smooth(&raw, dt)?);
        }
        Ok(out)
    }

    /// The low-pass that the acceleration estimate applies, as a smoother
    /// (the torque's filter with `filter_torque`, and the one the diagnosis
    /// applies to its regressor columns): the SMA twice (velocity, then
    /// difference), the Savitzky-Golay fit or the Butterworth.
    pub fn smooth(&self, x: &[f64], dt: f64) -> Result<Vec<f64>, PreprocessError> {
        match self.filter {
            Filter::None => Ok(x.to_vec()),
            Filter::Sma { window, centered } => {
                let c = Centering::of(centered);
                moving_average(&moving_average(x, window, c)?, window, c)
            }
            Filter::SavitzkyGolay { window, order } => savitzky_golay(x, window, order, 0, dt),
            Filter::Butterworth { cutoff_hz } => Ok(ZeroPhaseLowPass::new(cutoff_hz, dt)?.apply(x)),
        }
    }

    /// Returns (smoothed velocity, acceleration) for one joint.
    fn filter_velocity(&self, v: &[f64], dt: f64) -> Result<(Vec<f64>, Vec<f64>), PreprocessError> {
        match self.filter {
            Filter::None => Ok((v.to_vec(), central_difference(v, dt)?)),
            Filter::Sma { window, centered } => {
                let c = Centering::of(centered);
                let smooth = moving_average(v, window, c)?;
                let acc = moving_average(&central_difference(&smooth, dt)?, window, c)?;
                Ok((smooth, acc))
            }
            Filter::SavitzkyGolay { window, order } => Ok((
                savitzky_golay(v, window, order, 0, dt)?,
                savitzky_golay(v, window, order, 1, dt)?,
            )),
            Filter::Butterworth { .. } => {
                let smooth = self.smooth(v, dt)?;
                let acc = central_difference(&smooth, dt)?;
                Ok((smooth, acc))
            }
        }
    }
}

/// Mean sampling interval of a uniformly sampled trajectory.
pub fn step(traj: &Trajectory) -> f64 {
    let n = traj.len();
    (traj.t()[n - 1] - traj.t()[0]) / (n - 1).max(1) as f64
}

/// A joint whose logged velocity is exactly zero stands still, and its
/// filtered velocity is set to zero there too. A recursive low-pass leaves
/// a decaying tail of the motion before a stop (1e-3 .. 1e-10 rad/s for
/// seconds); the model's sign(qd) would read that tail as motion and apply
/// full Coulomb friction with the tail's sign to a joint at rest (arms
/// that log 0 at rest, e.g. a UR's 4-decimal velocities, rest a third of
/// an identification run). The acceleration stays the filtered one.
fn still_where_logged_still(filtered: &mut DMatrix<f64>, logged: &DMatrix<f64>) {
    for (v, &raw) in filtered.iter_mut().zip(logged.iter()) {
        if raw == 0.0 {
            *v = 0.0;
        }
    }
}
