//! Plots of a diagnosis: each joint's residual against its velocity and its
//! acceleration, with the nominal model and with the named effects added.
//! A missing effect shows as structure in the "before" cloud (a step at zero
//! velocity for Coulomb friction, a slope for viscous friction or armature)
//! that the "after" cloud no longer has.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use super::diagnosis::{Diagnosis, ResidualSamples};
use crate::report::plot::{LinePlot, Series, Style, grid_plot};

/// Writes `residual_vs_velocity.svg` and `residual_vs_acceleration.svg` into
/// `dir` (created if needed) and returns their paths.
pub fn write(dir: &Path, diagnosis: &Diagnosis) -> Result<Vec<PathBuf>> {
    crate::output::create_folder(dir).with_context(|| format!("creating {}", dir.display()))?;
    let samples = &diagnosis.residuals;
    let mut written = Vec::new();
    for (file, what, unit, x) in [
        (
            "residual_vs_velocity.svg",
            "velocity",
            "qd [rad/s]",
            &samples.qd,
        ),
        (
            "residual_vs_acceleration.svg",
            "acceleration",
            "qdd [rad/s^2]",
            &samples.qdd,
        ),
    ] {
        let panels: Vec<LinePlot> = (0..samples.dof)
            .map(|j| LinePlot {
                title: format!("Joint {}", j + 1),
                x_label: unit.into(),
                y_label: "tau_measured - tau_model [N m]".into(),
                series: vec![
                    scatter("nominal model", samples, x, &samples.before, j),
                    scatter("with the named effects", samples, x, &samples.after, j),
                ],
                log_y: false,
            })
            .collect();
        let path = dir.join(file);
        let title = format!("{}: residual vs joint {what}", diagnosis.model);
        grid_plot(&path, &title, &panels)?;
        written.push(path);
    }
    Ok(written)
}

/// Joint j's points sorted by x, so the plot's decimation keeps each x
/// interval's extremes (the residual's envelope along x).
fn scatter(name: &str, samples: &ResidualSamples, x: &[f64], y: &[f64], j: usize) -> Series {
    let mut points: Vec<(f64, f64)> = (j..x.len())
        .step_by(samples.dof.max(1))
        .map(|r| (x[r], y[r]))
        .collect();
    points.sort_by(|a, b| a.0.total_cmp(&b.0));
    Series {
        name: name.into(),
        x: points.iter().map(|p| p.0).collect(),
        y: points.iter().map(|p| p.1).collect(),
        style: Style::Points,
    }
}
