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
//! by at least `min_gain` and its parameters are significant (|t| > 3, each
//! with the larger of its least-squares and its delete-one-trajectory
//! jackknife standard error, as are the reported 95% intervals).
//! A fit with a physically impossible sign (negative friction, armature or
//! payload mass) is never named as that effect: it is reported as a note
//! (e.g. a negative "armature" means the model's inertia about that joint is
//! too high) and selection goes on with the other candidates.
//! Parameters come from least squares with 95% confidence intervals.
//!
//! Inertial effects are fitted as physical bodies, not as free columns:
//! - `payload`: a point mass m at c (last link's frame) added to the last
//!   link. Its standard parameters are m * [1, c, |c|^2 E - c c^T] (the
//!   inertia about the link origin included, which is what a point mass at
//!   c adds), so the fit is nonlinear in c: Levenberg-Marquardt on the
//!   moment matrices of the link's ten inertial regressor columns, started
//!   from the linear fit of its mass and first-moment columns.
//! - `inertial_error`: the mass and centre of mass of a link other than the
//!   last differ from the model, its inertia about its centre of mass as
//!   modelled. Standard parameters [m', m'c', I_C + m'(|c'|^2 E - c'c'^T)]
//!   minus the model's; reported as the corrected mass and COM.
//!
//! A link's mass is identifiable from torques only through the acceleration
//! of the link's origin (its mass column in the regressor); its first
//! moment m*c and inertia have their own columns. When the origin lies on
//! the axes of every joint that moves the link (link 2 of the 3-DOF Kinova:
//! on both the joint-1 and joint-2 axes), that column vanishes and a fitted
//! mass would come only from the parallel-axis terms of the assumed inertia
//! about the COM. Rule ([`mass_identifiable`]): with the mass put in the
//! first moments' units by the arm's size, the mass is identifiable when the
//! information left about it once the link's first moments are projected
//! out is at least [`COLLINEAR`] times the largest eigenvalue of the link's
//! (mass, first moment) information. When it is not, the candidate fits the
//! first moment h = m*c alone (the mass held as modelled, the inertia about
//! the COM as modelled) and reports `first_moment` (kg m, with 95% CIs),
//! `mass` and `com` as `null` and a note saying why; `--apply` then keeps
//! the mass and moves the COM to h / (modelled mass), the assumption the
//! note states, and never changes the mass.
//!
//! Naming rule on the last link: an added point mass and a heavier last link
//! change the same mass and first-moment columns (they differ only in
//! second moments, which these data barely separate), so the last link gets
//! one candidate, the payload: mass added at the tip. A negative fitted
//! payload mass is a note (the last link is lighter than modelled), never a
//! payload. Links before the last get `inertial_error` candidates.
//!
//! Identifiability: a candidate whose parameters the data cannot separate
//! (its information matrix, after the already-selected effects are
//! projected out and scaled to unit diagonal, has a relative eigenvalue
//! below [`COLLINEAR`]: collinear columns, or parameters that only enter
//! through a base-parameter combination, such as the first link's mass and
//! COM, which act only through its inertia about the first axis) is never
//! named; if it would have been selected, a note says so. A named payload's
//! or link's COM (or first-moment) component whose 95% confidence
//! half-width exceeds [`Settings::com_resolution`] of the arm's size is
//! reported with its wide interval and a note: the data barely determine it
//! (typically the component along the joint axes, which acts only through
//! couplings with the first joint), so the torques barely depend on it.

use nalgebra::{DMatrix, DVector, Vector3};
use serde::Serialize;

use crate::dynamics::Dynamics;
use crate::oracle::coulomb_sign;
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
    /// A link's mass and centre of mass differ from the model (`link`,
    /// corrected `mass` kg and `com` [x, y, z] m in the link frame, and the
    /// model's `nominal_mass`, `nominal_com`).
    InertialError,
}

impl Kind {
    /// The kind as JSON names it (`viscous_friction`, ...).
    pub fn name(self) -> String {
        serde_json::to_value(self)
            .ok()
            .and_then(|v| v.as_str().map(str::to_string))
            .unwrap_or_default()
    }
}

/// A named missing effect with its fitted parameters.
#[derive(Debug, Clone, Serialize)]
pub struct Effect {
    pub kind: Kind,
    /// 1-based joint, or `None` for a payload or an inertial error.
    pub joint: Option<usize>,
    /// The link (its name in the description) of a payload or inertial error.
    pub link: Option<String>,
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
    /// Every sample's residual before and after the named effects (fitted
    /// to all data), for plots; not part of the JSON report.
    #[serde(skip)]
    pub residuals: ResidualSamples,
}

/// Per sample and joint (row `sample * dof + joint`): the joint's velocity
/// and acceleration and its residual with the nominal model and with the
/// named effects added.
#[derive(Debug, Clone, Default)]
pub struct ResidualSamples {
    pub dof: usize,
    pub qd: Vec<f64>,
    pub qdd: Vec<f64>,
    pub before: Vec<f64>,
    pub after: Vec<f64>,
}

/// Residual structure of one joint.
#[derive(Debug, Clone, Serialize)]
pub struct Regimes {
    pub velocity: f64,
    pub velocity_sign: f64,
    pub acceleration: f64,
    /// Correlation with the model's gravity torque of the joint (a
    /// configuration-dependent error: mass, COM, payload).
    pub gravity_load: f64,
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
    /// A COM component whose 95% confidence half-width exceeds this fraction
    /// of the arm's size ([`reach`] of the model; 1 m when the model has no
    /// description) gets a note that the data barely determine it.
    pub com_resolution: f64,
}

/// Relative eigenvalue of a candidate's unit-diagonal information matrix
/// below which its parameters are taken as not identifiable.
pub const COLLINEAR: f64 = 1e-6;

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
            com_resolution: 0.05,
        }
    }
}

