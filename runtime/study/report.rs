//! The study's results folder: comparison table (Markdown, CSV, JSON),
//! plots (SVG) and the trained networks.

use std::path::Path;

use anyhow::{Context, Result};
use nalgebra::DMatrix;

use super::{ANALYTICAL, IDENTIFIED, ModelResult, StudyResult, slug};
use crate::dynamics::Dynamics;
use crate::dynamics::model_torques;
use crate::mlp::{Dataset, Mlp};
use crate::report::plot::{BarChart, LinePlot, Series, Style, bar_chart, grid_plot};
use crate::report::table::{Comparison, ComparisonRow, to_markdown, write_csv};
use crate::trajectory::Trajectory;

/// What the plots are drawn from.
pub struct Figures<'a> {
    pub raw: &'a [Trajectory],
    pub processed: &'a [Trajectory],
    pub nominal: &'a dyn Dynamics,
    /// Seed-0 network of each trained model.
    pub networks: &'a [(String, &'a Mlp)],
    /// The model whose network predicts the residual of the analytical model.
    pub residual: &'a str,
}

/// The comparison table of a study.
pub fn comparison(result: &StudyResult) -> Comparison {
    let rows = result
        .models
        .iter()
        .map(|m| ComparisonRow {
            name: m.name.clone(),
            mse_mean: m.mse_mean,
            mse_std: m.mse_std,
            mse_per_joint: m.mse_per_joint.clone(),
            mse_per_joint_std: m.mse_per_joint_std.clone(),
            extra: vec![(
                "open-loop q RMS [rad]".into(),
                m.open_loop_rms.map_or("-".into(), |v| format!("{v:.4}")),
            )],
        })
        .collect();
    let title = match result.test_from {
        Some(from) => format!(
            "Test MSE on the part of each of the {} recordings after its first {from} s, {} seeds per network",
            result.test_trajectories.len(),
            result.config.seeds
        ),
        None => simulated_title(result),
    };
    Comparison {
        title,
        unit: "N m^2".into(),
        rows,
    }
}

/// The title of a simulated study: whole held-out trajectories.
fn simulated_title(result: &StudyResult) -> String {
    {
        if result.config.splits > 1 {
            format!(
                "Test MSE on {} held-out trajectories, {} seeds per network x {} train/test splits",
                result.test_trajectories.len(),
                result.config.seeds,
                result.config.splits
            )
        } else {
            format!(
                "Test MSE on {} held-out trajectories, {} seeds per network",
                result.test_trajectories.len(),
                result.config.seeds
            )
        }
    }
}

/// Writes results.{md,csv,json} and the plots below `out`.
pub fn write(result: &StudyResult, figures: &Figures<'_>, out: &Path) -> Result<()> {
    let table = comparison(result);
    let mut markdown = to_markdown(&table);
    if result.models.iter().any(|m| m.open_loop_rms.is_some()) {
        markdown.push_str(&format!(
            "\nopen-loop q RMS [rad]: each model's torques for the planned motion of the first \
             test trajectory, replayed on the plant without feedback for its first {} s (thesis \
             4.3.2); the RMS over joints and samples of the joint angle's distance from the plan \
             (one network per model, seed 0).\n",
            result.config.open_loop_seconds
        ));
    }
    crate::output::write(&out.join("results.md"), markdown.as_bytes())
        .with_context(|| format!("writing {}", out.join("results.md").display()))?;
    write_csv(out.join("results.csv"), &table)?;
    let json = serde_json::to_string_pretty(result)?;
    crate::output::write(&out.join("results.json"), json.as_bytes())
        .with_context(|| format!("writing {}", out.join("results.json").display()))?;
    let plots = out.join("plots");
    std::fs::create_dir_all(&plots)?;
    filter_plot(figures, &plots)?;
    torque_plots(result, figures, &plots)?;
    training_curves(figures, &plots)?;
    mse_bars(result, &plots)?;
    Ok(())
}

/// The table as Markdown, for printing.
pub fn markdown(result: &StudyResult) -> String {
    to_markdown(&comparison(result))
}

fn column(m: &DMatrix<f64>, j: usize) -> Vec<f64> {
    m.column(j).iter().copied().collect()
}

fn series(name: &str, x: &[f64], y: Vec<f64>, style: Style) -> Series {
    Series {
        name: name.into(),
        x: x.to_vec(),
        y,
        style,
    }
}

