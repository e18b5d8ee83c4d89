//! `sdnn reproduce` (the SDNN study on the virtual robot, its thesis
//! situation and the map) and `sdnn study` (on measured recordings).

use super::*;

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
    let config = map_config(args)?;
    let out = &args.run.out;
    let staged = begin_folder(out, "map")?;
    let bar = progress_bar();
    let report = |done: usize, total: usize, stage: &str| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
        bar.set_message(stage.to_string());
    };
    let cells = study::map::run_map(plant, exact, thesis, &config, &report)?;
    bar.finish_and_clear();
    let markdown = crate::study::report::write_map(&cells, &config, staged.path())?;
    commit_folder(staged, out)?;
    match args.run.format {
        Format::Json => crate::output::print_line(&serde_json::to_string_pretty(&cells)?)?,
        Format::Text => {
            crate::output::print(&format!("{markdown}\nMap written to {}\n", out.display()))?;
        }
    }
    Ok(())
}

/// The map's settings: its own defaults (10 s trajectories, 15 epochs, 3
/// splits), with `--seed`, `--seeds`, `--epochs`, `--hidden`,
/// `--duration` and `--splits` when they differ from `reproduce`'s
/// defaults. Options the map's grid or plant fixes are refused by name
/// (they were ignored without a word).
fn map_config(args: &ReproduceArgs) -> Result<study::map::MapConfig> {
    let study = StudyConfig::default();
    let fixed = [
        ("--trajectories", args.trajectories != 14),
        ("--train", args.train != 10),
        ("--situation", args.situation != Situation::Virtual),
        ("--plant", args.plant.is_some()),
        ("--nominal", args.nominal.is_some()),
        ("--noise-scale", args.noise_scale != 1.0),
        ("--patience", args.run.patience != study.patience),
        (
            "--learning-rate",
            args.run.learning_rate != study.learning_rate,
        ),
    ];
    if let Some((flag, _)) = fixed.iter().find(|(_, set)| *set) {
        bail!(
            "{flag} does not apply to --map: its grid sets the training trajectories and the \
             noise, on the thesis situation's plant, with its own network schedule (it takes \
             --seed, --seeds, --epochs, --hidden, --duration and --splits)"
        );
    }
    ranges::check_layers(&args.run.hidden).map_err(anyhow::Error::msg)?;
    let map = study::map::MapConfig::default();
    if args.duration != 20.0 && args.duration < MIN_STUDY_SECONDS {
        bail!(
            "--duration {} s: the map's trajectories need at least {MIN_STUDY_SECONDS} s",
            args.duration
        );
    }
    let or_default =
        |given: f64, default: f64, map: f64| if given != default { given } else { map };
    Ok(study::map::MapConfig {
        seed: args.run.seed,
        seeds: args.run.seeds,
        max_epochs: or_default(
            args.run.epochs as f64,
            study.max_epochs as f64,
            map.max_epochs as f64,
        ) as usize,
        hidden: args.run.hidden.clone(),
        duration: or_default(args.duration, 20.0, map.duration),
        splits: args.splits.unwrap_or(map.splits),
        ..map
    })
}

/// The study's situation (see `ReproduceArgs::situation`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Situation {
    #[default]
    Virtual,
    Thesis,
}

/// A `--plant` of another arm than the analytical model: the error names
/// the flag that chooses the model the study compares.
fn check_nominal_fits(plant: &dyn Dynamics, nominal: &dyn Dynamics, given: bool) -> Result<()> {
    if plant.dof() == nominal.dof() {
        return Ok(());
    }
    bail!(
        "--plant {} has {} joints and the analytical model `{}`{} has {}: pass `--nominal \
         MODEL`, the analytical model of that arm the study compares (for example \
         `--nominal {}`)",
        plant.name(),
        plant.dof(),
        nominal.name(),
        if given {
            " (--nominal)"
        } else {
            " (the default of --nominal)"
        },
        nominal.dof(),
        plant.name()
    )
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
    check_nominal_fits(plant, nominal, args.nominal.is_some())?;
    let what = format!(
        "--trajectories {} x --duration {}",
        args.trajectories, args.duration
    );
    check_simulated_seconds(&what, recorded, plant.dof())?;
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
    run_study(
        &args.run.out,
        "reproduce",
        args.run.format,
        |out, progress| study::run_models(models, &config, out, progress),
    )
}

/// Runs a study behind a progress bar into a staged copy of `out` (see
/// [`begin_folder`]) and prints its table.
fn run_study(
    out: &Path,
    kind: &'static str,
    format: Format,
    study: impl FnOnce(&Path, study::Progress<'_>) -> Result<study::StudyResult>,
) -> Result<()> {
    let staged = begin_folder(out, kind)?;
    // Said at once: the first stage reports only when its first item is
    // done, and without a terminal the bar is hidden, so a run printed
    // nothing for its first minute. Each new stage gets a line when the
    // bar cannot show it.
    crate::say!(
        "study: recording, preprocessing and training; results go to {}",
        out.display()
    );
    let bar = progress_bar();
    bar.set_message("starting");
    bar.tick();
    let stage_now = std::sync::Mutex::new(String::new());
    let report = |done: usize, total: usize, stage: &str| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
        bar.set_message(stage.to_string());
        if let Ok(mut now) = stage_now.lock() {
            if *now != stage && bar.is_hidden() {
                crate::say!("study: {stage} ({done}/{total})");
            }
            *now = stage.to_string();
        }
    };
    let result = study(staged.path(), &report)?;
    bar.finish_and_clear();
    commit_folder(staged, out)?;
    match format {
        Format::Json => crate::output::print_line(&serde_json::to_string_pretty(&result)?)?,
        Format::Text => {
            crate::output::print(&format!(
                "{}\nResults written to {}\n",
                crate::study::report::markdown(&result),
                out.display()
            ))?;
        }
    }
    Ok(())
}

/// Starts writing the results folder `out` whole: its files go to a
/// temporary folder inside it and move into place at the end, so an
/// interrupted or failed run leaves the earlier results whole, never new
/// recordings beside old networks and plots.
pub(super) fn begin_folder(out: &Path, kind: &'static str) -> Result<StagedFolder> {
    StagedFolder::begin(out, Some(kind)).with_context(|| format!("creating {}", out.display()))
}

/// Moves a run's files into `out` and says which files of the earlier run
/// of the same kind it removed (those this run does not write again).
pub(super) fn commit_folder(staged: StagedFolder, out: &Path) -> Result<()> {
    let removed = staged
        .commit()
        .with_context(|| format!("writing the results into {}", out.display()))?;
    if let Some(first) = removed.first() {
        crate::say!(
            "{}: removed {} file(s) of the earlier run that this one does not write ({}{})",
            out.display(),
            removed.len(),
            first.display(),
            if removed.len() > 1 { ", ..." } else { "" }
        );
    }
    Ok(())
}

#[derive(Debug, Args)]
pub struct StudyArgs {
    /// The analytical model: a compiled model's name or a TOML description.
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
    crate::args::check_angle_units(nominal, args.input.angles.into())?;
    let recordings = args
        .input
        .read_all(&args.data, Some(nominal.joint_names()))?;
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
    run_study(&args.run.out, "study", args.run.format, |out, progress| {
        study::run_on_measurements(nominal, &recordings, split, &config, out, progress)
    })
}

/// Shortest trajectory of a study, s.
const MIN_STUDY_SECONDS: f64 = 1.0;
