//! The SDNN study (thesis chapters 2-3) end to end: record trajectories on
//! the virtual robot, preprocess, synthesize analytical data, train the MLPs
//! over several seeds and compare every model on held-out trajectories.

use std::f64::consts::PI;
use std::path::Path;
use std::sync::Mutex;

use anyhow::{Context, Result, bail};
use nalgebra::DMatrix;
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use crate::dynamics::{Dynamics, model_torques, parsed_description};
use crate::identified::Identified;
use crate::mlp::{Dataset, Mlp};
use crate::preprocess::Preprocess;
use crate::seeds::{self, Purpose};
use crate::sim::models::Compiled;
use crate::sim::reference::{
    ExcitationConfig, ExcitationTrajectory, JointLimits, Reference, WaypointConfig,
    WaypointTrajectory,
};
use crate::sim::simulate::{SimConfig, open_loop, simulate};
use crate::trajectory::{Trajectory, write_csv};

pub mod map;
mod recording;
pub mod report;
mod training;

pub use recording::{limits, record_reference, record_trajectory, trajectory_seed};
use recording::{open_loop_evaluation, record, record_noisy};
use training::{Job, Recipe, Trained, jobs, save_networks, train_all};

/// Everything the study needs; `Default` is the thesis's setup.
#[derive(Debug, Clone, Serialize)]
pub struct StudyConfig {
    /// Recorded trajectories (thesis: 14) of `duration` s at 1 kHz.
    pub trajectories: usize,
    /// How many of them train (thesis: 10); the rest test.
    pub train: usize,
    pub duration: f64,
    /// Seeds per neural network (thesis: 5).
    pub seeds: usize,
    /// Master seed: trajectories, split and networks derive from it.
    pub seed: u64,
    pub preprocess: Preprocess,
    pub hidden: Vec<usize>,
    pub max_epochs: usize,
    pub patience: usize,
    pub batch_size: usize,
    pub learning_rate: f64,
    /// Analytical-to-measured sample ratios swept for SDNN (1.0 is the thesis's).
    pub mixing_ratios: Vec<f64>,
    /// Fully theoretical excitation trajectories for "SDNN (theoretical)".
    pub theoretical_trajectories: usize,
    /// Open-loop evaluation window on the first test trajectory, s.
    pub open_loop_seconds: f64,
    /// Joint velocity and acceleration caps of the random waypoint
    /// trajectories (the description's velocity limits cap them too).
    pub max_velocity: f64,
    pub max_acceleration: f64,
    /// Factor on the virtual robot's sensor noise (torque 0.05 N m,
    /// velocity 0.02 rad/s, angle 1e-5 rad standard deviations).
    pub noise_scale: f64,
    /// Train/test splits of the recorded trajectories; every model's spread
    /// is over its seeds and these splits.
    pub splits: usize,
}

impl Default for StudyConfig {
    fn default() -> Self {
        StudyConfig {
            trajectories: 14,
            train: 10,
            duration: 20.0,
            seeds: 5,
            seed: 1,
            preprocess: Preprocess::default(),
            hidden: vec![32, 32],
            max_epochs: 60,
            patience: 10,
            batch_size: 128,
            learning_rate: 3e-3,
            mixing_ratios: vec![0.5, 2.0],
            theoretical_trajectories: 10,
            open_loop_seconds: 1.0,
            max_velocity: 1.0,
            max_acceleration: 2.0,
            noise_scale: 1.0,
            splits: 1,
        }
    }
}

/// One model's test error over the seeds (N m^2).
#[derive(Debug, Clone, Serialize)]
pub struct ModelResult {
    pub name: String,
    pub mse_mean: f64,
    pub mse_std: f64,
    pub mse_per_joint: Vec<f64>,
    pub mse_per_joint_std: Vec<f64>,
    /// Joint-angle RMS error (rad) of open-loop torque replay, seed 0.
    pub open_loop_rms: Option<f64>,
    /// Per seed, per joint test MSE.
    pub mse_per_seed: Vec<Vec<f64>>,
}

