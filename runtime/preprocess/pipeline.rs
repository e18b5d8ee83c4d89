//! The preprocessing a command runs on its recordings: a preset resolved
//! against the data, the same for every command that reads measurements
//! (`evaluate`, `diagnose`, `study`, `train`, `synth`, `preprocess`).

use nalgebra::DMatrix;
use serde::Serialize;

use super::auto::{self, Choice, sample_rate};
use super::{Filter, Preprocess, PreprocessError};
use crate::trajectory::Trajectory;

/// Torques compared by [`Pipeline::compare`], samples x joints.
#[derive(Debug, Clone)]
pub struct Compared {
    /// Measured and predicted torque, both through the torque filter.
    pub measured: DMatrix<f64>,
    pub predicted: DMatrix<f64>,
    /// The torque as logged and the prediction unfiltered (on the filtered
    /// states), for a comparison with tools that filter only the states:
    /// every sample the trim keeps, not decimated (the logged torque's noise
    /// is white, so the decimated samples alone would estimate its MSE
    /// several percent less precisely).
    pub measured_as_logged: DMatrix<f64>,
    pub predicted_unfiltered: DMatrix<f64>,
}

/// A named set of preprocessing defaults.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum Preset {
    /// Chosen from the data (see [`auto`]).
    #[default]
    Auto,
    /// Thesis section 2.4 (100 Hz after keeping every 10th sample).
    Thesis,
}

/// The resolved preprocessing of a set of recordings.
#[derive(Debug, Clone, Serialize)]
pub struct Pipeline {
    pub preset: Preset,
    /// What the data said and what was chosen (auto only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub choice: Option<Choice>,
    /// The settings (for auto, `downsample` is per recording: see
    /// [`Pipeline::for_recording`]).
    pub settings: Preprocess,
}

/// Periods of the cut-off frequency the shortest recording must span: a
/// filter slower than that returns its own transient, not the data.
const MIN_PERIODS: f64 = 4.0;

impl Pipeline {
    /// The auto preset on `recordings` (raw), with an optional cut-off and
    /// decimated rate in Hz replacing the chosen ones.
    pub fn auto(
        recordings: &[Trajectory],
        cutoff_hz: Option<f64>,
        rate_hz: Option<f64>,
    ) -> Result<Pipeline, PreprocessError> {
        let mut choice = auto::choose(recordings);
        if let Some(cutoff) = cutoff_hz {
            let nyquist = 0.5 * choice.sample_rate_hz;
            if !(cutoff.is_finite() && cutoff > 0.0 && cutoff < nyquist) {
                return Err(PreprocessError::InvalidCutoff {
                    cutoff_hz: cutoff,
                    nyquist_hz: nyquist,
                });
            }
            let shortest = recordings
                .iter()
                .map(|r| r.t()[r.len() - 1] - r.t()[0])
                .fold(f64::INFINITY, f64::min);
            let lowest = MIN_PERIODS / shortest;
            if cutoff < lowest {
                return Err(PreprocessError::CutoffTooLow {
                    cutoff_hz: cutoff,
                    lowest_hz: lowest,
                    seconds: shortest,
                });
            }
            choice.cutoff_hz = cutoff;
            choice.decimated_rate_hz = (auto::RATE_PER_CUTOFF * cutoff).min(choice.sample_rate_hz);
        }
        if let Some(rate) = rate_hz {
            if !(rate.is_finite() && rate >= 2.0 * choice.cutoff_hz) {
                return Err(PreprocessError::InvalidRate {
                    rate_hz: rate,
                    cutoff_hz: choice.cutoff_hz,
                });
            }
            choice.decimated_rate_hz = rate.min(choice.sample_rate_hz);
        }
        let settings = Preprocess::identification(&choice, choice.sample_rate_hz);
        Ok(Pipeline {
            preset: Preset::Auto,
            choice: Some(choice),
            settings,
        })
    }

    /// Fixed settings (the thesis preset or explicit options).
    pub fn fixed(preset: Preset, settings: Preprocess) -> Pipeline {
        Pipeline {
            preset,
            choice: None,
            settings,
        }
    }

    /// The settings for one recording: for auto, its decimation follows its
    /// own sample rate.
    pub fn for_recording(&self, traj: &Trajectory) -> Preprocess {
        match &self.choice {
            Some(choice) => Preprocess::identification(choice, sample_rate(traj)),
            None => self.settings.clone(),
        }
    }

    /// Preprocesses one recording.
    pub fn apply(&self, traj: &Trajectory) -> Result<Trajectory, PreprocessError> {
        self.for_recording(traj).apply(traj)
    }