/// One candidate: a kind, a joint or link, its columns and how its named
/// parameters map to coefficients of those columns.
struct Candidate {
    kind: Kind,
    joint: Option<usize>,
    /// 0-based moving link and its name, for inertial candidates.
    link: Option<(usize, String)>,
    names: Vec<&'static str>,
    columns: Vec<DVector<f64>>,
    /// What the generated model computes for this effect once applied, when
    /// that differs from the fitted column (Coulomb: the fit leaves out
    /// samples near rest, the model's sign(qd) does not). Held-out errors are
    /// scored with it, so they are what the applied model will show.
    applied: Option<DVector<f64>>,
    shape: Shape,
}

/// Parameters -> column coefficients.
#[derive(Debug, Clone)]
enum Shape {
    /// The parameters are the coefficients.
    Linear,
    /// theta = (m, cx, cy, cz) over a link's ten inertial columns:
    /// coefficients m * [1, c, |c|^2 E - c c^T] + `offset`, and `base` the
    /// (mass, first moment) the linear start adds its fit to.
    Body {
        offset: [f64; 10],
        base_mass: f64,
        base_moment: Vector3<f64>,
    },
    /// theta = the first moment h = m c of a link whose mass the data cannot
    /// identify (see [`mass_identifiable`]), the mass held at the model's
    /// `base_mass`: coefficients point_mass(base_mass, h / base_mass) +
    /// `offset`, the inertia about the COM as modelled.
    Moment {
        offset: [f64; 10],
        base_mass: f64,
        base_moment: Vector3<f64>,
    },
}

impl Shape {
    fn width(&self, columns: usize) -> usize {
        match self {
            Shape::Linear => columns,
            Shape::Body { .. } => 4,
            Shape::Moment { .. } => 3,
        }
    }

    /// Coefficients and their Jacobian at theta.
    fn map(&self, theta: &[f64]) -> (Vec<f64>, DMatrix<f64>) {
        match self {
            Shape::Linear => (theta.to_vec(), DMatrix::identity(theta.len(), theta.len())),
            Shape::Body { offset, .. } => {
                let (m, c) = (theta[0], Vector3::new(theta[1], theta[2], theta[3]));
                let unit = point_mass(1.0, &c);
                let coefficients = (0..10).map(|k| m * unit[k] + offset[k]).collect();
                let mut jacobian = DMatrix::zeros(10, 4);
                for k in 0..10 {
                    jacobian[(k, 0)] = unit[k];
                }
                let (x, y, z) = (c.x, c.y, c.z);
                let partial = [
                    [0.0, 1.0, 0.0, 0.0, 0.0, -y, 2.0 * x, -z, 0.0, 2.0 * x],
                    [0.0, 0.0, 1.0, 0.0, 2.0 * y, -x, 0.0, 0.0, -z, 2.0 * y],
                    [0.0, 0.0, 0.0, 1.0, 2.0 * z, 0.0, 2.0 * z, -x, -y, 0.0],
                ];
                for (a, row) in partial.iter().enumerate() {
                    for k in 0..10 {
                        jacobian[(k, a + 1)] = m * row[k];
                    }
                }
                (coefficients, jacobian)
            }
            Shape::Moment {
                offset, base_mass, ..
            } => {
                let m = *base_mass;
                let c = Vector3::new(theta[0], theta[1], theta[2]) / m;
                let unit = point_mass(1.0, &c);
                let coefficients = (0..10).map(|k| m * unit[k] + offset[k]).collect();
                // d(m unit(h / m)) / dh = d unit / dc.
                let (x, y, z) = (c.x, c.y, c.z);
                let partial = [
                    [0.0, 1.0, 0.0, 0.0, 0.0, -y, 2.0 * x, -z, 0.0, 2.0 * x],
                    [0.0, 0.0, 1.0, 0.0, 2.0 * y, -x, 0.0, 0.0, -z, 2.0 * y],
                    [0.0, 0.0, 0.0, 1.0, 2.0 * z, 0.0, 2.0 * z, -x, -y, 0.0],
                ];
                let jacobian = DMatrix::from_fn(10, 3, |k, a| partial[a][k]);
                (coefficients, jacobian)
            }
        }
    }
}

/// Standard parameters (m, m*c, inertia about the origin in the order
/// ixx, ixy, iyy, ixz, iyz, izz) of a point mass m at c.
fn point_mass(m: f64, c: &Vector3<f64>) -> [f64; 10] {
    let (x, y, z) = (c.x, c.y, c.z);
    [
        m,
        m * x,
        m * y,
        m * z,
        m * (y * y + z * z),
        -m * x * y,
        m * (x * x + z * z),
        -m * x * z,
        -m * y * z,
        m * (x * x + y * y),
    ]
}

/// Stacked data: rows are (sample, joint) pairs, sample-major.
struct Stacked {
    residual: DVector<f64>,
    measured: DVector<f64>,
    qd: DVector<f64>,
    qdd: DVector<f64>,
    /// The model's gravity torque.
    gravity: DVector<f64>,
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
    /// For each candidate column, the moment column that scores it (itself,
    /// or its `applied` column stored after all candidate columns).
    applied: Vec<usize>,
}

