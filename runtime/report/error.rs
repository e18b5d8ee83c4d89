//! Typed errors for the reporting functions. Every variant names the output path.

use std::path::PathBuf;

/// An error raised while producing a report file.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// Writing the file (or its temporary sibling) failed.
    #[error("{}: I/O error: {source}", path.display())]
    Io {
        /// The output path that was being written.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// Encoding the CSV content failed.
    #[error("{}: CSV error: {source}", path.display())]
    Csv {
        /// The output path that was being written.
        path: PathBuf,
        /// The underlying CSV error.
        #[source]
        source: csv::Error,
    },
    /// The plotting library reported an error while drawing.
    #[error("{}: rendering failed: {message}", path.display())]
    Render {
        /// The output path that was being written.
        path: PathBuf,
        /// The plotting library's message.
        message: String,
    },
    /// The input data cannot be turned into the requested output.
    #[error("{}: invalid input: {problem}", path.display())]
    Input {
        /// The output path that was requested.
        path: PathBuf,
        /// What is wrong with the input.
        #[source]
        problem: InputError,
    },
}

/// Why the input of a report function was rejected.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum InputError {
    /// The output path has no file name component (e.g. `/` or `..`).
    #[error("output path has no file name")]
    NoFileName,
    /// A plot has no series, or a bar chart has no bars.
    #[error("nothing to plot: no series given")]
    NoSeries,
    /// A grid plot has no panels.
    #[error("grid plot has no panels")]
    NoPanels,
    /// A bar chart has no groups.
    #[error("bar chart has no groups")]
    NoGroups,
    /// A series has different numbers of x and y values.
    #[error("series `{series}` has {x_len} x values but {y_len} y values")]
    LengthMismatch {
        /// Name of the offending series.
        series: String,
        /// Number of x values.
        x_len: usize,
        /// Number of y values.
        y_len: usize,
    },
    /// A bar-chart model has a value (or error) vector of the wrong length.
    #[error("bars of `{model}`: expected {expected} {what} (one per group), got {got}")]
    BarLength {
        /// Name of the model whose bars are malformed.
        model: String,
        /// `"values"` or `"error bars"`.
        what: &'static str,
        /// Number of groups.
        expected: usize,
        /// Number of entries supplied.
        got: usize,
    },
    /// After skipping unusable values (non-finite, beyond ±1e100, or outside
    /// `[1e-100, 1e100]` on a log axis), no point or bar is left to draw.
    #[error(
        "nothing to draw: every value is missing, non-finite, beyond ±1e100 or non-positive on a log axis"
    )]
    NothingToDraw,
}