    /// Measured and predicted torques compared as the diagnosis compares
    /// them. For the Butterworth pipeline: `predict` runs on the filtered
    /// states at the full rate; the measured and the predicted torque both
    /// pass the torque filter (so a linear effect is compared exactly, and a
    /// discontinuous one such as Coulomb friction is smoothed alike on both
    /// sides), the ends are trimmed against filter transients
    /// ([`Pipeline::kept_samples`]), then decimated. Otherwise the
    /// preprocessed trajectory's torque against `predict` on it.
    pub fn compare(
        &self,
        raw: &Trajectory,
        predict: impl Fn(&Trajectory) -> anyhow::Result<DMatrix<f64>>,
    ) -> anyhow::Result<Compared> {
        let settings = self.for_recording(raw);
        if !matches!(settings.filter, Filter::Butterworth { .. }) {
            let traj = settings.apply(raw)?;
            let predicted = predict(&traj)?;
            return Ok(Compared {
                measured_as_logged: traj.tau().clone(),
                predicted_unfiltered: predicted.clone(),
                measured: traj.tau().clone(),
                predicted,
            });
        }
        let states = settings.states_at_full_rate(raw)?;
        let dt = super::step(&states);
        let unfiltered = predict(&states)?;
        let predicted = settings.smooth_columns(&unfiltered, dt)?;
        let measured = settings.smooth_columns(raw.tau(), dt)?;
        if let Some(at) = predicted.iter().position(|x| !x.is_finite()) {
            anyhow::bail!(
                "the predicted torque is not finite at sample {}, joint {}: the recording holds \
                 values no arm reaches (check its velocities and positions there)",
                at % predicted.nrows(),
                at / predicted.nrows() + 1
            );
        }
        let keep = Self::kept_samples(&settings, raw.len(), dt);
        let full_rate: Vec<usize> = Self::clear_of_transients(&settings, raw.len(), dt).collect();
        Ok(Compared {
            measured: measured.select_rows(keep.iter()),
            predicted: predicted.select_rows(keep.iter()),
            measured_as_logged: raw.tau().select_rows(full_rate.iter()),
            predicted_unfiltered: unfiltered.select_rows(full_rate.iter()),
        })
    }

    /// The samples a Butterworth pipeline keeps of a recording of `len`
    /// samples: one cut-off period trimmed at each end (filter transients,
    /// when the recording is longer than eight periods), then every
    /// `downsample`-th.
    pub fn kept_samples(settings: &Preprocess, len: usize, dt: f64) -> Vec<usize> {
        Self::clear_of_transients(settings, len, dt)
            .step_by(settings.downsample.max(1))
            .collect()
    }

    /// The samples clear of filter transients: one cut-off period trimmed at
    /// each end when the recording is longer than eight periods.
    pub fn clear_of_transients(
        settings: &Preprocess,
        len: usize,
        dt: f64,
    ) -> std::ops::Range<usize> {
        let trim = match settings.filter {
            Filter::Butterworth { cutoff_hz } => {
                let period = (1.0 / (cutoff_hz * dt)).ceil() as usize;
                if len > 8 * period { period } else { 0 }
            }
            _ => 0,
        };
        trim..len - trim
    }

    /// One line for reports.
    pub fn summary(&self) -> String {
        let s = &self.settings;
        let torque = if s.filter_torque {
            "torque filtered alike"
        } else {
            "torque unfiltered"
        };
        match (&self.choice, &s.filter) {
            (Some(c), Filter::Butterworth { cutoff_hz }) => {
                let bandwidth = c
                    .motion_bandwidth_hz
                    .map_or("not above the noise".to_string(), |b| format!("{b:.2} Hz"));
                let rates = match c.fastest_rate_hz > 1.01 * c.sample_rate_hz {
                    true => format!(
                        "recordings at {:.0} to {:.0} Hz (the slowest bounds the cut-off)",
                        c.fastest_rate_hz, c.sample_rate_hz
                    ),
                    false => format!("{:.0} Hz recordings", c.sample_rate_hz),
                };
                format!(
                    "preprocessing (auto, from the data): {rates}, motion bandwidth \
                     {bandwidth}; zero-phase Butterworth low-pass at {cutoff_hz:.2} Hz of q, qd and \
                     tau, qdd by central differences, decimated to {:.0} Hz ({torque})",
                    c.decimated_rate_hz
                )
            }
            (_, filter) => format!(
                "preprocessing ({}): keep every {} sample(s), {}, {torque}",
                match self.preset {
                    Preset::Auto => "explicit",
                    Preset::Thesis => "thesis",
                },
                s.downsample,
                match filter {
                    Filter::None => "no smoothing".to_string(),
                    Filter::Sma { window, .. } => format!("{window}-sample moving average"),
                    Filter::SavitzkyGolay { window, order } => {
                        format!("{window}-sample Savitzky-Golay of order {order}")
                    }
                    Filter::Butterworth { cutoff_hz } => {
                        format!("zero-phase Butterworth at {cutoff_hz:.2} Hz")
                    }
                }
            ),
        }
    }
}
