//! What `sdnn excite` reports: the designed motion against the default
//! recording (condition number, each parameter's predicted standard
//! deviation), the limits it uses, the settings; and a plot of the motion.

use std::fmt::Write;
use std::path::Path;

use anyhow::Result;
use serde_json::{Value, json};

use super::Design;
use crate::report::plot::{LinePlot, Series, grid_plot};
use crate::report::table::format_sig as sig;

/// The Markdown report (also printed).
pub fn markdown(d: &Design, model: &str, default_label: &str) -> String {
    let c = &d.config;
    let mut s = String::new();
    let _ = writeln!(s, "# Designed excitation for `{model}`\n");
    let _ = writeln!(
        s,
        "{} s at {} Hz: a rest of {} s at each end and between them {} harmonics of {} Hz per \
         joint ({} whole periods{}), each joint pausing {} s while the others move; seed {}, \
         {} motions evaluated.\n",
        sig(c.duration),
        sig(c.rate),
        sig(c.rest),
        c.harmonics,
        sig(d.schedule.base_hz()),
        (d.schedule.moving() * d.schedule.base_hz()).round(),
        c.base_hz
            .map_or(String::new(), |hz| format!("; asked: {} Hz", sig(hz))),
        sig(c.pause),
        c.seed,
        d.evaluations
    );
    let ratio = d.default.condition_number / d.designed.condition_number;
    let _ = writeln!(s, "| | designed | {default_label} |\n|---|---|---|");
    let _ = writeln!(
        s,
        "| condition number | {} | {} ({}x the designed) |",
        sig(d.designed.condition_number),
        sig(d.default.condition_number),
        sig(ratio)
    );
    let _ = writeln!(
        s,
        "The default recording is the median by condition number of the first {} random-waypoint \
         recordings of `sdnn simulate` (their condition numbers: {} to {}).\n",
        d.defaults,
        sig(d.default_range.0),
        sig(d.default_range.1)
    );
    let _ = writeln!(
        s,
        "| fixed-scale condition number | {} | {} ({}x the designed) |\n",
        sig(d.designed.condition_number_fixed),
        sig(d.default.condition_number_fixed),
        sig(d.default.condition_number_fixed / d.designed.condition_number_fixed)
    );
    let _ = writeln!(
        s,
        "The condition number is that of the information matrix of the model's {} base \
         parameters (the regressor's inertial columns and each joint's armature, viscous and \
         Coulomb friction, offset and direction-dependent friction, regrouped where only their \
         combination acts), scaled to a unit diagonal: 1 when the motion tells every base \
         parameter from every other.\n",
        d.parameters.len()
    );
    if !d.weighted.is_empty() {
        let _ = writeln!(
            s,
            "Weighted from the diagnosis: {}.\n",
            d.weighted.join(", ")
        );
    }
    stds(&mut s, d, default_label);
    usage(&mut s, d);
    s
}

fn stds(s: &mut String, d: &Design, default_label: &str) {
    let _ = writeln!(
        s,
        "Predicted standard deviation of each base parameter (SI units) for white torque \
         noise of {} N m per sample at {} Hz:\n\n| base parameter | designed | {default_label} | stands for |\n|---|---|---|---|",
        sig(d.config.noise),
        sig(d.config.rate)
    );
    let show = |v: Option<f64>| v.map_or("not determined".to_string(), sig);
    for (k, name) in d.parameters.iter().enumerate() {
        let _ = writeln!(
            s,
            "| {name} | {} | {} | {} |",
            show(d.designed.std[k]),
            show(d.default.std[k]),
            stands_for(name, &d.regrouped[k])
        );
    }
    let _ = writeln!(s);
}

/// `izz1 + armature1 - 0.5 m2`.
pub fn stands_for(name: &str, regrouped: &[(String, f64)]) -> String {
    let mut text = name.to_string();
    for (other, b) in regrouped {
        let sign = if *b < 0.0 { '-' } else { '+' };
        if (b.abs() - 1.0).abs() < 1e-9 {
            let _ = write!(text, " {sign} {other}");
        } else {
            let _ = write!(text, " {sign} {} {other}", sig(b.abs()));
        }
    }
    text
}

fn usage(s: &mut String, d: &Design) {
    let _ = writeln!(
        s,
        "Largest share of each limit used (position: of the half range about its middle; torque: \
         the model's torque against the effort limit, at most {}% by design):\n\n\
         | joint | position | velocity | acceleration | torque |\n|---|---|---|---|---|",
        sig(100.0 * d.config.torque_share)
    );
    for (j, u) in d.usage.iter().enumerate() {
        let torque = u
            .torque
            .map_or("no limit".to_string(), |t| format!("{:.0}%", 100.0 * t));
        let _ = writeln!(
            s,
            "| {} | {:.0}% | {:.0}% | {:.0}% | {torque} |",
            j + 1,
            100.0 * u.position,
            100.0 * u.velocity,
            100.0 * u.acceleration
        );
    }
}

/// The JSON report (`--format json`).
pub fn json(d: &Design, model: &str, trajectory: &Path) -> Value {
    let c = &d.config;
    let parameters: Vec<Value> = d
        .parameters
        .iter()
        .enumerate()
        .map(|(k, n)| json!({"name": n, "stands_for": stands_for(n, &d.regrouped[k]), "std_designed": d.designed.std[k], "std_default": d.default.std[k]}))
        .collect();
    let usage: Vec<Value> = d
        .usage
        .iter()
        .map(|u| json!({"position": u.position, "velocity": u.velocity, "acceleration": u.acceleration, "torque": u.torque}))
        .collect();
    json!({
        "model": model,
        "trajectory": trajectory.display().to_string(),
        "duration": c.duration, "rate": c.rate, "rest": c.rest, "pause": c.pause, "harmonics": c.harmonics,
        "base_hz": d.schedule.base_hz(), "seed": c.seed, "torque_share": c.torque_share,
        "noise": c.noise, "evaluations": d.evaluations,
        "condition_number": d.designed.condition_number,
        "condition_number_default": d.default.condition_number,
        "weighted": d.weighted,
        "parameters": parameters,
        "usage": usage,
    })
}

/// One panel per joint: its position and velocity over time.
pub fn plot(d: &Design, path: &Path, model: &str, levers: &[f64]) -> Result<()> {
    let traj = &d.trajectory;
    let panels: Vec<LinePlot> = (0..traj.dof())
        .map(|j| {
            let linear = levers.get(j).is_some_and(|&l| l != 1.0);
            let (q, v) = if linear {
                ("q (m)", "qd (m/s)")
            } else {
                ("q (rad)", "qd (rad/s)")
            };
            LinePlot {
                title: format!("joint {}", j + 1),
                x_label: "t (s)".into(),
                y_label: format!("{q}, {v}"),
                series: vec![
                    Series {
                        name: q.into(),
                        x: traj.t().to_vec(),
                        y: traj.q().column(j).iter().copied().collect(),
                        ..Default::default()
                    },
                    Series {
                        name: v.into(),
                        x: traj.t().to_vec(),
                        y: traj.qd().column(j).iter().copied().collect(),
                        ..Default::default()
                    },
                ],
                log_y: false,
            }
        })
        .collect();
    grid_plot(path, &format!("Designed excitation for {model}"), &panels)?;
    Ok(())
}