/// Like thesis Figure 3.1: raw and filtered velocity and acceleration of joint 2.
fn filter_plot(figures: &Figures<'_>, plots: &Path) -> Result<()> {
    let (raw, processed) = (&figures.raw[0], &figures.processed[0]);
    let j = 1.min(raw.dof() - 1);
    let raw_acc =
        crate::preprocess::central_difference(&column(raw.qd(), j), raw.t()[1] - raw.t()[0])?;
    let qdd = processed
        .qdd()
        .context("preprocessed trajectory has accelerations")?;
    let panels = [
        LinePlot {
            title: format!("Joint {} velocity", j + 1),
            x_label: "t [s]".into(),
            y_label: "qd [rad/s]".into(),
            series: vec![
                series(
                    "recorded (1 kHz)",
                    raw.t(),
                    column(raw.qd(), j),
                    Style::Points,
                ),
                series(
                    "filtered (100 Hz)",
                    processed.t(),
                    column(processed.qd(), j),
                    Style::Line,
                ),
            ],
            log_y: false,
        },
        LinePlot {
            title: format!("Joint {} acceleration", j + 1),
            x_label: "t [s]".into(),
            y_label: "qdd [rad/s^2]".into(),
            series: vec![
                series(
                    "difference of recorded velocity",
                    raw.t(),
                    raw_acc,
                    Style::Points,
                ),
                series(
                    "filtered (100 Hz)",
                    processed.t(),
                    column(qdd, j),
                    Style::Line,
                ),
            ],
            log_y: false,
        },
    ];
    grid_plot(
        plots.join("filtering.svg"),
        "Raw vs filtered (trajectory 1)",
        &panels,
    )?;
    Ok(())
}

/// Measured vs predicted torque per joint on the first test trajectory.
fn torque_plots(result: &StudyResult, figures: &Figures<'_>, plots: &Path) -> Result<()> {
    let k = result.test_trajectories[0];
    let traj = &figures.processed[k];
    let analytical = model_torques(figures.nominal, traj)?;
    let inputs = Dataset::from_trajectory(traj, k)?.inputs;
    let mut predictions = vec![("Analytical model".to_string(), analytical.clone())];
    for (name, network) in figures.networks {
        let mut p = network.predict(&inputs)?;
        if name == figures.residual {
            p += &analytical;
        }
        predictions.push((name.clone(), p));
    }
    for (name, predicted) in &predictions {
        let panels: Vec<LinePlot> = (0..traj.dof())
            .map(|j| LinePlot {
                title: format!("Joint {}", j + 1),
                x_label: "t [s]".into(),
                y_label: "tau [N m]".into(),
                series: vec![
                    series("measured", traj.t(), column(traj.tau(), j), Style::Line),
                    series(name, traj.t(), column(predicted, j), Style::Line),
                ],
                log_y: false,
            })
            .collect();
        let title = format!("{name}: test trajectory {}", k + 1);
        grid_plot(
            plots.join(format!("torque_{}.svg", slug(name))),
            &title,
            &panels,
        )?;
    }
    Ok(())
}

/// Training and validation loss in two panels, one colour per network in
/// both (one panel of 16 curves repeated the palette's colours).
fn training_curves(figures: &Figures<'_>, plots: &Path) -> Result<()> {
    let (mut train, mut valid) = (Vec::new(), Vec::new());
    for (name, network) in figures.networks {
        let history = network.history();
        let epochs: Vec<f64> = (1..=history.train_loss().len()).map(|e| e as f64).collect();
        train.push(series(
            name,
            &epochs,
            history.train_loss().to_vec(),
            Style::Line,
        ));
        if !history.valid_loss().is_empty() {
            valid.push(series(
                name,
                &epochs,
                history.valid_loss().to_vec(),
                Style::Line,
            ));
        }
    }
    let panel = |title: &str, series: Vec<Series>| LinePlot {
        title: title.into(),
        x_label: "epoch".into(),
        y_label: "loss".into(),
        series,
        log_y: true,
    };
    let mut panels = vec![panel("training", train)];
    if !valid.is_empty() {
        panels.push(panel("validation", valid));
    }
    grid_plot(
        plots.join("training_curves.svg"),
        "Training curves (seed 0, standardized MSE)",
        &panels,
    )?;
    Ok(())
}

