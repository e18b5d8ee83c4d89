//! Reading the CSV contract: the header's columns, the cells, their
//! plausibility and the time column.

use super::*;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(super) enum Channel {
    Q,
    Qd,
    Qdd,
    Tau,
}

pub(super) const CHANNELS: [Channel; 4] = [Channel::Q, Channel::Qd, Channel::Qdd, Channel::Tau];

impl Channel {
    pub(super) fn prefix(self) -> &'static str {
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
    pub(super) fn plausible(self) -> f64 {
        match self {
            Channel::Q | Channel::Qd => PLAUSIBLE_ANGLE,
            Channel::Qdd | Channel::Tau => PLAUSIBLE_TORQUE,
        }
    }

    pub(super) fn index(self) -> usize {
        self as usize
    }

    /// Angle-derived channels are scaled on unit conversion; torque is not.
    pub(super) fn is_angular(self) -> bool {
        self != Channel::Tau
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Presence {
    Required,
    Optional,
    Forbidden,
}

/// Which columns a kind of file must, may or must not have.
pub(super) struct Schema {
    time: Presence,
    channels: [Presence; 4],
    expected: &'static str,
}

pub(super) const TRAJECTORY_SCHEMA: Schema = Schema {
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
pub(super) const STATES_SCHEMA: Schema = Schema {
    time: Presence::Optional,
    channels: [
        Presence::Required,
        Presence::Required,
        Presence::Required,
        Presence::Optional,
    ],
    expected: "q1..qN, qd1..qdN, qdd1..qddN",
};

/// States and torques for `sdnn qdd`: a recording's `t` and `qdd`
/// columns may be present (read and not used).
pub(super) const FORWARD_SCHEMA: Schema = Schema {
    time: Presence::Optional,
    channels: [
        Presence::Required,
        Presence::Required,
        Presence::Optional,
        Presence::Required,
    ],
    expected: "q1..qN, qd1..qdN, tau1..tauN",
};

/// Positions for `sdnn pose`: any other contract column may be present.
pub(super) const POSITIONS_SCHEMA: Schema = Schema {
    time: Presence::Optional,
    channels: [
        Presence::Required,
        Presence::Optional,
        Presence::Optional,
        Presence::Optional,
    ],
    expected: "q1..qN",
};

/// A planned motion (`sdnn excite`, `simulate --trajectory`): a
/// recording's `tau` columns may be present (read and not used).
pub(super) const PLAN_SCHEMA: Schema = Schema {
    time: Presence::Required,
    channels: [
        Presence::Required,
        Presence::Required,
        Presence::Required,
        Presence::Optional,
    ],
    expected: "t, q1..qN, qd1..qdN, qdd1..qddN",
};

pub(super) const TORQUES_SCHEMA: Schema = Schema {
    time: Presence::Forbidden,
    channels: [
        Presence::Forbidden,
        Presence::Forbidden,
        Presence::Forbidden,
        Presence::Required,
    ],
    expected: "tau1..tauN",
};

pub(super) enum Column {
    Time,
    Joint(Channel, usize),
}

/// Whether `name` is a column of the CSV contract (`t`, `q3`, `tau1`, ...).
pub fn is_contract_column(name: &str) -> bool {
    parse_column_name(name).is_some()
}

/// Parses a contract name such as `qd3` into (channel, 0-based joint).
pub(super) fn parse_column_name(name: &str) -> Option<Column> {
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
pub(super) struct Layout {
    width: usize,
    names: Vec<String>,
    time: Option<usize>,
    dof: usize,
    /// Per channel, the file column of each joint.
    channels: [Option<Vec<usize>>; 4],
}

pub(super) fn parse_header(
    (path, line): (&Path, u64),
    header: &csv::StringRecord,
    opts: &ReadOptions,
    schema: &Schema,
) -> Result<Layout, TrajectoryError> {
    let (time, joints) = classify_columns((path, line), header, opts, schema)?;
    if schema.time == Presence::Required && time.is_none() {
        return Err(missing((path, line), "t".to_owned()));
    }
    let found = joints.keys().map(|&(_, j)| j + 1).max().unwrap_or(0);
    if let Some(expected) = opts.dof
        && expected != found
        && found > 0
    {
        return Err(TrajectoryError::WrongDof {
            path: path.to_owned(),
            line,
            expected,
            found,
        });
    }
    // With no joint columns at all, dof 1 makes the error name `q1`/`tau1`.
    let dof = found.max(1);
    let mut channels: [Option<Vec<usize>>; 4] = Default::default();
    for ch in CHANNELS {
        channels[ch.index()] = channel_columns((path, line), &joints, ch, dof, schema)?;
    }
    Ok(Layout {
        width: header.len(),
        names: header.iter().map(str::to_owned).collect(),
        time,
        dof,
        channels,
    })
}

pub(super) fn classify_columns(
    (path, line): (&Path, u64),
    header: &csv::StringRecord,
    opts: &ReadOptions,
    schema: &Schema,
) -> Result<Classified, TrajectoryError> {
    let mut time = None;
    let mut joints = HashMap::new();
    let mut seen = HashSet::new();
    for (idx, raw) in header.iter().enumerate() {
        // The reader drops a byte-order mark only at the very start of the
        // file, not after blank lines.
        let raw = raw.trim_start_matches('\u{feff}');
        if opts.ignored.iter().any(|i| i == raw) {
            continue;
        }
        let name = opts.renames.get(raw).map_or(raw, String::as_str);
        let unexpected = || TrajectoryError::UnexpectedColumn {
            path: path.to_owned(),
            line,
            column: raw.to_owned(),
            expected: schema.expected.to_owned(),
            advice: super::advice::unexpected(raw),
        };
        if !seen.insert(name.to_owned()) {
            return Err(TrajectoryError::DuplicateColumn {
                path: path.to_owned(),
                line,
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

pub(super) fn missing((path, line): (&Path, u64), column: String) -> TrajectoryError {
    TrajectoryError::MissingColumn {
        path: path.to_owned(),
        line,
        column,
    }
}

/// Resolves a channel's columns: a required channel needs every joint, an
/// optional one needs all or none.
pub(super) fn channel_columns(
    (path, line): (&Path, u64),
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
                .ok_or_else(|| missing((path, line), format!("{}{}", ch.prefix(), j + 1)))
        })
        .collect::<Result<Vec<_>, _>>()
        .map(Some)
}

/// Parsed numeric columns (indexed by file column) and each row's file line.
pub(super) struct Table {
    layout: Layout,
    columns: Vec<Vec<f64>>,
    lines: Vec<u64>,
}

pub(super) fn read_table(
    path: &Path,
    opts: &ReadOptions,
    schema: &Schema,
) -> Result<Table, TrajectoryError> {
    let io_err = |source| TrajectoryError::Io {
        path: path.to_owned(),
        source,
    };
    // `-` is standard input.
    let source: Box<dyn io::Read> = if path == Path::new("-") {
        Box::new(io::stdin().lock())
    } else {
        crate::output::note_input(path);
        Box::new(crate::suggest::open_input(path).map_err(io_err)?)
    };
    // The reader trims the header; a record's cells are trimmed as they
    // are parsed (`str::trim`, what the reader's own trimming of a record
    // gives), which spares a new record per row for the cells not read.
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::Headers)
        .flexible(true)
        .from_reader(io::BufReader::new(crate::bounded::LineLimited::new(
            // Every record ends in `\n`, whatever the file's line endings.
            crate::line_ends::UnixLineEnds::new(source),
        )));
    let header = reader
        .headers()
        .map_err(|e| csv_error(path, e, None))?
        .clone();
    if header.is_empty() {
        return Err(TrajectoryError::MissingHeader {
            path: path.to_owned(),
        });
    }
    // The line the header ends on (csv skips blank lines before it).
    let header_line = reader.position().line().saturating_sub(1).max(1);
    if header.iter().all(str::is_empty) {
        return Err(TrajectoryError::BlankHeader {
            path: path.to_owned(),
            line: header_line,
        });
    }
    let layout = parse_header((path, header_line), &header, opts, schema)?;
    let used = used_columns(&layout);
    let mut columns = vec![Vec::new(); layout.width];
    let mut lines = Vec::new();
    // One record, reused for every row. Its line is the one it ends on
    // (where it starts, csv counts the blank lines it skipped before it).
    let mut record = csv::StringRecord::new();
    let ended_on = |reader: &csv::Reader<_>| reader.position().line().saturating_sub(1);
    while reader
        .read_record(&mut record)
        .map_err(|e| csv_error(path, e, Some(ended_on(&reader))))?
    {
        let line = ended_on(&reader);
        if record.len() != layout.width {
            return Err(TrajectoryError::RaggedRow {
                path: path.to_owned(),
                line,
                expected: layout.width,
                found: record.len(),
            });
        }
        for &idx in &used {
            let cell = record[idx].trim();
            columns[idx].push(parse_cell(path, line, &layout.names[idx], cell)?);
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
pub(super) fn check_magnitudes(
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
                problem: if Some(c) == layout.time {
                    format!(
                        "a time beyond any recording (|t| <= {limit:e} s): if it is a clock's \
                         (Unix time), subtract the first sample's (t counts seconds from the \
                         recording's start)"
                    )
                } else {
                    format!(
                        "beyond any arm (|value| <= {limit:e}, {unit} and its derivatives); a \
                         logging fault?"
                    )
                },
            });
        }
    }
    Ok(())
}

/// `line` overrides csv's own (a record's start, before skipped blanks).
pub(super) fn csv_error(path: &Path, e: csv::Error, line: Option<u64>) -> TrajectoryError {
    let line = line.unwrap_or_else(|| e.position().map_or(0, |p| p.line()));
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

pub(super) fn used_columns(layout: &Layout) -> Vec<usize> {
    let joints = layout.channels.iter().flatten().flatten().copied();
    layout.time.into_iter().chain(joints).collect()
}

pub(super) fn parse_cell(
    path: &Path,
    line: u64,
    column: &str,
    cell: &str,
) -> Result<f64, TrajectoryError> {
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
    /// The time column (empty without one) after its checks.
    pub(super) fn checked_time(&self, path: &Path) -> Result<Vec<f64>, TrajectoryError> {
        let t = self
            .layout
            .time
            .map(|i| self.columns[i].clone())
            .unwrap_or_default();
        check_time(path, &t, &self.lines)?;
        Ok(t)
    }

    /// A channel as samples x joints, converted to radians when asked.
    pub(super) fn matrix(&self, ch: Channel, units: Units) -> Option<DMatrix<f64>> {
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

    pub(super) fn required(&self, ch: Channel, units: Units) -> DMatrix<f64> {
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

/// Reads (q, qd, tau), samples x joints, for forward dynamics.
pub fn read_forward_csv(
    path: impl AsRef<Path>,
    opts: &ReadOptions,
) -> Result<[DMatrix<f64>; 3], TrajectoryError> {
    let path = path.as_ref();
    no_resample(path, opts)?;
    let table = read_table(path, opts, &FORWARD_SCHEMA)?;
    Ok([Channel::Q, Channel::Qd, Channel::Tau].map(|ch| table.required(ch, opts.units)))
}

/// Reads joint positions (`q1..qN`), samples x joints.
pub fn read_positions_csv(
    path: impl AsRef<Path>,
    opts: &ReadOptions,
) -> Result<DMatrix<f64>, TrajectoryError> {
    let path = path.as_ref();
    no_resample(path, opts)?;
    let table = read_table(path, opts, &POSITIONS_SCHEMA)?;
    Ok(table.required(Channel::Q, opts.units))
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

pub(super) fn no_resample(path: &Path, opts: &ReadOptions) -> Result<(), TrajectoryError> {
    match opts.resample_hz {
        Some(_) => Err(TrajectoryError::ResampleWithoutTime {
            path: path.to_owned(),
        }),
        None => Ok(()),
    }
}
