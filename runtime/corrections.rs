//! Corrections of a recording's torque that `sdnn diagnose` reports as
//! properties of the data, not of the robot: a joint's torque sensor scale
//! (`--torque-scale J=S`) and a delay between the logged torque and the
//! logged state (`--torque-delay SECONDS`). Every command that reads
//! recordings applies them right after reading.

use anyhow::{Result, bail};
use nalgebra::DMatrix;

use crate::trajectory::Trajectory;

/// Largest delay accepted, s: a torque logged a second late is a
/// different recording, not a delay.
pub const MAX_DELAY: f64 = 1.0;

/// The corrections of one set of recordings.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Corrections {
    /// 1-based joint and the scale its logged torque is divided by.
    pub scales: Vec<(usize, f64)>,
    /// Seconds the torque is logged after its state.
    pub delay: f64,
}

impl Corrections {
    /// The data corrections a diagnosis reports.
    pub fn diagnosed(diagnosis: &crate::diagnose::Diagnosis) -> Corrections {
        Corrections::named(&diagnosis.effects)
    }

    /// The data corrections among named effects.
    pub fn named(effects: &[crate::diagnose::Effect]) -> Corrections {
        use crate::diagnose::Kind;
        let mut out = Corrections::default();
        for e in effects {
            let value = |name: &str| e.parameters.get(name).and_then(|v| v.as_f64());
            match (e.kind, e.joint, value("scale"), value("delay")) {
                (Kind::TorqueScale, Some(j), Some(scale), _) => out.scales.push((j, scale)),
                (Kind::TorqueDelay, _, _, Some(delay)) => out.delay += delay,
                _ => {}
            }
        }
        out
    }

    /// These corrections followed by `next` (found on data already
    /// corrected by these): scales multiply, delays add.
    pub fn then(&self, next: &Corrections) -> Corrections {
        let mut scales = self.scales.clone();
        for &(joint, scale) in &next.scales {
            match scales.iter_mut().find(|(j, _)| *j == joint) {
                Some((_, s)) => *s *= scale,
                None => scales.push((joint, scale)),
            }
        }
        scales.sort_by_key(|&(j, _)| j);
        Corrections {
            scales,
            delay: self.delay + next.delay,
        }
    }

    /// The command-line options that apply them.
    pub fn flags(&self) -> String {
        let mut flags: String = self
            .scales
            .iter()
            .map(|(j, s)| format!(" --torque-scale {j}={s:.4}"))
            .collect();
        if self.delay != 0.0 {
            flags.push_str(&format!(" --torque-delay {:.5}", self.delay));
        }
        flags
    }
}

/// Parses `J=S`: a 1-based joint and a positive scale.
pub fn parse_scale(text: &str) -> Result<(usize, f64), String> {
    let expected = || format!("expected JOINT=SCALE (e.g. 2=1.05), found `{text}`");
    let (joint, scale) = text.split_once('=').ok_or_else(expected)?;
    let joint: usize = joint.trim().parse().map_err(|_| expected())?;
    let scale: f64 = scale.trim().parse().map_err(|_| expected())?;
    if joint == 0 {
        return Err(format!("joints are numbered from 1, found `{text}`"));
    }
    if !(scale.is_finite() && (0.1..=10.0).contains(&scale)) {
        return Err(format!(
            "a torque scale must lie between 0.1 and 10, found {scale} (a sensor off by more is \
             a wrong unit: convert the column)"
        ));
    }
    Ok((joint, scale))
}

