//! Discrepancy diagnosis: where the compiled model and measured data
//! disagree, which physical effect explains it, and how much it closes the
//! gap on held-out trajectories.
//!
//! The residual r = tau_measured - tau_model is linear in the parameters of
//! every candidate effect: per joint viscous friction (column qd_j), Coulomb
//! friction (sign(qd_j)), armature (qdd_j) and a torque offset (1); and a
//! payload on the last link (the generated regressor's m and m*c columns of
//! that link; the payload's own rotational inertia is neglected). Effects are
//! chosen by forward selection, each step keeping the candidate that lowers
//! the leave-one-trajectory-out cross-validated MSE most, while it lowers it
//! by at least `min_gain` and its parameters are significant (|t| > 3).
//! Parameters come from least squares with 95% confidence intervals.

use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use crate::dynamics::Dynamics;
use crate::study::model_torques;
use crate::trajectory::Trajectory;

/// The kinds of effect the diagnosis can name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    ViscousFriction,
    CoulombFriction,
    Armature,
    TorqueOffset,
    Payload,
}

/// A named missing effect with its fitted parameters.
#[derive(Debug, Clone, Serialize)]
pub struct Effect {
    pub kind: Kind,
    /// 1-based joint, or `None` for a payload.
    pub joint: Option<usize>,
    pub parameters: serde_json::Map<String, serde_json::Value>,
    pub ci95: serde_json::Map<String, serde_json::Value>,
    /// Fraction of the residual sum of squares this effect removes.
    pub share_explained: f64,
}

/// The diagnosis report (`sdnn diagnose --format json`).
#[derive(Debug, Clone, Serialize)]
pub struct Diagnosis {
    pub model: String,
    pub samples: usize,
    /// Residual RMS per joint (N m) and its share of the measured torque RMS.
    pub residual_rms: Vec<f64>,
    pub residual_share: Vec<f64>,
    /// Correlation of each joint's residual with its velocity, its velocity
    /// sign, its acceleration and a constant: where the residual concentrates.
    pub regimes: Vec<Regimes>,
    /// Held-out (leave-one-trajectory-out) torque MSE per joint, N m^2.
    pub mse_before: Vec<f64>,
    pub mse_after: Vec<f64>,
    pub effects: Vec<Effect>,
}

/// Residual structure of one joint.
#[derive(Debug, Clone, Serialize)]
pub struct Regimes {
    pub velocity: f64,
    pub velocity_sign: f64,
    pub acceleration: f64,
    pub mean: f64,
}

/// Selection settings.
#[derive(Debug, Clone, Copy)]
pub struct Settings {
    /// Minimum relative drop of the cross-validated MSE to accept an effect.
    pub min_gain: f64,
    /// Minimum |t| statistic of every parameter of an accepted effect.
    pub min_t: f64,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            min_gain: 0.10,
            min_t: 3.0,
        }
    }
}

/// One candidate: a kind, a joint, named parameter columns.
struct Candidate {
    kind: Kind,
    joint: Option<usize>,
    names: Vec<&'static str>,
    columns: Vec<DVector<f64>>,
}

/// Stacked data: rows are (sample, joint) pairs, sample-major.
struct Stacked {
    residual: DVector<f64>,
    measured: DVector<f64>,
    group: Vec<usize>,
    dof: usize,
}

/// Diagnoses `model` on preprocessed trajectories (with qdd).
pub fn diagnose(
    model: &dyn Dynamics,
    trajectories: &[Trajectory],
    settings: Settings,
) -> anyhow::Result<Diagnosis> {
    if trajectories.len() < 2 {
        anyhow::bail!(
            "diagnosis needs at least 2 trajectories to cross-validate, got {}",
            trajectories.len()
        );
    }
    let (data, candidates) = stack(model, trajectories)?;
    let selected = select(&data, &candidates, settings);
    let design = columns_of(&candidates, &selected);
    let mse_before = cv_mse_per_joint(&data, &[]);
    let mse_after = cv_mse_per_joint(&data, &design);
    let effects = describe(&data, &candidates, &selected);
    Ok(Diagnosis {
        model: model.name().to_string(),
        samples: data.residual.len() / data.dof,
        residual_rms: per_joint(&data, |r, _| r * r)
            .iter()
            .map(|v| v.sqrt())
            .collect(),
        residual_share: residual_share(&data),
        regimes: regimes(&data, &candidates),
        mse_before,
        mse_after,
        effects,
    })
}

