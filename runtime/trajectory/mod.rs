//! Joint-space trajectories and their CSV contract.
//!
//! Layout: `t` is a `Vec<f64>` of times in seconds; `q`, `qd`, `qdd` and `tau`
//! are `DMatrix<f64>` with **one row per sample and one column per joint**, so
//! a joint's channel is a contiguous column (cheap to filter) and the matrices
//! stack directly into MLP datasets (rows = samples).
//!
//! CSV contract: a header row naming `t,q1..qN,qd1..qdN,tau1..tauN` and
//! optionally `qdd1..qddN`, in any order. Errors report the file line: the
//! header's own (line 1 unless blank lines come first) or a data row's.

use std::collections::{HashMap, HashSet};
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use nalgebra::DMatrix;
use thiserror::Error;

mod advice;
mod plan;
mod read;
mod sampling;

pub use plan::{read_plan_csv, write_plan_csv};
use read::*;
pub use read::{
    is_contract_column, read_csv, read_forward_csv, read_positions_csv, read_states_csv,
    read_torques_csv,
};
use sampling::*;
pub use sampling::{MIN_STEP, resample, uniform};

/// Relative deviation of a time step from the median step above which the
/// sampling is treated as non-uniform.
pub const JITTER_TOLERANCE: f64 = 0.01;

/// Upper bound on resampled length, so a typo in the rate cannot exhaust memory.
pub const MAX_RESAMPLED: usize = 100_000_000;

/// Errors from building, reading or writing trajectories.
#[derive(Debug, Error)]
pub enum TrajectoryError {
    /// The file could not be opened, read or written.
    #[error("{}: {source}", .path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: io::Error,
    },
    /// The CSV layer rejected the file (e.g. invalid UTF-8).
    #[error("{}: line {line}: malformed CSV: {message}", .path.display())]
    Csv {
        path: PathBuf,
        line: u64,
        message: String,
    },
    /// The file has no header row.
    #[error("{}: empty file, expected a header row on line 1", .path.display())]
    MissingHeader { path: PathBuf },
    /// The first non-empty line holds only blanks (spaces, tabs).
    #[error(
        "{}: line {line} holds only blanks where the header row was expected (t, q1..qN, \
         qd1..qdN, tau1..tauN): delete that line",
        .path.display()
    )]
    BlankHeader { path: PathBuf, line: u64 },
    /// A required contract column is absent.
    #[error("{}: missing column '{column}' in the header (line {line})", .path.display())]
    MissingColumn {
        path: PathBuf,
        line: u64,
        column: String,
    },
    /// A header names a column outside the contract.
    #[error(
        "{}: unexpected column '{column}' in the header (line {line}); expected {expected}; {advice}",
        .path.display()
    )]
    UnexpectedColumn {
        path: PathBuf,
        line: u64,
        column: String,
        expected: String,
        /// What to do: rename or ignore the column, or, for a header cell
        /// that holds other delimiters, write the file comma-separated.
        advice: String,
    },
    /// Two header cells map to the same contract column.
    #[error("{}: column '{column}' appears twice in the header (line {line})", .path.display())]
    DuplicateColumn {
        path: PathBuf,
        line: u64,
        column: String,
    },
    /// The file's joint count differs from the caller's.
    #[error("{}: expected {expected} joints, the header (line {line}) has {found}", .path.display())]
    WrongDof {
        path: PathBuf,
        line: u64,
        expected: usize,
        found: usize,
    },
    /// A data row has a different number of fields than the header.
    #[error("{}: line {line}: expected {expected} fields as in the header, found {found}", .path.display())]
    RaggedRow {
        path: PathBuf,
        line: u64,
        expected: usize,
        found: usize,
    },
    /// A cell is not a number.
    #[error("{}: line {line}, column '{column}': expected a number, found '{value}'", .path.display())]
    ParseNumber {
        path: PathBuf,
        line: u64,
        column: String,
        value: String,
    },
    /// A cell is NaN or infinite.
    #[error("{}: line {line}, column '{column}': expected a finite number, found {value}", .path.display())]
    NonFinite {
        path: PathBuf,
        line: u64,
        column: String,
        value: f64,
    },
    /// A value far beyond any arm, or a time step below a microsecond.
    #[error("{}: line {line}, column '{column}': {value:e} is {problem}", .path.display())]
    Implausible {
        path: PathBuf,
        line: u64,
        column: String,
        value: f64,
        problem: String,
    },
    /// Time does not strictly increase.
    #[error(
        "{}: line {line}: time {current} is not greater than the previous time {previous}; time must strictly increase",
        .path.display()
    )]
    NonMonotonicTime {
        path: PathBuf,
        line: u64,
        previous: f64,
        current: f64,
    },
    /// Fewer samples than the caller requires.
    #[error("{}: {found} samples, at least {min} are required", .path.display())]
    TooFewSamples {
        path: PathBuf,
        found: usize,
        min: usize,
    },
    /// Time steps vary by more than [`JITTER_TOLERANCE`].
    #[error(
        "{}: non-uniform sampling: time steps range from {min_step} s to {max_step} s (median {median_step} s, more than 1% apart); pass --resample HZ to resample onto a uniform grid",
        .path.display()
    )]
    NonUniformSampling {
        path: PathBuf,
        min_step: f64,
        max_step: f64,
        median_step: f64,
    },
    /// The resampling rate is not a positive finite number.
    #[error("resample rate must be a positive finite number of Hz, got {hz}")]
    InvalidResampleRate { hz: f64 },
    /// Resampling would produce an unreasonable number of samples.
    #[error(
        "resampling {span} s at {hz} Hz would give {samples} samples, more than the limit of {MAX_RESAMPLED}"
    )]
    ResampleTooLarge { span: f64, hz: f64, samples: f64 },
    /// Sample times passed to a constructor are not finite and increasing.
    #[error(
        "sample {index} (0-based): time {current} must be finite and greater than the previous time {previous}"
    )]
    InvalidTime {
        index: usize,
        previous: f64,
        current: f64,
    },
    /// Resampling was requested for a file without a time column.
    #[error("{}: resampling needs a time column, which state and torque files do not have", .path.display())]
    ResampleWithoutTime { path: PathBuf },
    /// Matrices passed to a constructor disagree in shape.
    #[error("{what} has shape {found_rows}x{found_cols}, expected {rows}x{cols}")]
    Shape {
        what: &'static str,
        rows: usize,
        cols: usize,
        found_rows: usize,
        found_cols: usize,
    },
}

