//! The pipeline's stage commands; the study (`reproduction`) and the
//! diagnosis (`diagnosis`) have their own files.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use nalgebra::DMatrix;

use crate::args::{AngleArg, Format, check_angle_units, find_model};
use crate::corrections::Corrections;
use crate::diagnose::Diagnosis;
use crate::dynamics::Dynamics;
use crate::dynamics::model_torques;
use crate::inputs::{FilterArgs, InputArgs, load, load_one, load_preprocessed, shell_word};
use crate::mlp::{Dataset, Mlp};
use crate::output::StagedFolder;
use crate::preprocess::Compared;
use crate::ranges;
use crate::study::{self, StudyConfig, mse_per_joint};
use crate::trajectory::{
    ReadOptions, read_states_csv, write_csv, write_torques, write_torques_csv,
};

mod diagnosis;
mod evaluation;
mod excitation;
mod pointwise;
mod reproduction;

pub use diagnosis::{DiagnoseArgs, diagnose};
pub use evaluation::{EvaluateArgs, evaluate};
pub use excitation::{ExciteArgs, excite};
pub use pointwise::{PointwiseArgs, pose, qdd, tau};
pub use reproduction::{
    ReproduceArgs, Situation, StudyArgs, StudyRunArgs, reproduce, study_command,
};

/// The default virtual robot: the thesis model plus joint friction and armature.
pub const DEFAULT_PLANT: &str = "kinova_gen3_lite_3dof_plant";
/// The thesis's analytical model.
pub const DEFAULT_NOMINAL: &str = "kinova_gen3_lite_3dof";

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
    /// Record this planned motion (`t,q1..qN,qd1..qdN,qdd1..qddN`, e.g.
    /// from `sdnn excite`) instead of random ones: written as
    /// trajectory_01.csv.
    #[arg(long, conflicts_with_all = ["count", "duration"])]
    pub trajectory: Option<PathBuf>,
    /// Number of trajectories (1-1000).
    #[arg(long, default_value_t = 14, value_parser = ranges::integer(1, 1000, "run several times with other --seed and --out"))]
    pub count: usize,
    /// Seconds per trajectory (above 0, at most 3600).
    #[arg(long, default_value_t = 20.0, value_parser = ranges::real(0.0, 3600.0, true, "record several trajectories"))]
    pub duration: f64,
    /// The arm that moves (the truth recorded), a compiled model's name or
    /// a .toml file [default: kinova_gen3_lite_3dof_plant, the thesis
    /// model plus joint friction and armature].
    #[arg(long)]
    pub plant: Option<String>,
    /// The controller's model of the arm (computed-torque tracking; its
    /// limits bound the random motions) [default: the --plant given, else
    /// kinova_gen3_lite_3dof].
    #[arg(long)]
    pub nominal: Option<String>,
}

impl SimulateArgs {
    /// The plant and the controller's model. Without `--nominal` the
    /// controller knows a `--plant` given (the default 3-joint model
    /// would not fit another arm); the two must have the same joints.
    fn models(&self) -> Result<(&'static dyn Dynamics, &'static dyn Dynamics)> {
        let plant = find_model(self.plant.as_deref().unwrap_or(DEFAULT_PLANT))?;
        let nominal = match (&self.nominal, &self.plant) {
            (Some(nominal), _) => find_model(nominal)?,
            (None, Some(_)) => plant,
            (None, None) => find_model(DEFAULT_NOMINAL)?,
        };
        if nominal.dof() != plant.dof() {
            bail!(
                "--nominal {} has {} joints and --plant {} has {}: the controller's model \
                 (--nominal) is a model of the plant, with its joints; leave --nominal out \
                 to control the plant with its own model",
                nominal.name(),
                nominal.dof(),
                plant.name(),
                plant.dof()
            );
        }
        Ok((plant, nominal))
    }
}

/// Most recorded seconds one `simulate` run writes, or one study records (10 h, about 2 GB of
/// CSV at 1 kHz for 3 joints): beyond it, run it several times.
const MOST_SIMULATED_SECONDS: f64 = 36_000.0;

/// Joints up to which a run may simulate [`MOST_SIMULATED_SECONDS`] (a
/// Panda); beyond, the seconds shrink with the cube of the joint count,
/// as the cost of a step does (the forward dynamics' mass matrix: a
/// 1,000-joint model took 4.8 s per 1 ms step).
const FULL_BUDGET_JOINTS: usize = 7;

/// Refuses `seconds` of simulation of a `dof`-joint plant beyond the
/// budget; `what` says which options made them.
fn check_simulated_seconds(what: &str, seconds: f64, dof: usize) -> Result<()> {
    let scale = (dof.max(FULL_BUDGET_JOINTS) as f64 / FULL_BUDGET_JOINTS as f64).powi(3);
    let most = MOST_SIMULATED_SECONDS / scale;
    if seconds > most {
        bail!(
            "{what} is {seconds} s of simulation of a {dof}-joint plant, more than one run \
             simulates ({most:.3e} s: {MOST_SIMULATED_SECONDS} s up to {FULL_BUDGET_JOINTS} \
             joints, shrinking with the cube of the joint count, as the cost of a step grows): \
             simulate fewer or shorter trajectories"
        );
    }
    Ok(())
}