fn stack(
    model: &dyn Dynamics,
    trajectories: &[Trajectory],
) -> anyhow::Result<(Stacked, Vec<Candidate>)> {
    let n = model.dof();
    let rows: usize = trajectories.iter().map(|t| t.len() * n).sum();
    let mut residual = DVector::zeros(rows);
    let mut measured = DVector::zeros(rows);
    let mut group = Vec::with_capacity(rows);
    let mut qd = DVector::zeros(rows);
    let mut qdd = DVector::zeros(rows);
    let mut payload = vec![DVector::zeros(rows); 4];
    let last = 10 * (n - 1);
    let mut at = 0;
    for (g, traj) in trajectories.iter().enumerate() {
        if traj.dof() != n {
            anyhow::bail!(
                "trajectory {} has {} joints, model `{}` has {n}",
                g + 1,
                traj.dof(),
                model.name()
            );
        }
        let predicted = model_torques(model, traj)?;
        let accel = traj
            .qdd()
            .ok_or_else(|| anyhow::anyhow!("trajectory {} has no accelerations", g + 1))?;
        for s in 0..traj.len() {
            let row = |m: &DMatrix<f64>| m.row(s).iter().copied().collect::<Vec<f64>>();
            let y = model.regressor(&row(traj.q()), &row(traj.qd()), &row(accel))?;
            for i in 0..n {
                residual[at] = traj.tau()[(s, i)] - predicted[(s, i)];
                measured[at] = traj.tau()[(s, i)];
                qd[at] = traj.qd()[(s, i)];
                qdd[at] = accel[(s, i)];
                for (k, column) in payload.iter_mut().enumerate() {
                    column[at] = y[(i, last + k)];
                }
                group.push(g);
                at += 1;
            }
        }
    }
    let data = Stacked {
        residual,
        measured,
        group,
        dof: n,
    };
    let candidates = candidates(&data, &qd, &qdd, payload);
    Ok((data, candidates))
}

fn candidates(
    data: &Stacked,
    qd: &DVector<f64>,
    qdd: &DVector<f64>,
    payload: Vec<DVector<f64>>,
) -> Vec<Candidate> {
    let n = data.dof;
    let own = |j: usize, f: &dyn Fn(usize) -> f64| {
        DVector::from_fn(
            data.residual.len(),
            |r, _| if r % n == j { f(r) } else { 0.0 },
        )
    };
    let mut list = Vec::new();
    for j in 0..n {
        let one = |kind, name, f: &dyn Fn(usize) -> f64| Candidate {
            kind,
            joint: Some(j),
            names: vec![name],
            columns: vec![own(j, f)],
        };
        list.push(one(Kind::ViscousFriction, "coefficient", &|r| qd[r]));
        list.push(one(Kind::CoulombFriction, "level", &|r| moving_sign(qd[r])));
        list.push(one(Kind::Armature, "inertia", &|r| qdd[r]));
        list.push(one(Kind::TorqueOffset, "offset", &|_| 1.0));
    }
    list.push(Candidate {
        kind: Kind::Payload,
        joint: None,
        names: vec!["mass", "mx", "my", "mz"],
        columns: payload,
    });
    list
}

/// Joints slower than this (rad/s) are taken as at rest: their friction is
/// static, anywhere between the Coulomb levels, so those samples do not
/// inform the Coulomb level.
pub const MOVING: f64 = 0.02;

fn moving_sign(qd: f64) -> f64 {
    if qd.abs() > MOVING { qd.signum() } else { 0.0 }
}

fn columns_of(candidates: &[Candidate], selected: &[usize]) -> Vec<DVector<f64>> {
    selected
        .iter()
        .flat_map(|&c| candidates[c].columns.iter().cloned())
        .collect()
}

