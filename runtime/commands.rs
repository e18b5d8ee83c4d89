//! The pipeline's stage commands and the study (`sdnn reproduce`).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use nalgebra::DMatrix;

use crate::args::{AngleArg, Format, find_model};
use crate::corrections::Corrections;
use crate::diagnose::Diagnosis;
use crate::dynamics::Dynamics;
use crate::dynamics::model_torques;
use crate::inputs::{FilterArgs, InputArgs, load, load_one, load_preprocessed, shell_word};
use crate::mlp::{Dataset, Mlp};
use crate::preprocess::Compared;
use crate::ranges;
use crate::study::{self, StudyConfig, mse_per_joint};
use crate::trajectory::{
    ReadOptions, read_states_csv, write_csv, write_torques, write_torques_csv,
};

/// The default virtual robot: the thesis model plus joint friction and armature.
pub const DEFAULT_PLANT: &str = "kinova_gen3_lite_3dof_plant";
/// The thesis's analytical model.
pub const DEFAULT_NOMINAL: &str = "kinova_gen3_lite_3dof";

/// Options shared by the studies: where results go, seeds and networks.
#[derive(Debug, Args)]
pub struct StudyRunArgs {
    /// Results folder.
    #[arg(long, default_value = "results")]
    pub out: PathBuf,
    /// Master seed (any 64-bit number).
    #[arg(long, default_value_t = 1, value_parser = ranges::seed)]
    pub seed: u64,
    /// Seeds per network (1-100).
    #[arg(long, default_value_t = 5, value_parser = ranges::integer(1, 100, "run again with another --seed"))]
    pub seeds: usize,
    /// Maximum training epochs per network (1-100000).
    #[arg(long, default_value_t = StudyConfig::default().max_epochs, value_parser = ranges::integer(1, 100_000, "continue from the written network"))]
    pub epochs: usize,
    /// Early-stopping patience in epochs (1-100000).
    #[arg(long, default_value_t = StudyConfig::default().patience, value_parser = ranges::integer(1, 100_000, "no patience beyond the epochs is useful"))]
    pub patience: usize,
    /// Hidden layer widths, comma separated (1-8 layers of 1-4096).
    #[arg(long, value_delimiter = ',', default_values_t = StudyConfig::default().hidden, value_parser = ranges::width)]
    pub hidden: Vec<usize>,
    /// Adam learning rate (above 0, at most 1).
    #[arg(long, default_value_t = StudyConfig::default().learning_rate, value_parser = ranges::real(0.0, 1.0, true, "rates above 1 diverge"))]
    pub learning_rate: f64,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

impl StudyRunArgs {
    /// The study defaults with these seeds and network settings.
    fn config(&self) -> Result<StudyConfig> {
        ranges::check_layers(&self.hidden).map_err(anyhow::Error::msg)?;
        Ok(StudyConfig {
            seed: self.seed,
            seeds: self.seeds,
            max_epochs: self.epochs,
            patience: self.patience,
            hidden: self.hidden.clone(),
            learning_rate: self.learning_rate,
            ..StudyConfig::default()
        })
    }
}

#[derive(Debug, Args)]
pub struct ReproduceArgs {
    /// Number of recorded trajectories (1-1000) and of training trajectories.
    #[arg(long, default_value_t = 14, value_parser = ranges::integer(1, 1000, "run several studies"))]
    pub trajectories: usize,
    /// Training trajectories, fewer than --trajectories.
    #[arg(long, default_value_t = 10, value_parser = ranges::integer(1, 999, "record more trajectories"))]
    pub train: usize,
    /// Seconds per trajectory (above 0, at most 3600).
    #[arg(long, default_value_t = 20.0, value_parser = ranges::real(0.0, 3600.0, true, "record several trajectories"))]
    pub duration: f64,
    /// Which situation: `virtual` (the plant is the analytical model plus
    /// friction and armature) or `thesis` (the plant is Kinova's own
    /// description of the arm plus friction and armature, tracked by a
    /// controller that knows it, within its 0.35 rad/s limit; the analytical
    /// model is the thesis's, with its conventions).
    #[arg(long, value_enum, default_value_t)]
    pub situation: Situation,
    /// Plant (truth) and nominal (analytical) models [default: the
    /// situation's].
    #[arg(long)]
    pub plant: Option<String>,
    #[arg(long)]
    pub nominal: Option<String>,
    /// Factor on the virtual robot's sensor noise (standard deviations
    /// torque 0.05 N m, velocity 0.02 rad/s, angle 1e-5 rad), 0-10.
    #[arg(long, default_value_t = 1.0, value_parser = ranges::real(0.0, 10.0, false, "noise beyond 10x the sensor's is not a measurement"))]
    pub noise_scale: f64,
    /// Train/test splits of the recorded trajectories (1-20); every model's
    /// spread is over its seeds and the splits [default: 1; 3 in the thesis
    /// situation].
    #[arg(long, value_parser = ranges::integer(1, 20, "run the study again with another --seed"))]
    pub splits: Option<usize>,
    /// Instead of one study, map when SDNN helps: a grid over the
    /// analytical model's error (0, 0.5, 1, 2 x the thesis's), training
    /// trajectories (2, 5, 10, 20) and sensor noise (0.5, 1, 2 x), 5 seeds x
    /// 3 splits per cell, on the thesis situation's plant; writes map.md,
    /// map.json and map.svg into --out.
    #[arg(long)]
    pub map: bool,
    #[command(flatten)]
    pub run: StudyRunArgs,
}

fn reproduce_map(args: &ReproduceArgs) -> Result<()> {
    let (plant, exact, thesis) = (
        find_model(THESIS_PLANT)?,
        find_model(THESIS_CONTROLLER)?,
        find_model(DEFAULT_NOMINAL)?,
    );
    let config = study::map::MapConfig {
        seed: args.run.seed,
        ..study::map::MapConfig::default()
    };
    let out = &args.run.out;
    crate::output::create_folder(out).with_context(|| format!("creating {}", out.display()))?;
    let bar = progress_bar();
    let report = |done: usize, total: usize, stage: &str| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
        bar.set_message(stage.to_string());
    };
    let cells = study::map::run_map(plant, exact, thesis, &config, &report)?;
    bar.finish_and_clear();
    let markdown = crate::study::report::write_map(&cells, &config, out)?;
    match args.run.format {
        Format::Json => println!("{}", serde_json::to_string_pretty(&cells)?),
        Format::Text => {
            println!("{markdown}");
            println!("Map written to {}", out.display());
        }
    }
    Ok(())
}

