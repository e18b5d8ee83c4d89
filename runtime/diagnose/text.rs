//! The diagnosis as text a person reads: the same kind names as the JSON,
//! numbers to three significant digits, each effect's share of its joint's
//! held-out MSE.

use std::fmt::Write;

use super::diagnosis::{Diagnosis, Effect};
use super::digits::sig;
use super::kind::Kind;

impl Diagnosis {
    /// The text report (`sdnn diagnose` without `--format json`).
    pub fn text(&self) -> String {
        let mut out = String::new();
        let l = &self.layout;
        let _ = writeln!(
            out,
            "model {}: {} samples in {} cross-validation segments of {} s",
            self.model,
            self.samples,
            l.segments,
            sig(l.segment_seconds)
        );
        let _ = writeln!(out, "{}", self.preprocessing.summary());
        if !self.sanity.findings.is_empty() {
            let _ = writeln!(
                out,
                "the sanity checks failed (diagnosed anyway, --no-sanity-gate): what follows may \
                 explain a data error as physics:"
            );
            for finding in &self.sanity.findings {
                let _ = writeln!(out, "  - {}", finding.message);
            }
        }
        for j in 0..self.mse_before.len() {
            let (before, after) = (self.mse_before[j], self.mse_after[j]);
            let torque = self.torque_unit(j + 1);
            let _ = writeln!(
                out,
                "joint {}: residual RMS {} {torque} ({:.1}% of the torque RMS); held-out MSE {} -> {} {torque}^2 ({})",
                j + 1,
                sig(self.residual_rms[j]),
                100.0 * self.residual_share[j],
                sig(before),
                sig(after),
                percent_change(before, after)
            );
            let fitted = self.mse_after_fitted[j];
            if fitted < 0.8 * after {
                let _ = writeln!(
                    out,
                    "  {} {torque}^2 ({}) with Coulomb friction zero while the joint is at rest: it \
                     sticks, and there the model's sign(qd) term follows velocity noise",
                    sig(fitted),
                    percent_change(before, fitted)
                );
            }
            let r = &self.regimes[j];
            let _ = writeln!(
                out,
                "  residual correlates with velocity {:+.2}, its sign {:+.2}, acceleration {:+.2}, \
                 gravity load {:+.2}; mean {} {torque}",
                r.velocity,
                r.velocity_sign,
                r.acceleration,
                r.gravity_load,
                sig(r.mean)
            );
        }
        if self.effects.is_empty() {
            let _ = writeln!(out, "missing effects: none significant");
        } else {
            let _ = writeln!(out, "missing effects (in the order named):");
        }
        for e in &self.effects {
            let _ = writeln!(out, "  {}", self.effect_line(e));
        }
        self.supported_lines(&mut out);
        if let Some(condition) = self.identifiability.condition_number {
            let _ = writeln!(
                out,
                "identifiability: condition number {} of the named parameters",
                sig(condition)
            );
        }
        for c in &self.identifiability.confounded {
            let _ = writeln!(
                out,
                "  barely told apart by these data: {} ~ {} (correlation {:+.2})",
                c.first, c.second, c.correlation
            );
        }
        for u in &self.unexplained {
            let _ = writeln!(out, "unexplained: {}", u.text);
        }
        for note in &self.notes {
            let _ = writeln!(out, "note: {note}");
        }
        out
    }
}

impl Diagnosis {
    /// The unit of joint j's (1-based) torque: N m, or N on a prismatic joint.
    fn torque_unit(&self, joint: usize) -> &'static str {
        if self.sliding(joint) { "N" } else { "N m" }
    }

    fn sliding(&self, joint: usize) -> bool {
        self.joint_kinds
            .get(joint - 1)
            .is_some_and(|k| k == "prismatic")
    }

    fn effect_line(&self, e: &Effect) -> String {
        let place = match (e.joint, &e.link) {
            (Some(j), _) => format!("joint {j}"),
            (None, Some(link)) => format!("link `{link}`"),
            (None, None) => "all joints".to_string(),
        };
        let values: Vec<String> = e
            .parameters
            .iter()
            .filter(|(_, v)| !v.is_null() && !is_null_array(v))
            .map(|(name, value)| {
                let interval = e.ci95.get(name).map_or(String::new(), interval_text);
                let revolute = unit(e.kind, name);
                let unit = match e.joint {
                    Some(j) if self.sliding(j) => linear(revolute),
                    _ => revolute,
                };
                format!("{name} {}{unit}{interval}", value_text(value))
            })
            .collect();
        let whose = match e.joint {
            Some(j) => format!("joint {j}'s"),
            None => "the joints'".to_string(),
        };
        let correction = self.correction_text(e);
        let ambiguous = if e.ambiguous_with.is_empty() {
            String::new()
        } else {
            format!(
                "; ambiguous with {} (see notes)",
                e.ambiguous_with.join(", ")
            )
        };
        format!(
            "{} on {place}: {}{correction}; removes {:.0}% of {whose} held-out MSE ({} {}^2){ambiguous}",
            e.kind.name(),
            values.join(", "),
            100.0 * e.heldout_share,
            sig(e.heldout_mse_removed),
            e.joint.map_or("N m", |j| self.torque_unit(j))
        )
    }
}

