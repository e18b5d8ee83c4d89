//! Multi-layer perceptron regressor mapping joint states (q, qd, qdd) to
//! torques (thesis §2.5), in the style of linfa: [`Mlp::params`] gives a
//! builder, `check()` validates it, `fit` trains.
//!
//! ```
//! use sdnn_runtime::mlp::{Activation, Mlp};
//! let params = Mlp::params()
//!     .hidden(vec![32, 32])
//!     .activation(Activation::Tanh)
//!     .seed(7)
//!     .check()
//!     .unwrap();
//! assert_eq!(params.hidden(), &[32, 32]);
//! ```

mod algorithm;
mod error;
mod file;
mod hyperparams;
mod linalg;
mod split;
mod tanh;

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

pub use error::TrainError;
pub use hyperparams::{Activation, MlpParams, MlpValidParams};

use crate::trajectory::Trajectory;
use algorithm::{Layer, Scaler};

/// Version written by [`Mlp::save`] and the only one [`Mlp::load`] accepts.
pub const FORMAT_VERSION: u32 = 1;

/// Samples as rows: `inputs` is samples x features, `targets` samples x
/// outputs. `groups` (one id per sample, e.g. the trajectory index) makes
/// validation splits take whole groups, so no trajectory leaks across.
#[derive(Debug, Clone, PartialEq)]
pub struct Dataset {
    pub inputs: DMatrix<f64>,
    pub targets: DMatrix<f64>,
    pub groups: Option<Vec<usize>>,
}

impl Dataset {
    /// Builds a dataset, checking that row counts agree.
    pub fn new(
        inputs: DMatrix<f64>,
        targets: DMatrix<f64>,
        groups: Option<Vec<usize>>,
    ) -> Result<Self, TrainError> {
        let data = Self {
            inputs,
            targets,
            groups,
        };
        data.check_shapes()?;
        Ok(data)
    }

    /// Inputs `[q, qd, qdd]` (3N columns) and targets `tau` (N columns) of a
    /// trajectory, all tagged with `group`. Give a measured trajectory and
    /// its analytical twin the same group so they are split together.
    pub fn from_trajectory(traj: &Trajectory, group: usize) -> Result<Self, TrainError> {
        let qdd = traj.qdd().ok_or(TrainError::MissingAcceleration)?;
        let n = traj.dof();
        let inputs = DMatrix::from_fn(traj.len(), 3 * n, |r, c| match c / n {
            0 => traj.q()[(r, c)],
            1 => traj.qd()[(r, c - n)],
            _ => qdd[(r, c - 2 * n)],
        });
        Self::new(inputs, traj.tau().clone(), Some(vec![group; traj.len()]))
    }

    /// Stacks datasets row-wise; groups are kept only if every part has them.
    pub fn concat(parts: &[Dataset]) -> Result<Self, TrainError> {
        let Some(first) = parts.first() else {
            return Err(TrainError::EmptyDataset {
                which: "concatenated",
            });
        };
        for p in parts {
            p.check_shapes()?;
            first.check_same_width(p)?;
        }
        let rows: usize = parts.iter().map(Dataset::len).sum();
        let stack = |f: fn(&Dataset) -> &DMatrix<f64>| {
            let mut out = DMatrix::zeros(rows, f(first).ncols());
            let mut at = 0;
            for p in parts {
                let m = f(p);
                out.rows_mut(at, m.nrows()).copy_from(m);
                at += m.nrows();
            }
            out
        };
        let groups: Option<Vec<usize>> = parts
            .iter()
            .map(|p| p.groups.clone())
            .collect::<Option<Vec<_>>>()
            .map(|g| g.concat());
        Self::new(stack(|d| &d.inputs), stack(|d| &d.targets), groups)
    }

    /// Splits into (rest, held-out): a `fraction` of the groups (or of the
    /// samples, without groups), chosen by `seed`. Training with the same
    /// fraction and seed holds out exactly these samples.
    pub fn split(&self, fraction: f64, seed: u64) -> Result<(Dataset, Dataset), TrainError> {
        if !(fraction > 0.0 && fraction < 1.0) {
            return Err(TrainError::InvalidParam {
                name: "fraction",
                value: fraction.to_string(),
                expected: "a value in (0, 1)",
            });
        }
        self.check_shapes()?;
        let mut rng = algorithm::rng(seed, 0);
        let (a, b) = split::split_rows(self, fraction, &mut rng)?;
        Ok((self.select_rows(&a), self.select_rows(&b)))
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.inputs.nrows()
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.inputs.nrows() == 0
    }

