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
//! A fit with a physically impossible sign (negative friction, armature or
//! payload mass) is never named as that effect: it is reported as a note
//! (e.g. a negative "armature" means the model's inertia about that joint is
//! too high) and selection goes on with the other candidates.
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
    /// Fraction of the residual sum of squares this effect removes: of its
    /// joint's residual for a joint effect, of all joints' for a payload.
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
    /// Structure the data supports but no physical effect explains, e.g. a
    /// negative armature (the model's inertia about a joint is too high).
    pub notes: Vec<String>,
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
    /// The arm's size (m): a payload's centre of mass must lie within it
    /// (see [`reach`]); infinite accepts any.
    pub reach: f64,
}

/// The arm's size: the summed joint offsets of the chain, base to tip.
pub fn reach(model: &dyn Dynamics) -> f64 {
    crate::dynamics::parsed_description(model).map_or(f64::INFINITY, |d| {
        d.chain().bodies.iter().map(|b| b.translation.norm()).sum()
    })
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            min_gain: 0.10,
            min_t: 3.0,
            reach: f64::INFINITY,
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

/// Second moments of all candidate columns and the residual, per
/// trajectory and joint: every least-squares fit and cross-validation fold
/// is then a small solve, independent of the number of samples.
struct Moments {
    /// `[group][joint]`: X^T X, X^T r, r^T r and the row count.
    xx: Vec<Vec<DMatrix<f64>>>,
    xr: Vec<Vec<DVector<f64>>>,
    rr: Vec<Vec<f64>>,
    rows: Vec<Vec<usize>>,
}

impl Moments {
    fn new(data: &Stacked, candidates: &[Candidate]) -> Moments {
        let columns: Vec<&DVector<f64>> =
            candidates.iter().flat_map(|c| c.columns.iter()).collect();
        let p = columns.len();
        let groups = data.group.iter().max().map_or(0, |g| g + 1);
        let mut m = Moments {
            xx: vec![vec![DMatrix::zeros(p, p); data.dof]; groups],
            xr: vec![vec![DVector::zeros(p); data.dof]; groups],
            rr: vec![vec![0.0; data.dof]; groups],
            rows: vec![vec![0; data.dof]; groups],
        };
        for (r, (&g, &y)) in data.group.iter().zip(data.residual.iter()).enumerate() {
            let j = r % data.dof;
            let x = DVector::from_fn(p, |k, _| columns[k][r]);
            m.xx[g][j].ger(1.0, &x, &x, 1.0);
            m.xr[g][j].axpy(y, &x, 1.0);
            m.rr[g][j] += y * y;
            m.rows[g][j] += 1;
        }
        m
    }

    /// Sums of X^T X and X^T r over the groups `keep` accepts, restricted to `columns`.
    fn normal_equations(
        &self,
        columns: &[usize],
        keep: impl Fn(usize) -> bool,
    ) -> (DMatrix<f64>, DVector<f64>) {
        let k = columns.len();
        let (mut a, mut b) = (DMatrix::zeros(k, k), DVector::zeros(k));
        for g in (0..self.xx.len()).filter(|&g| keep(g)) {
            for j in 0..self.xx[g].len() {
                a += self.xx[g][j].select_rows(columns).select_columns(columns);
                b += self.xr[g][j].select_rows(columns);
            }
        }
        (a, b)
    }

    /// Residual sum of squares of group g, joint j after subtracting X theta.
    fn sse(&self, g: usize, j: usize, columns: &[usize], theta: &DVector<f64>) -> f64 {
        let a = self.xx[g][j].select_rows(columns).select_columns(columns);
        let b = self.xr[g][j].select_rows(columns);
        self.rr[g][j] - 2.0 * theta.dot(&b) + theta.dot(&(a * theta))
    }
}

/// Diagnoses `model` on preprocessed trajectories (with qdd).
pub fn diagnose(
    model: &dyn Dynamics,
    trajectories: &[Trajectory],
    settings: Settings,
) -> anyhow::Result<Diagnosis> {
    if trajectories.len() < 2 {
        anyhow::bail!(
            "diagnosis needs at least 2 trajectories to cross-validate, got {} (cut one recording into pieces with --segments N)",
            trajectories.len()
        );
    }
    reject_duplicates(trajectories)?;
    let (data, candidates) = stack(model, trajectories)?;
    let moments = Moments::new(&data, &candidates);
    let (selected, notes) = select(&moments, data.dof, &candidates, settings);
    let mse_before = cv_mse_per_joint(&moments, data.dof, &[]);
    let mse_after = cv_mse_per_joint(&moments, data.dof, &columns_of(&candidates, &selected));
    let effects = describe(&moments, &candidates, &selected);
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
        notes,
    })
}