pub fn simulate(args: &SimulateArgs) -> Result<()> {
    if let Some(path) = &args.trajectory {
        return simulate_plan(args, path);
    }
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
    let (plant, nominal) = args.models()?;
    let what = format!("--count {} x --duration {}", args.count, args.duration);
    check_simulated_seconds(&what, total, plant.dof())?;
    let staged = begin_recordings(&args.out, args.count)?;
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
        let path = staged.path().join(format!("trajectory_{:02}.csv", k + 1));
        warn_if_not_followed(&recording, &path);
        write_csv(&path, &recording.measured)?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    reproduction::commit_folder(staged, &args.out)?;
    crate::output::print_line(&format!(
        "{} trajectories written to {}",
        args.count,
        args.out.display()
    ))?;
    Ok(())
}

/// Tracking error (rad or m) beyond which a recording is not of the
/// planned motion.
const LOST_TRACKING: f64 = 0.2;

/// Warns when the virtual robot left its planned motion: the drives
/// saturated at their effort limits (a plant heavier than the controller's
/// model, a plan too fast for them) and the joint ran away, so the
/// recording's positions may leave the description's limits.
fn warn_if_not_followed(recording: &crate::sim::simulate::Recording, path: &Path) {
    let Some((joint, error, time)) = recording.worst_tracking() else {
        return;
    };
    if error > LOST_TRACKING {
        let name = path.file_name().map_or(path, Path::new).display();
        eprintln!(
            "warning: {name}: joint {} left its planned motion by {error:.3} at t = {time:.3} s \
             (the drives saturate at their effort limits, or the plant differs from the \
             controller's model too much to follow): the recording is of the motion the robot \
             made, which may leave its limits",
            joint + 1
        );
    }
}

/// Starts writing `count` recordings into the folder `out` whole (see
/// `reproduction::begin_folder`): interrupted, the earlier recordings stay
/// as they were. A folder holding more of them is refused.
fn begin_recordings(out: &Path, count: usize) -> Result<StagedFolder> {
    crate::output::create_folder(out).with_context(|| format!("creating {}", out.display()))?;
    refuse_stale_recordings(out, count)?;
    StagedFolder::begin(out, None).with_context(|| format!("creating {}", out.display()))
}

/// Refuses a folder holding recordings `trajectory_NN.csv` numbered
/// beyond `count` (an earlier, larger run's): this run would leave them
/// beside its own, and a later `train DIR/*.csv` would take them too.
fn refuse_stale_recordings(dir: &Path, count: usize) -> Result<()> {
    let entries = std::fs::read_dir(dir).with_context(|| format!("reading {}", dir.display()))?;
    let mut stale: Vec<String> = entries
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|name| {
            let number = name
                .strip_prefix("trajectory_")
                .and_then(|n| n.strip_suffix(".csv"))
                .and_then(|n| n.parse::<usize>().ok());
            number.is_some_and(|n| n > count)
        })
        .collect();
    if stale.is_empty() {
        return Ok(());
    }
    stale.sort();
    let shown = stale.len().min(5);
    bail!(
        "{} holds {} recording(s) of an earlier run beyond --count {count} ({}{}): this run would \
         leave them beside its own; remove them or choose another --out",
        dir.display(),
        stale.len(),
        stale[..shown].join(", "),
        if stale.len() > shown { ", ..." } else { "" }
    )
}

/// Records one planned motion read from `path` on the virtual robot.
fn simulate_plan(args: &SimulateArgs, path: &Path) -> Result<()> {
    let (plant, nominal) = args.models()?;
    let options = ReadOptions {
        dof: Some(plant.dof()),
        ..ReadOptions::default()
    };
    crate::output::note_input(path);
    let plan = crate::trajectory::read_plan_csv(path, &options).map_err(|e| match e {
        // A plan for another arm (`excite --model panda`): name the plant.
        crate::trajectory::TrajectoryError::WrongDof { .. } => anyhow::anyhow!(
            "{e}: the plant `{}`{} has {} joints; pass `--plant MODEL`, the arm the plan was \
             designed for (`sdnn excite --model MODEL`)",
            plant.name(),
            if args.plant.is_none() {
                ", the default when `--plant` is not given,"
            } else {
                ""
            },
            plant.dof()
        ),
        e => e.into(),
    })?;
    if plan
        .t()
        .last()
        .zip(plan.t().first())
        .is_some_and(|(l, f)| l - f > MOST_SIMULATED_SECONDS)
    {
        bail!(
            "{}: the plan lasts more than {MOST_SIMULATED_SECONDS} s, more than one run records",
            path.display()
        );
    }
    let staged = begin_recordings(&args.out, 1)?;
    let reference = crate::sim::replay::Planned::new(&plan);
    let seed = study::trajectory_seed(args.seed, 0);
    let recording = study::record_reference(plant, nominal, &reference, seed, 1.0)
        .with_context(|| format!("recording {}", path.display()))?;
    warn_if_not_followed(&recording, Path::new("trajectory_01.csv"));
    write_csv(staged.path().join("trajectory_01.csv"), &recording.measured)?;
    reproduction::commit_folder(staged, &args.out)?;
    let out = args.out.join("trajectory_01.csv");
    crate::output::print_line(&format!(
        "{} recorded on the virtual robot into {}",
        path.display(),
        out.display()
    ))?;
    Ok(())
}