/// Unit of angles (and their derivatives) in a file.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum AngleUnit {
    /// rad, rad/s, rad/s^2 (SI).
    #[default]
    Radians,
    /// deg, deg/s, deg/s^2; converted to radians on read.
    Degrees,
}

/// Units of a file. Torques are always N·m and never converted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Units {
    /// Unit of `q`, `qd` and `qdd`.
    pub angles: AngleUnit,
}

/// Options for [`read_csv`], [`read_states_csv`] and [`read_torques_csv`].
#[derive(Debug, Clone)]
pub struct ReadOptions {
    /// Units of the file.
    pub units: Units,
    /// Expected joint count; `None` accepts whatever the header has.
    pub dof: Option<usize>,
    /// File header name -> contract name (e.g. `"time" -> "t"`).
    pub renames: HashMap<String, String>,
    /// File header names to skip.
    pub ignored: Vec<String>,
    /// Minimum number of data rows.
    pub min_samples: usize,
    /// Resample onto a uniform grid at this rate (trajectories only).
    pub resample_hz: Option<f64>,
}

impl Default for ReadOptions {
    fn default() -> Self {
        Self {
            units: Units::default(),
            dof: None,
            renames: HashMap::new(),
            ignored: Vec::new(),
            min_samples: 2,
            resample_hz: None,
        }
    }
}

/// A sampled joint trajectory (see the module docs for the layout).
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    t: Vec<f64>,
    q: DMatrix<f64>,
    qd: DMatrix<f64>,
    qdd: Option<DMatrix<f64>>,
    tau: DMatrix<f64>,
}

impl Trajectory {
    /// Builds a trajectory; every matrix must be `t.len()` x `q.ncols()` and
    /// `t` finite and strictly increasing.
    pub fn new(
        t: Vec<f64>,
        q: DMatrix<f64>,
        qd: DMatrix<f64>,
        qdd: Option<DMatrix<f64>>,
        tau: DMatrix<f64>,
    ) -> Result<Self, TrajectoryError> {
        let (rows, cols) = (t.len(), q.ncols());
        check_shape("q", &q, rows, cols)?;
        check_shape("qd", &qd, rows, cols)?;
        if let Some(qdd) = &qdd {
            check_shape("qdd", qdd, rows, cols)?;
        }
        check_shape("tau", &tau, rows, cols)?;
        check_times(&t)?;
        Ok(Self { t, q, qd, qdd, tau })
    }

