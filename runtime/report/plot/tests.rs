//! Tests of the public plotting functions: files exist, are SVG, contain the
//! texts, and bad input gives the documented errors.

use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use proptest::prelude::*;

use super::*;

fn out(dir: &tempfile::TempDir, name: &str) -> PathBuf {
    dir.path().join(name)
}

fn read_svg(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap();
    assert!(
        text.starts_with("<svg") || text.starts_with("<?xml"),
        "not SVG: {}",
        &text[..40.min(text.len())]
    );
    assert!(text.trim_end().ends_with("</svg>"));
    text
}

/// The trimmed contents of every `<text>` element.
fn svg_texts(svg: &str) -> Vec<String> {
    svg.split("<text")
        .skip(1)
        .filter_map(|t| {
            Some(
                t.split_once('>')?
                    .1
                    .split_once("</text>")?
                    .0
                    .trim()
                    .to_string(),
            )
        })
        .collect()
}

fn assert_texts(svg: &str, wanted: &[&str]) {
    let texts = svg_texts(svg);
    for w in wanted {
        assert!(
            texts.iter().any(|t| t == w),
            "missing text {w:?} in {texts:?}"
        );
    }
}

fn line(name: &str, x: Vec<f64>, y: Vec<f64>) -> Series {
    Series {
        name: name.into(),
        x,
        y,
        style: Style::Line,
    }
}

fn velocity_plot() -> LinePlot {
    let t: Vec<f64> = (0..500).map(|i| f64::from(i) * 0.01).collect();
    let raw: Vec<f64> = t
        .iter()
        .enumerate()
        .map(|(i, t)| (2.0 * PI * t).sin() + 0.2 * ((i * 7919 % 13) as f64 / 13.0 - 0.5))
        .collect();
    let filtered: Vec<f64> = t.iter().map(|t| (2.0 * PI * t).sin()).collect();
    LinePlot {
        title: "Joint 2 velocity: raw vs SMA-filtered".into(),
        x_label: "time [s]".into(),
        y_label: "velocity [rad/s]".into(),
        series: vec![
            Series {
                name: "raw".into(),
                x: t.clone(),
                y: raw,
                style: Style::Points,
            },
            line("filtered", t, filtered),
        ],
        log_y: false,
    }
}

fn bar() -> BarChart {
    BarChart {
        title: "MSE per joint".into(),
        y_label: "MSE [(N·m)²]".into(),
        groups: vec!["J1".into(), "J2".into(), "J3".into(), "mean".into()],
        bars: vec![
            (
                "Analytical".into(),
                vec![2.0, 3.5, 2.9, 2.8],
                Some(vec![0.0; 4]),
            ),
            (
                "NN exp".into(),
                vec![2.5, 4.0, 2.6, 3.05],
                Some(vec![0.3, 0.5, 0.4, 0.42]),
            ),
            ("SDNN".into(), vec![1.0, 3.0, 2.4, 2.14], None),
        ],
    }
}

#[test]
fn line_plot_writes_svg_with_texts() {
    let dir = tempfile::tempdir().unwrap();
    let path = out(&dir, "vel.svg");
    let report = line_plot(&path, &velocity_plot()).unwrap();
    let svg = read_svg(&path);
    assert_texts(
        &svg,
        &[
            "Joint 2 velocity: raw vs SMA-filtered",
            "time [s]",
            "velocity [rad/s]",
            "raw",
            "filtered",
        ],
    );
    assert_eq!(
        report,
        PlotReport {
            points_drawn: 1000,
            points_skipped: 0,
            decimated_series: vec![]
        }
    );
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        1,
        "temp file left behind"
    );
}

#[test]
fn training_curve_log_y_skips_non_positive_and_nan() {
    let dir = tempfile::tempdir().unwrap();
    let path = out(&dir, "train.svg");
    let epochs: Vec<f64> = (1..=100).map(f64::from).collect();
    let mut loss: Vec<f64> = epochs.iter().map(|e| 10.0 / e).collect();
    loss[3] = f64::NAN;
    loss[4] = 0.0;
    let plot = LinePlot {
        title: "Training curve".into(),
        x_label: "epoch".into(),
        y_label: "loss (MSE)".into(),
        series: vec![
            line("train", epochs.clone(), loss),
            line(
                "validation",
                epochs.clone(),
                epochs.iter().map(|e| 12.0 / e).collect(),
            ),
        ],
        log_y: true,
    };
    let report = line_plot(&path, &plot).unwrap();
    assert_eq!(report.points_skipped, 2);
    assert_eq!(report.points_drawn, 198);
    let svg = read_svg(&path);
    assert_texts(
        &svg,
        &[
            "loss (MSE)",
            "Training curve",
            "epoch",
            "train",
            "validation",
        ],
    );
}

