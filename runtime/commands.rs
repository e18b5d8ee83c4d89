//! The pipeline's stage commands and the study (`sdnn reproduce`).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use nalgebra::DMatrix;

use crate::cli::{AngleArg, Format, find_model};
use crate::mlp::{Dataset, Mlp};
use crate::preprocess::{Filter, Preprocess};
use crate::study::{self, StudyConfig, model_torques, mse_per_joint};
use crate::trajectory::{
    ReadOptions, Trajectory, read_csv, read_states_csv, write_csv, write_torques, write_torques_csv,
};

/// The default virtual robot: the thesis model plus joint friction and armature.
pub const DEFAULT_PLANT: &str = "kinova_gen3_lite_3dof_plant";
/// The thesis's analytical model.
pub const DEFAULT_NOMINAL: &str = "kinova_gen3_lite_3dof";

/// Options of reading measured CSV files.
#[derive(Debug, Args, Clone)]
pub struct InputArgs {
    /// Unit of q, qd and qdd in the files (Kinova's API logs degrees).
    #[arg(long, value_enum, default_value_t)]
    pub angles: AngleArg,
    /// Resample jittery timestamps to this uniform rate (Hz) by linear interpolation.
    #[arg(long)]
    pub resample: Option<f64>,
    /// Map a file column to a contract column, e.g. `--column time=t --column pos1=q1`.
    #[arg(long = "column", value_name = "FILE=CONTRACT", value_parser = parse_mapping)]
    pub columns: Vec<(String, String)>,
    /// File columns to ignore (extra columns are an error otherwise).
    #[arg(long = "ignore-column", value_name = "NAME")]
    pub ignored: Vec<String>,
}

fn parse_mapping(text: &str) -> Result<(String, String), String> {
    match text.split_once('=') {
        Some((from, to)) if !from.is_empty() && !to.is_empty() => {
            Ok((from.to_string(), to.to_string()))
        }
        _ => Err(format!(
            "expected FILE_COLUMN=CONTRACT_COLUMN, found `{text}`"
        )),
    }
}

impl InputArgs {
    fn options(&self, dof: Option<usize>, min_samples: usize) -> ReadOptions {
        ReadOptions {
            units: self.angles.into(),
            dof,
            resample_hz: self.resample,
            min_samples,
            renames: self.columns.iter().cloned().collect(),
            ignored: self.ignored.clone(),
        }
    }
}

/// Preprocessing options (thesis 2.4.2 defaults).
#[derive(Debug, Args, Clone)]
pub struct FilterArgs {
    /// Keep every n-th sample (10: 1 kHz -> 100 Hz).
    #[arg(long, default_value_t = 10)]
    pub downsample: usize,
    /// Velocity filter: `sma` (centred moving average, thesis), `sg` (Savitzky-Golay,
    /// cubic, zero-phase; odd window) or `none`.
    #[arg(long, default_value = "sma")]
    pub filter: String,
    /// Filter window in samples after downsampling (40 = 0.4 s at 100 Hz).
    #[arg(long, default_value_t = 40)]
    pub window: usize,
    /// Also smooth the measured torque with the acceleration's filter
    /// (parallel filtering): recommended for `diagnose`, whose fit then sees
    /// torque and states smoothed alike; off in the thesis pipeline.
    #[arg(long)]
    pub filter_torque: bool,
}

impl FilterArgs {
    pub fn preprocess(&self) -> Result<Preprocess> {
        let filter = match self.filter.as_str() {
            "sma" => Filter::Sma {
                window: self.window,
                centered: true,
            },
            "sg" if self.window.is_multiple_of(2) => bail!(
                "--window {} for `sg`: a Savitzky-Golay window has a centre sample, so it must be odd ({} or {})",
                self.window,
                self.window.saturating_sub(1).max(1),
                self.window + 1
            ),
            "sg" => Filter::SavitzkyGolay {
                window: self.window,
                order: 3,
            },
            "none" => Filter::None,
            other => bail!("--filter must be `sma`, `sg` or `none`, not `{other}`"),
        };
        Ok(Preprocess {
            downsample: self.downsample,
            filter,
            filter_torque: self.filter_torque,
        })
    }
}

