//! Model-comparison tables (like Table 3.1 of the SDNN thesis).
//!
//! Rows may be ragged: the number of joint columns is the largest
//! `mse_per_joint` length over all rows, and the extra columns are the union of
//! all `extra` keys in order of first appearance. Missing cells are left empty
//! (CSV) or shown as `–` (Markdown). Non-finite numbers are printed as `NaN`,
//! `inf` or `-inf`; nothing here panics on odd input.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::report::atomic::write_atomic;
use crate::report::error::ReportError;

/// One model's results: overall MSE and per-joint MSE, each as mean and
/// standard deviation over repeated runs, plus free-form extra columns.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ComparisonRow {
    /// Model name, e.g. `"NN trained on Synthesized-Data (SDNN)"`.
    pub name: String,
    /// Mean of the overall MSE over repetitions.
    pub mse_mean: f64,
    /// Standard deviation of the overall MSE over repetitions.
    pub mse_std: f64,
    /// Mean MSE per joint (joint 1 first).
    pub mse_per_joint: Vec<f64>,
    /// Standard deviation of the MSE per joint (same order).
    pub mse_per_joint_std: Vec<f64>,
    /// Extra `(column, value)` pairs, e.g. `("epochs", "200")`.
    pub extra: Vec<(String, String)>,
}

/// A titled comparison table.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Comparison {
    /// Table caption.
    pub title: String,
    /// Unit of the MSE values, e.g. `"(N·m)²"`; may be empty.
    pub unit: String,
    /// One row per model.
    pub rows: Vec<ComparisonRow>,
}

impl Comparison {
    /// Number of joint columns: the longest per-joint vector over all rows.
    pub fn joint_count(&self) -> usize {
        let len = |r: &ComparisonRow| r.mse_per_joint.len().max(r.mse_per_joint_std.len());
        self.rows.iter().map(len).max().unwrap_or(0)
    }

    /// Extra column names, in order of first appearance.
    pub fn extra_columns(&self) -> Vec<String> {
        let mut names: Vec<String> = Vec::new();
        for (key, _) in self.rows.iter().flat_map(|r| &r.extra) {
            if !names.contains(key) {
                names.push(key.clone());
            }
        }
        names
    }
}

impl ComparisonRow {
    /// Value of the extra column `key`, if this row has it.
    pub fn extra_value(&self, key: &str) -> Option<&str> {
        self.extra
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }
}

/// Formats `x` with 4 significant digits: fixed notation for
/// `1e-3 <= |x| < 1e4` (and for 0), scientific (`1.234e-5`) otherwise.
/// Non-finite values print as `NaN`, `inf`, `-inf`.
pub fn format_sig(x: f64) -> String {
    if !x.is_finite() {
        return format!("{x}");
    }
    if x == 0.0 {
        return "0".to_string();
    }
    let sci = format!("{x:.3e}");
    // Decide on the rounded value so that 9999.6 becomes 1.000e4, not "10000".
    let rounded: f64 = sci.parse().unwrap_or(x);
    let mag = rounded.abs();
    if !(1e-3..1e4).contains(&mag) {
        return sci;
    }
    let decimals = (3 - mag.log10().floor() as i32).max(0) as usize;
    format!("{rounded:.decimals$}")
}

/// `mean ± std`, or just `mean` when `std` is absent.
fn mean_std(mean: Option<f64>, std: Option<f64>) -> String {
    match (mean, std) {
        (Some(m), Some(s)) => format!("{} ± {}", format_sig(m), format_sig(s)),
        (Some(m), None) => format_sig(m),
        (None, Some(s)) => format!("– ± {}", format_sig(s)),
        (None, None) => "–".to_string(),
    }
}

/// Makes text safe for one Markdown table cell.
fn md_cell(text: &str) -> String {
    text.replace(['\n', '\r'], " ").replace('|', "\\|")
}

fn md_line(cells: &[String]) -> String {
    format!("| {} |", cells.join(" | "))
}

fn md_header(cmp: &Comparison, joints: usize, extras: &[String]) -> Vec<String> {
    let unit = if cmp.unit.trim().is_empty() {
        String::new()
    } else {
        format!(" [{}]", md_cell(&cmp.unit))
    };
    let mut cells = vec!["Model".to_string(), format!("MSE{unit}")];
    cells.extend((1..=joints).map(|j| format!("J{j} MSE{unit}")));
    cells.extend(extras.iter().map(|e| md_cell(e)));
    cells
}

fn md_row(row: &ComparisonRow, joints: usize, extras: &[String]) -> Vec<String> {
    let mut cells = vec![
        md_cell(&row.name),
        mean_std(Some(row.mse_mean), Some(row.mse_std)),
    ];
    cells.extend((0..joints).map(|j| {
        let mean = row.mse_per_joint.get(j).copied();
        mean_std(mean, row.mse_per_joint_std.get(j).copied())
    }));
    cells.extend(
        extras
            .iter()
            .map(|k| row.extra_value(k).map_or_else(|| "–".to_string(), md_cell)),
    );
    cells
}