/// The study's outcome.
fn one_based<S: serde::Serializer>(indices: &[usize], serializer: S) -> Result<S::Ok, S::Error> {
    serializer.collect_seq(indices.iter().map(|i| i + 1))
}

#[derive(Debug, Clone, Serialize)]
pub struct StudyResult {
    pub plant: String,
    pub nominal: String,
    /// Indices into the recordings; written 1-based in the JSON, as the
    /// files are numbered (`trajectory_01.csv` is 1).
    #[serde(serialize_with = "one_based")]
    pub train_trajectories: Vec<usize>,
    #[serde(serialize_with = "one_based")]
    pub test_trajectories: Vec<usize>,
    /// Measured recordings: each one's test piece starts this long (s)
    /// after its start (the test "trajectories" are those pieces).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub test_from: Option<f64>,
    pub models: Vec<ModelResult>,
    /// Analytical-model test MSE with each filter (the zero-phase comparison).
    pub filter_comparison: Vec<(String, f64)>,
    pub config: StudyConfig,
}

/// Progress reporting hook: (done, total, message).
pub type Progress<'a> = &'a (dyn Fn(usize, usize, &str) + Sync);

/// Recorded, preprocessed and split data.
struct Data {
    raw: Vec<Trajectory>,
    processed: Vec<Trajectory>,
    references: Vec<Trajectory>,
    train: Vec<usize>,
    test: Vec<usize>,
    /// Measured recordings: each is tested from this time on (s).
    test_from: Option<f64>,
}

/// The models of a study on the virtual robot.
#[derive(Clone, Copy)]
pub struct Models<'a> {
    /// The truth the recordings come from.
    pub plant: &'a dyn Dynamics,
    /// The model the arm's computed-torque controller tracks with (its
    /// velocity limits cap the motions).
    pub controller: &'a dyn Dynamics,
    /// The analytical model under test.
    pub nominal: &'a dyn Dynamics,
}

/// Runs the study with the nominal model as the controller's (the default
/// situation) and writes its results below `out`.
pub fn run(
    plant: &dyn Dynamics,
    nominal: &dyn Dynamics,
    config: &StudyConfig,
    out: &Path,
    progress: Progress<'_>,
) -> Result<StudyResult> {
    let models = Models {
        plant,
        controller: nominal,
        nominal,
    };
    run_models(models, config, out, progress)
}

/// Runs the study on `models` and writes its results below `out`.
pub fn run_models(
    models: Models<'_>,
    config: &StudyConfig,
    out: &Path,
    progress: Progress<'_>,
) -> Result<StudyResult> {
    let Models { plant, nominal, .. } = models;
    check(config, plant, nominal)?;
    if models.controller.dof() != plant.dof() {
        bail!(
            "the controller's model `{}` has {} joints but plant `{}` has {}",
            models.controller.name(),
            models.controller.dof(),
            plant.name(),
            plant.dof()
        );
    }
    crate::output::create_folder(out)
        .and_then(|()| std::fs::create_dir_all(out.join("data")))
        .with_context(|| format!("creating {}", out.display()))?;
    let data = record(plant, models.controller, config, out, progress)?;
    let filter_comparison = compare_filters(nominal, &data, config)?;
    analyse(
        Some(plant),
        nominal,
        data,
        filter_comparison,
        config,
        out,
        progress,
    )
}

/// How measured recordings are cut into training and test data.
#[derive(Debug, Clone, Copy)]
pub struct MeasuredSplit {
    /// Test on each recording from this time (s after its start) on.
    pub test_from: f64,
    /// Training pieces per recording: the networks' validation split holds
    /// out whole pieces, so it needs several.
    pub train_pieces: usize,
}