/// Options shared by the studies: where results go, seeds and networks.
#[derive(Debug, Args)]
pub struct StudyRunArgs {
    /// Results folder.
    #[arg(long, default_value = "results")]
    pub out: PathBuf,
    /// Master seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Seeds per network.
    #[arg(long, default_value_t = 5)]
    pub seeds: usize,
    /// Maximum training epochs per network.
    #[arg(long, default_value_t = StudyConfig::default().max_epochs)]
    pub epochs: usize,
    /// Early-stopping patience in epochs.
    #[arg(long, default_value_t = StudyConfig::default().patience)]
    pub patience: usize,
    /// Hidden layer widths, comma separated.
    #[arg(long, value_delimiter = ',', default_values_t = StudyConfig::default().hidden)]
    pub hidden: Vec<usize>,
    /// Adam learning rate.
    #[arg(long, default_value_t = StudyConfig::default().learning_rate)]
    pub learning_rate: f64,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

impl StudyRunArgs {
    /// The study defaults with these seeds and network settings.
    fn config(&self) -> StudyConfig {
        StudyConfig {
            seed: self.seed,
            seeds: self.seeds,
            max_epochs: self.epochs,
            patience: self.patience,
            hidden: self.hidden.clone(),
            learning_rate: self.learning_rate,
            ..StudyConfig::default()
        }
    }
}

#[derive(Debug, Args)]
pub struct ReproduceArgs {
    /// Number of recorded trajectories and of training trajectories.
    #[arg(long, default_value_t = 14)]
    pub trajectories: usize,
    #[arg(long, default_value_t = 10)]
    pub train: usize,
    /// Seconds per trajectory.
    #[arg(long, default_value_t = 20.0)]
    pub duration: f64,
    /// Plant (truth) and nominal (analytical) compiled models.
    #[arg(long, default_value = DEFAULT_PLANT)]
    pub plant: String,
    #[arg(long, default_value = DEFAULT_NOMINAL)]
    pub nominal: String,
    #[command(flatten)]
    pub run: StudyRunArgs,
}

pub fn reproduce(args: &ReproduceArgs) -> Result<()> {
    let (plant, nominal) = (find_model(&args.plant)?, find_model(&args.nominal)?);
    let config = StudyConfig {
        trajectories: args.trajectories,
        train: args.train,
        duration: args.duration,
        ..args.run.config()
    };
    let out = &args.run.out;
    run_study(out, args.run.format, |progress| {
        study::run(plant, nominal, &config, out, progress)
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
            println!("{}", crate::study_report::markdown(&result));
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
    #[arg(long)]
    pub test_from: f64,
    /// Training pieces per recording (the networks validate on whole pieces).
    #[arg(long, default_value_t = 5)]
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
    let recordings = args
        .data
        .iter()
        .map(|path| Ok(read_csv(path, &args.input.options(Some(nominal.dof()), 2))?))
        .collect::<Result<Vec<_>>>()?;
    let config = StudyConfig {
        preprocess: args.filter.preprocess()?,
        trajectories: recordings.len() * (args.train_pieces + 1),
        train: recordings.len() * args.train_pieces,
        ..args.run.config()
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
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Number of trajectories.
    #[arg(long, default_value_t = 14)]
    pub count: usize,
    #[arg(long, default_value_t = 20.0)]
    pub duration: f64,
    #[arg(long, default_value = DEFAULT_PLANT)]
    pub plant: String,
    #[arg(long, default_value = DEFAULT_NOMINAL)]
    pub nominal: String,
}

pub fn simulate(args: &SimulateArgs) -> Result<()> {
    let (plant, nominal) = (find_model(&args.plant)?, find_model(&args.nominal)?);
    std::fs::create_dir_all(&args.out)
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
    let preprocess = args.filter.preprocess()?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    for_each_file(&args.data, |path| {
        let processed = preprocess.apply(&read_csv(path, &args.input.options(None, 2))?)?;
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
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    for_each_file(&args.data, |path| {
        let traj = load(
            path,
            model.dof(),
            &args.input,
            &args.filter,
            args.preprocessed,
        )?;
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
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Hidden layer widths, comma separated.
    #[arg(long, value_delimiter = ',', default_values_t = StudyConfig::default().hidden)]
    pub hidden: Vec<usize>,
    #[arg(long, default_value_t = StudyConfig::default().max_epochs)]
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
    let mut parts = Vec::new();
    for (group, path) in args.data.iter().enumerate() {
        let traj = load_any(path, &args.input, &args.filter, args.preprocessed)?;
        parts.push(
            Dataset::from_trajectory(&traj, group).with_context(|| path.display().to_string())?,
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
    match args.format {
        Format::Json => println!("{summary}"),
        Format::Text => println!(
            "trained on {} samples for {} epochs (best {}); written to {}",
            data.len(),
            history.epochs(),
            history.best_epoch(),
            args.out.display()
        ),
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
    let mut predicted = Vec::new();
    let mut measured = Vec::new();
    for path in &args.data {
        let traj = load(path, model.dof(), &args.input, &args.filter, false)?;
        predicted.push(match &network {
            Some(n) => n.predict(&Dataset::from_trajectory(&traj, 0)?.inputs)?,
            None => model_torques(model, &traj)?,
        });
        measured.push(traj.tau().clone());
    }
    let (p, m) = (study::stack(predicted), study::stack(measured));
    let mse = mse_per_joint(&p, &m);
    let mean = mse.iter().sum::<f64>() / mse.len().max(1) as f64;
    let name = args
        .nn
        .as_ref()
        .map_or(model.name().to_string(), |p| p.display().to_string());
    match args.format {
        Format::Json => println!(
            "{}",
            serde_json::json!({ "model": name, "samples": m.nrows(), "mse": mse, "mse_mean": mean })
        ),
        Format::Text => {
            println!("model {name}: {} samples", m.nrows());
            for (j, v) in mse.iter().enumerate() {
                println!("  joint {}: MSE {v:.6} N m^2", j + 1);
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
    /// Compiled model to check.
    #[arg(long, default_value = DEFAULT_NOMINAL)]
    pub model: String,
    /// Raw measured CSV files (at least two trajectories, or one with
    /// --segments: the gap is cross-validated across them).
    #[arg(long, required = true, num_args = 1..)]
    pub data: Vec<PathBuf>,
    #[command(flatten)]
    pub input: InputArgs,
    #[command(flatten)]
    pub filter: FilterArgs,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
    /// Cut each file into this many contiguous pieces after preprocessing, so
    /// a single long recording can be cross-validated across its pieces.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub segments: u32,
    /// Write the named effects into the model's TOML (a `.bak` copy is kept).
    #[arg(long)]
    pub apply: bool,
    /// The description to update with --apply (default models/MODEL.toml).
    #[arg(long)]
    pub toml: Option<PathBuf>,
    /// Write residual-vs-velocity and residual-vs-acceleration plots (SVG,
    /// per joint, before and after the named effects) into this folder.
    #[arg(long)]
    pub plots: Option<PathBuf>,
}

pub fn diagnose(args: &DiagnoseArgs) -> Result<()> {
    let model = find_model(&args.model)?;
    let trajectories = args
        .data
        .iter()
        .map(|path| load(path, model.dof(), &args.input, &args.filter, false))
        .collect::<Result<Vec<_>>>()?
        .iter()
        .flat_map(|traj| traj.split(args.segments as usize))
        .collect::<Vec<_>>();
    let report = crate::diagnose::diagnose(
        model,
        &trajectories,
        crate::diagnose::Settings {
            reach: crate::diagnose::reach(model),
            ..crate::diagnose::Settings::default()
        },
    )?;
    match args.format {
        Format::Json => println!("{}", serde_json::to_string_pretty(&report)?),
        Format::Text => {
            println!("model {}: {} samples", report.model, report.samples);
            for j in 0..report.mse_before.len() {
                println!(
                    "  joint {}: residual RMS {:.4} N m ({:.1}% of torque RMS); held-out MSE {:.5} -> {:.5} N m^2",
                    j + 1,
                    report.residual_rms[j],
                    100.0 * report.residual_share[j],
                    report.mse_before[j],
                    report.mse_after[j]
                );
                let r = &report.regimes[j];
                println!(
                    "    residual correlates with velocity {:+.2}, its sign {:+.2}, acceleration \
                     {:+.2}, gravity load {:+.2}; mean {:+.4} N m",
                    r.velocity, r.velocity_sign, r.acceleration, r.gravity_load, r.mean
                );
            }
            if report.effects.is_empty() {
                println!("no significant missing effect found");
            }
            for e in &report.effects {
                let joint = match (e.joint, &e.link) {
                    (Some(j), _) => format!("joint {j}"),
                    (None, Some(link)) => format!("link `{link}`"),
                    (None, None) => "the last link".to_string(),
                };
                let whose = if e.joint.is_some() {
                    "its joint's"
                } else {
                    "the"
                };
                println!(
                    "  missing: {:?} on {joint}: {} (95% CI {}), explains {:.1}% of {whose} residual",
                    e.kind,
                    serde_json::Value::Object(e.parameters.clone()),
                    serde_json::Value::Object(e.ci95.clone()),
                    100.0 * e.share_explained
                );
            }
            for note in &report.notes {
                println!("  note: {note}");
            }
        }
    }
    if let Some(dir) = &args.plots {
        for path in crate::diagnose_plots::write(dir, &report)? {
            eprintln!("wrote {}", path.display());
        }
    }
    if args.apply && !report.effects.is_empty() {
        let toml = args
            .toml
            .clone()
            .unwrap_or_else(|| PathBuf::from(format!("models/{}.toml", model.name())));
        let description = crate::dynamics::parsed_description(model)?;
        let last = description
            .chain()
            .bodies
            .last()
            .map(|b| b.link.clone())
            .unwrap_or_default();
        let backup = crate::apply::apply_to_file(&toml, &report, model.joint_names(), &last)?;
        eprintln!(
            "updated {} (backup {}); next: `cargo build --release` regenerates the model, then \
             `sdnn evaluate --model {} --data ...` with the same preprocessing options shows the \
             new gap",
            toml.display(),
            backup.display(),
            model.name()
        );
    }
    Ok(())
}

/// Reads a measured file with the model's joint count and preprocesses it.
fn load(
    path: &Path,
    dof: usize,
    input: &InputArgs,
    filter: &FilterArgs,
    preprocessed: bool,
) -> Result<Trajectory> {
    let traj = read_csv(path, &input.options(Some(dof), 2))?;
    if preprocessed {
        if traj.qdd().is_none() {
            bail!(
                "{}: --preprocessed needs qdd1..qddN columns",
                path.display()
            );
        }
        return Ok(traj);
    }
    Ok(filter.preprocess()?.apply(&traj)?)
}

fn load_any(
    path: &Path,
    input: &InputArgs,
    filter: &FilterArgs,
    preprocessed: bool,
) -> Result<Trajectory> {
    let dof = read_csv(path, &input.options(None, 2))?.dof();
    load(path, dof, input, filter, preprocessed)
}

fn file_name(path: &Path) -> Result<&std::ffi::OsStr> {
    path.file_name()
        .with_context(|| format!("{}: not a file name", path.display()))
}

/// Runs `f` on every file; a bad file is reported and the rest still run.
fn for_each_file(files: &[PathBuf], f: impl Fn(&Path) -> Result<()>) -> Result<()> {
    let mut failed = 0;
    for path in files {
        if let Err(e) = f(path) {
            eprintln!("sdnn: {e:#}");
            failed += 1;
        }
    }
    if failed > 0 {
        bail!("{failed} of {} files failed", files.len());
    }
    Ok(())
}