/// Renders the comparison as a bold caption followed by a GitHub Markdown
/// table: model, overall MSE (`mean ± std`), one `mean ± std` column per joint,
/// then the extra columns. Numbers use [`format_sig`].
pub fn to_markdown(cmp: &Comparison) -> String {
    let joints = cmp.joint_count();
    let extras = cmp.extra_columns();
    let header = md_header(cmp, joints, &extras);
    let mut align = vec![":---".to_string()];
    align.extend(std::iter::repeat_n("---:".to_string(), 1 + joints));
    align.extend(std::iter::repeat_n(":---".to_string(), extras.len()));
    let mut out = String::new();
    if !cmp.title.trim().is_empty() {
        out.push_str(&format!("**{}**\n\n", md_cell(cmp.title.trim())));
    }
    out.push_str(&md_line(&header));
    out.push('\n');
    out.push_str(&md_line(&align));
    out.push('\n');
    for row in &cmp.rows {
        out.push_str(&md_line(&md_row(row, joints, &extras)));
        out.push('\n');
    }
    out
}

/// Writes [`to_markdown`] output to `path` atomically.
pub fn write_markdown(path: impl AsRef<Path>, cmp: &Comparison) -> Result<(), ReportError> {
    write_atomic(path.as_ref(), to_markdown(cmp).as_bytes())
}

fn csv_header(joints: usize, extras: &[String]) -> Vec<String> {
    let mut cells = vec!["name".into(), "mse_mean".into(), "mse_std".into()];
    cells.extend((1..=joints).map(|j| format!("mse_j{j}")));
    cells.extend((1..=joints).map(|j| format!("mse_j{j}_std")));
    cells.extend(extras.iter().cloned());
    cells
}

fn csv_num(v: Option<&f64>) -> String {
    v.map(f64::to_string).unwrap_or_default()
}

fn csv_row(row: &ComparisonRow, joints: usize, extras: &[String]) -> Vec<String> {
    let mut cells = vec![
        row.name.clone(),
        row.mse_mean.to_string(),
        row.mse_std.to_string(),
    ];
    cells.extend((0..joints).map(|j| csv_num(row.mse_per_joint.get(j))));
    cells.extend((0..joints).map(|j| csv_num(row.mse_per_joint_std.get(j))));
    cells.extend(
        extras
            .iter()
            .map(|k| row.extra_value(k).unwrap_or("").into()),
    );
    cells
}

/// Renders the comparison as CSV bytes (see [`write_csv`] for the columns).
pub fn to_csv(cmp: &Comparison) -> Result<Vec<u8>, csv::Error> {
    let joints = cmp.joint_count();
    let extras = cmp.extra_columns();
    let mut writer = csv::Writer::from_writer(Vec::new());
    writer.write_record(csv_header(joints, &extras))?;
    for row in &cmp.rows {
        writer.write_record(csv_row(row, joints, &extras))?;
    }
    writer
        .into_inner()
        .map_err(|e| csv::Error::from(e.into_error()))
}

