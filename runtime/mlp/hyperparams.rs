//! Hyperparameters: an unchecked builder ([`MlpParams`]) and its validated
//! form ([`MlpValidParams`]).

use serde::{Deserialize, Serialize};

use super::error::TrainError;
use super::{Dataset, Mlp};

/// Hidden-layer nonlinearity. The output layer is always linear.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Activation {
    /// Hyperbolic tangent; Xavier (Glorot) uniform initialization.
    Tanh,
    /// Rectified linear unit; He uniform initialization.
    Relu,
    /// GELU, tanh approximation; He uniform initialization.
    Gelu,
}

const GELU_K: f64 = 0.797_884_560_802_865_4; // sqrt(2 / pi)
const GELU_C: f64 = 0.044_715;

impl Activation {
    /// f(z).
    pub(crate) fn eval(self, z: f64) -> f64 {
        match self {
            Activation::Tanh => tanh(z),
            Activation::Relu => z.max(0.0),
            Activation::Gelu => 0.5 * z * (1.0 + tanh(GELU_K * (z + GELU_C * z * z * z))),
        }
    }

    /// f'(z), given z and a = f(z) (tanh reuses a to skip a tanh call).
    pub(crate) fn derivative(self, z: f64, a: f64) -> f64 {
        match self {
            Activation::Tanh => 1.0 - a * a,
            Activation::Relu => f64::from(u8::from(z > 0.0)),
            Activation::Gelu => {
                let t = tanh(GELU_K * (z + GELU_C * z * z * z));
                0.5 * (1.0 + t) + 0.5 * z * (1.0 - t * t) * GELU_K * (1.0 + 3.0 * GELU_C * z * z)
            }
        }
    }
}

use super::tanh::tanh;

/// Validated hyperparameters; build with [`Mlp::params`] then
/// [`MlpParams::check`].
#[derive(Debug, Clone, PartialEq)]
pub struct MlpValidParams {
    pub(crate) hidden: Vec<usize>,
    pub(crate) activation: Activation,
    pub(crate) learning_rate: f64,
    pub(crate) batch_size: usize,
    pub(crate) max_epochs: usize,
    pub(crate) patience: Option<usize>,
    pub(crate) validation_fraction: f64,
    pub(crate) weight_decay: f64,
    pub(crate) seed: u64,
}

impl MlpValidParams {
    /// Hidden layer widths.
    pub fn hidden(&self) -> &[usize] {
        &self.hidden
    }
    /// Hidden-layer activation.
    pub fn activation(&self) -> Activation {
        self.activation
    }
    /// Adam step size.
    pub fn learning_rate(&self) -> f64 {
        self.learning_rate
    }
    /// Samples per mini-batch.
    pub fn batch_size(&self) -> usize {
        self.batch_size
    }
    /// Upper bound on epochs.
    pub fn max_epochs(&self) -> usize {
        self.max_epochs
    }
    /// Epochs without validation improvement before stopping.
    pub fn patience(&self) -> Option<usize> {
        self.patience
    }
    /// Share of samples (or groups) held out for validation.
    pub fn validation_fraction(&self) -> f64 {
        self.validation_fraction
    }
    /// Decoupled (AdamW) weight decay per step, relative to the learning rate.
    pub fn weight_decay(&self) -> f64 {
        self.weight_decay
    }
    /// Seed of initialization, split and shuffling.
    pub fn seed(&self) -> u64 {
        self.seed
    }
}

/// Unchecked hyperparameters (consuming builder).
#[derive(Debug, Clone, PartialEq)]
pub struct MlpParams(MlpValidParams);

impl Default for MlpParams {
    /// hidden [64, 64], tanh, lr 1e-3, batch 64, 200 epochs, patience 20,
    /// validation 20 %, no weight decay, seed 0.
    fn default() -> Self {
        Self(MlpValidParams {
            hidden: vec![64, 64],
            activation: Activation::Tanh,
            learning_rate: 1e-3,
            batch_size: 64,
            max_epochs: 200,
            patience: Some(20),
            validation_fraction: 0.2,
            weight_decay: 0.0,
            seed: 0,
        })
    }
}