    fn select_rows(&self, rows: &[usize]) -> Dataset {
        Dataset {
            inputs: self.inputs.select_rows(rows),
            targets: self.targets.select_rows(rows),
            groups: self
                .groups
                .as_ref()
                .map(|g| rows.iter().map(|&i| g[i]).collect()),
        }
    }

    fn check_shapes(&self) -> Result<(), TrainError> {
        let n = self.inputs.nrows();
        let shape = |what, found| TrainError::Shape {
            what,
            expected: n,
            found,
        };
        if self.targets.nrows() != n {
            return Err(shape(
                "target rows (one per input row)",
                self.targets.nrows(),
            ));
        }
        match &self.groups {
            Some(g) if g.len() != n => Err(shape("group ids (one per input row)", g.len())),
            _ => Ok(()),
        }
    }

    fn check_same_width(&self, other: &Dataset) -> Result<(), TrainError> {
        let check = |what, expected: usize, found: usize| {
            if expected == found {
                Ok(())
            } else {
                Err(TrainError::Shape {
                    what,
                    expected,
                    found,
                })
            }
        };
        check("input columns", self.inputs.ncols(), other.inputs.ncols())?;
        check(
            "target columns",
            self.targets.ncols(),
            other.targets.ncols(),
        )
    }

    /// Shapes, non-emptiness and finiteness, before training.
    fn validate(&self, which: &'static str) -> Result<(), TrainError> {
        self.check_shapes()?;
        if self.is_empty() || self.inputs.ncols() == 0 || self.targets.ncols() == 0 {
            return Err(TrainError::EmptyDataset { which });
        }
        for (kind, m) in [("input", &self.inputs), ("target", &self.targets)] {
            if let Some((i, &value)) = m.iter().enumerate().find(|(_, v)| !v.is_finite()) {
                return Err(TrainError::NonFiniteData {
                    which: kind,
                    row: i % m.nrows(),
                    col: i / m.nrows(),
                    value,
                });
            }
        }
        Ok(())
    }
}

/// Per-epoch losses (MSE of standardized targets).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct History {
    train_loss: Vec<f64>,
    valid_loss: Vec<f64>,
    best_epoch: usize,
}

impl History {
    /// Mean training loss of each epoch.
    pub fn train_loss(&self) -> &[f64] {
        &self.train_loss
    }
    /// Validation loss after each epoch; empty without validation.
    pub fn valid_loss(&self) -> &[f64] {
        &self.valid_loss
    }
    /// 1-based epoch whose weights the model holds.
    pub fn best_epoch(&self) -> usize {
        self.best_epoch
    }
    /// Epochs run.
    pub fn epochs(&self) -> usize {
        self.train_loss.len()
    }
}

/// What a progress callback sees after each epoch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EpochReport {
    /// 1-based epoch just finished.
    pub epoch: usize,
    pub max_epochs: usize,
    pub train_loss: f64,
    pub valid_loss: Option<f64>,
    /// Epoch of the best validation loss so far.
    pub best_epoch: usize,
    /// This epoch set a new best.
    pub improved: bool,
    /// Early stopping ends training after this epoch.
    pub stopping: bool,
}

/// A fitted MLP with its normalization statistics and training history.
#[derive(Debug, Clone, PartialEq)]
pub struct Mlp {
    layers: Vec<Layer>,
    activation: Activation,
    input: Scaler,
    output: Scaler,
    seed: u64,
    history: History,
}

impl Mlp {
    /// Default hyperparameters (see [`MlpParams::default`]).
    pub fn params() -> MlpParams {
        MlpParams::default()
    }

