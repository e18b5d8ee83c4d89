//! The report's numbers: named effects with intervals and shares, residual
//! statistics and regimes, and the residual samples for plots.

use nalgebra::{DVector, Vector3};

use super::candidate::{Candidate, Shape, label, width};
use super::diagnosis::{Effect, Regimes, ResidualSamples};
use super::extent::moments_within;
use super::fit::{Fit, fit};
use super::heldout::cv_mse_per_joint;
use super::kind::Kind;
use super::moments::Moments;
use super::shape::physically_consistent;
use super::shape::{holds, reported_interval};
use super::solve::ROUNDING;
use super::stacked::Stacked;
use super::uncertainty::{fit_robust, rest_shift, robust_quantity, widened};
use super::whole::about_com;

/// The residuals before and after subtracting what the selected effects,
/// fitted to all data, add to the model (as the applied model computes it).
pub(super) fn residual_samples(
    data: &Stacked,
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
) -> ResidualSamples {
    let mut after = data.residual.clone();
    if let Some(fit) = fit(m, candidates, selected, |_| true) {
        let columns = selected.iter().flat_map(|&c| {
            let candidate = &candidates[c];
            // As in `Moments::new`: an `applied` column scores the first.
            (0..candidate.columns.len()).map(move |k| match (&candidate.applied, k) {
                (Some(applied), 0) => applied,
                _ => &candidate.columns[k],
            })
        });
        for (column, coefficient) in columns.zip(fit.coefficients.iter()) {
            after.axpy(-coefficient, column, 1.0);
        }
    }
    ResidualSamples {
        dof: data.dof,
        qd: data.qd.as_slice().to_vec(),
        qdd: data.qdd.as_slice().to_vec(),
        before: data.residual.as_slice().to_vec(),
        after: after.as_slice().to_vec(),
    }
}

