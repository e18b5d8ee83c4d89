//! Designed excitation (`sdnn excite`): the motion to record so that the
//! model's identifiable parameters and the joint-level effects (friction,
//! offset, armature) are well determined.
//!
//! Every joint follows a finite Fourier series between two rests
//! ([`fourier`]); its coefficients are chosen by a seeded evolution
//! strategy ([`search`]) that minimizes the condition number of the
//! information matrix of the parameters' identifiable combinations
//! ([`information`]), plus, with `--from`, the predicted variance of what
//! a diagnosis found ambiguous or poorly determined ([`weights`]). Limits
//! are kept by construction: each joint's series is scaled to its
//! position, velocity and acceleration limits, and all of them shrink
//! together until the model's own torque stays within the effort limits.

pub mod fourier;
pub mod information;
pub mod problem;
pub mod report;
pub mod search;
pub mod spectrum;
pub mod weights;

use anyhow::{Result, bail};
use nalgebra::DMatrix;

use crate::dynamics::Dynamics;
use crate::seeds::{Purpose, derive};
use crate::trajectory::Trajectory;
use fourier::{Basis, Bounds, JointSeries, Schedule};
use information::{Parameters, Samples, condition_number, inverse_diagonal};
use problem::Problem;
use search::{Budget, Criteria, minimize};

/// What to design.
#[derive(Debug, Clone, PartialEq)]
pub struct Config {
    /// Length of the recording, s.
    pub duration: f64,
    /// Harmonics per joint (at least 2: two constraints hold the ends at rest).
    pub harmonics: usize,
    /// Wanted base frequency, Hz (rounded to whole periods of the moving
    /// time); `None`: one period (a repeated period adds no new information).
    pub base_hz: Option<f64>,
    /// Sample rate of the written trajectory, Hz.
    pub rate: f64,
    /// Rest at each end, s.
    pub rest: f64,
    /// Each joint's own pause while the others move, s.
    pub pause: f64,
    /// Share of each effort limit the planned torque may use (the rest is
    /// left to feedback and to what the model lacks).
    pub torque_share: f64,
    /// Torque noise (N m, or N on a prismatic joint) of one sample at
    /// `rate`, for the predicted standard deviations.
    pub noise: f64,
    pub seed: u64,
    /// The search's length; its `searches` are replaced by
    /// [`default_searches`] unless `searches` is set.
    pub budget: Budget,
    pub searches: Option<usize>,
}

impl Config {
    /// The defaults for a recording of `duration` s on `dof` joints: one
    /// period of 10 harmonics, rests of 5% of the duration at each end and
    /// a pause of 20% per joint (at most 2 and 8 s), 1 kHz; the search's
    /// rounds from the joint count ([`default_rounds`]).
    pub fn new(duration: f64, dof: usize) -> Config {
        let (rounds, exact_rounds) = split_rounds(default_rounds(dof));
        Config {
            duration,
            harmonics: 10,
            base_hz: None,
            rate: 1000.0,
            rest: (0.05 * duration).min(2.0),
            pause: (0.2 * duration).min(8.0),
            torque_share: 0.9,
            noise: 0.05,
            seed: 1,
            budget: Budget {
                starts: 32,
                searches: 1,
                rounds,
                exact_rounds,
                generations: GENERATIONS,
                offspring: 8,
            },
            searches: None,
        }
    }
}

/// Generations per joint and round of the search.
pub const GENERATIONS: usize = 30;

/// Joint searches (rounds times joints) of the default search: every
/// round searches every joint, so 24 / dof rounds keep the count of
/// evaluated motions about even from arm to arm (5760 on 3 joints, 6720 on
/// 7), and the time grows only with the cost of one evaluation. A quarter
/// of the rounds, at least one, minimize the condition number itself.
const JOINT_SEARCHES: usize = 24;

/// Rounds of the default search on `dof` joints.
pub fn default_rounds(dof: usize) -> usize {
    JOINT_SEARCHES.div_ceil(dof.max(1)).max(2)
}

/// The work of one search on the largest arm shipped (the Panda: 7
/// joints, 76 base parameters), in joints times base parameters: one
/// evaluation's time grows about as that product (measured: 0.10 ms on 2
/// joints and 15 parameters to 0.83 ms on 7 and 76, one core).
const REFERENCE_WORK: usize = 7 * 76;

