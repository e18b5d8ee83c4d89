//! Import of robot logs that store each channel in its own text file.
//!
//! Layout ("line-major"): one number per line; a joint channel holds `dof`
//! lines per sample, so sample `k` is lines `dof*k + 1 ..= dof*k + dof`
//! (1-based) and the time file holds one line per sample. This is how the
//! Franka Panda identification log of Gaz et al. (2019) is stored.
//!
//! [`write_contract_csv`] writes the result in the trajectory CSV contract:
//! header `t,q1..qN,qd1..qdN,tau1..tauN`, SI units, one row per sample.
//!
//! Every error names the file and, where it applies, the 1-based line.

use std::io::Write;
use std::path::{Path, PathBuf};

use thiserror::Error;

/// The four channel files of a line-major log.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LineMajorSources {
    /// Sample times in seconds, one per line, strictly increasing.
    pub time: PathBuf,
    /// Joint positions, rad (m for prismatic joints).
    pub positions: PathBuf,
    /// Joint velocities, rad/s.
    pub velocities: PathBuf,
    /// Joint torques, N m.
    pub torques: PathBuf,
    /// Number of joints: values per sample in each joint channel.
    pub dof: usize,
}

/// A log as rows: `q[k]`, `qd[k]` and `tau[k]` hold sample `k`'s joints.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Columns {
    pub t: Vec<f64>,
    pub q: Vec<Vec<f64>>,
    pub qd: Vec<Vec<f64>>,
    pub tau: Vec<Vec<f64>>,
}

/// Errors from reading a line-major log or writing the contract CSV.
#[derive(Debug, Error)]
pub enum ImportLogError {
    /// The number of joints is zero.
    #[error("dof must be at least 1, got 0")]
    ZeroDof,
    /// A file could not be read.
    #[error("{}: {source}", .path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A line is not valid UTF-8.
    #[error("{}: line {line}: not valid UTF-8 text", .path.display())]
    NotText { path: PathBuf, line: usize },
    /// A line is empty or only whitespace.
    #[error("{}: line {line}: blank line, expected one number per line", .path.display())]
    BlankLine { path: PathBuf, line: usize },
    /// A line does not parse as a number.
    #[error("{}: line {line}: expected a number, found {text:?}", .path.display())]
    NotANumber {
        path: PathBuf,
        line: usize,
        text: String,
    },
    /// A line holds NaN or an infinity.
    #[error("{}: line {line}: value {value} is not finite", .path.display())]
    NonFinite {
        path: PathBuf,
        line: usize,
        value: f64,
    },
    /// The time file has no samples.
    #[error("{}: no samples", .path.display())]
    Empty { path: PathBuf },
    /// A joint channel's line count is not a whole number of samples.
    #[error(
        "{}: {values} values is not a multiple of {dof} joints (the last sample, from line {last_start}, is incomplete)",
        .path.display()
    )]
    PartialSample {
        path: PathBuf,
        values: usize,
        dof: usize,
        last_start: usize,
    },
    /// A channel has a different number of samples than the time file.
    #[error(
        "{}: {found} samples ({dof} values per sample), but the time file {} has {expected}",
        .path.display(),
        .time.display()
    )]
    SampleCountMismatch {
        path: PathBuf,
        time: PathBuf,
        found: usize,
        expected: usize,
        dof: usize,
    },
    /// Time does not strictly increase.
    #[error(
        "{}: line {line}: time {current} s does not increase (previous line {previous} s)",
        .path.display()
    )]
    NonIncreasingTime {
        path: PathBuf,
        line: usize,
        previous: f64,
        current: f64,
    },
    /// The columns handed to the writer are inconsistent.
    #[error("cannot write CSV: {0}")]
    Shape(String),
    /// The CSV writer failed.
    #[error("writing CSV: {0}")]
    Csv(#[from] csv::Error),
}

/// Reads the four channel files of a line-major log into rows.
pub fn read_line_major(src: &LineMajorSources) -> Result<Columns, ImportLogError> {
    if src.dof == 0 {
        return Err(ImportLogError::ZeroDof);
    }
    let t = read_values(&src.time)?;
    if t.is_empty() {
        return Err(ImportLogError::Empty {
            path: src.time.clone(),
        });
    }
    check_increasing(&src.time, &t)?;
    let channel = |path: &PathBuf| read_channel(path, src, t.len());
    Ok(Columns {
        q: channel(&src.positions)?,
        qd: channel(&src.velocities)?,
        tau: channel(&src.torques)?,
        t,
    })
}