/// The study on measured recordings (no simulator): each recording is
/// preprocessed whole, then cut in time into training pieces and one test
/// piece. There is no open-loop replay (no plant to replay on) and no
/// filter comparison (the user chose the filter).
pub fn run_on_measurements(
    nominal: &dyn Dynamics,
    recordings: &[Trajectory],
    split: MeasuredSplit,
    config: &StudyConfig,
    out: &Path,
    progress: Progress<'_>,
) -> Result<StudyResult> {
    if config.seeds == 0 || split.train_pieces < 2 {
        bail!("the study needs at least 1 seed and 2 training pieces");
    }
    let mut data = Data {
        raw: Vec::new(),
        processed: Vec::new(),
        references: Vec::new(),
        train: Vec::new(),
        test: Vec::new(),
        test_from: Some(split.test_from),
    };
    for (r, raw) in recordings.iter().enumerate() {
        if raw.dof() != nominal.dof() {
            bail!(
                "recording {} has {} joints, model `{}` has {}",
                r + 1,
                raw.dof(),
                nominal.name(),
                nominal.dof()
            );
        }
        let processed = config.preprocess.apply(raw)?;
        let cut_at = |t: &Trajectory| {
            let start = t.t().first().copied().unwrap_or(0.0);
            t.t().partition_point(|&x| x < start + split.test_from)
        };
        let (cut, raw_cut) = (cut_at(&processed), cut_at(raw));
        if cut < split.train_pieces * 10 || processed.len() - cut < 10 {
            bail!(
                "recording {}: cutting at {} s leaves too little data to train ({} samples) or test ({})",
                r + 1,
                split.test_from,
                cut,
                processed.len() - cut
            );
        }
        let train = processed.rows(0, cut).split(split.train_pieces);
        let raw_train = raw.rows(0, raw_cut).split(split.train_pieces);
        for (piece, raw_piece) in train.into_iter().zip(raw_train) {
            data.train.push(data.processed.len());
            data.processed.push(piece);
            data.raw.push(raw_piece);
        }
        data.test.push(data.processed.len());
        data.processed
            .push(processed.rows(cut, processed.len() - cut));
        data.raw.push(raw.rows(raw_cut, raw.len() - raw_cut));
    }
    crate::output::create_folder(out).with_context(|| format!("creating {}", out.display()))?;
    analyse(None, nominal, data, Vec::new(), config, out, progress)
}

/// Trains and compares every model on split data, writes the report.
fn analyse(
    plant: Option<&dyn Dynamics>,
    nominal: &dyn Dynamics,
    data: Data,
    filter_comparison: Vec<(String, f64)>,
    config: &StudyConfig,
    out: &Path,
    progress: Progress<'_>,
) -> Result<StudyResult> {
    let jobs = jobs(config);
    let (mut runs, identified, networks) = split_runs(nominal, &data, config, &jobs, progress)?;
    save_networks(&jobs, &networks, out)?;
    // Further train/test splits of the recorded trajectories (a simulated
    // study; measured recordings are cut in time once).
    let splits = if plant.is_some() { config.splits } else { 1 };
    for split in 1..splits {
        let other = data.resplit(config, split);
        let (more, _, _) = split_runs(nominal, &other, config, &jobs, progress)?;
        for (all, extra) in runs.iter_mut().zip(more) {
            all.extend(extra);
        }
    }
    let names = [ANALYTICAL.to_string(), IDENTIFIED.to_string()]
        .into_iter()
        .chain(jobs.iter().map(|j| j.name.clone()));
    let mut models: Vec<ModelResult> = names
        .zip(runs)
        .map(|(name, per_run)| summarize(&name, per_run))
        .collect();
    if let Some(plant) = plant {
        open_loop_evaluation(
            plant,
            nominal,
            &identified,
            &data,
            config,
            (&jobs, &networks),
            &mut models,
        )?;
    }
    let result = StudyResult {
        plant: plant.map_or("measured data".to_string(), |p| p.name().to_string()),
        nominal: nominal.name().to_string(),
        train_trajectories: data.train.clone(),
        test_trajectories: data.test.clone(),
        test_from: data.test_from,
        models,
        filter_comparison,
        config: config.clone(),
    };
    let trained: Vec<(String, &Mlp)> = jobs
        .iter()
        .zip(&networks)
        .map(|(j, n)| (j.name.clone(), &n[0].1))
        .collect();
    let figures = crate::study::report::Figures {
        raw: &data.raw,
        processed: &data.processed,
        nominal,
        networks: &trained,
        residual: "Hybrid (analytical + NN residual)",
    };
    crate::study::report::write(&result, &figures, out)?;
    Ok(result)
}