/// Least squares; `None` when the columns are (nearly) collinear.
fn fit(x: &DMatrix<f64>, y: &DVector<f64>) -> Option<DVector<f64>> {
    let gram = x.transpose() * x;
    let chol = gram.cholesky()?;
    Some(chol.solve(&(x.transpose() * y)))
}

fn design(columns: &[DVector<f64>], rows: &[usize]) -> DMatrix<f64> {
    DMatrix::from_fn(rows.len(), columns.len(), |r, c| columns[c][rows[r]])
}

/// Leave-one-trajectory-out MSE per joint of the residual after the effects.
fn cv_mse_per_joint(data: &Stacked, columns: &[DVector<f64>]) -> Vec<f64> {
    let groups = data.group.iter().max().map_or(0, |g| g + 1);
    let mut sse = vec![0.0; data.dof];
    let mut count = vec![0usize; data.dof];
    for g in 0..groups {
        let train: Vec<usize> = (0..data.group.len())
            .filter(|&r| data.group[r] != g)
            .collect();
        let test: Vec<usize> = (0..data.group.len())
            .filter(|&r| data.group[r] == g)
            .collect();
        let theta = if columns.is_empty() {
            Some(DVector::zeros(0))
        } else {
            let y = DVector::from_fn(train.len(), |r, _| data.residual[train[r]]);
            fit(&design(columns, &train), &y)
        };
        let Some(theta) = theta else {
            return vec![f64::INFINITY; data.dof];
        };
        for &r in &test {
            let predicted: f64 = columns
                .iter()
                .zip(theta.iter())
                .map(|(c, t)| c[r] * t)
                .sum();
            let e = data.residual[r] - predicted;
            sse[r % data.dof] += e * e;
            count[r % data.dof] += 1;
        }
    }
    sse.iter()
        .zip(&count)
        .map(|(s, &c)| s / c.max(1) as f64)
        .collect()
}

fn total(v: &[f64]) -> f64 {
    v.iter().sum()
}

/// Forward selection by cross-validated MSE with a significance check.
fn select(data: &Stacked, candidates: &[Candidate], settings: Settings) -> Vec<usize> {
    let mut selected: Vec<usize> = Vec::new();
    let mut current = total(&cv_mse_per_joint(data, &[]));
    loop {
        let best = (0..candidates.len())
            .filter(|c| !selected.contains(c))
            .map(|c| {
                let mut trial = selected.clone();
                trial.push(c);
                (
                    c,
                    total(&cv_mse_per_joint(data, &columns_of(candidates, &trial))),
                )
            })
            .filter(|(_, mse)| mse.is_finite())
            .min_by(|a, b| a.1.total_cmp(&b.1));
        let Some((c, mse)) = best else { break };
        let mut trial = selected.clone();
        trial.push(c);
        if mse > current * (1.0 - settings.min_gain)
            || !significant(data, candidates, &trial, c, settings.min_t)
        {
            break;
        }
        selected = trial;
        current = mse;
    }
    selected
}

/// Full-data fit: parameters and their standard errors.
fn fit_all(data: &Stacked, columns: &[DVector<f64>]) -> Option<(DVector<f64>, DVector<f64>, f64)> {
    let rows: Vec<usize> = (0..data.residual.len()).collect();
    let x = design(columns, &rows);
    let theta = fit(&x, &data.residual)?;
    let e = &data.residual - &x * &theta;
    let dof = (rows.len().saturating_sub(columns.len())).max(1) as f64;
    let sigma2 = e.norm_squared() / dof;
    let inverse = (x.transpose() * &x).try_inverse()?;
    let se = DVector::from_fn(columns.len(), |k, _| {
        (sigma2 * inverse[(k, k)]).max(0.0).sqrt()
    });
    Some((theta, se, e.norm_squared()))
}