impl Moments {
    fn new(data: &Stacked, candidates: &[Candidate]) -> Moments {
        let mut columns: Vec<&DVector<f64>> =
            candidates.iter().flat_map(|c| c.columns.iter()).collect();
        let mut applied: Vec<usize> = (0..columns.len()).collect();
        let mut at = 0;
        for c in candidates {
            if let Some(column) = &c.applied {
                applied[at] = columns.len();
                columns.push(column);
            }
            at += c.columns.len();
        }
        let p = columns.len();
        let groups = data.group.iter().max().map_or(0, |g| g + 1);
        let mut m = Moments {
            xx: vec![vec![DMatrix::zeros(p, p); data.dof]; groups],
            xr: vec![vec![DVector::zeros(p); data.dof]; groups],
            rr: vec![vec![0.0; data.dof]; groups],
            rows: vec![vec![0; data.dof]; groups],
            applied,
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

    /// The scoring columns of fitted `columns` (see `Candidate::applied`).
    fn applied(&self, columns: &[usize]) -> Vec<usize> {
        columns.iter().map(|&c| self.applied[c]).collect()
    }

    /// Residual sum of squares of group g, joint j after subtracting X theta.
    fn sse(&self, g: usize, j: usize, columns: &[usize], theta: &DVector<f64>) -> f64 {
        let a = self.xx[g][j].select_rows(columns).select_columns(columns);
        let b = self.xr[g][j].select_rows(columns);
        // Clamped: rounding can push a near-perfect fit's sum below zero.
        (self.rr[g][j] - 2.0 * theta.dot(&b) + theta.dot(&(a * theta))).max(0.0)
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
    let size = Some(reach(model))
        .filter(|r| r.is_finite() && *r > 0.0)
        .unwrap_or(1.0);
    let (data, mut candidates) = stack(model, trajectories)?;
    let moments = Moments::new(&data, &candidates);
    let massless: Vec<usize> = (0..candidates.len())
        .filter(|&c| !mass_identifiable(&moments, &candidates, c, size))
        .collect();
    for c in massless {
        if let Shape::Body {
            offset,
            base_mass,
            base_moment,
        } = candidates[c].shape
        {
            candidates[c].shape = Shape::Moment {
                offset,
                base_mass,
                base_moment,
            };
            candidates[c].names = vec!["mx", "my", "mz"];
        }
    }
    let (selected, mut notes) = select(&moments, data.dof, &candidates, settings);
    let mse_before = cv_mse_per_joint(&moments, data.dof, &candidates, &[]);
    let mse_after = cv_mse_per_joint(&moments, data.dof, &candidates, &selected);
    let effects = describe(
        &moments,
        &candidates,
        &selected,
        settings.com_resolution * size,
        &mut notes,
    );
    let residuals = residual_samples(&data, &moments, &candidates, &selected);
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
        residuals,
    })
}

/// The residuals before and after subtracting what the selected effects,
/// fitted to all data, add to the model (as the applied model computes it).
fn residual_samples(
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

/// Whether the data identify the mass of an `inertial_error` candidate's
/// link from its own regressor column, i.e. from the acceleration of the
/// link's origin (true for every other candidate). The mass is put in the
/// first moments' units by the arm's size `lever` (a mass change dm acts
/// like a first-moment change of dm * lever), which makes the link's 4x4
/// information matrix of (mass, first moment) dimensionally consistent; the
/// mass is identifiable when its information left once the first moments
/// are projected out (the Schur complement) is at least [`COLLINEAR`] times
/// that matrix's largest eigenvalue. A link whose origin lies on the axes of
/// all joints that move it has a zero mass column: its mass enters the
/// torques only through the parallel-axis terms of an assumed inertia about
/// the COM, which the data do not check.
fn mass_identifiable(m: &Moments, candidates: &[Candidate], c: usize, lever: f64) -> bool {
    let candidate = &candidates[c];
    if candidate.kind != Kind::InertialError
        || !matches!(candidate.shape, Shape::Body { base_mass, .. } if base_mass > 0.0)
    {
        return true;
    }
    let columns: Vec<usize> = columns_of(candidates, &[c]).into_iter().take(4).collect();
    let (mut a, _) = m.normal_equations(&columns, |_| true);
    for k in 0..4 {
        a[(0, k)] /= lever;
        a[(k, 0)] /= lever;
    }
    let largest = a.symmetric_eigenvalues().max();
    if largest <= 0.0 {
        return false;
    }
    let h = a.view((1, 1), (3, 3)).into_owned();
    let coupling = a.view((1, 0), (3, 1)).column(0).into_owned();
    let schur = a[(0, 0)] - coupling.dot(&pseudo_solve(&h, &coupling));
    schur >= COLLINEAR * largest
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

/// A moving link of the model: its name and standard parameters.
struct Link {
    name: String,
    parameters: [f64; 10],
}

fn links(model: &dyn Dynamics) -> Vec<Link> {
    let names: Vec<String> = crate::dynamics::parsed_description(model)
        .map(|d| d.chain().bodies.iter().map(|b| b.link.clone()).collect())
        .unwrap_or_default();
    (0..model.dof())
        .map(|k| {
            let mut parameters = [0.0; 10];
            if let Some(p) = model.parameters().get(10 * k..10 * k + 10) {
                parameters.copy_from_slice(p);
            }
            Link {
                name: names
                    .get(k)
                    .cloned()
                    .unwrap_or_else(|| format!("link {}", k + 1)),
                parameters,
            }
        })
        .collect()
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
    let mut gravity = DVector::zeros(rows);
    let mut inertial = vec![DVector::zeros(rows); 10 * n];
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
            let q = row(traj.q());
            let y = model.regressor(&q, &row(traj.qd()), &row(accel))?;
            let load = model.gravity(&q)?;
            for i in 0..n {
                gravity[at] = load[i];
                residual[at] = traj.tau()[(s, i)] - predicted[(s, i)];
                measured[at] = traj.tau()[(s, i)];
                qd[at] = traj.qd()[(s, i)];
                qdd[at] = accel[(s, i)];
                for (k, column) in inertial.iter_mut().enumerate() {
                    column[at] = y[(i, k)];
                }
                group.push(g);
                at += 1;
            }
        }
    }
    let data = Stacked {
        residual,
        measured,
        qd,
        qdd,
        gravity,
        group,
        dof: n,
    };
    let candidates = candidates(&data, inertial, &links(model));
    Ok((data, candidates))
}

fn candidates(data: &Stacked, mut inertial: Vec<DVector<f64>>, links: &[Link]) -> Vec<Candidate> {
    let (n, qd, qdd) = (data.dof, &data.qd, &data.qdd);
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
            link: None,
            names: vec![name],
            columns: vec![own(j, f)],
            applied: None,
            shape: Shape::Linear,
        };
        list.push(one(Kind::ViscousFriction, "coefficient", &|r| qd[r]));
        list.push(Candidate {
            applied: Some(own(j, &|r| coulomb_sign(qd[r]))),
            ..one(Kind::CoulombFriction, "level", &|r| moving_sign(qd[r]))
        });
        list.push(one(Kind::Armature, "inertia", &|r| qdd[r]));
        list.push(one(Kind::TorqueOffset, "offset", &|_| 1.0));
    }
    for (k, link) in links.iter().enumerate().rev() {
        let columns: Vec<DVector<f64>> = inertial.drain(10 * k..).collect();
        let (mass, moment) = (
            link.parameters[0],
            Vector3::new(link.parameters[1], link.parameters[2], link.parameters[3]),
        );
        let shape = if k + 1 == n {
            Shape::Body {
                offset: [0.0; 10],
                base_mass: 0.0,
                base_moment: Vector3::zeros(),
            }
        } else {
            let com = if mass > 0.0 {
                moment / mass
            } else {
                Vector3::zeros()
            };
            Shape::Body {
                offset: point_mass(-mass, &com),
                base_mass: mass,
                base_moment: moment,
            }
        };
        list.push(Candidate {
            kind: if k + 1 == n {
                Kind::Payload
            } else {
                Kind::InertialError
            },
            joint: None,
            link: Some((k, link.name.clone())),
            names: vec!["mass", "cx", "cy", "cz"],
            columns,
            applied: None,
            shape,
        });
    }
    list
}