/// Supported but unnamed effects printed; the rest are in the JSON.
const SUPPORTED_SHOWN: usize = 5;

impl Diagnosis {
    /// The effects the data support that were not named, most held-out
    /// error first, so a small effect is never silently dropped.
    fn supported_lines(&self, out: &mut String) {
        if self.supported.is_empty() {
            return;
        }
        let _ = writeln!(
            out,
            "supported by the data but not named (interval excludes zero, held-out error \
             drops, below the naming bar; fitted with the named effects):"
        );
        for e in self.supported.iter().take(SUPPORTED_SHOWN) {
            let _ = writeln!(out, "  {}", self.effect_line(e));
        }
        if self.supported.len() > SUPPORTED_SHOWN {
            let _ = writeln!(
                out,
                "  and {} more (--format json: supported)",
                self.supported.len() - SUPPORTED_SHOWN
            );
        }
    }

    /// For an effect the model already has on the joint: the values above
    /// are what is missing, added to the model's (what `--apply` writes).
    fn correction_text(&self, e: &Effect) -> String {
        if e.total.is_empty() {
            return String::new();
        }
        let list = |values: &serde_json::Map<String, serde_json::Value>| {
            values
                .iter()
                .map(|(name, value)| {
                    let revolute = unit(e.kind, name);
                    let unit = match e.joint {
                        Some(j) if self.sliding(j) => linear(revolute),
                        _ => revolute,
                    };
                    format!("{name} {}{unit}", value_text(value))
                })
                .collect::<Vec<_>>()
                .join(", ")
        };
        format!(
            "; adds to the model's {}: {} in all",
            list(&e.modelled),
            list(&e.total)
        )
    }
}

fn is_null_array(v: &serde_json::Value) -> bool {
    v.as_array().is_some_and(|a| a.iter().all(|x| x.is_null()))
}

fn value_text(v: &serde_json::Value) -> String {
    match v {
        serde_json::Value::Number(n) if n.is_u64() => n.to_string(),
        serde_json::Value::Number(n) => n.as_f64().map_or(n.to_string(), sig),
        serde_json::Value::Array(a) => {
            format!(
                "[{}]",
                a.iter().map(value_text).collect::<Vec<_>>().join(", ")
            )
        }
        other => other.to_string(),
    }
}

/// `(95% CI a .. b)` for a scalar interval, per component for vectors.
fn interval_text(v: &serde_json::Value) -> String {
    let Some(items) = v.as_array() else {
        return String::new();
    };
    let pair = |p: &serde_json::Value| -> Option<String> {
        let p = p.as_array()?;
        Some(format!(
            "{} .. {}",
            sig(p.first()?.as_f64()?),
            sig(p.get(1)?.as_f64()?)
        ))
    };
    if items.first().is_some_and(|x| x.is_number()) {
        return pair(v).map_or(String::new(), |p| format!(" (95% CI {p})"));
    }
    let parts: Vec<String> = items.iter().filter_map(pair).collect();
    if parts.is_empty() {
        String::new()
    } else {
        format!(" (95% CI {})", parts.join("; "))
    }
}

fn unit(kind: Kind, name: &str) -> &'static str {
    match (kind, name) {
        (Kind::ViscousFriction, _) => " N m s/rad",
        (Kind::CoulombFriction | Kind::TorqueOffset | Kind::CoulombAsymmetry, _) => " N m",
        (Kind::Armature, _) => " kg m^2",
        (Kind::TorqueScale | Kind::TorqueDelay, "correction") => "",
        (Kind::TorqueScale, _) => "",
        (Kind::TorqueDelay, _) => " s",
        (Kind::GravityDirection, "tilt_deg") => " deg",
        (Kind::GravityDirection, _) => " m/s^2",
        (Kind::JointSpring, "stiffness") => " N m/rad",
        (Kind::JointSpring, "rest") => " rad",
        (Kind::JointSpring, _) => " N m",
        (Kind::StribeckFriction, "velocity") => " rad/s",
        (Kind::StribeckFriction, _) => " N m",
        (Kind::TorqueRipple, "cycles") => " per revolution",
        (Kind::TorqueRipple, _) => " N m",
        (_, "physically_consistent") => "",
        (_, "mass" | "nominal_mass") => " kg",
        (_, "first_moment" | "nominal_first_moment") => " kg m",
        (_, "inertia" | "nominal_inertia") => " kg m^2",
        // A whole body's combinations mix units; the rest are counts and names.
        (_, "combinations" | "determined" | "identifiable_combinations") => "",
        _ => " m",
    }
}

/// A joint effect's unit on a prismatic joint: force for torque, metre
/// for radian.
fn linear(revolute: &'static str) -> &'static str {
    match revolute {
        " N m s/rad" => " N s/m",
        " N m" => " N",
        " kg m^2" => " kg",
        " N m/rad" => " N/m",
        " rad" => " m",
        " rad/s" => " m/s",
        " per revolution" => " per 2 pi m",
        other => other,
    }
}

fn percent_change(before: f64, after: f64) -> String {
    if before > 0.0 {
        format!("{:+.0}%", 100.0 * (after - before) / before)
    } else {
        "unchanged".to_string()
    }
}