    /// Predicts targets for each row of `inputs` (original units).
    pub fn predict(&self, inputs: &DMatrix<f64>) -> Result<DMatrix<f64>, TrainError> {
        if inputs.ncols() != self.n_inputs() {
            return Err(TrainError::Shape {
                what: "input columns",
                expected: self.n_inputs(),
                found: inputs.ncols(),
            });
        }
        let x = self.input.standardize(inputs);
        let y = self
            .output
            .restore(algorithm::forward(&self.layers, self.activation, &x));
        match (0..y.nrows()).find(|&r| y.row(r).iter().any(|v| !v.is_finite())) {
            Some(row) => Err(TrainError::NonFinitePrediction { row }),
            None => Ok(y),
        }
    }

    /// Predicts one sample.
    pub fn predict_one(&self, input: &[f64]) -> Result<Vec<f64>, TrainError> {
        let row = DMatrix::from_row_slice(1, input.len(), input);
        Ok(self.predict(&row)?.iter().copied().collect())
    }

    /// Widths from input to output, e.g. `[9, 64, 64, 3]`.
    pub fn layer_sizes(&self) -> Vec<usize> {
        std::iter::once(self.n_inputs())
            .chain(self.layers.iter().map(|l| l.w.ncols()))
            .collect()
    }

    /// Number of input features.
    pub fn n_inputs(&self) -> usize {
        self.layers.first().map_or(0, |l| l.w.nrows())
    }

    /// Number of outputs.
    pub fn n_outputs(&self) -> usize {
        self.layers.last().map_or(0, |l| l.w.ncols())
    }

    /// Hidden-layer activation.
    pub fn activation(&self) -> Activation {
        self.activation
    }

    /// Seed the model was trained with.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// Losses per epoch.
    pub fn history(&self) -> &History {
        &self.history
    }