fn mse_bars(result: &StudyResult, plots: &Path) -> Result<()> {
    let joints = result.models.first().map_or(0, |m| m.mse_per_joint.len());
    let mut groups: Vec<String> = (1..=joints).map(|j| format!("joint {j}")).collect();
    groups.push("mean".into());
    // The networks first, in training order, so that each has the colour
    // it has in training_curves.svg (colours follow the series' order);
    // the analytical and identified models, which train nothing, last.
    let trains = |m: &&ModelResult| m.name != ANALYTICAL && m.name != IDENTIFIED;
    let ordered = result
        .models
        .iter()
        .filter(trains)
        .chain(result.models.iter().filter(|m| !trains(m)));
    let bars = ordered
        .map(|m| {
            let mut values = m.mse_per_joint.clone();
            values.push(m.mse_mean);
            let mut errors = m.mse_per_joint_std.clone();
            errors.push(m.mse_std);
            (m.name.clone(), values, Some(errors))
        })
        .collect();
    bar_chart(
        plots.join("mse.svg"),
        &BarChart {
            title: "Test MSE (mean ± std over seeds)".into(),
            y_label: "MSE [N m^2]".into(),
            groups,
            bars,
        },
    )?;
    Ok(())
}

/// Writes the map's table (Markdown), JSON and heat map below `out`.
pub fn write_map(
    cells: &[crate::study::map::Cell],
    config: &crate::study::map::MapConfig,
    out: &Path,
) -> Result<String> {
    use crate::report::plot::{HeatPanel, heat_map};
    use crate::study::map::MAP_MODELS;
    let json = serde_json::json!({ "config": config, "cells": cells });
    crate::output::write(
        &out.join("map.json"),
        serde_json::to_string_pretty(&json)?.as_bytes(),
    )
    .with_context(|| format!("writing {}", out.join("map.json").display()))?;
    let markdown = map_markdown(cells, config);
    crate::output::write(&out.join("map.md"), markdown.as_bytes())
        .with_context(|| format!("writing {}", out.join("map.md").display()))?;
    let panels: Vec<HeatPanel> = config
        .noise_scales
        .iter()
        .map(|&noise| HeatPanel {
            title: format!("sensor noise x{noise}"),
            row_title: "rows: analytical error x thesis's".into(),
            column_title: "columns: training trajectories".into(),
            rows: config.error_scales.iter().map(|e| format!("{e}")).collect(),
            columns: config.train_counts.iter().map(|n| n.to_string()).collect(),
            cells: config
                .error_scales
                .iter()
                .map(|&e| {
                    config
                        .train_counts
                        .iter()
                        .filter_map(|&n| {
                            let cell = cells.iter().find(|c| {
                                c.noise_scale == noise && c.error_scale == e && c.train == n
                            })?;
                            let best = MAP_MODELS.iter().position(|m| *m == cell.best)?;
                            let text = format!("{:.2}", cell.sdnn_over_analytical.mean);
                            Some((best, text))
                        })
                        .collect()
                })
                .collect(),
        })
        .collect();
    heat_map(
        out.join("map.svg"),
        "Best model per cell (colour); SDNN / analytical test MSE (text)",
        &panels,
        &MAP_MODELS,
    )?;
    Ok(markdown)
}

fn map_markdown(
    cells: &[crate::study::map::Cell],
    config: &crate::study::map::MapConfig,
) -> String {
    let spread = |s: &crate::study::map::Spread| format!("{:.3} ± {:.3}", s.mean, s.std);
    let mut text = format!(
        "**When SDNN helps: test MSE (N m^2, mean of joints) and ratios, mean ± std over {} seeds x {} splits**\n\n\
         | noise | error | train | best | analytical | NN measured | SDNN | hybrid | SDNN/analytical | SDNN/NN measured | hybrid/analytical |\n\
         | ---: | ---: | ---: | :--- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n",
        config.seeds, config.splits
    );
    for c in cells {
        text.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
            c.noise_scale,
            c.error_scale,
            c.train,
            c.best,
            spread(&c.analytical),
            spread(&c.nn_measured),
            spread(&c.sdnn),
            spread(&c.hybrid),
            spread(&c.sdnn_over_analytical),
            spread(&c.sdnn_over_nn_measured),
            spread(&c.hybrid_over_analytical),
        ));
    }
    text
}