/// Writes a machine-readable CSV to `path` atomically: one row per model,
/// columns `name, mse_mean, mse_std, mse_j1.., mse_j1_std.., <extras>`.
/// Numbers are written with full precision (shortest round-trip form).
pub fn write_csv(path: impl AsRef<Path>, cmp: &Comparison) -> Result<(), ReportError> {
    let path = path.as_ref();
    let bytes = to_csv(cmp).map_err(|source| ReportError::Csv {
        path: path.to_path_buf(),
        source,
    })?;
    write_atomic(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn row(name: &str, mean: f64, std: f64, joints: &[f64]) -> ComparisonRow {
        ComparisonRow {
            name: name.into(),
            mse_mean: mean,
            mse_std: std,
            mse_per_joint: joints.to_vec(),
            mse_per_joint_std: joints.iter().map(|j| j / 10.0).collect(),
            extra: vec![],
        }
    }

    fn thesis_table() -> Comparison {
        let mut sdnn = row(
            "NN trained on Synthesized-Data (SDNN)",
            2.1442,
            0.1159,
            &[1.0, 3.0, 2.4],
        );
        sdnn.extra.push(("epochs".into(), "200".into()));
        Comparison {
            title: "Averaged MSE vs experimental data".into(),
            unit: "(N·m)²".into(),
            rows: vec![
                row(
                    "Analytical Model (Euler-Lagrange)",
                    2.8054,
                    0.0,
                    &[2.0, 3.5, 2.9],
                ),
                row(
                    "NN trained on Experimental Data only",
                    3.0521,
                    0.4235,
                    &[2.5, 4.0, 2.6],
                ),
                sdnn,
            ],
        }
    }

    #[test]
    fn format_sig_cases() {
        assert_eq!(format_sig(2.8054), "2.805");
        assert_eq!(format_sig(0.4235), "0.4235");
        assert_eq!(format_sig(0.0), "0");
        assert_eq!(format_sig(123.456), "123.5");
        assert_eq!(format_sig(0.001), "0.001000");
        assert_eq!(format_sig(0.000_123_45), "1.234e-4");
        assert_eq!(format_sig(12345.0), "1.234e4");
        assert_eq!(format_sig(9999.6), "1.000e4");
        assert_eq!(format_sig(-0.5), "-0.5000");
        assert_eq!(format_sig(f64::NAN), "NaN");
        assert_eq!(format_sig(f64::NEG_INFINITY), "-inf");
    }

    #[test]
    fn markdown_has_all_columns() {
        let md = to_markdown(&thesis_table());
        let lines: Vec<&str> = md.lines().collect();
        assert_eq!(lines[0], "**Averaged MSE vs experimental data**");
        assert!(lines[2].contains("| Model | MSE [(N·m)²] | J1 MSE"));
        assert!(lines[2].ends_with("| J3 MSE [(N·m)²] | epochs |"));
        assert!(md.contains("| 2.805 ± 0 |"));
        assert!(md.contains("| 2.144 ± 0.1159 |"));
        assert!(md.contains("| 200 |"));
        assert_eq!(lines.len(), 2 + 2 + 3);
    }

    #[test]
    fn markdown_escapes_pipes_and_fills_missing() {
        let cmp = Comparison {
            title: String::new(),
            unit: String::new(),
            rows: vec![row("a|b", 1.0, f64::NAN, &[]), row("c", 1.0, 0.1, &[0.5])],
        };
        let md = to_markdown(&cmp);
        assert!(md.starts_with("| Model | MSE | J1 MSE |"));
        assert!(md.contains("| a\\|b | 1.000 ± NaN | – |"));
    }

    #[test]
    fn empty_table_is_just_a_header() {
        let md = to_markdown(&Comparison::default());
        assert_eq!(md, "| Model | MSE |\n| :--- | ---: |\n");
    }

    #[test]
    fn csv_columns_and_roundtrip_values() {
        let bytes = to_csv(&thesis_table()).unwrap();
        let text = String::from_utf8(bytes).unwrap();
        let mut lines = text.lines();
        assert_eq!(
            lines.next().unwrap(),
            "name,mse_mean,mse_std,mse_j1,mse_j2,mse_j3,mse_j1_std,mse_j2_std,mse_j3_std,epochs"
        );
        assert_eq!(
            lines.nth(2).unwrap(),
            "NN trained on Synthesized-Data (SDNN),2.1442,0.1159,1,3,2.4,0.1,0.3,0.24,200"
        );
    }

    #[test]
    fn write_files_atomically() {
        let dir = tempfile::tempdir().unwrap();
        let csv_path = dir.path().join("t.csv");
        let md_path = dir.path().join("t.md");
        write_csv(&csv_path, &thesis_table()).unwrap();
        write_markdown(&md_path, &thesis_table()).unwrap();
        let mut reader = csv::Reader::from_path(&csv_path).unwrap();
        assert_eq!(reader.records().count(), 3);
        assert!(std::fs::read_to_string(&md_path).unwrap().contains("SDNN"));
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
    }

    #[test]
    fn write_error_names_path() {
        let err = write_csv("/nonexistent-dir/x/table.csv", &thesis_table()).unwrap_err();
        assert!(err.to_string().contains("/nonexistent-dir/x/table.csv"));
    }

    #[test]
    fn serde_roundtrip() {
        let cmp = thesis_table();
        let json = serde_json::to_string(&cmp).unwrap();
        let back: Comparison = serde_json::from_str(&json).unwrap();
        assert_eq!(back, cmp);
    }

    fn any_row() -> impl Strategy<Value = ComparisonRow> {
        let num = prop_oneof![any::<f64>(), -1e6..1e6f64];
        (
            ".{0,12}",
            num.clone(),
            num.clone(),
            prop::collection::vec(num.clone(), 0..5),
            prop::collection::vec(num, 0..5),
            prop::collection::vec(("[a-c|]{1,3}", ".{0,5}"), 0..3),
        )
            .prop_map(|(name, m, s, j, js, extra)| ComparisonRow {
                name,
                mse_mean: m,
                mse_std: s,
                mse_per_joint: j,
                mse_per_joint_std: js,
                extra,
            })
    }

    proptest! {
        #[test]
        fn markdown_rows_have_equal_cell_counts(rows in prop::collection::vec(any_row(), 0..5)) {
            let cmp = Comparison { title: String::new(), unit: String::new(), rows };
            let md = to_markdown(&cmp);
            let cells = |l: &str| l.replace("\\|", "").matches('|').count();
            let lines: Vec<&str> = md.lines().collect();
            prop_assert_eq!(lines.len(), cmp.rows.len() + 2);
            for l in &lines {
                prop_assert_eq!(cells(l), cells(lines[0]));
            }
            prop_assert!(to_csv(&cmp).is_ok());
        }

        #[test]
        fn format_sig_keeps_four_digits(x in -1e12..1e12f64) {
            let parsed: f64 = format_sig(x).parse().unwrap();
            prop_assert!((parsed - x).abs() <= x.abs() * 5e-4 + 1e-300);
        }
    }
}