#[derive(Debug, Args)]
pub struct PreprocessArgs {
    /// Measured CSV files.
    #[arg(required = true)]
    pub data: Vec<PathBuf>,
    /// Output folder (same file names; a bag's `.mcap` becomes `.csv`).
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
        crate::say!("{}: {}", path.display(), pipeline.summary());
        write_csv(args.out.join(output_name(path)?), &processed)?;
        Ok(())
    })
}

#[derive(Debug, Args)]
pub struct SynthArgs {
    /// The model that produces the torques: a compiled model's name or a
    /// TOML description.
    #[arg(long, default_value = DEFAULT_NOMINAL)]
    pub model: String,
    /// Measured CSV files (preprocessed here unless --preprocessed).
    #[arg(required = true)]
    pub data: Vec<PathBuf>,
    #[arg(long)]
    pub out: PathBuf,
    /// The files already carry filtered qd and qdd (the filter, resampling
    /// and torque corrections were applied when they were written).
    #[arg(long, conflicts_with_all = crate::inputs::PREPROCESSED_CONFLICTS)]
    pub preprocessed: bool,
    #[command(flatten)]
    pub input: InputArgs,
    #[command(flatten)]
    pub filter: FilterArgs,
}

pub fn synth(args: &SynthArgs) -> Result<()> {
    let model = find_model(&args.model)?;
    check_angle_units(model, args.input.angles.into())?;
    crate::output::create_folder(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    for_each_file(&args.data, |path| {
        let traj = if args.preprocessed {
            load_preprocessed(path, Some(model.joint_names()), &args.input)?
        } else {
            load_one(path, Some(model.joint_names()), &args.input, &args.filter)?.0
        };
        let analytical = traj.with_tau(model_torques(model, &traj)?)?;
        write_csv(args.out.join(output_name(path)?), &analytical)?;
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
    /// The files already carry filtered qd and qdd (the filter, resampling
    /// and torque corrections were applied when they were written).
    #[arg(long, conflicts_with_all = crate::inputs::PREPROCESSED_CONFLICTS)]
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
            .collect::<Result<Vec<_>>>()
            .and_then(|all| crate::inputs::reject_repeated(&args.data, &all).map(|()| all))?
    } else {
        let (trajectories, pipeline) = load(&args.data, None, &args.input, &args.filter)?;
        crate::say!("{}", pipeline.summary());
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
        crate::say!("{text}");
    } else {
        crate::output::print_line(&text)?;
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

/// The output's file name for input `path` in an output folder: the
/// input's name, a bag's (`.mcap`) with `.csv` since the output is CSV.
fn output_name(path: &Path) -> Result<std::ffi::OsString> {
    if path == Path::new("-") {
        bail!(
            "`-` (standard input) has no file name to give its output in the output folder: \
             save it to a file first"
        );
    }
    let name = Path::new(
        path.file_name()
            .with_context(|| format!("{}: not a file name", path.display()))?,
    );
    let bag = name
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("mcap"));
    Ok(if bag {
        name.with_extension("csv").into_os_string()
    } else {
        name.as_os_str().to_os_string()
    })
}

/// Runs `f` on every file, whose output is [`output_name`] in the output
/// folder; a bad file is reported and the rest still run.
fn for_each_file(files: &[PathBuf], f: impl Fn(&Path) -> Result<()>) -> Result<()> {
    let names = files
        .iter()
        .map(|p| output_name(p))
        .collect::<Result<Vec<_>>>()?;
    for (k, (path, name)) in files.iter().zip(&names).enumerate() {
        if let Some(other) = names[..k].iter().position(|n| n == name) {
            bail!(
                "{} and {} give the same output file name ({}): their outputs would overwrite \
                 each other in the output folder (rename one, or run them separately)",
                files[other].display(),
                path.display(),
                name.to_string_lossy()
            );
        }
    }
    let mut failed = 0;
    for path in files {
        if let Err(e) = f(path) {
            crate::say!("sdnn: {}", crate::errors::message(&e));
            failed += 1;
        }
    }
    if failed > 0 {
        bail!("{failed} of {} files failed", files.len());
    }
    Ok(())
}