/// Independent searches on an arm of `dof` joints and `rank` base
/// parameters: as many as fit the work of one search on the reference arm,
/// at most 4. The search ends in the basin of its start, and which basin
/// is best is luck: on the 3-joint arm one search's condition number
/// ranged 11.1 to 16.3 over seeds 1-20, the best of two 11.7 to 13.9.
pub fn default_searches(dof: usize, rank: usize) -> usize {
    (REFERENCE_WORK / (dof * rank).max(1)).clamp(1, 4)
}

/// `all` rounds split into (smooth, exact) ones.
pub fn split_rounds(all: usize) -> (usize, usize) {
    let exact = (all / 4).max(1);
    (all.saturating_sub(exact), exact)
}

impl Config {
    /// The motion without the rests that tell a torque offset from
    /// direction-dependent friction, for a diagnosis that asks about
    /// neither: no pause, and at each end a rest of 1% of the duration
    /// (at most 0.5 s). At rest, dry friction sticks or follows its own law
    /// near zero speed, which no column of the model knows: rest samples
    /// tell the offset from that friction, and for every other parameter
    /// they only add error.
    pub fn without_rests(self) -> Config {
        Config {
            rest: (0.01 * self.duration).min(0.5),
            pause: 0.0,
            ..self
        }
    }
}

/// A motion's figures of merit.
#[derive(Debug, Clone, PartialEq)]
pub struct Merit {
    /// Condition number of the base parameters' information matrix scaled
    /// to a unit diagonal.
    pub condition_number: f64,
    /// The same with every column scaled by a fixed factor, the same for
    /// every motion ([`information::condition_number_fixed`]).
    pub condition_number_fixed: f64,
    /// Per base parameter its predicted standard deviation for the
    /// configured torque noise; `None` when this motion does not determine
    /// the base parameters (a singular information matrix).
    pub std: Vec<Option<f64>>,
}

/// Per joint the largest share of each limit the written motion uses.
#[derive(Debug, Clone, PartialEq)]
pub struct Usage {
    pub position: f64,
    pub velocity: f64,
    pub acceleration: f64,
    /// `None` for a joint without an effort limit.
    pub torque: Option<f64>,
}

/// The designed excitation.
pub struct Design {
    pub schedule: Schedule,
    pub joints: Vec<JointSeries>,
    /// The written samples; `tau` holds the model's planned torque.
    pub trajectory: Trajectory,
    /// The base parameters, and what each stands for beside itself.
    pub parameters: Vec<String>,
    pub regrouped: Vec<Vec<(String, f64)>>,
    pub designed: Merit,
    /// The default recording with the median condition number of those
    /// compared, and the range of their condition numbers.
    pub default: Merit,
    pub default_range: (f64, f64),
    pub defaults: usize,
    pub usage: Vec<Usage>,
    pub evaluations: usize,
    /// Parameters weighted from a diagnosis (`--from`).
    pub weighted: Vec<String>,
    pub config: Config,
}

/// A motion as a function of time: (q, qd, qdd).
pub type Motion<'a> = &'a dyn Fn(f64) -> (Vec<f64>, Vec<f64>, Vec<f64>);