/// The same recording passed twice would leak into its own held-out fold.
fn reject_duplicates(trajectories: &[Trajectory]) -> anyhow::Result<()> {
    for (a, first) in trajectories.iter().enumerate() {
        for (b, second) in trajectories.iter().enumerate().skip(a + 1) {
            if first.t() == second.t() && first.q() == second.q() {
                anyhow::bail!(
                    "trajectories {} and {} hold the same samples: pass each recording once \
                     (use --segments to cross-validate within one recording)",
                    a + 1,
                    b + 1
                );
            }
        }
    }
    Ok(())
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

/// Global column indices of the selected candidates.
fn columns_of(candidates: &[Candidate], selected: &[usize]) -> Vec<usize> {
    let offsets: Vec<usize> = candidates
        .iter()
        .scan(0, |at, c| {
            let start = *at;
            *at += c.columns.len();
            Some(start)
        })
        .collect();
    selected
        .iter()
        .flat_map(|&c| offsets[c]..offsets[c] + candidates[c].columns.len())
        .collect()
}

/// Solves the normal equations; `None` when the columns are (nearly) collinear.
fn solve(a: DMatrix<f64>, b: &DVector<f64>) -> Option<DVector<f64>> {
    Some(a.cholesky()?.solve(b))
}

/// Leave-one-trajectory-out MSE per joint of the residual after the effects.
fn cv_mse_per_joint(m: &Moments, dof: usize, columns: &[usize]) -> Vec<f64> {
    let mut sse = vec![0.0; dof];
    let mut count = vec![0usize; dof];
    for g in 0..m.xx.len() {
        let (a, b) = m.normal_equations(columns, |h| h != g);
        let theta = if columns.is_empty() {
            Some(DVector::zeros(0))
        } else {
            solve(a, &b)
        };
        let Some(theta) = theta else {
            return vec![f64::INFINITY; dof];
        };
        for j in 0..dof {
            sse[j] += m.sse(g, j, columns, &theta);
            count[j] += m.rows[g][j];
        }
    }
    sse.iter()
        .zip(&count)
        .map(|(s, &c)| s / c.max(1) as f64)
        .collect()
}

/// Largest relative drop of any joint's MSE from `before` to `after`.
fn relative_gain(before: &[f64], after: &[f64]) -> f64 {
    before
        .iter()
        .zip(after)
        .map(|(b, a)| if *b > 0.0 { (b - a) / b } else { 0.0 })
        .fold(f64::NEG_INFINITY, f64::max)
}

/// Forward selection by cross-validated MSE with a significance check: each
/// step adds the candidate that lowers some joint's held-out MSE the most
/// (relative to that joint's current MSE, so a weak joint's effect is not
/// drowned by a strong joint's torque scale).
fn select(
    m: &Moments,
    dof: usize,
    candidates: &[Candidate],
    settings: Settings,
) -> (Vec<usize>, Vec<String>) {
    let mut selected: Vec<usize> = Vec::new();
    let mut refused: Vec<usize> = Vec::new();
    let mut notes = Vec::new();
    let mut current = cv_mse_per_joint(m, dof, &[]);
    loop {
        let best = (0..candidates.len())
            .filter(|c| !selected.contains(c) && !refused.contains(c))
            .map(|c| {
                let mut trial = selected.clone();
                trial.push(c);
                let mse = cv_mse_per_joint(m, dof, &columns_of(candidates, &trial));
                (c, relative_gain(&current, &mse), mse)
            })
            .filter(|(_, gain, _)| gain.is_finite())
            .max_by(|a, b| a.1.total_cmp(&b.1));
        let Some((c, gain, mse)) = best else { break };
        let mut trial = selected.clone();
        trial.push(c);
        if gain < settings.min_gain {
            break;
        }
        let Some(values) = significant(m, candidates, &trial, c, settings.min_t) else {
            break;
        };
        if let Err(note) = physical(&candidates[c], &values, gain, settings.reach) {
            notes.push(note);
            refused.push(c);
            continue;
        }
        selected = trial;
        current = mse;
    }
    (selected, notes)
}

/// Whether fitted `values` can be the candidate's physical effect; if not,
/// the note that says what the data show instead.
fn physical(candidate: &Candidate, values: &[f64], gain: f64, reach: f64) -> Result<(), String> {
    let at = candidate
        .joint
        .map_or("the last link".to_string(), |j| format!("joint {}", j + 1));
    let percent = 100.0 * gain;
    let value = values[0];
    let meaning = match candidate.kind {
        Kind::TorqueOffset => return Ok(()),
        _ if value <= 0.0 => match candidate.kind {
            Kind::Armature => {
                "the model's inertia about this joint is too high (an inertial error, not a rotor)"
            }
            Kind::ViscousFriction => {
                "torque falls with speed: not viscous friction (check the velocity filter, or a Stribeck effect)"
            }
            Kind::CoulombFriction => {
                "the residual opposes friction's direction: check the torque sign convention"
            }
            _ => "the last link is lighter than modelled (an inertial error, not a payload)",
        },
        Kind::Payload => {
            let com: Vec<f64> = values[1..].iter().map(|h| h / value).collect();
            let distance = com.iter().map(|c| c * c).sum::<f64>().sqrt();
            if distance <= reach {
                return Ok(());
            }
            return Err(format!(
                "{at}: the data fit a first-moment change m*c = [{:.4}, {:.4}, {:.4}] kg m with a mass of \
                 only {value:.4} kg, i.e. a centre of mass {distance:.2} m away, beyond the arm's reach \
                 ({reach:.2} m): an inertial error of the last link, not a payload; not named \
                 (it would cut a joint's held-out MSE by {percent:.0}%)",
                values[1], values[2], values[3]
            ));
        }
        _ => return Ok(()),
    };
    let kind = serde_json::to_value(candidate.kind)
        .ok()
        .and_then(|v| v.as_str().map(str::to_string))
        .unwrap_or_default();
    Err(format!(
        "{at}: the data fit {kind} = {value:.4}, a negative value (it would cut a joint's \
         held-out MSE by {percent:.0}%): {meaning}; not named"
    ))
}

/// Full-data fit: parameters, their standard errors, and the residual SSE.
fn fit_all(m: &Moments, columns: &[usize]) -> Option<(DVector<f64>, DVector<f64>, f64)> {
    let (a, b) = m.normal_equations(columns, |_| true);
    let theta = solve(a.clone(), &b)?;
    let groups = 0..m.xx.len();
    let sse: f64 = groups
        .clone()
        .flat_map(|g| (0..m.xx[g].len()).map(move |j| (g, j)))
        .map(|(g, j)| m.sse(g, j, columns, &theta))
        .sum();
    let rows: usize = m.rows.iter().flatten().sum();
    let sigma2 = sse.max(0.0) / (rows.saturating_sub(columns.len())).max(1) as f64;
    let inverse = a.try_inverse()?;
    let se = DVector::from_fn(columns.len(), |k, _| {
        (sigma2 * inverse[(k, k)]).max(0.0).sqrt()
    });
    Some((theta, se, sse))
}

/// The fitted parameters of `added` when every parameter that must be is
/// significant (a payload's mass; its COM components may be zero).
fn significant(
    m: &Moments,
    candidates: &[Candidate],
    trial: &[usize],
    added: usize,
    min_t: f64,
) -> Option<Vec<f64>> {
    let (theta, se, _) = fit_all(m, &columns_of(candidates, trial))?;
    let offset: usize = trial[..trial.len() - 1]
        .iter()
        .map(|&c| candidates[c].columns.len())
        .sum();
    let width = candidates[added].columns.len();
    let tested = if candidates[added].kind == Kind::Payload {
        1
    } else {
        width
    };
    (offset..offset + tested)
        .all(|k| theta[k].abs() > min_t * se[k])
        .then(|| theta.rows(offset, width).iter().copied().collect())
}

fn describe(m: &Moments, candidates: &[Candidate], selected: &[usize]) -> Vec<Effect> {
    let Some((theta, se, _)) = fit_all(m, &columns_of(candidates, selected)) else {
        return Vec::new();
    };
    let all = columns_of(candidates, selected);
    let sse_none = sse_per_joint(m, &[], &DVector::zeros(0));
    let sse_with = sse_per_joint(m, &all, &theta);
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
        let rest = columns_of(candidates, &without);
        let sse_without = fit_all(m, &rest).map_or(sse_none.clone(), |(theta, _, _)| {
            sse_per_joint(m, &rest, &theta)
        });
        let share = match candidate.joint {
            Some(j) => (sse_without[j] - sse_with[j]) / sse_none[j],
            None => {
                let total = |v: &[f64]| v.iter().sum::<f64>();
                (total(&sse_without) - total(&sse_with)) / total(&sse_none)
            }
        };
        let share = share.clamp(0.0, 1.0);
        effects.push(effect(candidate, &values, share));
    }
    effects
}