/// The study's situation (see `ReproduceArgs::situation`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Situation {
    #[default]
    Virtual,
    Thesis,
}

/// The thesis situation's plant and controller model.
const THESIS_PLANT: &str = "kinova_gen3_lite_urdf_plant";
const THESIS_CONTROLLER: &str = "kinova_gen3_lite_3dof_locked";
/// Train/test splits of the thesis situation's study.
const THESIS_SPLITS: usize = 3;

pub fn reproduce(args: &ReproduceArgs) -> Result<()> {
    if args.map {
        return reproduce_map(args);
    }
    if args.duration < MIN_STUDY_SECONDS {
        bail!(
            "--duration {} s: a study's trajectories need at least {MIN_STUDY_SECONDS} s (the \
             thesis preprocessing keeps every 10th sample and averages 40 of them)",
            args.duration
        );
    }
    let recorded = args.trajectories as f64 * args.duration;
    if recorded > MOST_SIMULATED_SECONDS {
        bail!(
            "--trajectories {} x --duration {} s is {recorded} s of recordings, more than one \
             study records ({MOST_SIMULATED_SECONDS} s): record fewer or shorter trajectories",
            args.trajectories,
            args.duration
        );
    }
    let nominal = find_model(args.nominal.as_deref().unwrap_or(DEFAULT_NOMINAL))?;
    // The controller knows the arm: in the default situation the arm is the
    // nominal model (plus effects it does not know); in the thesis's it is
    // Kinova's rigid body, or the plant given.
    let (plant, controller) = match (args.situation, args.plant.as_deref()) {
        (Situation::Virtual, plant) => (find_model(plant.unwrap_or(DEFAULT_PLANT))?, nominal),
        (Situation::Thesis, None) => (find_model(THESIS_PLANT)?, find_model(THESIS_CONTROLLER)?),
        (Situation::Thesis, Some(plant)) => {
            let plant = find_model(plant)?;
            (plant, plant)
        }
    };
    let config = StudyConfig {
        trajectories: args.trajectories,
        train: args.train,
        duration: args.duration,
        noise_scale: args.noise_scale,
        splits: args.splits.unwrap_or(match args.situation {
            Situation::Virtual => 1,
            Situation::Thesis => THESIS_SPLITS,
        }),
        ..args.run.config()?
    };
    let models = study::Models {
        plant,
        controller,
        nominal,
    };
    let out = &args.run.out;
    run_study(out, args.run.format, |progress| {
        study::run_models(models, &config, out, progress)
    })
}