impl MlpParams {
    /// Hidden layer widths (may be empty: linear regression).
    pub fn hidden(mut self, widths: Vec<usize>) -> Self {
        self.0.hidden = widths;
        self
    }
    /// Hidden-layer activation.
    pub fn activation(mut self, activation: Activation) -> Self {
        self.0.activation = activation;
        self
    }
    /// Adam step size.
    pub fn learning_rate(mut self, lr: f64) -> Self {
        self.0.learning_rate = lr;
        self
    }
    /// Samples per mini-batch.
    pub fn batch_size(mut self, size: usize) -> Self {
        self.0.batch_size = size;
        self
    }
    /// Upper bound on epochs.
    pub fn max_epochs(mut self, epochs: usize) -> Self {
        self.0.max_epochs = epochs;
        self
    }
    /// Early-stopping patience in epochs; `None` trains all epochs. Only
    /// applies when there is a validation set.
    pub fn patience(mut self, epochs: impl Into<Option<usize>>) -> Self {
        self.0.patience = epochs.into();
        self
    }
    /// Share held out for validation, in [0, 1); by whole groups when the
    /// dataset has groups. Ignored when an explicit validation set is given.
    pub fn validation_fraction(mut self, fraction: f64) -> Self {
        self.0.validation_fraction = fraction;
        self
    }
    /// Decoupled weight decay (AdamW) on weights, not biases; 0 disables.
    pub fn weight_decay(mut self, decay: f64) -> Self {
        self.0.weight_decay = decay;
        self
    }
    /// Seed of initialization, validation split and shuffling.
    pub fn seed(mut self, seed: u64) -> Self {
        self.0.seed = seed;
        self
    }

    /// Validates every value; the error names the offending one.
    pub fn check(self) -> Result<MlpValidParams, TrainError> {
        let p = &self.0;
        let bad = |name, value: String, expected| {
            Err(TrainError::InvalidParam {
                name,
                value,
                expected,
            })
        };
        if let Some(&w) = p.hidden.iter().find(|&&w| w == 0) {
            return bad(
                "hidden",
                format!("{:?} (width {w})", p.hidden),
                "widths >= 1",
            );
        }
        if !(p.learning_rate.is_finite() && p.learning_rate > 0.0) {
            return bad(
                "learning_rate",
                p.learning_rate.to_string(),
                "a finite value > 0",
            );
        }
        if p.batch_size == 0 {
            return bad("batch_size", "0".into(), "at least 1");
        }
        if p.max_epochs == 0 {
            return bad("max_epochs", "0".into(), "at least 1");
        }
        if p.patience == Some(0) {
            return bad("patience", "0".into(), "at least 1, or None to disable");
        }
        if !(0.0..1.0).contains(&p.validation_fraction) {
            let v = p.validation_fraction.to_string();
            return bad("validation_fraction", v, "a value in [0, 1)");
        }
        if !(p.weight_decay.is_finite() && p.weight_decay >= 0.0) {
            return bad(
                "weight_decay",
                p.weight_decay.to_string(),
                "a finite value >= 0",
            );
        }
        Ok(self.0)
    }

    /// Checks the parameters and trains on `data` (see [`MlpValidParams::fit`]).
    pub fn fit(self, data: &Dataset) -> Result<Mlp, TrainError> {
        self.check()?.fit(data)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_params_are_rejected_with_their_value() {
        let cases = [
            (Mlp::params().hidden(vec![8, 0]), "hidden"),
            (Mlp::params().learning_rate(-0.1), "-0.1"),
            (Mlp::params().learning_rate(f64::NAN), "NaN"),
            (Mlp::params().batch_size(0), "batch_size"),
            (Mlp::params().max_epochs(0), "max_epochs"),
            (Mlp::params().patience(0), "patience"),
            (
                Mlp::params().validation_fraction(1.0),
                "validation_fraction = 1",
            ),
            (Mlp::params().weight_decay(-1.0), "weight_decay = -1"),
        ];
        for (params, needle) in cases {
            let msg = params.check().unwrap_err().to_string();
            assert!(msg.contains(needle), "{msg}");
        }
        assert!(Mlp::params().patience(None).check().is_ok());
    }

    #[test]
    fn gelu_derivative_matches_finite_difference() {
        for act in [Activation::Tanh, Activation::Relu, Activation::Gelu] {
            for z in [-2.0, -0.3, 0.4, 1.7] {
                let h = 1e-6;
                let numeric = (act.eval(z + h) - act.eval(z - h)) / (2.0 * h);
                let analytic = act.derivative(z, act.eval(z));
                assert!((numeric - analytic).abs() < 1e-6, "{act:?} at {z}");
            }
        }
    }
}
