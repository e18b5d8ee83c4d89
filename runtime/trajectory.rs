//! Joint-space trajectories and their CSV contract.
//!
//! Layout: `t` is a `Vec<f64>` of times in seconds; `q`, `qd`, `qdd` and `tau`
//! are `DMatrix<f64>` with **one row per sample and one column per joint**, so
//! a joint's channel is a contiguous column (cheap to filter) and the matrices
//! stack directly into MLP datasets (rows = samples).
//!
//! CSV contract: a header row naming `t,q1..qN,qd1..qdN,tau1..tauN` and
//! optionally `qdd1..qddN`, in any order. Errors report the file line, with the
//! header on line 1 (so the first data row is line 2).

use std::collections::{HashMap, HashSet};
use std::fs::File;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use nalgebra::DMatrix;
use thiserror::Error;

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
    /// A required contract column is absent.
    #[error("{}: missing column '{column}' in the header (line 1)", .path.display())]
    MissingColumn { path: PathBuf, column: String },
    /// A header names a column outside the contract.
    #[error(
        "{}: unexpected column '{column}' in the header (line 1); expected {expected}; rename it or pass it as ignored",
        .path.display()
    )]
    UnexpectedColumn {
        path: PathBuf,
        column: String,
        expected: String,
    },
    /// Two header cells map to the same contract column.
    #[error("{}: column '{column}' appears twice in the header (line 1)", .path.display())]
    DuplicateColumn { path: PathBuf, column: String },
    /// The file's joint count differs from the caller's.
    #[error("{}: expected {expected} joints, the header (line 1) has {found}", .path.display())]
    WrongDof {
        path: PathBuf,
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

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Channel {
    Q,
    Qd,
    Qdd,
    Tau,
}

const CHANNELS: [Channel; 4] = [Channel::Q, Channel::Qd, Channel::Qdd, Channel::Tau];

/// Largest |q| (rad) and |qd| (rad/s), |qdd| (rad/s^2) and |tau| (N m),
/// and |t| (s) a recording may hold (see `Channel::plausible`).
pub const PLAUSIBLE_ANGLE: f64 = 1e3;
pub const PLAUSIBLE_TORQUE: f64 = 1e6;
pub const PLAUSIBLE_TIME: f64 = 1e9;

impl Channel {
    fn prefix(self) -> &'static str {
        match self {
            Channel::Q => "q",
            Channel::Qd => "qd",
            Channel::Qdd => "qdd",
            Channel::Tau => "tau",
        }
    }

    /// Largest magnitude accepted, SI units: far beyond any arm (160 turns,
    /// 1000 rad/s, 1e6 rad/s^2, a million N m); past it a value is a logging
    /// fault, and squared in the dynamics it would overflow.
    fn plausible(self) -> f64 {
        match self {
            Channel::Q | Channel::Qd => PLAUSIBLE_ANGLE,
            Channel::Qdd | Channel::Tau => PLAUSIBLE_TORQUE,
        }
    }

    fn index(self) -> usize {
        self as usize
    }

    /// Angle-derived channels are scaled on unit conversion; torque is not.
    fn is_angular(self) -> bool {
        self != Channel::Tau
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Presence {
    Required,
    Optional,
    Forbidden,
}

/// Which columns a kind of file must, may or must not have.
struct Schema {
    time: Presence,
    channels: [Presence; 4],
    expected: &'static str,
}

const TRAJECTORY_SCHEMA: Schema = Schema {
    time: Presence::Required,
    channels: [
        Presence::Required,
        Presence::Required,
        Presence::Optional,
        Presence::Required,
    ],
    expected: "t, q1..qN, qd1..qdN, tau1..tauN and optionally qdd1..qddN",
};

/// States for `sdnn tau`: a recording's `t` and `tau` columns may be
/// present (they are read and not used).
const STATES_SCHEMA: Schema = Schema {
    time: Presence::Optional,
    channels: [
        Presence::Required,
        Presence::Required,
        Presence::Required,
        Presence::Optional,
    ],
    expected: "q1..qN, qd1..qdN, qdd1..qddN",
};

const TORQUES_SCHEMA: Schema = Schema {
    time: Presence::Forbidden,
    channels: [
        Presence::Forbidden,
        Presence::Forbidden,
        Presence::Forbidden,
        Presence::Required,
    ],
    expected: "tau1..tauN",
};

enum Column {
    Time,
    Joint(Channel, usize),
}

/// Whether `name` is a column of the CSV contract (`t`, `q3`, `tau1`, ...).
pub fn is_contract_column(name: &str) -> bool {
    parse_column_name(name).is_some()
}

/// Parses a contract name such as `qd3` into (channel, 0-based joint).
fn parse_column_name(name: &str) -> Option<Column> {
    if name == "t" {
        return Some(Column::Time);
    }
    let split = name.find(|c: char| c.is_ascii_digit())?;
    let (prefix, digits) = name.split_at(split);
    if digits.starts_with('0') || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    let joint: usize = digits.parse().ok()?;
    let channel = CHANNELS.into_iter().find(|c| c.prefix() == prefix)?;
    Some(Column::Joint(channel, joint - 1))
}

/// Where each contract column sits in the file.
struct Layout {
    width: usize,
    names: Vec<String>,
    time: Option<usize>,
    dof: usize,
    /// Per channel, the file column of each joint.
    channels: [Option<Vec<usize>>; 4],
}

fn parse_header(
    path: &Path,
    header: &csv::StringRecord,
    opts: &ReadOptions,
    schema: &Schema,
) -> Result<Layout, TrajectoryError> {
    let (time, joints) = classify_columns(path, header, opts, schema)?;
    if schema.time == Presence::Required && time.is_none() {
        return Err(missing(path, "t".to_owned()));
    }
    let found = joints.keys().map(|&(_, j)| j + 1).max().unwrap_or(0);
    if let Some(expected) = opts.dof
        && expected != found
        && found > 0
    {
        return Err(TrajectoryError::WrongDof {
            path: path.to_owned(),
            expected,
            found,
        });
    }
    // With no joint columns at all, dof 1 makes the error name `q1`/`tau1`.
    let dof = found.max(1);
    let mut channels: [Option<Vec<usize>>; 4] = Default::default();
    for ch in CHANNELS {
        channels[ch.index()] = channel_columns(path, &joints, ch, dof, schema)?;
    }
    Ok(Layout {
        width: header.len(),
        names: header.iter().map(str::to_owned).collect(),
        time,
        dof,
        channels,
    })
}

/// File columns of the time and of each (channel, joint), after renames and
/// skipping ignored columns.
type Classified = (Option<usize>, HashMap<(Channel, usize), usize>);

fn classify_columns(
    path: &Path,
    header: &csv::StringRecord,
    opts: &ReadOptions,
    schema: &Schema,
) -> Result<Classified, TrajectoryError> {
    let mut time = None;
    let mut joints = HashMap::new();
    let mut seen = HashSet::new();
    for (idx, raw) in header.iter().enumerate() {
        if opts.ignored.iter().any(|i| i == raw) {
            continue;
        }
        let name = opts.renames.get(raw).map_or(raw, String::as_str);
        let unexpected = || TrajectoryError::UnexpectedColumn {
            path: path.to_owned(),
            column: raw.to_owned(),
            expected: schema.expected.to_owned(),
        };
        if !seen.insert(name.to_owned()) {
            return Err(TrajectoryError::DuplicateColumn {
                path: path.to_owned(),
                column: name.to_owned(),
            });
        }
        match parse_column_name(name).ok_or_else(unexpected)? {
            Column::Time if schema.time != Presence::Forbidden => time = Some(idx),
            Column::Joint(ch, j) if schema.channels[ch.index()] != Presence::Forbidden => {
                joints.insert((ch, j), idx);
            }
            _ => return Err(unexpected()),
        }
    }
    Ok((time, joints))
}

fn missing(path: &Path, column: String) -> TrajectoryError {
    TrajectoryError::MissingColumn {
        path: path.to_owned(),
        column,
    }
}

/// Resolves a channel's columns: a required channel needs every joint, an
/// optional one needs all or none.
fn channel_columns(
    path: &Path,
    joints: &HashMap<(Channel, usize), usize>,
    ch: Channel,
    dof: usize,
    schema: &Schema,
) -> Result<Option<Vec<usize>>, TrajectoryError> {
    let presence = schema.channels[ch.index()];
    let any = (0..dof).any(|j| joints.contains_key(&(ch, j)));
    if presence == Presence::Forbidden || (presence == Presence::Optional && !any) {
        return Ok(None);
    }
    (0..dof)
        .map(|j| {
            joints
                .get(&(ch, j))
                .copied()
                .ok_or_else(|| missing(path, format!("{}{}", ch.prefix(), j + 1)))
        })
        .collect::<Result<Vec<_>, _>>()
        .map(Some)
}

/// Parsed numeric columns (indexed by file column) and each row's file line.
struct Table {
    layout: Layout,
    columns: Vec<Vec<f64>>,
    lines: Vec<u64>,
}

fn read_table(path: &Path, opts: &ReadOptions, schema: &Schema) -> Result<Table, TrajectoryError> {
    let io_err = |source| TrajectoryError::Io {
        path: path.to_owned(),
        source,
    };
    // `-` is standard input.
    let source: Box<dyn io::Read> = if path == Path::new("-") {
        Box::new(io::stdin().lock())
    } else {
        crate::output::note_input(path);
        Box::new(File::open(path).map_err(io_err)?)
    };
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .flexible(true)
        .from_reader(io::BufReader::new(crate::bounded::LineLimited::new(source)));
    let header = reader.headers().map_err(|e| csv_error(path, e))?.clone();
    if header.is_empty() {
        return Err(TrajectoryError::MissingHeader {
            path: path.to_owned(),
        });
    }
    let layout = parse_header(path, &header, opts, schema)?;
    let used = used_columns(&layout);
    let mut columns = vec![Vec::new(); layout.width];
    let mut lines = Vec::new();
    for record in reader.records() {
        let record = record.map_err(|e| csv_error(path, e))?;
        let line = record.position().map_or(0, |p| p.line());
        if record.len() != layout.width {
            return Err(TrajectoryError::RaggedRow {
                path: path.to_owned(),
                line,
                expected: layout.width,
                found: record.len(),
            });
        }
        for &idx in &used {
            columns[idx].push(parse_cell(path, line, &layout.names[idx], &record[idx])?);
        }
        lines.push(line);
    }
    check_magnitudes(path, &layout, &columns, &lines, opts.units)?;
    if lines.len() < opts.min_samples {
        return Err(TrajectoryError::TooFewSamples {
            path: path.to_owned(),
            found: lines.len(),
            min: opts.min_samples,
        });
    }
    Ok(Table {
        layout,
        columns,
        lines,
    })
}

/// Refuses values beyond [`Channel::plausible`] (in the file's angle unit)
/// and times beyond 1e9 s, naming the line and column.
fn check_magnitudes(
    path: &Path,
    layout: &Layout,
    columns: &[Vec<f64>],
    lines: &[u64],
    units: Units,
) -> Result<(), TrajectoryError> {
    let degrees = matches!(units.angles, AngleUnit::Degrees);
    let mut limits: Vec<(usize, f64, &str)> = Vec::new();
    for ch in CHANNELS {
        let scale = if degrees && ch.is_angular() {
            180.0 / std::f64::consts::PI
        } else {
            1.0
        };
        let unit = if ch.is_angular() { "rad" } else { "N m" };
        for &c in layout.channels[ch.index()].iter().flatten() {
            limits.push((c, ch.plausible() * scale, unit));
        }
    }
    limits.extend(layout.time.map(|c| (c, PLAUSIBLE_TIME, "s")));
    for (c, limit, unit) in limits {
        if let Some(row) = columns[c].iter().position(|v| v.abs() > limit) {
            return Err(TrajectoryError::Implausible {
                path: path.to_owned(),
                line: lines[row],
                column: layout.names[c].clone(),
                value: columns[c][row],
                problem: format!(
                    "beyond any arm (|value| <= {limit:e}, {unit} and its derivatives); a logging fault?"
                ),
            });
        }
    }
    Ok(())
}

fn csv_error(path: &Path, e: csv::Error) -> TrajectoryError {
    let line = e.position().map_or(0, |p| p.line());
    let message = e.to_string();
    match e.into_kind() {
        csv::ErrorKind::Io(source) => TrajectoryError::Io {
            path: path.to_owned(),
            source,
        },
        csv::ErrorKind::Utf8 { err, .. } => TrajectoryError::Csv {
            path: path.to_owned(),
            line,
            message: format!(
                "field {} is not valid UTF-8 text (a binary file, or another encoding?)",
                err.field() + 1
            ),
        },
        _ => TrajectoryError::Csv {
            path: path.to_owned(),
            line,
            message,
        },
    }
}

fn used_columns(layout: &Layout) -> Vec<usize> {
    let joints = layout.channels.iter().flatten().flatten().copied();
    layout.time.into_iter().chain(joints).collect()
}

fn parse_cell(path: &Path, line: u64, column: &str, cell: &str) -> Result<f64, TrajectoryError> {
    let value: f64 = cell.parse().map_err(|_| TrajectoryError::ParseNumber {
        path: path.to_owned(),
        line,
        column: column.to_owned(),
        value: cell.to_owned(),
    })?;
    if !value.is_finite() {
        return Err(TrajectoryError::NonFinite {
            path: path.to_owned(),
            line,
            column: column.to_owned(),
            value,
        });
    }
    Ok(value)
}

impl Table {
    /// A channel as samples x joints, converted to radians when asked.
    fn matrix(&self, ch: Channel, units: Units) -> Option<DMatrix<f64>> {
        let cols = self.layout.channels[ch.index()].as_ref()?;
        let scale = match units.angles {
            AngleUnit::Degrees if ch.is_angular() => std::f64::consts::PI / 180.0,
            _ => 1.0,
        };
        let rows = self.lines.len();
        Some(DMatrix::from_fn(rows, cols.len(), |r, j| {
            self.columns[cols[j]][r] * scale
        }))
    }

    fn required(&self, ch: Channel, units: Units) -> DMatrix<f64> {
        // Schema validation guarantees presence; an empty matrix is a safe fallback.
        self.matrix(ch, units)
            .unwrap_or_else(|| DMatrix::zeros(self.lines.len(), self.layout.dof))
    }
}

/// Reads a trajectory CSV, validating it and optionally resampling it onto a
/// uniform grid (see [`resample`]).
pub fn read_csv(path: impl AsRef<Path>, opts: &ReadOptions) -> Result<Trajectory, TrajectoryError> {
    let path = path.as_ref();
    let table = read_table(path, opts, &TRAJECTORY_SCHEMA)?;
    let t = table
        .layout
        .time
        .map(|i| table.columns[i].clone())
        .unwrap_or_default();
    check_time(path, &t, &table.lines)?;
    let traj = Trajectory::new(
        t,
        table.required(Channel::Q, opts.units),
        table.required(Channel::Qd, opts.units),
        table.matrix(Channel::Qdd, opts.units),
        table.required(Channel::Tau, opts.units),
    )?;
    uniform(path, traj, opts)
}

/// `traj` resampled to `opts.resample_hz`, or checked for uniform sampling
/// when no rate is given (any reader's last step).
pub fn uniform(
    path: &Path,
    traj: Trajectory,
    opts: &ReadOptions,
) -> Result<Trajectory, TrajectoryError> {
    match opts.resample_hz {
        Some(hz) => {
            let out = resample(&traj, hz)?;
            if out.len() < opts.min_samples {
                return Err(TrajectoryError::TooFewSamples {
                    path: path.to_owned(),
                    found: out.len(),
                    min: opts.min_samples,
                });
            }
            Ok(out)
        }
        None => check_uniform(path, traj.t()).map(|()| traj),
    }
}

/// Shortest time step accepted: a 1 MHz log.
const MIN_STEP: f64 = 1e-6;

fn check_time(path: &Path, t: &[f64], lines: &[u64]) -> Result<(), TrajectoryError> {
    for (i, w) in t.windows(2).enumerate() {
        if w[1] > w[0] && w[1] - w[0] < MIN_STEP {
            return Err(TrajectoryError::Implausible {
                path: path.to_owned(),
                line: lines[i + 1],
                column: "t".into(),
                value: w[1],
                problem: format!(
                    "{:e} s after the previous sample; steps below {MIN_STEP:e} s (1 MHz) are \
                     not a joint log (time in another unit? the contract is seconds)",
                    w[1] - w[0]
                ),
            });
        }
        if w[1] <= w[0] {
            return Err(TrajectoryError::NonMonotonicTime {
                path: path.to_owned(),
                line: lines[i + 1],
                previous: w[0],
                current: w[1],
            });
        }
    }
    Ok(())
}

/// Fails when any step deviates from the median step by more than
/// [`JITTER_TOLERANCE`] (relative).
fn check_uniform(path: &Path, t: &[f64]) -> Result<(), TrajectoryError> {
    let mut steps: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    if steps.is_empty() {
        return Ok(());
    }
    steps.sort_by(f64::total_cmp);
    let (min_step, max_step) = (steps[0], steps[steps.len() - 1]);
    let median_step = steps[steps.len() / 2];
    let deviation = (max_step - median_step).max(median_step - min_step) / median_step;
    if deviation > JITTER_TOLERANCE {
        return Err(TrajectoryError::NonUniformSampling {
            path: path.to_owned(),
            min_step,
            max_step,
            median_step,
        });
    }
    Ok(())
}

/// Resamples every channel onto the grid `t0 + k / hz` (k = 0, 1, ... while
/// not past the last sample) by linear interpolation between the two
/// neighbouring samples. Linear interpolation cannot overshoot, so it adds no
/// artefacts to noisy sensor data; it does slightly smooth content near the
/// new Nyquist rate.
pub fn resample(traj: &Trajectory, hz: f64) -> Result<Trajectory, TrajectoryError> {
    if !(hz.is_finite() && hz > 0.0) {
        return Err(TrajectoryError::InvalidResampleRate { hz });
    }
    let t = traj.t();
    let Some((&t0, &t_end)) = t.first().zip(t.last()) else {
        return Ok(traj.clone());
    };
    // The small slack keeps a grid point that lands on t_end despite rounding.
    let samples = ((t_end - t0) * hz * (1.0 + 1e-12)).floor() + 1.0;
    if samples > MAX_RESAMPLED as f64 {
        let span = t_end - t0;
        return Err(TrajectoryError::ResampleTooLarge { span, hz, samples });
    }
    let n = samples as usize;
    let grid: Vec<f64> = (0..n).map(|k| t0 + k as f64 / hz).collect();
    let weights = interpolation_weights(t, &grid);
    let interp = |m: &DMatrix<f64>| {
        DMatrix::from_fn(n, m.ncols(), |r, j| {
            let (i, w) = weights[r];
            let next = (i + 1).min(m.nrows() - 1);
            m[(i, j)] * (1.0 - w) + m[(next, j)] * w
        })
    };
    Trajectory::new(
        grid.clone(),
        interp(traj.q()),
        interp(traj.qd()),
        traj.qdd().map(interp),
        interp(traj.tau()),
    )
}

/// For each grid time, the left sample index and the weight of the right one.
fn interpolation_weights(t: &[f64], grid: &[f64]) -> Vec<(usize, f64)> {
    let mut i = 0;
    grid.iter()
        .map(|&g| {
            while i + 2 < t.len() && t[i + 1] < g {
                i += 1;
            }
            if i + 1 >= t.len() {
                return (i, 0.0);
            }
            let w = ((g - t[i]) / (t[i + 1] - t[i])).clamp(0.0, 1.0);
            (i, w)
        })
        .collect()
}

/// Reads a state file (`q1..qN,qd1..qdN,qdd1..qddN`).
pub fn read_states_csv(
    path: impl AsRef<Path>,
    opts: &ReadOptions,
) -> Result<States, TrajectoryError> {
    let path = path.as_ref();
    no_resample(path, opts)?;
    let table = read_table(path, opts, &STATES_SCHEMA)?;
    States::new(
        table.required(Channel::Q, opts.units),
        table.required(Channel::Qd, opts.units),
        table.required(Channel::Qdd, opts.units),
    )
}

/// Reads a torque file (`tau1..tauN`) as samples x joints.
pub fn read_torques_csv(
    path: impl AsRef<Path>,
    opts: &ReadOptions,
) -> Result<DMatrix<f64>, TrajectoryError> {
    let path = path.as_ref();
    no_resample(path, opts)?;
    let table = read_table(path, opts, &TORQUES_SCHEMA)?;
    Ok(table.required(Channel::Tau, opts.units))
}

fn no_resample(path: &Path, opts: &ReadOptions) -> Result<(), TrajectoryError> {
    match opts.resample_hz {
        Some(_) => Err(TrajectoryError::ResampleWithoutTime {
            path: path.to_owned(),
        }),
        None => Ok(()),
    }
}

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
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A unique scratch directory per test.
    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("pipeline-traj-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn write_file(name: &str, body: &str) -> PathBuf {
        let path = scratch(name).join("in.csv");
        std::fs::write(&path, body).unwrap();
        path
    }

    const GOOD: &str = "t,q1,q2,qd1,qd2,tau1,tau2\n\
                        0.0,1,2,3,4,5,6\n\
                        0.01,1,2,3,4,5,6\n\
                        0.02,1,2,3,4,5,6\n";

    #[test]
    fn reads_contract_file() {
        let traj = read_csv(write_file("good", GOOD), &ReadOptions::default()).unwrap();
        assert_eq!((traj.len(), traj.dof()), (3, 2));
        assert_eq!(traj.qd()[(2, 1)], 4.0);
        assert!(traj.qdd().is_none());
    }

    #[test]
    fn maps_columns_by_header_name() {
        let body = "tau1,qd1,time,q1,junk\n5,3,0,1,x\n6,4,1,2,y\n";
        let mut opts = ReadOptions::default();
        opts.renames.insert("time".into(), "t".into());
        opts.ignored.push("junk".into());
        let traj = read_csv(write_file("order", body), &opts).unwrap();
        assert_eq!(traj.t(), &[0.0, 1.0]);
        assert_eq!(traj.q()[(1, 0)], 2.0);
        assert_eq!(traj.tau()[(1, 0)], 6.0);
    }

    #[test]
    fn converts_degrees_but_not_torque() {
        let body = "t,q1,qd1,qdd1,tau1\n0,180,90,45,7\n1,0,0,0,7\n";
        let opts = ReadOptions {
            units: Units {
                angles: AngleUnit::Degrees,
            },
            ..ReadOptions::default()
        };
        let traj = read_csv(write_file("deg", body), &opts).unwrap();
        assert!((traj.q()[(0, 0)] - std::f64::consts::PI).abs() < 1e-15);
        assert!((traj.qdd().unwrap()[(0, 0)] - std::f64::consts::FRAC_PI_4).abs() < 1e-15);
        assert_eq!(traj.tau()[(0, 0)], 7.0);
    }

    fn read_err(name: &str, body: &str, opts: &ReadOptions) -> String {
        read_csv(write_file(name, body), opts)
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn reports_bad_cells_with_line_and_column() {
        let body = GOOD.replace("0.01,1,2,3,4", "0.01,1,2,abc,4");
        let msg = read_err("parse", &body, &ReadOptions::default());
        assert!(
            msg.contains("line 3") && msg.contains("'qd1'") && msg.contains("'abc'"),
            "{msg}"
        );
        let body = GOOD.replace("0.02,1,2,3,4,5,6", "0.02,1,2,3,4,5,NaN");
        let msg = read_err("nan", &body, &ReadOptions::default());
        assert!(
            msg.contains("line 4") && msg.contains("tau2") && msg.contains("finite"),
            "{msg}"
        );
        let body = GOOD.replace("0.02,1,2,3,4,5,6", "0.02,1,2,3,4,5");
        let msg = read_err("ragged", &body, &ReadOptions::default());
        assert!(msg.contains("line 4") && msg.contains("7 fields"), "{msg}");
    }

    #[test]
    fn reports_header_problems() {
        let opts = ReadOptions::default();
        let msg = read_err(
            "missing",
            "t,q1,q2,qd1,tau1,tau2\n0,1,1,1,1,1\n1,1,1,1,1,1\n",
            &opts,
        );
        assert!(msg.contains("missing column 'qd2'"), "{msg}");
        let msg = read_err("extra", "t,q1,qd1,tau1,temp\n0,1,1,1,1\n1,1,1,1,1\n", &opts);
        assert!(
            msg.contains("unexpected column 'temp'") && msg.contains("ignored"),
            "{msg}"
        );
        let msg = read_err("dup", "t,q1,q1,qd1,tau1\n0,1,1,1,1\n1,1,1,1,1\n", &opts);
        assert!(msg.contains("'q1' appears twice"), "{msg}");
        let msg = read_err("partial-qdd", "t,q1,q2,qd1,qd2,qdd1,tau1,tau2\n", &opts);
        assert!(msg.contains("missing column 'qdd2'"), "{msg}");
        let three = ReadOptions {
            dof: Some(3),
            ..ReadOptions::default()
        };
        let msg = read_err("dof", GOOD, &three);
        assert!(
            msg.contains("expected 3 joints") && msg.contains("has 2"),
            "{msg}"
        );
        let msg = read_err("empty", "", &opts);
        assert!(msg.contains("empty file"), "{msg}");
    }

    #[test]
    fn rejects_bad_time() {
        let body = GOOD.replace("0.02,", "0.01,");
        let msg = read_err("repeat", &body, &ReadOptions::default());
        assert!(
            msg.contains("line 4") && msg.contains("strictly increase"),
            "{msg}"
        );
        let few = ReadOptions {
            min_samples: 10,
            ..ReadOptions::default()
        };
        let msg = read_err("few", GOOD, &few);
        assert!(msg.contains("3 samples, at least 10"), "{msg}");
    }

    #[test]
    fn jitter_needs_resampling() {
        let body = "t,q1,qd1,tau1\n0,0,0,0\n0.01,1,1,1\n0.025,2,2,2\n0.03,3,3,3\n";
        let msg = read_err("jitter", body, &ReadOptions::default());
        assert!(
            msg.contains("--resample HZ") && msg.contains("0.015"),
            "{msg}"
        );
        let opts = ReadOptions {
            resample_hz: Some(100.0),
            ..ReadOptions::default()
        };
        let traj = read_csv(write_file("jitter-ok", body), &opts).unwrap();
        assert_eq!(traj.len(), 4);
        // At t = 0.02 the value lies 2/3 of the way from 1 (t=0.01) to 2 (t=0.025).
        assert!((traj.q()[(2, 0)] - (1.0 + 2.0 / 3.0)).abs() < 1e-12);
        assert!(matches!(
            resample(&traj, f64::NAN),
            Err(TrajectoryError::InvalidResampleRate { .. })
        ));
    }

    #[test]
    fn states_and_torques_round_trip() {
        let dir = scratch("states");
        let m = |k: f64| DMatrix::from_fn(3, 2, |r, c| k + r as f64 * 0.1 + c as f64);
        let states = States::new(m(1.0), m(2.0), m(3.0)).unwrap();
        write_states_csv(dir.join("s.csv"), &states).unwrap();
        let back = read_states_csv(dir.join("s.csv"), &ReadOptions::default()).unwrap();
        assert_eq!(back, states);
        write_torques_csv(dir.join("tau.csv"), &m(4.0)).unwrap();
        let tau = read_torques_csv(dir.join("tau.csv"), &ReadOptions::default()).unwrap();
        assert_eq!(tau, m(4.0));
        let err = read_states_csv(dir.join("tau.csv"), &ReadOptions::default()).unwrap_err();
        assert!(err.to_string().contains("missing column 'q1'"), "{err}");
    }

    #[test]
    fn shape_mismatch_is_an_error() {
        let z = |r, c| DMatrix::zeros(r, c);
        let err = Trajectory::new(vec![0.0, 1.0], z(2, 3), z(2, 3), None, z(2, 2)).unwrap_err();
        assert!(err.to_string().contains("tau has shape 2x2, expected 2x3"));
        let err = Trajectory::new(vec![0.0, 0.0], z(2, 1), z(2, 1), None, z(2, 1)).unwrap_err();
        assert!(err.to_string().contains("sample 1 (0-based)"), "{err}");
        let ok = Trajectory::new(vec![0.0, 1e9], z(2, 1), z(2, 1), None, z(2, 1)).unwrap();
        assert!(matches!(
            resample(&ok, 1e6),
            Err(TrajectoryError::ResampleTooLarge { .. })
        ));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]
        #[test]
        fn write_read_is_bit_exact(
            values in prop::collection::vec(-1e3f64..1e3, 12),
            tiny in 1e-300f64..1e-290,
        ) {
            let n = 4;
            let t: Vec<f64> = (0..n).map(|i| i as f64 * 0.001).collect();
            let m = |k: usize| DMatrix::from_fn(n, 1, |r, _| values[(k * n + r) % 12] * if r == 0 { tiny } else { 1.0 });
            let traj = Trajectory::new(t, m(0), m(1), Some(m(2)), m(0)).unwrap();
            let path = scratch("prop").join("rt.csv");
            write_csv(&path, &traj).unwrap();
            let back = read_csv(&path, &ReadOptions::default()).unwrap();
            prop_assert_eq!(back, traj);
        }
    }
}