/// Per model, per run, the per-joint test MSE.
type Runs = Vec<Vec<Vec<f64>>>;

/// Per model (analytical, identified, then the jobs), the per-joint test
/// MSE of each run on one split (one run for the models, one per seed for
/// the networks); the identified model and the networks of this split.
fn split_runs<'a>(
    nominal: &'a dyn Dynamics,
    data: &Data,
    config: &StudyConfig,
    jobs: &[Job],
    progress: Progress<'_>,
) -> Result<(Runs, Identified<'a>, Trained)> {
    let analytical = analytical_mse(nominal, data)?;
    let training: Vec<&Trajectory> = data.train.iter().map(|&k| &data.processed[k]).collect();
    let identified = Identified::fit(nominal, &training)?;
    let fitted = identified_mse(&identified, data)?;
    let networks = train_all(nominal, &identified, data, config, jobs, progress)?;
    let mut runs = vec![vec![analytical], vec![fitted]];
    runs.extend(
        networks
            .iter()
            .map(|seeds| seeds.iter().map(|(mse, _)| mse.clone()).collect()),
    );
    Ok((runs, identified, networks))
}

fn check(config: &StudyConfig, plant: &dyn Dynamics, nominal: &dyn Dynamics) -> Result<()> {
    if plant.dof() != nominal.dof() {
        bail!(
            "plant `{}` has {} joints but nominal model `{}` has {}",
            plant.name(),
            plant.dof(),
            nominal.name(),
            nominal.dof()
        );
    }
    if config.train == 0 || config.train >= config.trajectories {
        bail!(
            "--train must be between 1 and {} (trajectories - 1), got {}",
            config.trajectories.saturating_sub(1),
            config.train
        );
    }
    if config.seeds == 0 {
        bail!("--seeds must be at least 1");
    }
    Ok(())
}

/// Mean squared error per joint.
pub fn mse_per_joint(predicted: &DMatrix<f64>, measured: &DMatrix<f64>) -> Vec<f64> {
    let rows = measured.nrows().max(1) as f64;
    (0..measured.ncols())
        .map(|j| (predicted.column(j) - measured.column(j)).norm_squared() / rows)
        .collect()
}

fn pooled_mse(pairs: &[(DMatrix<f64>, &Trajectory)]) -> Vec<f64> {
    let predicted = stack(pairs.iter().map(|(p, _)| p.clone()).collect());
    let measured = stack(pairs.iter().map(|(_, t)| t.tau().clone()).collect());
    mse_per_joint(&predicted, &measured)
}

/// Rows of all blocks, in order.
pub fn stack(blocks: Vec<DMatrix<f64>>) -> DMatrix<f64> {
    let rows = blocks.iter().map(|b| b.nrows()).sum();
    let cols = blocks.first().map_or(0, |b| b.ncols());
    let mut out = DMatrix::zeros(rows, cols);
    let mut at = 0;
    for b in blocks {
        out.rows_mut(at, b.nrows()).copy_from(&b);
        at += b.nrows();
    }
    out
}