/// Joints slower than this (rad/s) are taken as at rest for the Coulomb fit:
/// their friction is static, anywhere between the Coulomb levels, and a
/// measured velocity that small has an unreliable sign (noise), which would
/// bias the level low. Held-out errors are still scored with the generated
/// model's plain sign(qd) (`Candidate::applied`).
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

fn width(candidate: &Candidate) -> usize {
    candidate.shape.width(candidate.columns.len())
}

/// Smallest squared Cholesky pivot of a unit-diagonal matrix that
/// [`pseudo_solve`] trusts; below it the SVD decides what is singular.
const CHOLESKY_PIVOT: f64 = 1e-8;

/// A least-squares fit of some candidates.
struct Fit {
    /// The candidates' parameters, concatenated in selection order.
    theta: DVector<f64>,
    /// Coefficients of their columns ([`columns_of`] order).
    coefficients: DVector<f64>,
    /// Information matrix J^T J at `theta`, J the residual's Jacobian.
    information: DMatrix<f64>,
}

/// Solves H x = g for a symmetric positive semi-definite H by the
/// pseudo-inverse of its unit-diagonal scaling (minimum-norm in scaled
/// parameters when H is singular). A Cholesky factor whose pivots all stay
/// above [`CHOLESKY_PIVOT`] (a well-conditioned H, nearly every call) solves
/// it at a fraction of the SVD's cost, with the same solution.
fn pseudo_solve(h: &DMatrix<f64>, g: &DVector<f64>) -> DVector<f64> {
    let k = h.nrows();
    if k == 0 {
        return DVector::zeros(0);
    }
    let d = DVector::from_fn(k, |i, _| {
        let v = h[(i, i)];
        if v > 0.0 { v.sqrt() } else { 1.0 }
    });
    let scaled = DMatrix::from_fn(k, k, |i, j| h[(i, j)] / (d[i] * d[j]));
    let rhs = DVector::from_fn(k, |i, _| g[i] / d[i]);
    if let Some(cholesky) = scaled.clone().cholesky() {
        let l = cholesky.l_dirty();
        if (0..k).all(|i| l[(i, i)] * l[(i, i)] > CHOLESKY_PIVOT) {
            let x = cholesky.solve(&rhs);
            return DVector::from_fn(k, |i, _| x[i] / d[i]);
        }
    }
    let svd = scaled.svd(true, true);
    let tolerance = 1e-12 * svd.singular_values.max().max(f64::MIN_POSITIVE);
    let x = svd
        .solve(&rhs, tolerance)
        .unwrap_or_else(|_| DVector::zeros(k));
    DVector::from_fn(k, |i, _| x[i] / d[i])
}

/// Column coefficients and their Jacobian for concatenated parameters.
fn coefficients(
    candidates: &[Candidate],
    selected: &[usize],
    theta: &DVector<f64>,
) -> (DVector<f64>, DMatrix<f64>) {
    let columns: usize = selected.iter().map(|&c| candidates[c].columns.len()).sum();
    let mut coefficients = DVector::zeros(columns);
    let mut jacobian = DMatrix::zeros(columns, theta.len());
    let (mut row, mut col) = (0, 0);
    for &c in selected {
        let candidate = &candidates[c];
        let w = width(candidate);
        let parameters: Vec<f64> = theta.rows(col, w).iter().copied().collect();
        let (values, d) = candidate.shape.map(&parameters);
        for (k, v) in values.iter().enumerate() {
            coefficients[row + k] = *v;
        }
        jacobian
            .view_mut((row, col), (values.len(), w))
            .copy_from(&d);
        row += values.len();
        col += w;
    }
    (coefficients, jacobian)
}