/// Runs a study behind a progress bar and prints its table.
fn run_study(
    out: &Path,
    format: Format,
    study: impl FnOnce(study::Progress<'_>) -> Result<study::StudyResult>,
) -> Result<()> {
    let bar = progress_bar();
    let report = |done: usize, total: usize, stage: &str| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
        bar.set_message(stage.to_string());
    };
    let result = study(&report)?;
    bar.finish_and_clear();
    match format {
        Format::Json => println!("{}", serde_json::to_string_pretty(&result)?),
        Format::Text => {
            println!("{}", crate::study::report::markdown(&result));
            println!("Results written to {}", out.display());
        }
    }
    Ok(())
}

#[derive(Debug, Args)]
pub struct StudyArgs {
    /// Compiled model (the analytical model).
    #[arg(long)]
    pub model: String,
    /// Measured CSV recordings.
    #[arg(long, required = true, num_args = 1..)]
    pub data: Vec<PathBuf>,
    /// Test on each recording from this time on (s after its start); train before.
    #[arg(long, value_parser = ranges::real(0.0, 1e7, false, "no recording is that long"))]
    pub test_from: f64,
    /// Training pieces per recording (1-1000; the networks validate on whole pieces).
    #[arg(long, default_value_t = 5, value_parser = ranges::integer(1, 1000, "use fewer, longer pieces"))]
    pub train_pieces: usize,
    #[command(flatten)]
    pub input: InputArgs,
    #[command(flatten)]
    pub filter: FilterArgs,
    #[command(flatten)]
    pub run: StudyRunArgs,
}

/// The SDNN study on measured recordings (see `study::run_on_measurements`).
pub fn study_command(args: &StudyArgs) -> Result<()> {
    let nominal = find_model(&args.model)?;
    let recordings = args.input.read_all(&args.data, Some(nominal.dof()))?;
    let config = StudyConfig {
        preprocess: args.filter.resolve(&recordings)?.settings,
        trajectories: recordings.len() * (args.train_pieces + 1),
        train: recordings.len() * args.train_pieces,
        ..args.run.config()?
    };
    let split = study::MeasuredSplit {
        test_from: args.test_from,
        train_pieces: args.train_pieces,
    };
    let out = &args.run.out;
    run_study(out, args.run.format, |progress| {
        study::run_on_measurements(nominal, &recordings, split, &config, out, progress)
    })
}

fn progress_bar() -> ProgressBar {
    let bar = ProgressBar::new(1);
    if let Ok(style) = ProgressStyle::with_template("{msg:24} [{bar:30}] {pos}/{len} {elapsed}") {
        bar.set_style(style.progress_chars("=> "));
    }
    bar
}