/// Writes the columns as a contract CSV: header `t,q1..qN,qd1..qN,tau1..tauN`,
/// every number in Rust's shortest representation that parses back exactly.
pub fn write_contract_csv(w: impl Write, c: &Columns) -> Result<(), ImportLogError> {
    let dof = check_shape(c)?;
    let mut out = csv::Writer::from_writer(w);
    out.write_record(header(dof))?;
    for (k, &t) in c.t.iter().enumerate() {
        let joints = c.q[k].iter().chain(&c.qd[k]).chain(&c.tau[k]);
        out.write_record(std::iter::once(&t).chain(joints).map(|x| format!("{x:?}")))?;
    }
    out.flush().map_err(csv::Error::from)?;
    Ok(())
}

/// One finite number per line; a final line terminator is optional.
fn read_values(path: &Path) -> Result<Vec<f64>, ImportLogError> {
    crate::output::note_input(path);
    let bytes = crate::bounded::read(path).map_err(|source| ImportLogError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    // A byte-order mark (Windows editors) and blank lines at the end are
    // not samples; a blank line between samples stays an error.
    let body = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(&bytes);
    let end = body
        .iter()
        .rposition(|b| !b.is_ascii_whitespace())
        .map_or(0, |i| i + 1);
    let body = &body[..end];
    if body.is_empty() {
        return Ok(Vec::new());
    }
    // Lines end in `\n` (Unix; Windows' `\r` is trimmed) or, in a file
    // without one, in `\r` (classic Mac): each line is then its own.
    let newline = if body.contains(&b'\n') { b'\n' } else { b'\r' };
    body.split(|&b| b == newline)
        .enumerate()
        .map(|(i, raw)| parse_line(path, i + 1, raw))
        .collect()
}

fn parse_line(path: &Path, line: usize, raw: &[u8]) -> Result<f64, ImportLogError> {
    let path = || path.to_path_buf();
    let text = std::str::from_utf8(raw)
        .map_err(|_| ImportLogError::NotText { path: path(), line })?
        .trim();
    if text.is_empty() {
        return Err(ImportLogError::BlankLine { path: path(), line });
    }
    let value: f64 = text.parse().map_err(|_| ImportLogError::NotANumber {
        path: path(),
        line,
        text: text.to_string(),
    })?;
    if !value.is_finite() {
        return Err(ImportLogError::NonFinite {
            path: path(),
            line,
            value,
        });
    }
    Ok(value)
}

fn check_increasing(path: &Path, t: &[f64]) -> Result<(), ImportLogError> {
    match t.windows(2).position(|w| w[1] <= w[0]) {
        None => Ok(()),
        Some(i) => Err(ImportLogError::NonIncreasingTime {
            path: path.to_path_buf(),
            line: i + 2,
            previous: t[i],
            current: t[i + 1],
        }),
    }
}

/// A joint channel split into `samples` rows of `src.dof` values.
fn read_channel(
    path: &Path,
    src: &LineMajorSources,
    samples: usize,
) -> Result<Vec<Vec<f64>>, ImportLogError> {
    let values = read_values(path)?;
    let dof = src.dof;
    if !values.len().is_multiple_of(dof) {
        return Err(ImportLogError::PartialSample {
            path: path.to_path_buf(),
            values: values.len(),
            dof,
            last_start: values.len() / dof * dof + 1,
        });
    }
    if values.len() / dof != samples {
        return Err(ImportLogError::SampleCountMismatch {
            path: path.to_path_buf(),
            time: src.time.clone(),
            found: values.len() / dof,
            expected: samples,
            dof,
        });
    }
    Ok(values.chunks_exact(dof).map(<[f64]>::to_vec).collect())
}

/// The joint count, once every channel has one row per time and equal rows.
fn check_shape(c: &Columns) -> Result<usize, ImportLogError> {
    let dof = c.q.first().map_or(0, Vec::len);
    if c.t.is_empty() || dof == 0 {
        return Err(ImportLogError::Shape(
            "need at least one sample of at least one joint".into(),
        ));
    }
    for (name, rows) in [("q", &c.q), ("qd", &c.qd), ("tau", &c.tau)] {
        if rows.len() != c.t.len() {
            return Err(ImportLogError::Shape(format!(
                "{name} has {} samples, t has {}",
                rows.len(),
                c.t.len()
            )));
        }
        if let Some(k) = rows.iter().position(|r| r.len() != dof) {
            return Err(ImportLogError::Shape(format!(
                "{name} sample {k} has {} joints, q sample 0 has {dof}",
                rows[k].len()
            )));
        }
    }
    Ok(dof)
}

fn header(dof: usize) -> Vec<String> {
    let joints = |prefix: &'static str| (1..=dof).map(move |j| format!("{prefix}{j}"));
    std::iter::once("t".to_string())
        .chain(joints("q"))
        .chain(joints("qd"))
        .chain(joints("tau"))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Writes the four channel files into a fresh temporary directory.
    fn sources(
        dof: usize,
        time: &str,
        q: &str,
        qd: &str,
        tau: &str,
    ) -> (tempfile::TempDir, LineMajorSources) {
        let dir = tempfile::tempdir().unwrap();
        let file = |name: &str, body: &str| {
            let path = dir.path().join(name);
            std::fs::write(&path, body).unwrap();
            path
        };
        let src = LineMajorSources {
            time: file("time.txt", time),
            positions: file("positions.txt", q),
            velocities: file("velocity.txt", qd),
            torques: file("torques.txt", tau),
            dof,
        };
        (dir, src)
    }

    /// Two samples of two joints, every channel valid.
    const T: &str = "0\n0.001\n";
    const Q: &str = "0.1\n0.2\n0.3\n0.4\n";
    const QD: &str = "1\n2\n3\n4\n";
    const TAU: &str = "-1.5\n2.5e-3\n7\n8\n";

    fn read_err(dof: usize, time: &str, q: &str, qd: &str, tau: &str) -> String {
        let (_dir, src) = sources(dof, time, q, qd, tau);
        read_line_major(&src).unwrap_err().to_string()
    }

    fn assert_mentions(msg: &str, parts: &[&str]) {
        for part in parts {
            assert!(msg.contains(part), "{msg:?} lacks {part:?}");
        }
    }

    #[test]
    fn reads_line_major_rows() {
        let (_dir, src) = sources(2, T, Q, QD, TAU);
        let c = read_line_major(&src).unwrap();
        assert_eq!(c.t, vec![0.0, 0.001]);
        assert_eq!(c.q, vec![vec![0.1, 0.2], vec![0.3, 0.4]]);
        assert_eq!(c.qd, vec![vec![1.0, 2.0], vec![3.0, 4.0]]);
        assert_eq!(c.tau, vec![vec![-1.5, 2.5e-3], vec![7.0, 8.0]]);
    }

    #[test]
    fn accepts_crlf_spaces_and_no_final_newline() {
        let (_dir, src) = sources(2, "0\r\n 0.5 \r\n", "1\n2\n3\n4", QD, TAU);
        let c = read_line_major(&src).unwrap();
        assert_eq!(c.t, vec![0.0, 0.5]);
        assert_eq!(c.q[1], vec![3.0, 4.0]);
    }

    #[test]
    fn accepts_a_byte_order_mark_and_trailing_blank_lines() {
        let (_dir, src) = sources(
            2,
            "\u{feff}0\n0.5\n\n\r\n  \n",
            "\u{feff}1\n2\n3\n4\n\n",
            QD,
            TAU,
        );
        let c = read_line_major(&src).unwrap();
        assert_eq!(c.t, vec![0.0, 0.5]);
        assert_eq!(c.q[0], vec![1.0, 2.0]);
    }

    #[test]
    fn rejects_non_numbers_with_file_and_line() {
        let msg = read_err(2, T, "0.1\n0.2\nabc\n0.4\n", QD, TAU);
        assert_mentions(&msg, &["positions.txt", "line 3", "\"abc\""]);
    }

    #[test]
    fn names_the_same_line_whatever_the_line_endings() {
        for ending in ["\n", "\r\n", "\r"] {
            let q = ["0.1", "0.2", "abc", "0.4"]
                .map(|v| format!("{v}{ending}"))
                .concat();
            let msg = read_err(2, T, &q, QD, TAU);
            assert_mentions(&msg, &["positions.txt", "line 3", "\"abc\""]);
            let time = format!("0{ending}0.001{ending}");
            let (_dir, src) = sources(2, &time, Q, QD, TAU);
            assert_eq!(
                read_line_major(&src).unwrap().t,
                vec![0.0, 0.001],
                "{ending:?}"
            );
        }
    }

    #[test]
    fn rejects_blank_lines() {
        let msg = read_err(2, T, Q, "1\n\n3\n4\n", TAU);
        assert_mentions(&msg, &["velocity.txt", "line 2", "blank"]);
        // Between samples, not at the end (trailing blank lines are no samples).
        let msg = read_err(2, "0\n\n0.001\n", Q, QD, TAU);
        assert_mentions(&msg, &["time.txt", "line 2", "blank"]);
    }

    #[test]
    fn rejects_non_finite_values() {
        for bad in ["NaN", "inf", "-infinity", "1e400"] {
            let msg = read_err(2, T, Q, QD, &format!("1\n2\n3\n{bad}\n"));
            assert_mentions(&msg, &["torques.txt", "line 4", "not finite"]);
        }
    }

    #[test]
    fn rejects_invalid_utf8() {
        let (_dir, src) = sources(2, T, Q, QD, TAU);
        std::fs::write(&src.torques, b"1\n2\n\xff\n4\n").unwrap();
        let msg = read_line_major(&src).unwrap_err().to_string();
        assert_mentions(&msg, &["torques.txt", "line 3", "UTF-8"]);
    }

    #[test]
    fn rejects_partial_samples() {
        let msg = read_err(2, T, "0.1\n0.2\n0.3\n", QD, TAU);
        assert_mentions(
            &msg,
            &["positions.txt", "3 values", "multiple of 2", "line 3"],
        );
    }

    #[test]
    fn rejects_sample_count_mismatch() {
        let msg = read_err(2, T, Q, "1\n2\n3\n4\n5\n6\n", TAU);
        assert_mentions(&msg, &["velocity.txt", "3 samples", "time.txt", "has 2"]);
        let msg = read_err(2, "0\n1\n2\n", Q, QD, TAU);
        assert_mentions(&msg, &["positions.txt", "2 samples", "has 3"]);
    }

    #[test]
    fn rejects_non_increasing_time() {
        let msg = read_err(1, "0\n1\n1\n", "1\n2\n3\n", "1\n2\n3\n", "1\n2\n3\n");
        assert_mentions(&msg, &["time.txt", "line 3", "does not increase"]);
        let msg = read_err(1, "0\n-1\n", "1\n2\n", "1\n2\n", "1\n2\n");
        assert_mentions(&msg, &["time.txt", "line 2"]);
    }

    #[test]
    fn rejects_missing_file_empty_time_and_zero_dof() {
        let (_dir, mut src) = sources(2, T, Q, QD, TAU);
        src.torques.set_file_name("absent.txt");
        let msg = read_line_major(&src).unwrap_err().to_string();
        assert_mentions(&msg, &["absent.txt"]);
        assert_mentions(&read_err(2, "", Q, QD, TAU), &["time.txt", "no samples"]);
        assert!(matches!(
            read_line_major(&LineMajorSources { dof: 0, ..src }),
            Err(ImportLogError::ZeroDof)
        ));
    }

    #[test]
    fn writes_contract_csv_with_round_trip_floats() {
        let c = Columns {
            t: vec![0.0, 0.1 + 0.2],
            q: vec![vec![1.0 / 3.0], vec![-2.0]],
            qd: vec![vec![1e-7], vec![1e20]],
            tau: vec![vec![87.0], vec![f64::MIN_POSITIVE]],
        };
        let mut out = Vec::new();
        write_contract_csv(&mut out, &c).unwrap();
        let text = String::from_utf8(out).unwrap();
        let mut lines = text.lines();
        assert_eq!(lines.next(), Some("t,q1,qd1,tau1"));
        assert_eq!(lines.next(), Some("0.0,0.3333333333333333,1e-7,87.0"));
        let last: Vec<f64> = lines
            .next()
            .unwrap()
            .split(',')
            .map(|s| s.parse().unwrap())
            .collect();
        assert_eq!(last, vec![0.1 + 0.2, -2.0, 1e20, f64::MIN_POSITIVE]);
        assert_eq!(lines.next(), None);
    }

    #[test]
    fn file_to_csv_round_trip() {
        let (_dir, src) = sources(2, T, Q, QD, TAU);
        let mut out = Vec::new();
        write_contract_csv(&mut out, &read_line_major(&src).unwrap()).unwrap();
        let expected = "t,q1,q2,qd1,qd2,tau1,tau2\n\
                        0.0,0.1,0.2,1.0,2.0,-1.5,0.0025\n\
                        0.001,0.3,0.4,3.0,4.0,7.0,8.0\n";
        assert_eq!(String::from_utf8(out).unwrap(), expected);
    }

    #[test]
    fn writer_rejects_inconsistent_columns() {
        let good = Columns {
            t: vec![0.0, 1.0],
            q: vec![vec![1.0, 2.0]; 2],
            qd: vec![vec![1.0, 2.0]; 2],
            tau: vec![vec![1.0, 2.0]; 2],
        };
        let short = Columns {
            tau: vec![vec![1.0, 2.0]],
            ..good.clone()
        };
        let ragged = Columns {
            qd: vec![vec![1.0, 2.0], vec![1.0]],
            ..good.clone()
        };
        for (c, part) in [
            (short, "tau has 1 samples"),
            (ragged, "qd sample 1 has 1 joints"),
            (Columns::default(), "at least one sample"),
        ] {
            let msg = write_contract_csv(Vec::new(), &c).unwrap_err().to_string();
            assert_mentions(&msg, &[part]);
        }
        assert!(write_contract_csv(Vec::new(), &good).is_ok());
    }
}