/// Designs the excitation of `model` inside `bounds`; `defaults` are the
/// recordings it is compared with (a random recording's condition number
/// varies from draw to draw: the median one is reported), `weighted`
/// names parameters to favour.
pub fn design(
    model: &dyn Dynamics,
    bounds: &Bounds,
    levers: &[f64],
    config: &Config,
    defaults: &[Motion<'_>],
    weighted: &[String],
) -> Result<Design> {
    if defaults.is_empty() {
        bail!("no default recording to compare the design with");
    }
    check(model, bounds, config)?;
    let parameters = Parameters::new(
        model,
        bounds,
        levers,
        derive(config.seed, Purpose::Excitation, 0),
    )?;
    let schedule = Schedule::new(
        config.duration,
        (config.rest, config.pause),
        config.base_hz,
        config.harmonics,
        model.dof(),
    );
    let grid = schedule.grid(design_samples(&schedule));
    let focus = weighted_indices(&parameters, weighted);
    let problem = Problem {
        model,
        parameters: &parameters,
        bounds,
        schedule,
        basis: Basis::new(&schedule, &grid),
        grid_len: grid.len(),
        focus: &focus,
        share: config.torque_share,
    };
    let dim = model.dof() * schedule.per_joint();
    let criteria = Criteria {
        smooth: &|x| problem.smooth_cost(x),
        exact: &|x| problem.cost(x),
    };
    let budget = Budget {
        searches: config
            .searches
            .unwrap_or_else(|| default_searches(model.dof(), parameters.rank())),
        ..config.budget
    };
    let found = minimize(
        criteria,
        dim,
        model.dof(),
        derive(config.seed, Purpose::Excitation, 1),
        budget,
    );
    let Some((coarse, _)) = problem.motion(&found.x) else {
        bail!(
            "no motion inside the limits keeps the model's torque within {:.0}% of the effort limits \
             (the arm's weight alone may exceed them at the joints' mid-range): check the \
             description's `effort` limits",
            100.0 * config.torque_share
        );
    };
    let written = schedule_times(&schedule, config.rate);
    let Some(joints) = problem.refine(coarse, &written) else {
        bail!(
            "the designed motion cannot be kept within the effort limits at {} Hz",
            config.rate
        );
    };
    let trajectory = sampled(model, &schedule, &joints, &written)?;
    let usage = usage(&trajectory, bounds);
    let report_grid = schedule.grid(2 * grid.len());
    let at = |t: f64| state(&schedule, &joints, t);
    let designed = merit(model, &parameters, config, &report_grid, &at)?;
    let mut compared = defaults
        .iter()
        .map(|m| merit(model, &parameters, config, &report_grid, *m))
        .collect::<Result<Vec<Merit>>>()?;
    compared.sort_by(|a, b| a.condition_number.total_cmp(&b.condition_number));
    let default_range = (
        compared[0].condition_number,
        compared[compared.len() - 1].condition_number,
    );
    let default = compared.swap_remove(compared.len() / 2);
    Ok(Design {
        schedule,
        joints,
        trajectory,
        parameters: parameters.names.clone(),
        regrouped: parameters.regrouped.clone(),
        designed,
        default,
        default_range,
        defaults: defaults.len(),
        usage,
        evaluations: found.evaluations,
        weighted: focus.iter().map(|&k| parameters.names[k].clone()).collect(),
        config: config.clone(),
    })
}

fn check(model: &dyn Dynamics, bounds: &Bounds, config: &Config) -> Result<()> {
    let dof = model.dof();
    if [
        bounds.position.len(),
        bounds.velocity.len(),
        bounds.acceleration.len(),
        bounds.effort.len(),
    ]
    .iter()
    .any(|&n| n != dof)
    {
        bail!(
            "the limits list another joint count than model `{}` ({dof} joints)",
            model.name()
        );
    }
    if config.harmonics < 2 {
        bail!(
            "--harmonics {}: at least 2 are needed (two conditions hold the motion's ends at rest)",
            config.harmonics
        );
    }
    if config.pause > 0.0 && config.harmonics < 3 {
        bail!(
            "--harmonics {} with a pause: at least 3 are needed (four conditions hold the motion \
             at rest at its ends and at the pause); or pass --pause 0",
            config.harmonics
        );
    }
    if config.duration <= 2.0 * config.rest + config.pause + 1.0 / config.rate {
        bail!(
            "--duration {} s leaves no time to move beside the rests of {} s at each end and the \
             pause of {} s",
            config.duration,
            config.rest,
            config.pause
        );
    }
    Ok(())
}

/// Samples of the design grid: 16 per period of the highest harmonic, at
/// least 240 (the rests get a share), at most 4000. The search exploits
/// the gaps between samples: with 8 per period (120 samples on the Panda)
/// its motion's condition number on a grid twice as fine was 10% worse
/// than on its own; on 16 per period the designs, compared on the report's
/// grid, came out 4% better on the 3-DOF arm (7 seeds) and 15% on the
/// Panda (2 seeds).
fn design_samples(schedule: &Schedule) -> usize {
    let highest = schedule.base_hz() * schedule.harmonics as f64;
    ((16.0 * schedule.duration * highest).ceil() as usize).clamp(240, 4000)
}

/// The written sample times: 0, 1/rate, ... up to the duration.
fn schedule_times(schedule: &Schedule, rate: f64) -> Vec<f64> {
    let count = (schedule.duration * rate + 1e-9).floor() as usize;
    (0..=count).map(|i| i as f64 / rate).collect()
}

/// The base parameters the weighted names are or are regrouped into.
fn weighted_indices(parameters: &Parameters, weighted: &[String]) -> Vec<usize> {
    (0..parameters.rank())
        .filter(|&k| {
            weighted.contains(&parameters.names[k])
                || parameters.regrouped[k]
                    .iter()
                    .any(|(n, _)| weighted.contains(n))
        })
        .collect()
}

/// All joints' (q, qd, qdd) at t.
fn state(schedule: &Schedule, joints: &[JointSeries], t: f64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let mut out = (Vec::new(), Vec::new(), Vec::new());
    for s in joints {
        let (q, qd, qdd) = s.eval(schedule, t);
        out.0.push(q);
        out.1.push(qd);
        out.2.push(qdd);
    }
    out
}

fn sample_motion(motion: Motion<'_>, times: &[f64]) -> Samples {
    let mut s = Samples {
        q: Vec::new(),
        qd: Vec::new(),
        qdd: Vec::new(),
    };
    for &t in times {
        let (q, qd, qdd) = motion(t);
        s.q.push(q);
        s.qd.push(qd);
        s.qdd.push(qdd);
    }
    s
}

/// The written trajectory, with the model's planned torque.
fn sampled(
    model: &dyn Dynamics,
    schedule: &Schedule,
    joints: &[JointSeries],
    times: &[f64],
) -> Result<Trajectory> {
    let (n, dof) = (times.len(), joints.len());
    let (mut q, mut qd, mut qdd, mut tau) = (
        DMatrix::zeros(n, dof),
        DMatrix::zeros(n, dof),
        DMatrix::zeros(n, dof),
        DMatrix::zeros(n, dof),
    );
    for (i, &t) in times.iter().enumerate() {
        let (a, b, c) = state(schedule, joints, t);
        let torque = model.tau(&a, &b, &c)?;
        for j in 0..dof {
            (q[(i, j)], qd[(i, j)], qdd[(i, j)], tau[(i, j)]) = (a[j], b[j], c[j], torque[j]);
        }
    }
    Ok(Trajectory::new(times.to_vec(), q, qd, Some(qdd), tau)?)
}

/// Per joint the largest share of each limit used by the written samples.
fn usage(traj: &Trajectory, bounds: &Bounds) -> Vec<Usage> {
    let peak = |m: &DMatrix<f64>, j: usize| m.column(j).amax();
    (0..traj.dof())
        .map(|j| {
            let (lo, hi) = bounds.position[j];
            let mid = 0.5 * (lo + hi);
            let reach = traj
                .q()
                .column(j)
                .iter()
                .map(|q| (q - mid).abs())
                .fold(0.0, f64::max);
            Usage {
                position: reach / (0.5 * (hi - lo)).max(f64::MIN_POSITIVE),
                velocity: peak(traj.qd(), j) / bounds.velocity[j],
                acceleration: traj.qdd().map_or(0.0, |a| peak(a, j)) / bounds.acceleration[j],
                torque: bounds.effort[j].map(|l| peak(traj.tau(), j) / l),
            }
        })
        .collect()
}

/// A motion's condition number and predicted standard deviations, from
/// `times` weighted as samples at the configured rate.
fn merit(
    model: &dyn Dynamics,
    p: &Parameters,
    config: &Config,
    times: &[f64],
    motion: Motion<'_>,
) -> Result<Merit> {
    let samples = sample_motion(motion, times);
    let weight = config.rate * config.duration / times.len() as f64;
    let f = p.information(model, &samples, weight)?;
    let variances = inverse_diagonal(&f);
    let std = (0..p.rank())
        .map(|k| variances.as_ref().map(|v| config.noise * v[k].sqrt()))
        .collect();
    let per_sample = &f / (weight * times.len() as f64);
    Ok(Merit {
        condition_number: condition_number(&f),
        condition_number_fixed: information::condition_number_fixed(&per_sample, &p.typical),
        std,
    })
}