#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// Output folder for trajectory_NN.csv files.
    #[arg(long, default_value = "recordings")]
    pub out: PathBuf,
    #[arg(long, default_value_t = 1, value_parser = ranges::seed)]
    pub seed: u64,
    /// Number of trajectories (1-1000).
    #[arg(long, default_value_t = 14, value_parser = ranges::integer(1, 1000, "run several times with other --seed and --out"))]
    pub count: usize,
    /// Seconds per trajectory (above 0, at most 3600).
    #[arg(long, default_value_t = 20.0, value_parser = ranges::real(0.0, 3600.0, true, "record several trajectories"))]
    pub duration: f64,
    #[arg(long, default_value = DEFAULT_PLANT)]
    pub plant: String,
    #[arg(long, default_value = DEFAULT_NOMINAL)]
    pub nominal: String,
}

/// Shortest trajectory of a study, s.
const MIN_STUDY_SECONDS: f64 = 1.0;

/// Most recorded seconds one `simulate` run writes, or one study records (10 h, about 2 GB of
/// CSV at 1 kHz for 3 joints): beyond it, run it several times.
const MOST_SIMULATED_SECONDS: f64 = 36_000.0;

pub fn simulate(args: &SimulateArgs) -> Result<()> {
    let total = args.count as f64 * args.duration;
    if total > MOST_SIMULATED_SECONDS {
        bail!(
            "--count {} x --duration {} s is {total} s of recordings, more than one run writes \
             ({MOST_SIMULATED_SECONDS} s, about 2 GB at 1 kHz for 3 joints): run it several \
             times with other --seed values",
            args.count,
            args.duration
        );
    }
    let (plant, nominal) = (find_model(&args.plant)?, find_model(&args.nominal)?);
    crate::output::create_folder(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let config = StudyConfig {
        duration: args.duration,
        ..StudyConfig::default()
    };
    let waypoints = crate::sim::reference::WaypointConfig {
        duration: args.duration,
        limits: study::limits(nominal, &config)?,
        ..Default::default()
    };
    let bar = progress_bar();
    bar.set_length(args.count as u64);
    bar.set_message("recording trajectories");
    for k in 0..args.count {
        let seed = study::trajectory_seed(args.seed, k);
        let recording = study::record_trajectory(plant, nominal, &waypoints, seed)?;
        let path = args.out.join(format!("trajectory_{:02}.csv", k + 1));
        write_csv(&path, &recording.measured)?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    println!(
        "{} trajectories written to {}",
        args.count,
        args.out.display()
    );
    Ok(())
}

#[derive(Debug, Args)]
pub struct PreprocessArgs {
    /// Measured CSV files.
    #[arg(required = true)]
    pub data: Vec<PathBuf>,
    /// Output folder (same file names).
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub input: InputArgs,
    #[command(flatten)]
    pub filter: FilterArgs,
}

pub fn preprocess(args: &PreprocessArgs) -> Result<()> {
    crate::output::create_folder(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    for_each_file(&args.data, |path| {
        let (processed, pipeline) = load_one(path, None, &args.input, &args.filter)?;
        eprintln!("{}: {}", path.display(), pipeline.summary());
        write_csv(args.out.join(file_name(path)?), &processed)?;
        Ok(())
    })
}

#[derive(Debug, Args)]
pub struct SynthArgs {
    /// Compiled model that produces the torques.
    #[arg(long, default_value = DEFAULT_NOMINAL)]
    pub model: String,
    /// Measured CSV files (preprocessed here unless --preprocessed).
    #[arg(required = true)]
    pub data: Vec<PathBuf>,
    #[arg(long)]
    pub out: PathBuf,
    /// The files already carry filtered qd and qdd.
    #[arg(long)]
    pub preprocessed: bool,
    #[command(flatten)]
    pub input: InputArgs,
    #[command(flatten)]
    pub filter: FilterArgs,
}

pub fn synth(args: &SynthArgs) -> Result<()> {
    let model = find_model(&args.model)?;
    crate::output::create_folder(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    for_each_file(&args.data, |path| {
        let traj = if args.preprocessed {
            load_preprocessed(path, Some(model.dof()), &args.input)?
        } else {
            load_one(path, Some(model.dof()), &args.input, &args.filter)?.0
        };
        let analytical = traj.with_tau(model_torques(model, &traj)?)?;
        write_csv(args.out.join(file_name(path)?), &analytical)?;
        Ok(())
    })
}

#[derive(Debug, Args)]
pub struct TrainArgs {
    /// Training CSV files (measured and/or synthesized).
    #[arg(required = true)]
    pub data: Vec<PathBuf>,
    /// Model file to write (JSON).
    #[arg(long)]
    pub out: PathBuf,
    #[arg(long, default_value_t = 0, value_parser = ranges::seed)]
    pub seed: u64,
    /// Hidden layer widths, comma separated (1-8 layers of 1-4096).
    #[arg(long, value_delimiter = ',', default_values_t = StudyConfig::default().hidden, value_parser = ranges::width)]
    pub hidden: Vec<usize>,
    /// Maximum training epochs (1-100000).
    #[arg(long, default_value_t = StudyConfig::default().max_epochs, value_parser = ranges::integer(1, 100_000, "continue from the written network"))]
    pub epochs: usize,
    /// The files already carry filtered qd and qdd.
    #[arg(long)]
    pub preprocessed: bool,
    #[command(flatten)]
    pub input: InputArgs,
    #[command(flatten)]
    pub filter: FilterArgs,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

pub fn train(args: &TrainArgs) -> Result<()> {
    ranges::check_layers(&args.hidden).map_err(anyhow::Error::msg)?;
    let trajectories = if args.preprocessed {
        args.data
            .iter()
            .map(|path| load_preprocessed(path, None, &args.input))
            .collect::<Result<Vec<_>>>()?
    } else {
        let (trajectories, pipeline) = load(&args.data, None, &args.input, &args.filter)?;
        eprintln!("{}", pipeline.summary());
        trajectories
    };
    let mut parts = Vec::new();
    for (group, (path, traj)) in args.data.iter().zip(&trajectories).enumerate() {
        parts.push(
            Dataset::from_trajectory(traj, group).with_context(|| path.display().to_string())?,
        );
    }
    let data = Dataset::concat(&parts)?;
    let bar = progress_bar();
    bar.set_length(args.epochs as u64);
    bar.set_message("training");
    let defaults = StudyConfig::default();
    let network = Mlp::params()
        .hidden(args.hidden.clone())
        .max_epochs(args.epochs)
        .patience(defaults.patience)
        .batch_size(defaults.batch_size)
        .learning_rate(defaults.learning_rate)
        .seed(args.seed)
        .check()?
        .fit_with(&data, None, &mut |epoch| {
            bar.set_position(epoch.epoch as u64)
        })?;
    bar.finish_and_clear();
    network.save(&args.out)?;
    let history = network.history();
    let summary = serde_json::json!({
        "model": args.out.display().to_string(),
        "samples": data.len(),
        "epochs": history.epochs(),
        "best_epoch": history.best_epoch(),
        "train_loss": history.train_loss().last(),
        "valid_loss": history.valid_loss().last(),
    });
    let text = match args.format {
        Format::Json => summary.to_string(),
        Format::Text => format!(
            "trained on {} samples for {} epochs (best {}); written to {}",
            data.len(),
            history.epochs(),
            history.best_epoch(),
            args.out.display()
        ),
    };
    // With the network on standard output, the summary goes to stderr.
    if crate::output::is_stdout(&args.out) {
        eprintln!("{text}");
    } else {
        println!("{text}");
    }
    Ok(())
}

#[derive(Debug, Args)]
pub struct EvaluateArgs {
    /// Compiled model (the analytical model, or the nominal model with --nn).
    #[arg(long, default_value = DEFAULT_NOMINAL)]
    pub model: String,
    /// Measured CSV files.
    #[arg(long, required = true, num_args = 1..)]
    pub data: Vec<PathBuf>,
    /// Evaluate this trained network instead of the analytical model.
    #[arg(long)]
    pub nn: Option<PathBuf>,
    #[command(flatten)]
    pub input: InputArgs,
    #[command(flatten)]
    pub filter: FilterArgs,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

pub fn evaluate(args: &EvaluateArgs) -> Result<()> {
    let model = find_model(&args.model)?;
    let network = args.nn.as_ref().map(Mlp::load).transpose()?;
    if let (Some(n), Some(path)) = (&network, &args.nn) {
        let dof = model.dof();
        if n.n_inputs() != 3 * dof || n.n_outputs() != dof {
            bail!(
                "{}: the network maps {} inputs to {} torques; model `{}` has {dof} joints \
                 (3 x {dof} inputs q, qd, qdd and {dof} torques): pass the --model it was trained for",
                path.display(),
                n.n_inputs(),
                n.n_outputs(),
                model.name()
            );
        }
    }
    let recordings = args.input.read_all(&args.data, Some(model.dof()))?;
    let pipeline = args.filter.resolve(&recordings)?;
    let mut compared = Vec::new();
    for (raw, path) in recordings.iter().zip(&args.data) {
        compared.push(
            pipeline
                .compare(raw, |traj| match &network {
                    Some(n) => Ok(n.predict(&Dataset::from_trajectory(traj, 0)?.inputs)?),
                    None => model_torques(model, traj),
                })
                .with_context(|| path.display().to_string())?,
        );
    }
    let stacked = |f: fn(&Compared) -> &DMatrix<f64>| {
        study::stack(compared.iter().map(|c| f(c).clone()).collect())
    };
    let (p, m) = (stacked(|c| &c.predicted), stacked(|c| &c.measured));
    let mse = mse_per_joint(&p, &m);
    // Each recording weighs as in `mse` (by its kept samples, i.e. by its
    // duration), whatever rate it was logged at.
    let weights: Vec<f64> = compared.iter().map(|c| c.measured.nrows() as f64).collect();
    let total: f64 = weights.iter().sum::<f64>().max(1.0);
    let mut mse_as_logged = vec![0.0; model.dof()];
    for (c, w) in compared.iter().zip(&weights) {
        let each = mse_per_joint(&c.predicted_unfiltered, &c.measured_as_logged);
        for (sum, v) in mse_as_logged.iter_mut().zip(each) {
            *sum += v * w / total;
        }
    }
    let mean = mse.iter().sum::<f64>() / mse.len().max(1) as f64;
    let name = args
        .nn
        .as_ref()
        .map_or(model.name().to_string(), |p| p.display().to_string());
    match args.format {
        Format::Json => println!(
            "{}",
            serde_json::json!({
                "model": name, "samples": m.nrows(), "mse": mse, "mse_mean": mean,
                "mse_torque_as_logged": mse_as_logged, "preprocessing": pipeline,
            })
        ),
        Format::Text => {
            println!("model {name}: {} samples", m.nrows());
            println!("{}", pipeline.summary());
            for (j, v) in mse.iter().enumerate() {
                println!(
                    "  joint {}: MSE {v:.6} N m^2 (against the torque as logged: {:.6})",
                    j + 1,
                    mse_as_logged[j]
                );
            }
            println!("  mean:    MSE {mean:.6} N m^2");
        }
    }
    Ok(())
}

#[derive(Debug, Args)]
pub struct PredictArgs {
    /// Trained network (JSON from `sdnn train`).
    #[arg(long)]
    pub nn: PathBuf,
    /// State file (q1..qN,qd1..qdN,qdd1..qddN).
    #[arg(long)]
    pub input: PathBuf,
    /// Torque file; standard output if absent.
    #[arg(long)]
    pub output: Option<PathBuf>,
    #[arg(long, value_enum, default_value_t)]
    pub angles: AngleArg,
}

pub fn predict(args: &PredictArgs) -> Result<()> {
    let network = Mlp::load(&args.nn)?;
    let dof = network.n_outputs();
    if network.n_inputs() != 3 * dof {
        bail!(
            "{}: the network maps {} inputs to {dof} torques, not a network of joint states \
             (q, qd and qdd of each joint: {} inputs)",
            args.nn.display(),
            network.n_inputs(),
            3 * dof
        );
    }
    let options = ReadOptions {
        units: args.angles.into(),
        dof: Some(dof),
        min_samples: 1,
        ..ReadOptions::default()
    };
    let states = read_states_csv(&args.input, &options)?;
    let mut inputs = DMatrix::zeros(states.len(), 3 * dof);
    inputs.columns_mut(0, dof).copy_from(states.q());
    inputs.columns_mut(dof, dof).copy_from(states.qd());
    inputs.columns_mut(2 * dof, dof).copy_from(states.qdd());
    let tau = network.predict(&inputs)?;
    match &args.output {
        Some(path) => write_torques_csv(path, &tau)?,
        None => write_torques(&mut std::io::stdout().lock(), &tau)
            .context("writing to standard output")?,
    }
    Ok(())
}

#[derive(Debug, Args)]
pub struct DiagnoseArgs {
    /// The model to check: a compiled model's name, or a TOML description
    /// (evaluated by the numeric dynamics, no rebuild needed).
    #[arg(long, default_value = DEFAULT_NOMINAL)]
    pub model: String,
    /// Raw measured CSV files: one or more recordings, each cut into
    /// cross-validation segments.
    #[arg(long, required = true, num_args = 1..)]
    pub data: Vec<PathBuf>,
    #[command(flatten)]
    pub input: InputArgs,
    #[command(flatten)]
    pub filter: FilterArgs,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
    /// Cross-validation segments per recording [default: about 12 in all,
    /// 2-30 s each].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=100))]
    pub segments: Option<u32>,
    /// Let Stribeck friction compete too (off by default: from recordings
    /// its signature, confined to velocity reversals, is confounded with the
    /// stick-slip of plain dry friction; see docs/diagnosis.md).
    #[arg(long)]
    pub stribeck: bool,
    /// Write the named effects into the model's TOML (a `.bak` copy is kept).
    #[arg(long)]
    pub apply: bool,
    /// The description to update with --apply (default: the model's TOML).
    #[arg(long)]
    pub toml: Option<PathBuf>,
    /// Write residual-vs-velocity and residual-vs-acceleration plots (SVG,
    /// per joint, before and after the named effects) into this folder.
    #[arg(long)]
    pub plots: Option<PathBuf>,
}

pub fn diagnose(args: &DiagnoseArgs) -> Result<()> {
    let model = find_model(&args.model)?;
    let recordings = args.input.read_all(&args.data, Some(model.dof()))?;
    let pipeline = args.filter.resolve(&recordings)?;
    let report = crate::diagnose::diagnose(
        model,
        &recordings,
        &pipeline,
        crate::diagnose::Settings {
            reach: crate::diagnose::reach(model),
            segments: args.segments.map(|s| s as usize),
            stribeck: args.stribeck,
            ..crate::diagnose::Settings::default()
        },
    )?;
    match args.format {
        Format::Json => println!("{}", serde_json::to_string_pretty(&report)?),
        Format::Text => print!("{}", report.text()),
    }
    if let Some(dir) = &args.plots {
        for path in crate::diagnose::plots::write(dir, &report)? {
            eprintln!("wrote {}", path.display());
        }
    }
    if args.apply && !report.effects.is_empty() {
        apply(args, model, &report)?;
    }
    Ok(())
}

/// Writes the named effects into the description and says how to see the
/// gap shrink.
fn apply(args: &DiagnoseArgs, model: &dyn Dynamics, report: &Diagnosis) -> Result<()> {
    let toml = match (&args.toml, crate::args::model_path(&args.model)) {
        (Some(path), _) => path.clone(),
        (None, Some(path)) => path,
        (None, None) => PathBuf::from(format!("models/{}.toml", model.name())),
    };
    let on_disk = std::fs::read_to_string(&toml)
        .with_context(|| format!("{}: cannot read", toml.display()))?;
    if let Err(e) = codegen::Description::parse(&on_disk, model.name(), &toml) {
        bail!(
            "--toml {}: not a robot description this tool reads: {e}",
            toml.display()
        );
    }
    let plain = |text: &str| text.trim_start_matches('\u{feff}').replace("\r\n", "\n");
    if plain(&on_disk) != plain(model.description()) {
        bail!(
            "{}: the file is not the description `{}` was built from (an earlier --apply \
             or an edit since the build), so applying this diagnosis would count its effects \
             twice; rebuild (`cargo build --release`) or diagnose the file itself \
             (`--model {}`), then --apply",
            toml.display(),
            model.name(),
            toml.display()
        );
    }
    let description = crate::dynamics::parsed_description(model)?;
    let last = description
        .chain()
        .bodies
        .last()
        .map(|b| b.link.clone())
        .unwrap_or_default();
    let applied = crate::diagnose::apply::apply_to_file(&toml, report, model.joint_names(), &last)?;
    let backup = applied.backup;
    if applied.changes.is_empty() {
        eprintln!(
            "{}: unchanged (no effect of the robot was named)",
            toml.display()
        );
    } else {
        eprintln!("changed in {}:", toml.display());
    }
    for line in &applied.changes {
        eprintln!("  {line}");
    }
    let data: Vec<String> = args
        .data
        .iter()
        .map(|p| shell_word(&p.display().to_string()))
        .collect();
    let corrections = args
        .input
        .corrections()
        .then(&Corrections::diagnosed(report));
    let options =
        args.input.command_line(&corrections) + &args.filter.command_line(args.input.angles);
    if corrections != args.input.corrections() {
        eprintln!(
            "the recordings need correcting too (properties of the data, not of the robot, so not \
             in the TOML):{}",
            Corrections::diagnosed(report).flags()
        );
    }
    let done = if applied.changes.is_empty() {
        "the gap with the corrections".to_string()
    } else {
        format!(
            "updated {} (backup {}); the gap with the effects, no rebuild needed",
            toml.display(),
            backup.display()
        )
    };
    eprintln!(
        "{done}:\n  sdnn evaluate --model {} --data {}{options}\n(`cargo build --release` makes \
         it the compiled model `{}` when the file is under models/)",
        shell_word(&toml.display().to_string()),
        data.join(" "),
        toml.file_stem()
            .map_or(String::new(), |s| s.to_string_lossy().into_owned()),
    );
    Ok(())
}

fn file_name(path: &Path) -> Result<&std::ffi::OsStr> {
    path.file_name()
        .with_context(|| format!("{}: not a file name", path.display()))
}

/// Runs `f` on every file, whose output is the file's name in the output
/// folder; a bad file is reported and the rest still run.
fn for_each_file(files: &[PathBuf], f: impl Fn(&Path) -> Result<()>) -> Result<()> {
    for (k, path) in files.iter().enumerate() {
        let name = file_name(path)?;
        if let Some(other) = files[..k].iter().find(|p| p.file_name() == Some(name)) {
            bail!(
                "{} and {} have the same file name: their outputs would overwrite each other in \
                 the output folder (rename one, or run them separately)",
                other.display(),
                path.display()
            );
        }
    }
    let mut failed = 0;
    for path in files {
        if let Err(e) = f(path) {
            eprintln!("sdnn: {}", crate::errors::message(&e));
            failed += 1;
        }
    }
    if failed > 0 {
        bail!("{failed} of {} files failed", files.len());
    }
    Ok(())
}