    /// Number of joints.
    pub fn dof(&self) -> usize {
        self.q.ncols()
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Sample times in seconds.
    pub fn t(&self) -> &[f64] {
        &self.t
    }

    /// Joint angles (rad), samples x joints.
    pub fn q(&self) -> &DMatrix<f64> {
        &self.q
    }

    /// Joint velocities (rad/s), samples x joints.
    pub fn qd(&self) -> &DMatrix<f64> {
        &self.qd
    }

    /// Joint accelerations (rad/s^2), if known.
    pub fn qdd(&self) -> Option<&DMatrix<f64>> {
        self.qdd.as_ref()
    }

    /// Joint torques (N·m), samples x joints.
    pub fn tau(&self) -> &DMatrix<f64> {
        &self.tau
    }

    /// The same motion with other torques (e.g. analytical ones).
    pub fn with_tau(&self, tau: DMatrix<f64>) -> Result<Self, TrajectoryError> {
        Self::new(
            self.t.clone(),
            self.q.clone(),
            self.qd.clone(),
            self.qdd.clone(),
            tau,
        )
    }

    /// Samples `start .. start + len` (clamped to the trajectory).
    pub fn rows(&self, start: usize, len: usize) -> Self {
        let start = start.min(self.len());
        let len = len.min(self.len() - start);
        let cut = |m: &DMatrix<f64>| m.rows(start, len).into_owned();
        Self {
            t: self.t[start..start + len].to_vec(),
            q: cut(&self.q),
            qd: cut(&self.qd),
            qdd: self.qdd.as_ref().map(cut),
            tau: cut(&self.tau),
        }
    }

    /// `n` contiguous pieces of (almost) equal length, in time order.
    pub fn split(&self, n: usize) -> Vec<Self> {
        let n = n.clamp(1, self.len().max(1));
        (0..n)
            .map(|k| {
                let (start, end) = (k * self.len() / n, (k + 1) * self.len() / n);
                self.rows(start, end - start)
            })
            .collect()
    }

    /// The `(q, qd, qdd)` states, if accelerations are known.
    pub fn states(&self) -> Option<States> {
        let qdd = self.qdd.clone()?;
        Some(States {
            q: self.q.clone(),
            qd: self.qd.clone(),
            qdd,
        })
    }
}

/// Joint states without time or torque: the input of an analytical model.
#[derive(Debug, Clone, PartialEq)]
pub struct States {
    q: DMatrix<f64>,
    qd: DMatrix<f64>,
    qdd: DMatrix<f64>,
}

impl States {
    /// Builds states; all three matrices must have the same shape.
    pub fn new(
        q: DMatrix<f64>,
        qd: DMatrix<f64>,
        qdd: DMatrix<f64>,
    ) -> Result<Self, TrajectoryError> {
        let (rows, cols) = q.shape();
        check_shape("qd", &qd, rows, cols)?;
        check_shape("qdd", &qdd, rows, cols)?;
        Ok(Self { q, qd, qdd })
    }

    /// Number of joints.
    pub fn dof(&self) -> usize {
        self.q.ncols()
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.q.nrows()
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.q.nrows() == 0
    }

    /// Joint angles (rad).
    pub fn q(&self) -> &DMatrix<f64> {
        &self.q
    }

    /// Joint velocities (rad/s).
    pub fn qd(&self) -> &DMatrix<f64> {
        &self.qd
    }

