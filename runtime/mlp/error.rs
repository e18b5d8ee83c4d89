//! Errors of the MLP module.

use std::io;
use std::path::PathBuf;

use thiserror::Error;

/// Errors from building datasets, checking hyperparameters, training,
/// predicting and (de)serializing models.
#[derive(Debug, Error)]
pub enum TrainError {
    /// A hyperparameter is out of range.
    #[error("invalid hyperparameter {name} = {value}: expected {expected}")]
    InvalidParam {
        name: &'static str,
        value: String,
        expected: &'static str,
    },
    /// The dataset has no samples.
    #[error("the {which} dataset has no samples")]
    EmptyDataset { which: &'static str },
    /// Matrix or vector sizes disagree.
    #[error("{what}: expected {expected}, found {found}")]
    Shape {
        what: &'static str,
        expected: usize,
        found: usize,
    },
    /// A NaN or infinite value in the data.
    #[error(
        "{which} data: sample {row} (0-based), column {col} (0-based) is {value}; all values must be finite"
    )]
    NonFiniteData {
        which: &'static str,
        row: usize,
        col: usize,
        value: f64,
    },
    /// The network's output overflowed on an input.
    #[error(
        "the network's output is not finite at sample {row} (0-based): its weights overflow on \
         this input (no trained network does; check the network file)"
    )]
    NonFinitePrediction { row: usize },
    /// The validation set cannot be split off as asked.
    #[error("cannot split off a validation set: {0}")]
    Split(String),
    /// The loss became NaN or infinite.
    #[error(
        "loss became non-finite in epoch {epoch}; lower the learning rate or check the data scale"
    )]
    NonFiniteLoss { epoch: usize },
    /// A trajectory lacks accelerations.
    #[error("trajectory has no accelerations (qdd1..qddN); preprocess it first")]
    MissingAcceleration,
    /// A model file could not be read or written.
    #[error("{}: {source}", .path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: io::Error,
    },
    /// A model file is not valid JSON of the expected shape.
    #[error("{}: invalid model JSON: {source}", .path.display())]
    Json {
        path: PathBuf,
        #[source]
        source: serde_json::Error,
    },
    /// A model file has a format version this build cannot read.
    #[error("{}: unsupported format_version {found}, this build reads version {supported}", .path.display())]
    UnsupportedVersion {
        path: PathBuf,
        found: String,
        supported: u32,
    },
    /// A model file is internally inconsistent.
    #[error("{}: invalid model: {reason}", .path.display())]
    InvalidModel { path: PathBuf, reason: String },
}