/// Fits the `selected` candidates on the groups `keep` accepts: linear
/// candidates exactly, bodies by Levenberg-Marquardt from the linear fit of
/// their mass and first-moment columns. `None` when there are no data.
fn fit(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
    keep: impl Fn(usize) -> bool,
) -> Option<Fit> {
    let columns = columns_of(candidates, selected);
    let (a, b) = m.normal_equations(&columns, keep);
    if a.nrows() > 0 && a.diagonal().iter().all(|v| *v == 0.0) {
        return None;
    }
    // Start: linear fit of every linear column and each body's first four.
    let mut start_columns = Vec::new();
    let mut at = 0;
    for &c in selected {
        match candidates[c].shape {
            Shape::Linear => start_columns.extend(at..at + candidates[c].columns.len()),
            Shape::Body { .. } => start_columns.extend(at..at + 4),
            // The mass column carries no information (that is why the shape
            // was chosen): start from the first-moment columns alone.
            Shape::Moment { .. } => start_columns.extend(at + 1..at + 4),
        }
        at += candidates[c].columns.len();
    }
    let a0 = a.select_rows(&start_columns).select_columns(&start_columns);
    let x0 = pseudo_solve(&a0, &b.select_rows(&start_columns));
    let mut theta = Vec::new();
    let mut at = 0;
    for &c in selected {
        match &candidates[c].shape {
            Shape::Linear => {
                let count = candidates[c].columns.len();
                theta.extend(x0.rows(at, count).iter());
                at += count;
            }
            Shape::Body {
                base_mass,
                base_moment,
                ..
            } => {
                let mass = base_mass + x0[at];
                let moment = base_moment + Vector3::new(x0[at + 1], x0[at + 2], x0[at + 3]);
                let com = if mass.abs() > 1e-9 {
                    moment / mass
                } else {
                    Vector3::zeros()
                };
                theta.extend([mass, com.x, com.y, com.z]);
                at += 4;
            }
            Shape::Moment { base_moment, .. } => {
                theta.extend((base_moment + Vector3::new(x0[at], x0[at + 1], x0[at + 2])).iter());
                at += 3;
            }
        }
    }
    // Second start: every body as modelled (a link's change can be far from
    // what its first-moment columns alone suggest, which then absorb inertia).
    let mut modelled = theta.clone();
    let mut at = 0;
    let mut other_start = false;
    for &c in selected {
        let w = width(&candidates[c]);
        if let Shape::Body {
            base_mass,
            base_moment,
            ..
        } = &candidates[c].shape
            && *base_mass > 0.0
        {
            let com = base_moment / *base_mass;
            modelled[at..at + 4].copy_from_slice(&[*base_mass, com.x, com.y, com.z]);
            other_start = true;
        }
        if let Shape::Moment { base_moment, .. } = &candidates[c].shape {
            modelled[at..at + 3].copy_from_slice(base_moment.as_slice());
            other_start = true;
        }
        at += w;
    }
    let mut starts = vec![DVector::from_vec(theta)];
    if other_start {
        starts.push(DVector::from_vec(modelled));
    }
    let (theta, coef, jacobian) = starts
        .into_iter()
        .map(|start| descend(candidates, selected, &a, &b, start))
        .min_by(|x, y| x.3.total_cmp(&y.3))
        .map(|(t, c, j, _)| (t, c, j))?;
    let information = jacobian.transpose() * &a * &jacobian;
    Some(Fit {
        theta,
        coefficients: coef,
        information,
    })
}

/// Levenberg-Marquardt from `theta` on the normal equations (a, b); one
/// exact step when every candidate is linear. Returns the parameters, the
/// column coefficients, their Jacobian and the objective.
fn descend(
    candidates: &[Candidate],
    selected: &[usize],
    a: &DMatrix<f64>,
    b: &DVector<f64>,
    mut theta: DVector<f64>,
) -> (DVector<f64>, DVector<f64>, DMatrix<f64>, f64) {
    let objective = |coefficients: &DVector<f64>| {
        coefficients.dot(&(a * coefficients)) - 2.0 * coefficients.dot(b)
    };
    let nonlinear = selected
        .iter()
        .any(|&c| !matches!(candidates[c].shape, Shape::Linear));
    let (mut coef, mut jacobian) = coefficients(candidates, selected, &theta);
    let mut value = objective(&coef);
    let mut lambda = 1e-3;
    for _ in 0..200 {
        let gradient = jacobian.transpose() * (b - a * &coef);
        let hessian = jacobian.transpose() * a * &jacobian;
        let damped = if nonlinear {
            let mut h = hessian.clone();
            for i in 0..h.nrows() {
                h[(i, i)] *= 1.0 + lambda;
            }
            h
        } else {
            hessian
        };
        let step = pseudo_solve(&damped, &gradient);
        let trial = &theta + &step;
        let (trial_coef, trial_jacobian) = coefficients(candidates, selected, &trial);
        let trial_value = objective(&trial_coef);
        if !nonlinear {
            return (trial, trial_coef, trial_jacobian, trial_value);
        }
        if trial_value < value {
            let decrease = value - trial_value;
            theta = trial;
            coef = trial_coef;
            jacobian = trial_jacobian;
            value = trial_value;
            lambda = (lambda / 3.0).max(1e-12);
            // Converged when a step gains less than 1e-10 of the objective:
            // far below the noise of any torque measurement.
            if decrease <= 1e-10 * value.abs().max(1e-300) {
                break;
            }
        } else {
            lambda *= 4.0;
            if lambda > 1e12 {
                break;
            }
        }
    }
    (theta, coef, jacobian, value)
}