#[test]
fn grid_plot_stacks_panels() {
    let dir = tempfile::tempdir().unwrap();
    let path = out(&dir, "torque.svg");
    let t: Vec<f64> = (0..200).map(f64::from).collect();
    let panels: Vec<LinePlot> = (1..=3)
        .map(|j| LinePlot {
            title: format!("Joint {j}"),
            x_label: "sample".into(),
            y_label: format!("torque J{j} [N·m]"),
            series: vec![
                line(
                    "measured",
                    t.clone(),
                    t.iter().map(|v| (v / 20.0).sin() * f64::from(j)).collect(),
                ),
                line(
                    "predicted",
                    t.clone(),
                    t.iter()
                        .map(|v| (v / 20.0 + 0.1).sin() * f64::from(j))
                        .collect(),
                ),
            ],
            log_y: false,
        })
        .collect();
    let report = grid_plot(&path, "Measured vs predicted torque", &panels).unwrap();
    assert_eq!(report.points_drawn, 1200);
    let svg = read_svg(&path);
    assert_texts(
        &svg,
        &[
            "Measured vs predicted torque",
            "Joint 1",
            "Joint 3",
            "torque J2 [N·m]",
            "sample",
            "predicted",
        ],
    );
}

#[test]
fn bar_chart_writes_svg_with_groups_and_legend() {
    let dir = tempfile::tempdir().unwrap();
    let path = out(&dir, "mse.svg");
    let report = bar_chart(&path, &bar()).unwrap();
    assert_eq!(report.points_drawn, 12);
    let svg = read_svg(&path);
    assert_texts(
        &svg,
        &[
            "MSE per joint",
            "MSE [(N·m)²]",
            "J1",
            "J2",
            "J3",
            "mean",
            "Analytical",
            "SDNN",
            "NN exp",
        ],
    );
}

#[test]
fn tick_labels_drop_trailing_zeros() {
    assert_eq!(draw::tick_label(0.5), "0.5");
    assert_eq!(draw::tick_label(10.0), "10");
    assert_eq!(draw::tick_label(0.0), "0");
    assert_eq!(draw::tick_label(1e-4), "1e-4");
    assert_eq!(draw::tick_label(2.5e6), "2.5e6");
    assert_eq!(draw::tick_label(1234.0), "1234");
    assert_eq!(draw::axis_tick(-2.220446049250313e-16, &(-1.0..1.0)), "0");
    assert_eq!(draw::axis_tick(1e-12, &(0.0..1e-11)), "1e-12");
}

#[test]
fn text_is_escaped() {
    let dir = tempfile::tempdir().unwrap();
    let path = out(&dir, "esc.svg");
    let mut plot = velocity_plot();
    plot.title = "a < b & c".into();
    line_plot(&path, &plot).unwrap();
    assert_texts(&read_svg(&path), &["a &lt; b &amp; c"]);
}

#[test]
fn big_series_is_decimated_and_file_stays_small() {
    let dir = tempfile::tempdir().unwrap();
    let path = out(&dir, "big.svg");
    let x: Vec<f64> = (0..200_000).map(f64::from).collect();
    let y: Vec<f64> = x
        .iter()
        .map(|v| (v * 0.001).sin() + ((v * 12.9898).sin() * 0.1))
        .collect();
    let plot = LinePlot {
        series: vec![line("raw", x, y)],
        ..velocity_plot()
    };
    let report = line_plot(&path, &plot).unwrap();
    assert_eq!(report.decimated_series, vec!["raw".to_string()]);
    assert!(report.points_drawn <= MAX_POINTS);
    assert!(std::fs::metadata(&path).unwrap().len() < 400_000);
}

#[test]
fn mismatched_lengths_error_names_series_and_path() {
    let dir = tempfile::tempdir().unwrap();
    let path = out(&dir, "bad.svg");
    let mut plot = velocity_plot();
    plot.series[1].y.pop();
    let err = line_plot(&path, &plot).unwrap_err();
    let ReportError::Input { problem, .. } = &err else {
        panic!("{err}")
    };
    assert_eq!(
        problem,
        &InputError::LengthMismatch {
            series: "filtered".into(),
            x_len: 500,
            y_len: 499
        }
    );
    assert!(err.to_string().contains("bad.svg"));
    assert!(!path.exists());
}