fn significant(
    data: &Stacked,
    candidates: &[Candidate],
    trial: &[usize],
    added: usize,
    min_t: f64,
) -> bool {
    let Some((theta, se, _)) = fit_all(data, &columns_of(candidates, trial)) else {
        return false;
    };
    let offset: usize = trial[..trial.len() - 1]
        .iter()
        .map(|&c| candidates[c].columns.len())
        .sum();
    let width = candidates[added].columns.len();
    if candidates[added].kind == Kind::Payload {
        // The mass decides; COM components may be zero.
        return theta[offset].abs() > min_t * se[offset];
    }
    (offset..offset + width).all(|k| theta[k].abs() > min_t * se[k])
}

fn describe(data: &Stacked, candidates: &[Candidate], selected: &[usize]) -> Vec<Effect> {
    let Some((theta, se, sse_all)) = fit_all(data, &columns_of(candidates, selected)) else {
        return Vec::new();
    };
    let sse_none = data.residual.norm_squared();
    let mut offset = 0;
    let mut effects = Vec::new();
    for (position, &c) in selected.iter().enumerate() {
        let candidate = &candidates[c];
        let width = candidate.columns.len();
        let values: Vec<(f64, f64)> = (offset..offset + width)
            .map(|k| (theta[k], 1.96 * se[k]))
            .collect();
        offset += width;
        let without: Vec<usize> = selected
            .iter()
            .enumerate()
            .filter(|(p, _)| *p != position)
            .map(|(_, &s)| s)
            .collect();
        let sse_without =
            fit_all(data, &columns_of(candidates, &without)).map_or(sse_none, |f| f.2);
        let share = ((sse_without - sse_all) / sse_none).clamp(0.0, 1.0);
        effects.push(effect(candidate, &values, share));
    }
    effects
}

fn effect(candidate: &Candidate, values: &[(f64, f64)], share: f64) -> Effect {
    use serde_json::{Map, Value, json};
    let mut parameters = Map::new();
    let mut ci95 = Map::new();
    if candidate.kind == Kind::Payload {
        let (m, dm) = values[0];
        let com: Vec<f64> = values[1..].iter().map(|(h, _)| h / m).collect();
        // First-order propagation of the m*c uncertainty to c.
        let dcom: Vec<f64> = values[1..]
            .iter()
            .zip(&com)
            .map(|((_, dh), c)| (dh / m).hypot(c * dm / m))
            .collect();
        parameters.insert("mass".into(), json!(m));
        parameters.insert("com".into(), json!(com));
        ci95.insert("mass".into(), json!([m - dm, m + dm]));
        ci95.insert(
            "com".into(),
            Value::Array(
                com.iter()
                    .zip(&dcom)
                    .map(|(c, d)| json!([c - d, c + d]))
                    .collect(),
            ),
        );
    } else {
        for (name, (value, half)) in candidate.names.iter().zip(values) {
            parameters.insert((*name).into(), json!(value));
            ci95.insert((*name).into(), json!([value - half, value + half]));
        }
    }
    Effect {
        kind: candidate.kind,
        joint: candidate.joint.map(|j| j + 1),
        parameters,
        ci95,
        share_explained: share,
    }
}

fn per_joint(data: &Stacked, f: impl Fn(f64, f64) -> f64) -> Vec<f64> {
    let mut sum = vec![0.0; data.dof];
    for r in 0..data.residual.len() {
        sum[r % data.dof] += f(data.residual[r], data.measured[r]);
    }
    let samples = (data.residual.len() / data.dof).max(1) as f64;
    sum.iter().map(|s| s / samples).collect()
}

fn residual_share(data: &Stacked) -> Vec<f64> {
    let residual = per_joint(data, |r, _| r * r);
    let measured = per_joint(data, |_, m| m * m);
    residual
        .iter()
        .zip(&measured)
        .map(|(r, m)| (r / m.max(f64::MIN_POSITIVE)).sqrt())
        .collect()
}

fn regimes(data: &Stacked, candidates: &[Candidate]) -> Vec<Regimes> {
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
                mean: rows.map(|r| data.residual[r]).sum::<f64>() / count,
            }
        })
        .collect()
}

fn correlation(data: &Stacked, joint: usize, column: &DVector<f64>) -> f64 {
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
    if vr <= 0.0 || vc <= 0.0 {
        0.0
    } else {
        cov / (vr * vc).sqrt()
    }
}
