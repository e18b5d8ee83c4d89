//! The diagnosis as text a person reads: the same kind names as the JSON,
//! numbers to three significant digits, each effect's share of its joint's
//! held-out MSE.

use std::fmt::Write;

use super::choose::STILL_JOINTS;
use super::diagnosis::{Diagnosis, Effect};
use super::digits::sig;
use super::kind::Kind;

/// Notes printed without `--verbose`; the rest are counted.
const NOTES_SHOWN: usize = 5;

impl Diagnosis {
    /// The text report (`sdnn diagnose` without `--format json`): what to
    /// change first (the named effects), each joint's held-out error before
    /// and after them, then at most five notes, those that concern the most
    /// held-out error; `verbose` adds every note, each joint's residual
    /// regimes and the pairs of parameters the data barely tell apart.
    pub fn text(&self, verbose: bool) -> String {
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
        self.effect_table(&mut out);
        self.joint_table(&mut out, verbose);
        self.supported_lines(&mut out);
        if let Some(condition) = self.identifiability.condition_number {
            let _ = writeln!(
                out,
                "identifiability: condition number {} of the named parameters",
                sig(condition)
            );
        }
        if verbose {
            for c in &self.identifiability.confounded {
                let _ = writeln!(
                    out,
                    "  barely told apart by these data: {} ~ {} (correlation {:+.2})",
                    c.first, c.second, c.correlation
                );
            }
        }
        for u in &self.unexplained {
            let _ = writeln!(out, "unexplained: {}", u.text);
        }
        self.note_lines(&mut out, verbose);
        out
    }

    /// The named effects, one row each: kind, where, the held-out error it
    /// removes, its values with their 95% intervals.
    fn effect_table(&self, out: &mut String) {
        if self.effects.is_empty() {
            let _ = writeln!(out, "missing effects: none significant");
            return;
        }
        let _ = writeln!(
            out,
            "missing effects (in the order named; what to change):\n  {:<20} {:<18} {:<11} value (95% CI)",
            "kind", "where", "removes"
        );
        for e in &self.effects {
            let _ = writeln!(out, "  {}", self.effect_row(e));
        }
    }

    /// Each joint's held-out MSE before and after the named effects, and its
    /// residual; `verbose` adds how the residual correlates with the state.
    fn joint_table(&self, out: &mut String, verbose: bool) {
        let _ = writeln!(
            out,
            "held-out MSE per joint (before -> after the named effects):\n  {:<6} {:<14} {:<14} {:<7} residual RMS before (share of the torque RMS)",
            "joint", "before", "after", "change"
        );
        for j in 0..self.mse_before.len() {
            let (before, after) = (self.mse_before[j], self.mse_after[j]);
            let torque = self.torque_unit(j + 1);
            let _ = writeln!(
                out,
                "  {:<6} {:<14} {:<14} {:<7} {} {torque} ({:.1}%)",
                j + 1,
                format!("{} {torque}^2", sig(before)),
                format!("{} {torque}^2", sig(after)),
                percent_change(before, after),
                sig(self.residual_rms[j]),
                100.0 * self.residual_share[j],
            );
            let fitted = self.mse_after_fitted[j];
            if fitted < 0.8 * after {
                let _ = writeln!(
                    out,
                    "         {} {torque}^2 ({}) with Coulomb friction zero while the joint is at \
                     rest: it sticks, and there the model's sign(qd) term follows velocity noise",
                    sig(fitted),
                    percent_change(before, fitted)
                );
            }
            if verbose {
                let r = &self.regimes[j];
                let _ = writeln!(
                    out,
                    "         residual correlates with velocity {:+.2}, its sign {:+.2}, \
                     acceleration {:+.2}, gravity load {:+.2}; mean {} {torque}",
                    r.velocity,
                    r.velocity_sign,
                    r.acceleration,
                    r.gravity_load,
                    sig(r.mean)
                );
            }
        }
    }