    /// Each layer's weights (fan_in x fan_out) and biases.
    pub fn weights(&self) -> impl Iterator<Item = (&DMatrix<f64>, &DVector<f64>)> {
        self.layers.iter().map(|l| (&l.w, &l.b))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sine_data(n: usize, groups: bool) -> Dataset {
        let x = DMatrix::from_fn(n, 1, |r, _| -3.0 + 6.0 * r as f64 / (n - 1) as f64);
        let y = x.map(f64::sin);
        let g = groups.then(|| (0..n).map(|i| i % 10).collect());
        Dataset::new(x, y, g).unwrap()
    }

    fn small_params() -> MlpParams {
        Mlp::params()
            .hidden(vec![16, 16])
            .learning_rate(5e-3)
            .batch_size(32)
            .max_epochs(150)
            .patience(30)
            .seed(3)
    }

    fn scratch(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("pipeline-mlp-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir.join("model.json")
    }

    #[test]
    fn learns_sine_and_loss_decreases() {
        let data = sine_data(400, true);
        let model = small_params().fit(&data).unwrap();
        let h = model.history();
        assert!(h.train_loss()[h.epochs() - 1] < h.train_loss()[0] / 10.0);
        assert_eq!(h.valid_loss().len(), h.epochs());
        let pred = model.predict(&data.inputs).unwrap();
        let mse = (pred - &data.targets).map(|e| e * e).mean();
        assert!(mse < 1e-3, "mse {mse}");
        let one = model.predict_one(&[0.5]).unwrap();
        assert!((one[0] - 0.5f64.sin()).abs() < 0.05);
    }

    #[test]
    fn same_seed_gives_identical_weights() {
        let data = sine_data(100, false);
        let params = small_params().max_epochs(5).check().unwrap();
        let a = params.fit(&data).unwrap();
        let b = params.fit(&data).unwrap();
        assert_eq!(a, b);
        let c = small_params().max_epochs(5).seed(4).fit(&data).unwrap();
        assert_ne!(a.weights().next(), c.weights().next());
    }

    #[test]
    fn save_load_round_trip_is_exact() {
        let data = sine_data(100, false);
        let model = small_params().max_epochs(3).fit(&data).unwrap();
        let path = scratch("rt");
        model.save(&path).unwrap();
        let back = Mlp::load(&path).unwrap();
        assert_eq!(back, model);
        assert_eq!(
            back.predict(&data.inputs).unwrap(),
            model.predict(&data.inputs).unwrap()
        );
        assert_eq!(back.layer_sizes(), vec![1, 16, 16, 1]);
    }

    #[test]
    fn load_rejects_unknown_version_and_bad_shapes() {
        let model = small_params()
            .max_epochs(1)
            .fit(&sine_data(50, false))
            .unwrap();
        let path = scratch("bad");
        model.save(&path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        std::fs::write(
            &path,
            text.replace("\"format_version\":1", "\"format_version\":99"),
        )
        .unwrap();
        let msg = Mlp::load(&path).unwrap_err().to_string();
        assert!(msg.contains("unsupported format_version 99"), "{msg}");
        std::fs::write(
            &path,
            text.replace("\"layer_sizes\":[1,", "\"layer_sizes\":[2,"),
        )
        .unwrap();
        let msg = Mlp::load(&path).unwrap_err().to_string();
        assert!(msg.contains("layer 0 is not 2x16"), "{msg}");
    }

    #[test]
    fn non_finite_data_is_rejected() {
        let mut data = sine_data(50, false);
        data.inputs[(7, 0)] = f64::NAN;
        let msg = small_params().fit(&data).unwrap_err().to_string();
        assert!(
            msg.contains("input data: sample 7") && msg.contains("NaN"),
            "{msg}"
        );
    }

    #[test]
    fn exploding_training_reports_epoch() {
        let data = sine_data(50, false);
        let params = small_params().learning_rate(1e300).max_epochs(50);
        let err = params.fit(&data).unwrap_err();
        assert!(matches!(err, TrainError::NonFiniteLoss { .. }), "{err}");
    }

    #[test]
    fn early_stopping_and_progress() {
        let data = sine_data(200, true);
        let mut reports = Vec::new();
        let params = small_params().max_epochs(400).patience(3).check().unwrap();
        let model = params
            .fit_with(&data, None, &mut |r| reports.push(r))
            .unwrap();
        let last = reports.last().unwrap();
        assert_eq!(reports.len(), model.history().epochs());
        assert!(last.stopping && last.epoch < 400, "{last:?}");
        assert_eq!(last.epoch - last.best_epoch, 3);
        let h = model.history();
        let best = h.valid_loss()[h.best_epoch() - 1];
        assert!(h.valid_loss().iter().all(|&v| v >= best));
    }

    #[test]
    fn explicit_validation_set_and_dataset_helpers() {
        let (train, valid) = sine_data(200, true).split(0.2, 1).unwrap();
        assert_eq!(valid.len(), 40);
        let params = small_params().max_epochs(2).check().unwrap();
        let model = params.fit_with(&train, Some(&valid), &mut |_| {}).unwrap();
        assert_eq!(model.history().valid_loss().len(), 2);
        let both = Dataset::concat(&[train.clone(), valid]).unwrap();
        assert_eq!(both.len(), 200);
        let narrow = Dataset::new(DMatrix::zeros(3, 2), DMatrix::zeros(3, 1), None).unwrap();
        assert!(Dataset::concat(&[train, narrow]).is_err());
        assert!(Dataset::new(DMatrix::zeros(3, 1), DMatrix::zeros(2, 1), None).is_err());
        assert!(model.predict(&DMatrix::zeros(1, 2)).is_err());
    }

    #[test]
    fn dataset_from_trajectory_stacks_states() {
        let m = |k: f64| DMatrix::from_fn(4, 2, |r, c| k + r as f64 + 0.1 * c as f64);
        let traj =
            Trajectory::new(vec![0., 1., 2., 3.], m(0.), m(10.), Some(m(20.)), m(30.)).unwrap();
        let data = Dataset::from_trajectory(&traj, 5).unwrap();
        assert_eq!(data.inputs.ncols(), 6);
        assert_eq!(data.inputs[(1, 3)], 11.1);
        assert_eq!(data.inputs[(2, 4)], 22.0);
        assert_eq!(data.groups, Some(vec![5; 4]));
        let no_qdd = Trajectory::new(vec![0., 1., 2., 3.], m(0.), m(1.), None, m(2.)).unwrap();
        assert!(Dataset::from_trajectory(&no_qdd, 0).is_err());
    }
}