/// Residual SSE per joint over all samples with `columns` fitted as `theta`.
fn sse_per_joint(m: &Moments, columns: &[usize], theta: &DVector<f64>) -> Vec<f64> {
    let joints = m.xx.first().map_or(0, Vec::len);
    (0..joints)
        .map(|j| (0..m.xx.len()).map(|g| m.sse(g, j, columns, theta)).sum())
        .collect()
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

#[cfg(test)]
mod tests {
    use super::*;

    fn candidate(kind: Kind, joint: Option<usize>) -> Candidate {
        Candidate {
            kind,
            joint,
            names: vec![],
            columns: vec![],
        }
    }

    #[test]
    fn impossible_signs_become_notes() {
        let armature = candidate(Kind::Armature, Some(3));
        let note = physical(&armature, &[-0.1], 0.15, 1.0).unwrap_err();
        assert!(
            note.starts_with("joint 4:") && note.contains("inertia"),
            "{note}"
        );
        assert!(physical(&armature, &[0.1], 0.15, 1.0).is_ok());
        let offset = candidate(Kind::TorqueOffset, Some(0));
        assert!(physical(&offset, &[-0.3], 0.5, 1.0).is_ok());
    }

    #[test]
    fn a_payload_beyond_the_arm_is_a_note() {
        let payload = candidate(Kind::Payload, None);
        // 0.5 kg at 0.1 m: a payload.
        assert!(physical(&payload, &[0.5, 0.0, 0.0, 0.05], 0.3, 1.0).is_ok());
        // 7 g with m*c of 0.012 kg m: a COM 1.7 m away.
        let note = physical(&payload, &[0.007, 0.0, 0.0, 0.012], 0.3, 1.0).unwrap_err();
        assert!(note.contains("first-moment"), "{note}");
    }
}