/// Divides each listed joint's torque by its scale, then moves every torque
/// `delay` s back to the state it belongs to (the logged torque at t +
/// delay becomes the torque at t, by linear interpolation on the uniform
/// time grid); the samples the shift leaves without a torque are dropped.
pub fn correct(traj: &Trajectory, scales: &[(usize, f64)], delay: f64) -> Result<Trajectory> {
    let mut tau = traj.tau().clone();
    for (k, &(joint, scale)) in scales.iter().enumerate() {
        if scales[..k].iter().any(|&(j, _)| j == joint) {
            bail!("--torque-scale is given twice for joint {joint}: give each joint's scale once");
        }
        if joint > traj.dof() {
            bail!(
                "--torque-scale {joint}={scale}: the recording has {} joints",
                traj.dof()
            );
        }
        tau.column_mut(joint - 1).unscale_mut(scale);
    }
    if delay == 0.0 {
        return Ok(traj.with_tau(tau)?);
    }
    let t = traj.t();
    let dt = (t[t.len() - 1] - t[0]) / (t.len() - 1).max(1) as f64;
    let shift = delay / dt;
    let lost = shift.abs().ceil() as usize;
    if lost + 2 > traj.len() {
        bail!(
            "--torque-delay {delay}: the shift of {lost} samples leaves no recording ({} samples)",
            traj.len()
        );
    }
    let shifted = DMatrix::from_fn(tau.nrows(), tau.ncols(), |s, j| {
        let at = (s as f64 + shift).clamp(0.0, (tau.nrows() - 1) as f64);
        let (k, f) = (at.floor() as usize, at.fract());
        let next = (k + 1).min(tau.nrows() - 1);
        (1.0 - f) * tau[(k, j)] + f * tau[(next, j)]
    });
    let corrected = traj.with_tau(shifted)?;
    let keep = traj.len() - lost;
    let start = if delay > 0.0 { 0 } else { lost };
    Ok(corrected.rows(start, keep))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn recording(tau: impl Fn(f64) -> f64) -> Trajectory {
        let n = 200;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 0.01).collect();
        let column = |f: &dyn Fn(f64) -> f64| DMatrix::from_fn(n, 1, |s, _| f(t[s]));
        Trajectory::new(
            t.clone(),
            column(&|x| x.sin()),
            column(&|x| x.cos()),
            None,
            column(&tau),
        )
        .unwrap()
    }

    #[test]
    fn a_delayed_torque_is_moved_back_to_its_state() {
        let truth = |x: f64| 3.0 * x * x + 1.0;
        let delay = 0.035;
        let logged = recording(|x| truth(x - delay));
        let fixed = correct(&logged, &[], delay).unwrap();
        assert_eq!(fixed.len(), logged.len() - 4);
        for (s, &x) in fixed.t().iter().enumerate() {
            // Linear interpolation of a parabola: error <= 3 * dt^2 / 4.
            assert!((fixed.tau()[(s, 0)] - truth(x)).abs() < 1e-3, "at {x}");
        }
        let early = correct(&recording(|x| truth(x + delay)), &[], -delay).unwrap();
        assert!((early.t()[0] - 0.04).abs() < 1e-12);
        assert!((early.tau()[(0, 0)] - truth(0.04)).abs() < 1e-3);
    }

    #[test]
    fn a_scaled_joint_is_divided_and_bad_scales_are_refused() {
        let fixed = correct(&recording(|x| 2.0 * x), &[(1, 2.0)], 0.0).unwrap();
        assert!((fixed.tau()[(50, 0)] - fixed.t()[50]).abs() < 1e-12);
        assert!(correct(&recording(|x| x), &[(2, 1.1)], 0.0).is_err());
        assert_eq!(parse_scale("2=1.05"), Ok((2, 1.05)));
        for bad in ["0=1.0", "2", "x=1", "1=0", "1=nan", "1=100"] {
            assert!(parse_scale(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn corrections_compose_and_print_as_options() {
        let first = Corrections {
            scales: vec![(2, 1.1)],
            delay: 0.01,
        };
        let next = Corrections {
            scales: vec![(2, 1.02), (1, 0.9)],
            delay: -0.002,
        };
        let both = first.then(&next);
        assert_eq!(
            both.flags(),
            " --torque-scale 1=0.9000 --torque-scale 2=1.1220 --torque-delay 0.00800"
        );
        assert_eq!(Corrections::default().flags(), "");
    }

    #[test]
    fn a_delay_longer_than_the_recording_is_refused() {
        assert!(correct(&recording(|x| x), &[], 1.99).is_err());
    }
}