fn analytical_mse(nominal: &dyn Dynamics, data: &Data) -> Result<Vec<f64>> {
    let pairs = data
        .test
        .iter()
        .map(|&k| {
            Ok((
                model_torques(nominal, &data.processed[k])?,
                &data.processed[k],
            ))
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(pooled_mse(&pairs))
}

fn identified_mse(identified: &Identified, data: &Data) -> Result<Vec<f64>> {
    let pairs = data
        .test
        .iter()
        .map(|&k| Ok((identified.torques(&data.processed[k])?, &data.processed[k])))
        .collect::<Result<Vec<_>>>()?;
    Ok(pooled_mse(&pairs))
}

/// Analytical-model test MSE with the thesis's moving average and with a
/// zero-phase Savitzky-Golay filter.
fn compare_filters(
    nominal: &dyn Dynamics,
    data: &Data,
    config: &StudyConfig,
) -> Result<Vec<(String, f64)>> {
    use crate::preprocess::Filter;
    let filters = [
        (
            "moving average, window 40 (thesis)",
            config.preprocess.clone(),
        ),
        (
            "Savitzky-Golay, window 41, order 3 (zero-phase)",
            Preprocess {
                filter: Filter::SavitzkyGolay {
                    window: 41,
                    order: 3,
                },
                ..config.preprocess.clone()
            },
        ),
    ];
    filters
        .into_iter()
        .map(|(name, filter)| {
            let pairs = data
                .test
                .iter()
                .map(|&k| {
                    let t = filter.apply(&data.raw[k])?;
                    Ok((model_torques(nominal, &t)?, t))
                })
                .collect::<Result<Vec<_>>>()?;
            let refs: Vec<(DMatrix<f64>, &Trajectory)> =
                pairs.iter().map(|(p, t)| (p.clone(), t)).collect();
            let mse = pooled_mse(&refs);
            Ok((name.to_string(), mse.iter().sum::<f64>() / mse.len() as f64))
        })
        .collect()
}

/// The analytical model's row.
pub const ANALYTICAL: &str = "Analytical model (Euler-Lagrange)";
/// The identified model's row and its hybrid's, in every table.
pub const IDENTIFIED: &str = "Identified model (least squares)";
pub const IDENTIFIED_HYBRID: &str = "Hybrid (identified + NN residual)";

/// A file-name-safe version of a model name.
pub fn slug(name: &str) -> String {
    let mut s: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() {
                c.to_ascii_lowercase()
            } else {
                '_'
            }
        })
        .collect();
    while s.contains("__") {
        s = s.replace("__", "_");
    }
    s.trim_matches('_').to_string()
}

fn summarize(name: &str, per_seed: Vec<Vec<f64>>) -> ModelResult {
    let joints = per_seed.first().map_or(0, Vec::len);
    let means: Vec<f64> = per_seed
        .iter()
        .map(|m| m.iter().sum::<f64>() / joints as f64)
        .collect();
    let (mse_mean, mse_std) = mean_std(&means);
    let per_joint: Vec<(f64, f64)> = (0..joints)
        .map(|j| mean_std(&per_seed.iter().map(|m| m[j]).collect::<Vec<_>>()))
        .collect();
    ModelResult {
        name: name.to_string(),
        mse_mean,
        mse_std,
        mse_per_joint: per_joint.iter().map(|p| p.0).collect(),
        mse_per_joint_std: per_joint.iter().map(|p| p.1).collect(),
        open_loop_rms: None,
        mse_per_seed: per_seed,
    }
}

/// Mean and sample standard deviation (0 for one value).
fn mean_std(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    if values.len() < 2 {
        return (mean, 0.0);
    }
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, var.sqrt())
}

/// Maps `f` over 0..n on two threads (this machine's cores), in order.
fn parallel_map<T: Send>(n: usize, f: impl Fn(usize) -> Result<T> + Sync) -> Result<Vec<T>> {
    let next = Mutex::new(0usize);
    let slots: Vec<Mutex<Option<Result<T>>>> = (0..n).map(|_| Mutex::new(None)).collect();
    let workers = std::thread::available_parallelism()
        .map_or(2, |p| p.get())
        .clamp(1, 2);
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| {
                loop {
                    let i = {
                        let Ok(mut guard) = next.lock() else { return };
                        let i = *guard;
                        *guard += 1;
                        i
                    };
                    if i >= n {
                        return;
                    }
                    let result = f(i);
                    if let Ok(mut slot) = slots[i].lock() {
                        *slot = Some(result);
                    }
                }
            });
        }
    });
    slots
        .into_iter()
        .enumerate()
        .map(|(i, slot)| {
            slot.into_inner()
                .ok()
                .flatten()
                .unwrap_or_else(|| Err(anyhow::anyhow!("worker for job {i} stopped")))
        })
        .collect()
}