/// The named effects with their parameters, 95% intervals (the sampling
/// error widened by `bias` and the move of [`rest_shift`], see
/// [`widened`]) and the held-out
/// MSE each removes, counted in selection order (the first effect's whole
/// drop, then what each next one adds), so the parts add up to the drop
/// the report shows.
pub(super) fn describe(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
    resolution: f64,
    bias: &DVector<f64>,
    notes: &mut Vec<String>,
) -> Vec<Effect> {
    let Some((fit, half)) = half_widths(m, candidates, selected, bias) else {
        return Vec::new();
    };
    let theta = moments_within(
        candidates,
        selected,
        &fit.information,
        fit.theta.clone(),
        notes,
    );
    let removals = heldout_removals(m, candidates, selected);
    let mut offset = 0;
    let mut effects = Vec::new();
    for (&c, (removed, of)) in selected.iter().zip(removals) {
        let candidate = &candidates[c];
        let w = width(candidate);
        let values: Vec<(f64, f64)> = (offset..offset + w).map(|k| (theta[k], half[k])).collect();
        offset += w;
        let mut effect = effect(candidate, &values, resolution, notes);
        effect.heldout_mse_removed = removed;
        effect.heldout_share = (removed / of.max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
        if let Shape::Whole { basis, .. } = &candidate.shape {
            let at = offset - w;
            let body = |theta: &DVector<f64>| {
                let change = basis * theta.rows(at, w);
                let p: [f64; 10] = std::array::from_fn(|k| candidate.modelled[k] + change[k]);
                let (mass, com, inertia) = about_com(&p);
                DVector::from_iterator(10, [mass].into_iter().chain(com).chain(inertia))
            };
            let (_, se) = robust_quantity(m, candidates, selected, &fit, body);
            body_intervals(&mut effect, &se);
        }
        effects.push(effect);
    }
    effects
}

/// A whole body's mass and COM with 95% intervals from `se` (the standard
/// errors of mass, COM and inertia about the COM, in that order, propagated from the
/// fitted combinations with the other named effects, see
/// [`robust_quantity`]), centred on the named body's values. Only where
/// the data determine every standard parameter a quantity is made of (the
/// mass; mass and first moment for the COM): the rest are the model's,
/// held, and an interval there would claim the model's value known. The
/// inertia about the COM gets none: on the independent suite's 3-DOF arm
/// such intervals held the truth in 3 of 24 (four runs of six entries; the
/// last link's ixx twice the truth at +-1.5%; the Panda 106 of 114, the
/// UR10e 45 of 48),
/// so its combinations' intervals are what the report claims.
fn body_intervals(effect: &mut Effect, se: &DVector<f64>) {
    let determined: Vec<String> = effect
        .parameters
        .get("determined")
        .and_then(|d| d.as_array())
        .map(|d| {
            d.iter()
                .filter_map(|x| x.as_str().map(String::from))
                .collect()
        })
        .unwrap_or_default();
    let known = |needed: &[&str]| needed.iter().all(|p| determined.iter().any(|d| d == p));
    let mass = known(&["mass"]);
    let com = mass && known(&["mx", "my", "mz"]);
    let mut put = |name: &str, range: std::ops::Range<usize>, wanted: bool| {
        if !wanted {
            return;
        }
        let Some(value) = effect.parameters.get(name) else {
            return;
        };
        let values: Vec<f64> = match value {
            serde_json::Value::Array(a) => a.iter().filter_map(|x| x.as_f64()).collect(),
            other => other.as_f64().into_iter().collect(),
        };
        if values.len() != range.len() {
            return;
        }
        let pairs: Vec<[f64; 2]> = values
            .iter()
            .zip(range)
            .map(|(v, k)| [v - 1.96 * se[k], v + 1.96 * se[k]])
            .collect();
        let interval = match pairs.as_slice() {
            [one] => serde_json::json!(one),
            many => serde_json::json!(many),
        };
        effect.ci95.insert(name.into(), interval);
    };
    put("mass", 0..1, mass);
    put("com", 1..4, com);
}

/// The selected effects' fit and their 95% half-widths: the
/// sampling error widened by `bias` and the move of [`rest_shift`] (see
/// [`widened`]).
pub(super) fn half_widths(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
    bias: &DVector<f64>,
) -> Option<(Fit, DVector<f64>)> {
    let (fit, se) = fit_robust(m, candidates, selected)?;
    // The move when friction below the at-rest speed is left free adds to
    // the other probes' (docs/diagnosis.md, "How far the intervals hold").
    let rest = rest_shift(m, candidates, selected, &fit);
    let bias = bias.zip_map(&rest, |b, r| b + r.abs());
    let half = widened(&se, &bias);
    Some((fit, half))
}

/// Per selected effect, in selection order, the held-out MSE it removes
/// from its joints (all joints for a link or data effect) with the
/// generated model's columns, and those joints' MSE before the diagnosis.
pub(super) fn heldout_removals(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
) -> Vec<(f64, f64)> {
    let dof = m.xx.first().map_or(0, Vec::len);
    let mut previous = cv_mse_per_joint(m, dof, candidates, &[]);
    let before = previous.clone();
    (0..selected.len())
        .map(|position| {
            let now = cv_mse_per_joint(m, dof, candidates, &selected[..=position]);
            let joints: Vec<usize> = match candidates[selected[position]].joint {
                Some(j) => vec![j],
                None => (0..dof).collect(),
            };
            let removed: f64 = joints.iter().map(|&j| previous[j] - now[j]).sum();
            let of: f64 = joints.iter().map(|&j| before[j]).sum();
            previous = now;
            (removed, of)
        })
        .collect()
}

/// A fitted mass whose 95% half-width exceeds this fraction of it gets a
/// note that the data barely determine it.
pub const MASS_RESOLUTION: f64 = 0.1;

pub(super) fn effect(
    candidate: &Candidate,
    values: &[(f64, f64)],
    resolution: f64,
    notes: &mut Vec<String>,
) -> Effect {
    use serde_json::{Map, Value, json};
    let mut parameters = Map::new();
    let mut ci95 = Map::new();
    if let Shape::Body {
        base_mass,
        base_moment,
        held_com,
        ..
    } = &candidate.shape
    {
        let intervals: [(f64, f64); 4] = std::array::from_fn(|k| {
            let (value, half) = values[k];
            reported_interval((value - half, value + half), held_com, k)
        });
        let m = values[0].0;
        let (low, high) = intervals[0];
        parameters.insert("mass".into(), json!(m));
        ci95.insert("mass".into(), json!([low, high]));
        if (high - low) / 2.0 > MASS_RESOLUTION * m.abs() {
            notes.push(format!(
                "{}: the mass is poorly determined by these data (fit {m:.3} kg, 95% CI \
                 {low:.3} .. {high:.3} kg, more than {:.0}% either way): treat it as unknown \
                 within that interval",
                label(candidate),
                100.0 * MASS_RESOLUTION
            ));
        }
        let mut com = Vec::new();
        let mut interval = Vec::new();
        for (a, axis) in ["x", "y", "z"].iter().enumerate() {
            let c = values[a + 1].0;
            let (low, high) = intervals[a + 1];
            com.push(json!(c));
            interval.push(json!([low, high]));
            let dc = (high - low) / 2.0;
            if holds(held_com, a) {
                continue;
            }
            if dc > resolution {
                notes.push(format!(
                    "{}: the COM's {axis} component is poorly determined by these data \
                     (fit {c:.3} m, 95% CI half-width {dc:.3} m > {resolution:.3} m): the \
                     recorded torques barely depend on it, so --apply's use of the fit changes \
                     little here, but treat the value as unknown — record motions that move the \
                     first joint together with the others to determine it",
                    label(candidate)
                ));
            }
        }
        parameters.insert("com".into(), Value::Array(com));
        ci95.insert("com".into(), Value::Array(interval));
        if let Shape::Body {
            own_inertia: true, ..
        } = candidate.shape
        {
            // A payload's own moment of inertia about its COM, every axis.
            let (j, dj) = values[4];
            parameters.insert("inertia".into(), json!(j));
            ci95.insert("inertia".into(), json!([j - dj, j + dj]));
        }
        if candidate.kind == Kind::InertialError {
            let nominal_com = if *base_mass > 0.0 {
                base_moment / *base_mass
            } else {
                Vector3::zeros()
            };
            parameters.insert("nominal_mass".into(), json!(base_mass));
            parameters.insert(
                "nominal_com".into(),
                json!([nominal_com.x, nominal_com.y, nominal_com.z]),
            );
        }
    } else if let Shape::Moment {
        base_mass,
        base_moment,
        ..
    } = &candidate.shape
    {
        // The first moment is what the data determine; its components are
        // held to the COM resolution at the modelled mass.
        let mut moment = Vec::new();
        let mut interval = Vec::new();
        for (axis, &(h, dh)) in ["x", "y", "z"].iter().zip(values) {
            moment.push(json!(h));
            interval.push(json!([h - dh, h + dh]));
            if dh > resolution * base_mass {
                notes.push(format!(
                    "{}: the first moment's {axis} component is poorly determined by these \
                     data (fit {h:.4} kg m, 95% CI half-width {dh:.4} kg m, a COM uncertainty \
                     of {:.3} m at the modelled mass > {resolution:.3} m): treat the value as \
                     unknown",
                    label(candidate),
                    dh / base_mass
                ));
            }
        }
        notes.push(format!(
            "{}: the link's mass is not identifiable: its origin does not accelerate in the \
             recorded motion (it lies on the axes of the joints that move it, so its mass \
             column in the regressor is negligible against its first-moment columns), so its \
             mass cannot be told from torques; reported: the first moment m*c (kg m), fitted \
             with the mass as modelled ({base_mass:.4} kg) and the inertia about the COM as \
             modelled; mass and com are null; --apply keeps the mass and moves the COM to \
             first_moment / mass (that assumption)",
            label(candidate)
        ));
        parameters.insert("mass".into(), Value::Null);
        ci95.insert("mass".into(), Value::Null);
        parameters.insert("com".into(), json!([null, null, null]));
        ci95.insert("com".into(), json!([null, null, null]));
        parameters.insert("first_moment".into(), Value::Array(moment));
        ci95.insert("first_moment".into(), Value::Array(interval));
        let nominal_com = base_moment / *base_mass;
        parameters.insert("nominal_mass".into(), json!(base_mass));
        parameters.insert(
            "nominal_com".into(),
            json!([nominal_com.x, nominal_com.y, nominal_com.z]),
        );
        parameters.insert(
            "nominal_first_moment".into(),
            json!([base_moment.x, base_moment.y, base_moment.z]),
        );
    } else if let Shape::Whole { basis, gram } = &candidate.shape {
        super::whole::describe(
            (&label(candidate), &candidate.modelled, candidate.extent),
            (basis, gram),
            values,
            (&mut parameters, &mut ci95),
            notes,
        );
    } else if let Shape::Tilt { gravity, across } = &candidate.shape {
        let (a, b, g) = (values[0].0, values[1].0, gravity.norm());
        let along = (g * g - a * a - b * b).max(0.0).sqrt();
        let tilted = across[0] * a + across[1] * b + gravity * (along / g);
        let angle = gravity.angle(&tilted).to_degrees();
        let half = values[0].1.hypot(values[1].1) / gravity.norm();
        parameters.insert("gravity".into(), json!([tilted.x, tilted.y, tilted.z]));
        parameters.insert("tilt_deg".into(), json!(angle));
        ci95.insert(
            "tilt_deg".into(),
            json!([
                (angle - half.to_degrees()).max(0.0),
                angle + half.to_degrees()
            ]),
        );
    } else {
        for (name, (value, half)) in candidate.names.iter().zip(values) {
            parameters.insert((*name).into(), json!(value));
            ci95.insert((*name).into(), json!([value - half, value + half]));
        }
        // Chosen from the data before the fit: no interval of their own.
        for (name, value) in &candidate.settings {
            parameters.insert((*name).into(), json!(value));
        }
        data_correction(candidate, values, &mut parameters, &mut ci95);
    }
    if matches!(candidate.shape, Shape::Body { .. } | Shape::Moment { .. }) {
        consistency(candidate, values, &mut parameters, notes);
    }
    let joint = candidate.joint.map(|j| j + 1);
    let link = candidate.link.as_ref().map(|(_, name)| name.clone());
    Effect::new(candidate.kind, (joint, link), parameters, ci95)
}

/// Whether the corrected link (its model plus the fitted change) is a
/// physical body; reported as `physically_consistent`, with a note if not.
fn consistency(
    candidate: &Candidate,
    values: &[(f64, f64)],
    parameters: &mut serde_json::Map<String, serde_json::Value>,
    notes: &mut Vec<String>,
) {
    let theta: Vec<f64> = values.iter().map(|v| v.0).collect();
    let (coefficients, _) = candidate.shape.map(&theta);
    let corrected: [f64; 10] = std::array::from_fn(|k| candidate.modelled[k] + coefficients[k]);
    let consistent = physically_consistent(&corrected);
    parameters.insert(
        "physically_consistent".into(),
        serde_json::json!(consistent),
    );
    if consistent == Some(false) {
        notes.push(format!(
            "{}: the corrected body is not physically realizable (its pseudo-inertia is not \
             positive semi-definite: the modelled inertia about the COM breaks the triangle \
             inequality, or the fitted mass is not positive); correct the model's inertia first",
            label(candidate)
        ));
    }
}

/// A property of the recording (a torque sensor's scale, a delay) is
/// reported with the option that corrects the recording; a spring's rest
/// angle is derived from its fitted constant.
fn data_correction(
    candidate: &Candidate,
    values: &[(f64, f64)],
    parameters: &mut serde_json::Map<String, serde_json::Value>,
    ci95: &mut serde_json::Map<String, serde_json::Value>,
) {
    use serde_json::json;
    let (value, half) = values[0];
    let correction = match (candidate.kind, candidate.joint) {
        (Kind::TorqueScale, Some(j)) => {
            let scale = 1.0 + value;
            let interval = [scale - half, scale + half];
            parameters.insert("scale".into(), json!(scale));
            ci95.insert("scale".into(), json!(interval));
            format!("--torque-scale {}={scale:.4}", j + 1)
        }
        (Kind::TorqueDelay, _) => format!("--torque-delay {value:.5}"),
        (Kind::JointSpring, _) if value != 0.0 => {
            // k q + c = k (q - rest): rest = -c / k.
            let (c, dc) = values[1];
            let rest = -c / value;
            parameters.insert("rest".into(), json!(rest));
            ci95.insert(
                "rest".into(),
                json!([rest - dc / value.abs(), rest + dc / value.abs()]),
            );
            return;
        }
        _ => return,
    };
    parameters.insert("correction".into(), json!(correction));
}

pub(super) fn per_joint(data: &Stacked, f: impl Fn(f64, f64) -> f64) -> Vec<f64> {
    let mut sum = vec![0.0; data.dof];
    for r in 0..data.residual.len() {
        sum[r % data.dof] += f(data.residual[r], data.measured[r]);
    }
    let samples = (data.residual.len() / data.dof).max(1) as f64;
    sum.iter().map(|s| s / samples).collect()
}

pub(super) fn residual_share(data: &Stacked) -> Vec<f64> {
    let residual = per_joint(data, |r, _| r * r);
    let measured = per_joint(data, |_, m| m * m);
    residual
        .iter()
        .zip(&measured)
        .map(|(r, m)| (r / m.max(f64::MIN_POSITIVE)).sqrt())
        .collect()
}

pub(super) fn regimes(data: &Stacked, candidates: &[Candidate]) -> Vec<Regimes> {
    (0..data.dof)
        .map(|j| {
            let column = |kind: Kind| {
                candidates
                    .iter()
                    .find(|c| c.kind == kind && c.joint == Some(j))
                    .map(|c| &c.columns[0])
            };
            let corr = |kind| column(kind).map_or(0.0, |c| correlation(data, j, c));
            let rows = (0..data.residual.len()).filter(|r| r % data.dof == j);
            let count = rows.clone().count().max(1) as f64;
            Regimes {
                velocity: corr(Kind::ViscousFriction),
                velocity_sign: corr(Kind::CoulombFriction),
                acceleration: corr(Kind::Armature),
                gravity_load: correlation(data, j, &data.gravity),
                mean: rows.map(|r| data.residual[r]).sum::<f64>() / count,
            }
        })
        .collect()
}

pub(super) fn correlation(data: &Stacked, joint: usize, column: &DVector<f64>) -> f64 {
    let rows: Vec<usize> = (0..data.residual.len())
        .filter(|r| r % data.dof == joint)
        .collect();
    let mean = |f: &dyn Fn(usize) -> f64| {
        rows.iter().map(|&r| f(r)).sum::<f64>() / rows.len().max(1) as f64
    };
    let (mr, mc) = (mean(&|r| data.residual[r]), mean(&|r| column[r]));
    let cov = mean(&|r| (data.residual[r] - mr) * (column[r] - mc));
    let vr = mean(&|r| (data.residual[r] - mr).powi(2));
    let vc = mean(&|r| (column[r] - mc).powi(2));
    // A column at rounding level on this joint (the gravity load of a
    // vertical axis) correlates with noise, differently for each way the
    // model is computed: no correlation.
    let scale = column.norm_squared() / column.len().max(1) as f64;
    if vr <= 0.0 || vc <= ROUNDING * ROUNDING * scale {
        0.0
    } else {
        cov / (vr * vc).sqrt()
    }
}