/// Leave-one-trajectory-out MSE per joint of the residual after the effects.
fn cv_mse_per_joint(
    m: &Moments,
    dof: usize,
    candidates: &[Candidate],
    selected: &[usize],
) -> Vec<f64> {
    let columns = m.applied(&columns_of(candidates, selected));
    let mut sse = vec![0.0; dof];
    let mut count = vec![0usize; dof];
    for g in 0..m.xx.len() {
        let coefficients = if selected.is_empty() {
            DVector::zeros(0)
        } else {
            match fit(m, candidates, selected, |h| h != g) {
                Some(f) => f.coefficients,
                None => return vec![f64::INFINITY; dof],
            }
        };
        for j in 0..dof {
            sse[j] += m.sse(g, j, &columns, &coefficients);
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

/// Smallest eigenvalue of the unit-diagonal scaling of the information
/// about the parameters at `range` once the others are projected out
/// (the Schur complement); 0 when some parameter has no information.
fn identifiability(information: &DMatrix<f64>, range: std::ops::Range<usize>) -> f64 {
    let k = information.nrows();
    let inside: Vec<usize> = range.clone().collect();
    let outside: Vec<usize> = (0..k).filter(|i| !range.contains(i)).collect();
    let icc = information.select_rows(&inside).select_columns(&inside);
    let schur = if outside.is_empty() {
        icc.clone()
    } else {
        let ioo = information.select_rows(&outside).select_columns(&outside);
        let ioc = information.select_rows(&outside).select_columns(&inside);
        let solved = DMatrix::from_columns(
            &(0..inside.len())
                .map(|c| pseudo_solve(&ioo, &ioc.column(c).into_owned()))
                .collect::<Vec<_>>(),
        );
        &icc - ioc.transpose() * solved
    };
    let w = inside.len();
    let mut least: f64 = 1.0;
    let d: Vec<f64> = (0..w).map(|i| schur[(i, i)]).collect();
    for i in 0..w {
        // A parameter whose own information vanishes after projection.
        if icc[(i, i)] <= 0.0 || d[i] <= COLLINEAR * icc[(i, i)] {
            return 0.0;
        }
    }
    let scaled = DMatrix::from_fn(w, w, |i, j| schur[(i, j)] / (d[i] * d[j]).sqrt());
    for v in scaled.symmetric_eigenvalues().iter() {
        least = least.min(*v);
    }
    least
}

/// Forward selection by cross-validated MSE with a significance check: each
/// step adds the candidate that lowers some joint's held-out MSE the most
/// (relative to that joint's current MSE, so a weak joint's effect is not
/// drowned by a strong joint's torque scale). Candidates whose parameters
/// these data cannot identify on their own (see the module docs) do not
/// compete; if one would still explain structure at the end, a note says so.
fn select(
    m: &Moments,
    dof: usize,
    candidates: &[Candidate],
    settings: Settings,
) -> (Vec<usize>, Vec<String>) {
    let mut selected: Vec<usize> = Vec::new();
    let mut refused: Vec<usize> = Vec::new();
    let mut notes = Vec::new();
    let unidentifiable: Vec<usize> = (0..candidates.len())
        .filter(|&c| {
            fit(m, candidates, &[c], |_| true).is_none_or(|f| {
                identifiability(&f.information, 0..width(&candidates[c])) < COLLINEAR
            })
        })
        .collect();
    let mut current = cv_mse_per_joint(m, dof, candidates, &[]);
    loop {
        let best = (0..candidates.len())
            .filter(|c| {
                !selected.contains(c) && !refused.contains(c) && !unidentifiable.contains(c)
            })
            .map(|c| {
                let mut trial = selected.clone();
                trial.push(c);
                let mse = cv_mse_per_joint(m, dof, candidates, &trial);
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
        let Some(full) = fit(m, candidates, &trial, |_| true) else {
            break;
        };
        let offset: usize = selected.iter().map(|&s| width(&candidates[s])).sum();
        let w = width(&candidates[c]);
        if identifiability(&full.information, offset..offset + w) < COLLINEAR {
            notes.push(format!(
                "{}: would cut a joint's held-out MSE by {:.0}%, but its parameters are collinear \
                 with the effects already named ({}); not named",
                label(&candidates[c]),
                100.0 * gain,
                selected
                    .iter()
                    .map(|&s| label(&candidates[s]))
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
            refused.push(c);
            continue;
        }
        // A nonlinear candidate (a payload trading mass for lever arm) can
        // win on fit yet leave its parameters undetermined: refuse it and let
        // the others compete.
        let Some(values) = significant(m, candidates, &trial, &full, settings.min_t) else {
            notes.push(format!(
                "{}: would cut a joint's held-out MSE by {:.0}%, but its parameters are not \
                 significant (|t| <= {}); not named",
                label(&candidates[c]),
                100.0 * gain,
                settings.min_t
            ));
            refused.push(c);
            continue;
        };
        if let Err(note) = physical(&candidates[c], &values, gain, settings.reach) {
            notes.push(note);
            refused.push(c);
            continue;
        }
        selected = trial;
        current = mse;
    }
    prune(m, candidates, &mut selected, &mut notes, settings);
    for &c in &unidentifiable {
        let mut trial = selected.clone();
        trial.push(c);
        let gain = relative_gain(&current, &cv_mse_per_joint(m, dof, candidates, &trial));
        if gain >= settings.min_gain {
            notes.push(format!(
                "{}: would cut a joint's held-out MSE by {:.0}%, but these data cannot identify \
                 its parameters (they act only through a combination of them, e.g. a base \
                 parameter: only the inertia about the first joint's axis matters for the first \
                 link); not named — record motions that excite it, or look for an effect with \
                 the same signature",
                label(&candidates[c]),
                100.0 * gain
            ));
        }
    }
    (selected, notes)
}

/// Backward check of the forward selection: an effect named early can lose
/// its significance (or its physical sign) once later effects share its
/// work. Such effects are dropped, weakest first, until every named effect
/// holds up in the final joint fit.
fn prune(
    m: &Moments,
    candidates: &[Candidate],
    selected: &mut Vec<usize>,
    notes: &mut Vec<String>,
    settings: Settings,
) {
    loop {
        let failing = selected.iter().position(|&c| {
            let mut trial: Vec<usize> = selected.iter().copied().filter(|&s| s != c).collect();
            trial.push(c);
            let Some(full) = fit(m, candidates, &trial, |_| true) else {
                return true;
            };
            match significant(m, candidates, &trial, &full, settings.min_t) {
                Some(values) => physical(&candidates[c], &values, 0.0, settings.reach).is_err(),
                None => true,
            }
        });
        let Some(position) = failing else { return };
        let dropped = selected.remove(position);
        notes.push(format!(
            "{}: named while selecting, but not significant or not physical once the other \
             effects are fitted with it; dropped",
            label(&candidates[dropped])
        ));
    }
}

/// How a candidate is named in notes.
fn label(candidate: &Candidate) -> String {
    let kind = candidate.kind.name();
    match (&candidate.joint, &candidate.link) {
        (Some(j), _) => format!("{kind} on joint {}", j + 1),
        (None, Some((k, name))) => format!("{kind} of link {} (`{name}`)", k + 1),
        (None, None) => kind,
    }
}

/// Whether fitted `values` can be the candidate's physical effect; if not,
/// the note that says what the data show instead.
fn physical(candidate: &Candidate, values: &[f64], gain: f64, reach: f64) -> Result<(), String> {
    let at = match (&candidate.joint, &candidate.link) {
        (Some(j), _) => format!("joint {}", j + 1),
        (None, Some((k, name))) if candidate.kind == Kind::InertialError => {
            format!("link {} (`{name}`)", k + 1)
        }
        _ => "the last link".to_string(),
    };
    let percent = 100.0 * gain;
    let value = values[0];
    let meaning = match candidate.kind {
        Kind::TorqueOffset => return Ok(()),
        Kind::InertialError if matches!(candidate.shape, Shape::Moment { .. }) => {
            let Shape::Moment { base_mass, .. } = candidate.shape else {
                unreachable!("matched above")
            };
            let distance = values.iter().map(|h| h * h).sum::<f64>().sqrt() / base_mass;
            if distance <= reach {
                return Ok(());
            }
            return Err(format!(
                "{at}: the data fit a first moment that puts the centre of mass {distance:.2} m \
                 from the link origin at the modelled mass {base_mass:.4} kg (the arm's size is \
                 {reach:.2} m): not a physical body; not named (it would cut a joint's held-out \
                 MSE by {percent:.0}%)"
            ));
        }
        Kind::InertialError => {
            let distance = values[1..].iter().map(|c| c * c).sum::<f64>().sqrt();
            if value > 0.0 && distance <= reach {
                return Ok(());
            }
            return Err(format!(
                "{at}: the data fit a mass of {value:.4} kg with its centre of mass {distance:.2} m \
                 from the link origin (the arm's size is {reach:.2} m): not a physical body; not \
                 named (it would cut a joint's held-out MSE by {percent:.0}%)"
            ));
        }
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
            let com = &values[1..];
            let distance = com.iter().map(|c| c * c).sum::<f64>().sqrt();
            if distance <= reach {
                return Ok(());
            }
            return Err(format!(
                "{at}: the data fit a mass of only {value:.4} kg with its centre of mass at \
                 [{:.3}, {:.3}, {:.3}] m, {distance:.2} m away, beyond the arm's reach \
                 ({reach:.2} m): a first-moment change, i.e. an inertial error of the last link, \
                 not a payload; not named (it would cut a joint's held-out MSE by {percent:.0}%)",
                com[0], com[1], com[2]
            ));
        }
        _ => return Ok(()),
    };
    let kind = candidate.kind.name();
    Err(format!(
        "{at}: the data fit {kind} = {value:.4}, a negative value (it would cut a joint's \
         held-out MSE by {percent:.0}%): {meaning}; not named"
    ))
}

/// Full-data fit with the standard errors of its parameters.
fn fit_all(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
) -> Option<(Fit, DVector<f64>)> {
    if selected.is_empty() {
        return None;
    }
    let fit = fit(m, candidates, selected, |_| true)?;
    let columns = columns_of(candidates, selected);
    let sse: f64 = sse_per_joint(m, &columns, &fit.coefficients).iter().sum();
    let rows: usize = m.rows.iter().flatten().sum();
    let sigma2 = sse.max(0.0) / (rows.saturating_sub(fit.theta.len())).max(1) as f64;
    let k = fit.theta.len();
    let covariance = DMatrix::from_columns(
        &(0..k)
            .map(|c| {
                pseudo_solve(
                    &fit.information,
                    &DVector::from_fn(k, |r, _| f64::from(r == c)),
                )
            })
            .collect::<Vec<_>>(),
    );
    let se = DVector::from_fn(k, |i, _| (sigma2 * covariance[(i, i)]).max(0.0).sqrt());
    Some((fit, se))
}

/// The fitted parameters of the last candidate of `trial` when it is
/// significant: every parameter of a joint effect; a payload's mass (its COM
/// components may be zero); for an inertial error, a change of the mass or
/// of some COM component from the model's. Each |t| uses the larger of the
/// least-squares and the jackknife standard error, so a parameter that
/// swings from trajectory to trajectory is not significant however many
/// correlated samples pin it down within each.
fn significant(
    m: &Moments,
    candidates: &[Candidate],
    trial: &[usize],
    full: &Fit,
    min_t: f64,
) -> Option<Vec<f64>> {
    let (_, se) = fit_robust(m, candidates, trial)?;
    let theta = &full.theta;
    let added = *trial.last()?;
    let offset: usize = trial[..trial.len() - 1]
        .iter()
        .map(|&c| width(&candidates[c]))
        .sum();
    let w = width(&candidates[added]);
    let candidate = &candidates[added];
    let t = |k: usize, reference: f64| (theta[offset + k] - reference).abs() / se[offset + k];
    let ok = match (&candidate.kind, &candidate.shape) {
        (Kind::Payload, _) => t(0, 0.0) > min_t,
        (
            Kind::InertialError,
            Shape::Body {
                base_mass,
                base_moment,
                ..
            },
        ) => {
            let com = if *base_mass > 0.0 {
                base_moment / *base_mass
            } else {
                Vector3::zeros()
            };
            let nominal = [*base_mass, com.x, com.y, com.z];
            (0..4).any(|k| t(k, nominal[k]) > min_t)
        }
        (Kind::InertialError, Shape::Moment { base_moment, .. }) => {
            (0..3).any(|k| t(k, base_moment[k]) > min_t)
        }
        _ => (0..w).all(|k| t(k, 0.0) > min_t),
    };
    ok.then(|| theta.rows(offset, w).iter().copied().collect())
}

fn describe(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
    resolution: f64,
    notes: &mut Vec<String>,
) -> Vec<Effect> {
    let Some((fit, se)) = fit_robust(m, candidates, selected) else {
        return Vec::new();
    };
    let all = m.applied(&columns_of(candidates, selected));
    let sse_none = sse_per_joint(m, &[], &DVector::zeros(0));
    let sse_with = sse_per_joint(m, &all, &fit.coefficients);
    let mut offset = 0;
    let mut effects = Vec::new();
    for (position, &c) in selected.iter().enumerate() {
        let candidate = &candidates[c];
        let w = width(candidate);
        let values: Vec<(f64, f64)> = (offset..offset + w)
            .map(|k| (fit.theta[k], 1.96 * se[k]))
            .collect();
        offset += w;
        let without: Vec<usize> = selected
            .iter()
            .enumerate()
            .filter(|(p, _)| *p != position)
            .map(|(_, &s)| s)
            .collect();
        let rest = m.applied(&columns_of(candidates, &without));
        let sse_without = if without.is_empty() {
            sse_none.clone()
        } else {
            fit_all(m, candidates, &without).map_or(sse_none.clone(), |(f, _)| {
                sse_per_joint(m, &rest, &f.coefficients)
            })
        };
        let share = match candidate.joint {
            Some(j) => (sse_without[j] - sse_with[j]) / sse_none[j],
            None => {
                let total = |v: &[f64]| v.iter().sum::<f64>();
                (total(&sse_without) - total(&sse_with)) / total(&sse_none)
            }
        };
        let share = share.clamp(0.0, 1.0);
        effects.push(effect(candidate, &values, share, resolution, notes));
    }
    effects
}

/// [`fit_all`] with each standard error the larger of the least-squares and
/// the jackknife one (as a normal-equivalent error: the jackknife's 95%
/// half-width over 1.96), which significance tests and reported intervals
/// use.
fn fit_robust(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
) -> Option<(Fit, DVector<f64>)> {
    let (fit, se) = fit_all(m, candidates, selected)?;
    let se = match jackknife_half_widths(m, candidates, selected, &fit.theta) {
        Some(half) => se.zip_map(&half, |s, h| s.max(h / 1.96)),
        None => se,
    };
    Some((fit, se))
}

/// 95% half-widths of the parameters from the leave-one-trajectory-out
/// fits (delete-one jackknife over trajectories, Student t with G - 1
/// degrees of freedom): unlike the least-squares standard errors they hold
/// when the samples of a trajectory are correlated (filtered signals,
/// unmodelled structure), because trajectories are independent. `None`
/// below three trajectories or when a fold cannot be fitted.
fn jackknife_half_widths(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
    theta: &DVector<f64>,
) -> Option<DVector<f64>> {
    let groups = m.xx.len();
    if groups < 3 {
        return None;
    }
    let folds = (0..groups)
        .map(|g| fit(m, candidates, selected, |h| h != g).map(|f| f.theta))
        .collect::<Option<Vec<_>>>()?;
    let mean = folds.iter().fold(DVector::zeros(theta.len()), |a, f| a + f) / groups as f64;
    let g = groups as f64;
    let t = student_t975(groups - 1);
    Some(DVector::from_fn(theta.len(), |k, _| {
        let spread: f64 = folds.iter().map(|f| (f[k] - mean[k]).powi(2)).sum();
        t * ((g - 1.0) / g * spread).sqrt()
    }))
}

/// The 97.5% quantile of Student's t with `dof` degrees of freedom.
fn student_t975(dof: usize) -> f64 {
    const TABLE: [f64; 30] = [
        12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160,
        2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056,
        2.052, 2.048, 2.045, 2.042,
    ];
    match dof {
        0 => f64::INFINITY,
        1..=30 => TABLE[dof - 1],
        // Within 0.003 of the exact quantile beyond 30.
        _ => 1.96 + 2.4 / dof as f64,
    }
}

/// Residual SSE per joint over all samples with `columns` fitted as `coefficients`.
fn sse_per_joint(m: &Moments, columns: &[usize], coefficients: &DVector<f64>) -> Vec<f64> {
    let joints = m.xx.first().map_or(0, Vec::len);
    (0..joints)
        .map(|j| {
            (0..m.xx.len())
                .map(|g| m.sse(g, j, columns, coefficients))
                .sum()
        })
        .collect()
}

fn effect(
    candidate: &Candidate,
    values: &[(f64, f64)],
    share: f64,
    resolution: f64,
    notes: &mut Vec<String>,
) -> Effect {
    use serde_json::{Map, Value, json};
    let mut parameters = Map::new();
    let mut ci95 = Map::new();
    if let Shape::Body {
        base_mass,
        base_moment,
        ..
    } = &candidate.shape
    {
        let (m, dm) = values[0];
        parameters.insert("mass".into(), json!(m));
        ci95.insert("mass".into(), json!([m - dm, m + dm]));
        let mut com = Vec::new();
        let mut interval = Vec::new();
        for (axis, &(c, dc)) in ["x", "y", "z"].iter().zip(&values[1..]) {
            com.push(json!(c));
            interval.push(json!([c - dc, c + dc]));
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
    } else {
        for (name, (value, half)) in candidate.names.iter().zip(values) {
            parameters.insert((*name).into(), json!(value));
            ci95.insert((*name).into(), json!([value - half, value + half]));
        }
    }
    Effect {
        kind: candidate.kind,
        joint: candidate.joint.map(|j| j + 1),
        link: candidate.link.as_ref().map(|(_, name)| name.clone()),
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
                gravity_load: correlation(data, j, &data.gravity),
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
            link: None,
            names: vec![],
            columns: vec![],
            applied: None,
            shape: Shape::Linear,
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
        // 7 g at 1.7 m (a first moment of 0.012 kg m): beyond the arm.
        let note = physical(&payload, &[0.007, 0.0, 0.0, 1.7], 0.3, 1.0).unwrap_err();
        assert!(note.contains("first-moment"), "{note}");
    }

    #[test]
    fn student_quantiles_fall_towards_the_normal() {
        assert_eq!(student_t975(5), 2.571);
        assert_eq!(student_t975(30), 2.042);
        assert!((student_t975(60) - 2.000).abs() < 0.003);
        assert!((student_t975(1_000_000) - 1.96).abs() < 1e-5);
        assert!(student_t975(0).is_infinite());
    }
}