    /// Joint accelerations (rad/s^2).
    pub fn qdd(&self) -> &DMatrix<f64> {
        &self.qdd
    }
}

fn check_times(t: &[f64]) -> Result<(), TrajectoryError> {
    let mut previous = f64::NEG_INFINITY;
    for (index, &current) in t.iter().enumerate() {
        if !(current.is_finite() && current > previous) {
            return Err(TrajectoryError::InvalidTime {
                index,
                previous,
                current,
            });
        }
        previous = current;
    }
    Ok(())
}

fn check_shape(
    what: &'static str,
    m: &DMatrix<f64>,
    rows: usize,
    cols: usize,
) -> Result<(), TrajectoryError> {
    if m.shape() == (rows, cols) {
        return Ok(());
    }
    Err(TrajectoryError::Shape {
        what,
        rows,
        cols,
        found_rows: m.nrows(),
        found_cols: m.ncols(),
    })
}

// ---------------------------------------------------------------- reading --

/// Largest |q| (rad) and |qd| (rad/s), |qdd| (rad/s^2) and |tau| (N m),
/// and |t| (s) a recording may hold (see `Channel::plausible`).
pub const PLAUSIBLE_ANGLE: f64 = 1e3;
pub const PLAUSIBLE_TORQUE: f64 = 1e6;
pub const PLAUSIBLE_TIME: f64 = 1e9;

/// File columns of the time and of each (channel, joint), after renames and
/// skipping ignored columns.
type Classified = (Option<usize>, HashMap<(Channel, usize), usize>);

// ---------------------------------------------------------------- writing --

/// Writes a trajectory in the contract layout (SI units), atomically.
pub fn write_csv(path: impl AsRef<Path>, traj: &Trajectory) -> Result<(), TrajectoryError> {
    let t = DMatrix::from_column_slice(traj.len(), 1, traj.t());
    let mut blocks = vec![
        (None, &t),
        (Some(Channel::Q), traj.q()),
        (Some(Channel::Qd), traj.qd()),
    ];
    if let Some(qdd) = traj.qdd() {
        blocks.push((Some(Channel::Qdd), qdd));
    }
    blocks.push((Some(Channel::Tau), traj.tau()));
    write_blocks(path.as_ref(), &blocks)
}

/// Writes a state file (`q1..qN,qd1..qdN,qdd1..qddN`), atomically.
pub fn write_states_csv(path: impl AsRef<Path>, states: &States) -> Result<(), TrajectoryError> {
    let blocks = [
        (Some(Channel::Q), states.q()),
        (Some(Channel::Qd), states.qd()),
        (Some(Channel::Qdd), states.qdd()),
    ];
    write_blocks(path.as_ref(), &blocks)
}

/// Writes a torque file (`tau1..tauN`, samples x joints), atomically.
pub fn write_torques_csv(
    path: impl AsRef<Path>,
    tau: &DMatrix<f64>,
) -> Result<(), TrajectoryError> {
    write_blocks(path.as_ref(), &[(Some(Channel::Tau), tau)])
}

/// Writes column blocks side by side; `None` is the time column.
fn write_blocks(
    path: &Path,
    blocks: &[(Option<Channel>, &DMatrix<f64>)],
) -> Result<(), TrajectoryError> {
    let header: Vec<String> = blocks
        .iter()
        .flat_map(|(ch, m)| {
            (1..=m.ncols()).map(move |j| match ch {
                Some(ch) => format!("{}{j}", ch.prefix()),
                None => "t".to_owned(),
            })
        })
        .collect();
    atomic_write(path, |w| write_table(w, &header, blocks))
}

/// Writes a table with the given header: to `path` atomically, or to
/// standard output when `path` is `None`.
pub fn write_columns(
    path: Option<&Path>,
    header: &[String],
    values: &DMatrix<f64>,
) -> Result<(), TrajectoryError> {
    let blocks = [(None, values)];
    match path {
        Some(path) => atomic_write(path, |w| write_table(w, header, &blocks)),
        None => {
            let mut out = io::stdout().lock();
            write_table(&mut out, header, &blocks)
                .and_then(|()| out.flush())
                .map_err(|source| TrajectoryError::Io {
                    path: "standard output".into(),
                    source,
                })
        }
    }
}

/// Writes a torque table (`tau1..tauN`) to any writer, e.g. standard output.
pub fn write_torques(w: &mut impl Write, tau: &DMatrix<f64>) -> io::Result<()> {
    let header: Vec<String> = (1..=tau.ncols()).map(|j| format!("tau{j}")).collect();
    write_table(w, &header, &[(Some(Channel::Tau), tau)])
}

fn write_table(
    w: &mut (impl Write + ?Sized),
    header: &[String],
    blocks: &[(Option<Channel>, &DMatrix<f64>)],
) -> io::Result<()> {
    let rows = blocks.first().map_or(0, |(_, m)| m.nrows());
    writeln!(w, "{}", header.join(","))?;
    for r in 0..rows {
        let mut first = true;
        for (_, m) in blocks {
            for j in 0..m.ncols() {
                let sep = if first { "" } else { "," };
                first = false;
                // `{:?}` is Rust's shortest representation that parses
                // back to the identical f64.
                write!(w, "{sep}{:?}", m[(r, j)])?;
            }
        }
        writeln!(w)?;
    }
    Ok(())
}

fn atomic_write(
    path: &Path,
    body: impl FnOnce(&mut dyn Write) -> io::Result<()>,
) -> Result<(), TrajectoryError> {
    crate::output::write_with(path, body).map_err(|source| TrajectoryError::Io {
        path: path.to_owned(),
        source,
    })
}

#[cfg(test)]
mod tests;
