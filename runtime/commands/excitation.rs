//! `sdnn excite`: designs the motion to record (Fourier excitation inside
//! the limits), compared with the default random recording of the same
//! length; writes the trajectory, a report and a plot.

use super::*;
use crate::excite::fourier::Bounds;
use crate::excite::{self, Config, report};
use crate::sim::reference::{Reference, WaypointConfig, WaypointTrajectory};

#[derive(Debug, Args)]
pub struct ExciteArgs {
    /// The model to design for: a compiled model's name or a TOML description.
    #[arg(long)]
    pub model: String,
    /// Seconds of the recording (above 1, at most 3600).
    #[arg(long, default_value_t = 20.0, value_parser = ranges::real(1.0, 3600.0, true, "record several designed trajectories"))]
    pub duration: f64,
    /// Harmonics per joint (2-20; with a pause 3 or more).
    #[arg(long, default_value_t = 10, value_parser = ranges::integer(2, 20, "higher harmonics pass the limits at lower amplitudes"))]
    pub harmonics: usize,
    /// Base frequency in Hz, rounded so whole periods fill the moving time
    /// [default: one period].
    #[arg(long = "base-frequency", value_parser = ranges::real(0.0, 10.0, true, "an arm's excitation stays below a few Hz"))]
    pub base_frequency: Option<f64>,
    /// Rest at each end, s [default: 5% of the duration, at most 2 s].
    #[arg(long, value_parser = ranges::real(0.0, 3600.0, false, "rest in a separate recording"))]
    pub rest: Option<f64>,
    /// Each joint's pause while the others move, s [default: 20% of the
    /// duration, at most 8 s; 0 for none].
    #[arg(long, value_parser = ranges::real(0.0, 3600.0, false, "pause in a separate recording"))]
    pub pause: Option<f64>,
    /// Sample rate of the written trajectory, Hz.
    #[arg(long, default_value_t = 1000.0, value_parser = ranges::real(0.0, 100_000.0, true, "robots take positions at 1 kHz or less"))]
    pub rate: f64,
    /// A diagnosis (`sdnn diagnose --format json`) whose ambiguous or poorly
    /// determined effects the motion should determine better.
    #[arg(long)]
    pub from: Option<PathBuf>,
    #[arg(long, default_value_t = 1, value_parser = ranges::seed)]
    pub seed: u64,
    /// Torque noise of one sample (N m; N on a prismatic joint) for the
    /// predicted standard deviations [default: the virtual robot's].
    #[arg(long = "torque-noise", default_value_t = 0.05, value_parser = ranges::real(0.0, 1e3, true, "use a smaller unit"))]
    pub torque_noise: f64,
    /// Rounds of the search: each improves every joint's coefficients in
    /// turn for 30 generations of 8 motions, the last quarter of them on the
    /// condition number itself [default: 24 / joints, at least 2].
    #[arg(long, value_parser = ranges::integer(1, 10_000, "run the search again from another seed"))]
    pub rounds: Option<usize>,
    /// The trajectory to write (t, q, qd, qdd); the report (.md) and the
    /// plot (.svg) are written beside it with the same stem.
    #[arg(long)]
    pub out: PathBuf,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

/// Default recordings compared (the first ones `sdnn simulate` records).
const DEFAULTS: usize = 5;

/// Most samples one trajectory file holds (1 h at 1 kHz is 3.6 million).
const MOST_SAMPLES: f64 = 1e7;

pub fn excite(args: &ExciteArgs) -> Result<()> {
    if crate::output::is_stdout(&args.out) {
        bail!("--out needs a file name: the report and the plot are written beside it");
    }
    if args.duration * args.rate > MOST_SAMPLES {
        bail!(
            "--duration {} s at --rate {} Hz is more than {MOST_SAMPLES} samples: lower the rate",
            args.duration,
            args.rate
        );
    }
    let model = find_model(&args.model)?;
    let weighted = match &args.from {
        Some(path) => weighted(model, path)?,
        None => Vec::new(),
    };
    let (bounds, waypoints) = bounds(model, args.duration)?;
    let levers = crate::dynamics::joint_levers(model);
    let references = (0..DEFAULTS)
        .map(|k| WaypointTrajectory::new(&waypoints, study::trajectory_seed(args.seed, k)))
        .collect::<Result<Vec<_>, _>>()?;
    let samplers: Vec<_> = references
        .iter()
        .map(|r| {
            move |t: f64| {
                let (q, qd, qdd) = r.sample(t);
                (
                    q.as_slice().to_vec(),
                    qd.as_slice().to_vec(),
                    qdd.as_slice().to_vec(),
                )
            }
        })
        .collect();
    let defaults: Vec<excite::Motion<'_>> =
        samplers.iter().map(|f| f as excite::Motion<'_>).collect();
    let config = Config {
        harmonics: args.harmonics,
        base_hz: args.base_frequency,
        rate: args.rate,
        noise: args.torque_noise,
        seed: args.seed,
        ..Config::new(args.duration, model.dof())
    };
    // Rests only where the diagnosis asks what they tell (or, without one,
    // for every parameter alike).
    let config = if weighted.is_empty() || excite::weights::needs_rests(&weighted) {
        config
    } else {
        config.without_rests()
    };
    let (rounds, exact_rounds) = args.rounds.map_or(
        (config.budget.rounds, config.budget.exact_rounds),
        excite::split_rounds,
    );
    let config = Config {
        budget: excite::search::Budget {
            rounds,
            exact_rounds,
            ..config.budget
        },
        rest: args.rest.unwrap_or(config.rest),
        pause: args.pause.unwrap_or(config.pause),
        ..config
    };
    let design = excite::design(model, &bounds, &levers, &config, &defaults, &weighted)?;
    crate::trajectory::write_plan_csv(&args.out, &design.trajectory)?;
    let label = format!("default recording (`sdnn simulate --seed {}`)", args.seed);
    let text = report::markdown(&design, model.name(), &label);
    let (md, svg) = (
        args.out.with_extension("md"),
        args.out.with_extension("svg"),
    );
    crate::output::write(&md, text.as_bytes())
        .with_context(|| format!("writing {}", md.display()))?;
    report::plot(&design, &svg, model.name(), &levers)?;
    let printed = match args.format {
        Format::Json => {
            serde_json::to_string_pretty(&report::json(&design, model.name(), &args.out))?
        }
        Format::Text => format!(
            "{text}\nWritten: {}, {}, {}",
            args.out.display(),
            md.display(),
            svg.display()
        ),
    };
    crate::output::print_line(&printed)?;
    Ok(())
}

/// The limits of the default recording (the description's positions less
/// the waypoints' margin, its velocities capped as the recording caps them,
/// the recording's acceleration cap) and the description's effort limits;
/// with the waypoint configuration of that recording.
fn bounds(model: &dyn Dynamics, duration: f64) -> Result<(Bounds, WaypointConfig)> {
    let config = StudyConfig {
        duration,
        ..StudyConfig::default()
    };
    let waypoints = WaypointConfig {
        duration,
        limits: study::limits(model, &config)?,
        ..WaypointConfig::default()
    };
    let limits = &waypoints.limits;
    limits.validate(waypoints.margin)?;
    let position = (0..model.dof())
        .map(|j| {
            let (lo, hi) = limits.position[j];
            let m = limits.margin(j, waypoints.margin);
            (lo + m, hi - m)
        })
        .collect();
    let description = crate::dynamics::parsed_description(model)?;
    let bodies: Vec<&codegen::Body> = description.chain().free_bodies().collect();
    let effort = bodies
        .iter()
        .map(|b| b.limits.and_then(|l| l.effort).filter(|&e| e > 0.0))
        .collect();
    let velocity = bodies
        .iter()
        .zip(&limits.velocity)
        .map(|(b, &cap)| {
            b.limits
                .and_then(|l| l.velocity)
                .filter(|&v| v > 0.0)
                .unwrap_or(cap)
        })
        .collect();
    let bounds = Bounds {
        position,
        velocity,
        acceleration: limits.acceleration.clone(),
        effort,
    };
    Ok((bounds, waypoints))
}

/// The parameters a diagnosis JSON asks to weight.
fn weighted(model: &dyn Dynamics, path: &Path) -> Result<Vec<String>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let description = crate::dynamics::parsed_description(model)?;
    let links: Vec<String> = description
        .chain()
        .free_bodies()
        .map(|b| b.link.clone())
        .collect();
    let names = excite::weights::from_diagnosis(&text, &path.display().to_string(), &links)?;
    if names.is_empty() {
        crate::say!(
            "{}: the diagnosis found nothing ambiguous or poorly determined; designing for all parameters alike",
            path.display()
        );
    }
    Ok(names)
}