    /// The notes, those that concern the most held-out error first: at most
    /// [`NOTES_SHOWN`] unless `verbose`, the rest counted.
    fn note_lines(&self, out: &mut String, verbose: bool) {
        let mut ranked: Vec<(f64, &String)> =
            self.notes.iter().map(|n| (self.concern(n), n)).collect();
        // Stable: notes of equal concern keep the diagnosis's order.
        ranked.sort_by(|a, b| b.0.total_cmp(&a.0));
        let shown = if verbose { ranked.len() } else { NOTES_SHOWN };
        for (_, note) in ranked.iter().take(shown) {
            let _ = writeln!(out, "note: {note}");
        }
        let hidden = ranked.len().saturating_sub(shown);
        let pairs = if verbose {
            0
        } else {
            self.identifiability.confounded.len()
        };
        if hidden + pairs > 0 {
            let _ = writeln!(
                out,
                "{hidden} more {} and {pairs} {} of parameters the data barely tell apart: \
                 --verbose (or --format json)",
                if hidden == 1 { "note" } else { "notes" },
                if pairs == 1 { "pair" } else { "pairs" },
            );
        }
    }

    /// How much held-out error a note concerns (N m^2): a named effect's
    /// removal for a note about it, else the share a note says an effect
    /// "would cut" of that joint's held-out MSE before the diagnosis.
    fn concern(&self, note: &str) -> f64 {
        let named = self.effects.iter().find(|e| {
            let at = match (e.joint, &e.link) {
                (Some(j), _) => format!(" on joint {j}"),
                (None, Some(link)) => format!("(`{link}`)"),
                (None, None) => String::new(),
            };
            note.starts_with(&e.kind.name())
                && note.split(':').next().is_some_and(|h| h.contains(&at))
        });
        if let Some(e) = named {
            return e.heldout_mse_removed;
        }
        if let Some(list) = note.strip_prefix(STILL_JOINTS) {
            // "2 (5%), 4 (3%): ...": the held-out error those joints keep.
            let list = list.split(':').next().unwrap_or("");
            return list
                .split(", ")
                .filter_map(|j| j.split(' ').next()?.parse::<usize>().ok())
                .filter_map(|j| self.mse_after.get(j.checked_sub(1)?))
                .sum();
        }
        would_cut(note)
            .and_then(|(joint, share)| Some(share * self.mse_before.get(joint.checked_sub(1)?)?))
            .unwrap_or(0.0)
    }
}

/// "; ambiguous with ..." for an effect with runners-up, else nothing.
fn ambiguous_text(e: &Effect) -> String {
    if e.ambiguous_with.is_empty() {
        return String::new();
    }
    format!(
        "; ambiguous with {} (see notes)",
        e.ambiguous_with.join(", ")
    )
}

/// Parameters the JSON gives for reference, left out of the text: the
/// model's values and a whole body's raw combinations.
fn reference(name: &str) -> bool {
    name.starts_with("nominal_") || name.contains("combinations")
}