#[test]
fn empty_inputs_are_documented_errors() {
    let dir = tempfile::tempdir().unwrap();
    let path = out(&dir, "empty.svg");
    let problem = |e: ReportError| match e {
        ReportError::Input { problem, .. } => problem,
        other => panic!("{other}"),
    };
    let empty = LinePlot::default();
    assert_eq!(
        problem(line_plot(&path, &empty).unwrap_err()),
        InputError::NoSeries
    );
    let nan = LinePlot {
        series: vec![
            line("n", vec![1.0], vec![f64::NAN]),
            line("e", vec![], vec![]),
        ],
        ..empty
    };
    assert_eq!(
        problem(line_plot(&path, &nan).unwrap_err()),
        InputError::NothingToDraw
    );
    assert_eq!(
        problem(grid_plot(&path, "t", &[]).unwrap_err()),
        InputError::NoPanels
    );
    assert_eq!(
        problem(grid_plot(&path, "t", &[velocity_plot(), nan]).unwrap_err()),
        InputError::NothingToDraw
    );
    let no_groups = BarChart {
        groups: vec![],
        ..bar()
    };
    assert_eq!(
        problem(bar_chart(&path, &no_groups).unwrap_err()),
        InputError::NoGroups
    );
    assert!(!path.exists());
}

#[test]
fn empty_series_beside_data_is_allowed() {
    let dir = tempfile::tempdir().unwrap();
    let path = out(&dir, "partial.svg");
    let mut plot = velocity_plot();
    plot.series.push(line("nothing yet", vec![], vec![]));
    line_plot(&path, &plot).unwrap();
    assert_texts(&read_svg(&path), &["nothing yet"]);
}

#[test]
fn unwritable_path_is_io_error() {
    let err = line_plot("/nonexistent-dir/plot.svg", &velocity_plot()).unwrap_err();
    assert!(matches!(err, ReportError::Io { .. }));
    assert!(err.to_string().contains("/nonexistent-dir/plot.svg"));
}

fn value() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => -1e3..1e3f64,
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(0.0),
        1 => any::<f64>(),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn line_plot_never_panics(
        ys in prop::collection::vec(value(), 0..40),
        xs in prop::collection::vec(value(), 0..40),
        log_y in any::<bool>(),
    ) {
        let dir = tempfile::tempdir().unwrap();
        let path = out(&dir, "p.svg");
        let n = xs.len().min(ys.len());
        let plot = LinePlot {
            series: vec![line("a", xs[..n].to_vec(), ys[..n].to_vec())],
            log_y,
            ..velocity_plot()
        };
        match line_plot(&path, &plot) {
            Ok(r) => {
                prop_assert_eq!(r.points_drawn + r.points_skipped, n);
                read_svg(&path);
            }
            Err(e) => { let ok = matches!(e, ReportError::Input { problem: InputError::NothingToDraw, .. }); prop_assert!(ok, "{}", e); }
        }
    }

    #[test]
    fn narrow_and_huge_ranges_render(
        base in prop_oneof![-1e100..1e100f64, -10.0..10.0f64, Just(0.0)],
        rel in prop_oneof![Just(0.0), 1e-17..1e-6f64, 1e-3..1.0f64],
        n in 1usize..6,
        log_y in any::<bool>(),
    ) {
        let dir = tempfile::tempdir().unwrap();
        let path = out(&dir, "n.svg");
        let v: Vec<f64> = (0..n).map(|i| base + base.abs() * rel * i as f64).collect();
        let plot = LinePlot { series: vec![line("a", v.clone(), v)], log_y, ..velocity_plot() };
        match line_plot(&path, &plot) {
            Ok(_) => { read_svg(&path); }
            Err(e) => { let ok = matches!(e, ReportError::Input { problem: InputError::NothingToDraw, .. }); prop_assert!(ok, "{}", e); }
        }
    }

    #[test]
    fn bar_chart_never_panics(values in prop::collection::vec(value(), 3), errs in prop::collection::vec(value(), 3)) {
        let dir = tempfile::tempdir().unwrap();
        let path = out(&dir, "b.svg");
        let chart = BarChart {
            groups: vec!["a".into(), "b".into(), "c".into()],
            bars: vec![("m".into(), values, Some(errs))],
            ..bar()
        };
        match bar_chart(&path, &chart) {
            Ok(_) => { read_svg(&path); }
            Err(e) => { let ok = matches!(e, ReportError::Input { problem: InputError::NothingToDraw, .. }); prop_assert!(ok, "{}", e); }
        }
    }
}
