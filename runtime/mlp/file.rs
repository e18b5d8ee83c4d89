//! The network file: [`Mlp::save`] writes JSON, [`Mlp::load`] reads it back
//! checking its version, its shapes and the size of every number, so a file
//! from elsewhere is data, never a model that overflows.

use std::path::Path;

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use super::algorithm::{Layer, Scaler};
use super::{Activation, FORMAT_VERSION, History, Mlp, TrainError};

impl Mlp {
    /// Writes the model as JSON (atomically).
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), TrainError> {
        let path = path.as_ref();
        let file = ModelFile::from_model(self);
        crate::output::write_with(path, |w| {
            serde_json::to_writer(&mut *w, &file).map_err(std::io::Error::other)
        })
        .map_err(|source| TrainError::Io {
            path: path.to_owned(),
            source,
        })
    }

    /// Reads a model written by [`Mlp::save`], checking its version and shapes.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, TrainError> {
        let path = path.as_ref();
        crate::output::note_input(path);
        let text = crate::bounded::read_to_string(path).map_err(|source| TrainError::Io {
            path: path.to_owned(),
            source,
        })?;
        let json_err = |source| TrainError::Json {
            path: path.to_owned(),
            source,
        };
        let value: serde_json::Value = serde_json::from_str(&text).map_err(json_err)?;
        match value.get("format_version") {
            Some(v) if v.as_u64() == Some(u64::from(FORMAT_VERSION)) => {}
            found => {
                return Err(TrainError::UnsupportedVersion {
                    path: path.to_owned(),
                    found: found.map_or("(missing)".into(), ToString::to_string),
                    supported: FORMAT_VERSION,
                });
            }
        }
        let file: ModelFile = serde_json::from_value(value).map_err(json_err)?;
        file.into_model()
            .map_err(|reason| TrainError::InvalidModel {
                path: path.to_owned(),
                reason,
            })
    }
}

/// On-disk form. `weights[i][j]` connects input `i` to output `j`.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ModelFile {
    format_version: u32,
    layer_sizes: Vec<usize>,
    activation: Activation,
    seed: u64,
    input_mean: Vec<f64>,
    input_std: Vec<f64>,
    output_mean: Vec<f64>,
    output_std: Vec<f64>,
    layers: Vec<LayerFile>,
    history: History,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct LayerFile {
    weights: Vec<Vec<f64>>,
    bias: Vec<f64>,
}

impl ModelFile {
    fn from_model(m: &Mlp) -> Self {
        let layers = m
            .layers
            .iter()
            .map(|l| LayerFile {
                weights: l
                    .w
                    .row_iter()
                    .map(|r| r.iter().copied().collect())
                    .collect(),
                bias: l.b.iter().copied().collect(),
            })
            .collect();
        Self {
            format_version: FORMAT_VERSION,
            layer_sizes: m.layer_sizes(),
            activation: m.activation,
            seed: m.seed,
            input_mean: m.input.mean.clone(),
            input_std: m.input.std.clone(),
            output_mean: m.output.mean.clone(),
            output_std: m.output.std.clone(),
            layers,
            history: m.history.clone(),
        }
    }

    fn into_model(self) -> Result<Mlp, String> {
        let sizes = &self.layer_sizes;
        if sizes.len() < 2 || sizes.len() != self.layers.len() + 1 {
            return Err(format!(
                "layer_sizes {sizes:?} does not match {} layers",
                self.layers.len()
            ));
        }
        let layers = self
            .layers
            .iter()
            .zip(sizes.windows(2))
            .enumerate()
            .map(|(i, (l, w))| layer_from_file(i, l, w[0], w[1]))
            .collect::<Result<Vec<_>, _>>()?;
        let (n_in, n_out) = (sizes[0], sizes[sizes.len() - 1]);
        let input = scaler_from_file("input", self.input_mean, self.input_std, n_in)?;
        let output = scaler_from_file("output", self.output_mean, self.output_std, n_out)?;
        Ok(Mlp {
            layers,
            activation: self.activation,
            input,
            output,
            seed: self.seed,
            history: self.history,
        })
    }
}

/// Largest magnitude of any number in a network file.
const MAX_PARAMETER: f64 = 1e6;

fn layer_from_file(
    i: usize,
    l: &LayerFile,
    fan_in: usize,
    fan_out: usize,
) -> Result<Layer, String> {
    let rows_ok = l.weights.len() == fan_in && l.weights.iter().all(|r| r.len() == fan_out);
    if !rows_ok || l.bias.len() != fan_out {
        return Err(format!(
            "layer {i} is not {fan_in}x{fan_out} with {fan_out} biases"
        ));
    }
    let values = l.weights.iter().flatten().chain(&l.bias);
    if let Some(v) = values
        .into_iter()
        .find(|v| v.abs() > MAX_PARAMETER || v.is_nan())
    {
        return Err(format!(
            "layer {i} holds {v:e}; a trained network's weights and biases stay within \
             {MAX_PARAMETER:e} (larger ones overflow its outputs)"
        ));
    }
    let w = DMatrix::from_fn(fan_in, fan_out, |r, c| l.weights[r][c]);
    Ok(Layer {
        w,
        b: DVector::from_column_slice(&l.bias),
    })
}

fn scaler_from_file(
    which: &str,
    mean: Vec<f64>,
    std: Vec<f64>,
    n: usize,
) -> Result<Scaler, String> {
    if mean.len() != n || std.len() != n {
        return Err(format!("{which} normalization stats must have {n} entries"));
    }
    if std
        .iter()
        .any(|s| !(s.is_finite() && *s > 0.0 && *s <= MAX_PARAMETER))
    {
        return Err(format!(
            "{which}_std must be positive and at most {MAX_PARAMETER:e}"
        ));
    }
    if mean.iter().any(|m| m.abs() > MAX_PARAMETER || m.is_nan()) {
        return Err(format!(
            "{which}_mean must be finite and within {MAX_PARAMETER:e}"
        ));
    }
    Ok(Scaler { mean, std })
}