/// The joint and share in "... joint J's held-out MSE by P% ...".
fn would_cut(note: &str) -> Option<(usize, f64)> {
    let at = note.find("'s held-out MSE by ")?;
    let joint: usize = note[..at].rsplit(' ').next()?.parse().ok()?;
    let rest = &note[at + "'s held-out MSE by ".len()..];
    let percent: f64 = rest.split('%').next()?.parse().ok()?;
    Some((joint, percent / 100.0))
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

    /// A named effect as a row of the effect table.
    fn effect_row(&self, e: &Effect) -> String {
        let place = match (e.joint, &e.link) {
            (Some(j), _) => format!("joint {j}"),
            (None, Some(link)) => format!("link `{link}`"),
            (None, None) => "all joints".to_string(),
        };
        let ambiguous = ambiguous_text(e);
        format!(
            "{:<20} {:<18} {:<11} {}{}{ambiguous}",
            e.kind.name(),
            place,
            format!("{:.0}%", 100.0 * e.heldout_share),
            self.values_text(e).join(", "),
            self.correction_text(e),
        )
    }

    /// An effect's parameters with their units and 95% intervals.
    fn values_text(&self, e: &Effect) -> Vec<String> {
        e.parameters
            .iter()
            .filter(|(name, v)| !v.is_null() && !is_null_array(v) && !reference(name))
            .map(|(name, value)| {
                let ci95 = e.ci95.get(name);
                let interval = ci95.map_or(String::new(), interval_text);
                let revolute = unit(e.kind, name);
                let unit = match e.joint {
                    Some(j) if self.sliding(j) => linear(revolute),
                    _ => revolute,
                };
                let name = match value.as_array() {
                    // A body's six entries about its COM, in the JSON's order.
                    Some(entries) if name == "inertia" && entries.len() == 6 => {
                        "inertia about the COM (ixx, ixy, ixz, iyy, iyz, izz)"
                    }
                    Some(_) if name == "determined" => "determined (about the link origin)",
                    _ => name,
                };
                format!("{name} {}{unit}{interval}", value_within(value, ci95))
            })
            .collect()
    }

    fn effect_line(&self, e: &Effect) -> String {
        let place = match (e.joint, &e.link) {
            (Some(j), _) => format!("joint {j}"),
            (None, Some(link)) => format!("link `{link}`"),
            (None, None) => "all joints".to_string(),
        };
        let values = self.values_text(e);
        let whose = match e.joint {
            Some(j) => format!("joint {j}'s"),
            None => "the joints'".to_string(),
        };
        let correction = self.correction_text(e);
        let ambiguous = ambiguous_text(e);
        let removes = match e.heldout_left {
            // Against what the named effects leave: a share of the MSE
            // before the diagnosis reads 0% for any effect below the named.
            Some(left) => format!(
                "removes {}% of joint {}'s held-out MSE left by the named effects ({} {}^2)",
                sig(100.0 * left.share),
                left.joint,
                sig(e.heldout_mse_removed),
                self.torque_unit(left.joint)
            ),
            None => format!(
                "removes {:.0}% of {whose} held-out MSE ({} {}^2)",
                100.0 * e.heldout_share,
                sig(e.heldout_mse_removed),
                e.joint.map_or("N m", |j| self.torque_unit(j))
            ),
        };
        format!(
            "{} on {place}: {}{correction}; {removes}{ambiguous}",
            e.kind.name(),
            values.join(", "),
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

/// A value with the digits its interval needs (per component for
/// vectors), so that it never reads as outside its own interval.
fn value_within(v: &serde_json::Value, ci95: Option<&serde_json::Value>) -> String {
    let scalar =
        |x: &serde_json::Value, i: Option<&serde_json::Value>| match (x.as_f64(), i.and_then(ends))
        {
            (Some(x), Some((low, high))) => {
                crate::digits::significant(x, crate::digits::needed(low, high))
            }
            _ => value_text(x),
        };
    match (v, ci95.and_then(|i| i.as_array())) {
        (serde_json::Value::Array(a), Some(intervals)) => format!(
            "[{}]",
            a.iter()
                .enumerate()
                .map(|(k, x)| scalar(x, intervals.get(k)))
                .collect::<Vec<_>>()
                .join(", ")
        ),
        (serde_json::Value::Number(n), _) if n.is_u64() => n.to_string(),
        _ => scalar(v, ci95),
    }
}

/// An interval's `[low, high]`, when it is two numbers.
fn ends(interval: &serde_json::Value) -> Option<(f64, f64)> {
    let i = interval.as_array()?;
    Some((i.first()?.as_f64()?, i.get(1)?.as_f64()?))
}

/// `(95% CI a .. b)` for a scalar interval, per component for vectors.
fn interval_text(v: &serde_json::Value) -> String {
    let Some(items) = v.as_array() else {
        return String::new();
    };
    let pair = |p: &serde_json::Value| -> Option<String> {
        let (low, high) = ends(p)?;
        let (low, high) = crate::digits::apart(low, high);
        Some(format!("{low} .. {high}"))
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
