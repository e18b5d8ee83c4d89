//! Command-line options for reading and preprocessing measured recordings,
//! shared by every command that reads them.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Args;
use nalgebra::DMatrix;

use crate::args::AngleArg;
use crate::preprocess::{Filter, Pipeline, Preprocess, Preset};
use crate::ranges;
use crate::rosbag::{BagOptions, JointOrder, JointStates, read_joint_states};
pub use crate::shell::shell_word;
use crate::trajectory::{ReadOptions, Trajectory, TrajectoryError, read_csv, uniform};

/// The model's joint names, base first, when the command has a model.
pub type Joints<'a> = Option<&'a [&'static str]>;

/// Options of reading measured CSV files.
#[derive(Debug, Args, Clone)]
pub struct InputArgs {
    /// Unit of q, qd and qdd in the files (Kinova's API logs degrees).
    #[arg(long, value_enum, default_value_t)]
    pub angles: AngleArg,
    /// Resample to this uniform rate (Hz) by linear interpolation [default:
    /// files with jittery timestamps are resampled at their median rate].
    #[arg(long, value_parser = ranges::real(0.0, 1e6, true, "no joint log is sampled faster"))]
    pub resample: Option<f64>,
    /// Map a file column to a contract column, e.g. `--column time=t --column pos1=q1`.
    #[arg(long = "column", value_name = "FILE=CONTRACT", value_parser = parse_mapping)]
    pub columns: Vec<(String, String)>,
    /// File columns to ignore (extra columns are an error otherwise).
    #[arg(long = "ignore-column", value_name = "NAME")]
    pub ignored: Vec<String>,
    /// ROS 2 bags (`.mcap`): the sensor_msgs/JointState topic (needed only
    /// when the bag has several).
    #[arg(long)]
    pub topic: Option<String>,
    /// ROS 2 bags: the joints to read, in the model's order, comma
    /// separated (to choose or rename) [default: the model's joints by
    /// name when the bag names them all, else the first message's joints
    /// in its order].
    #[arg(long, value_delimiter = ',')]
    pub joints: Option<Vec<String>>,
    /// Divide joint J's logged torque by S (a torque sensor's scale error,
    /// as `sdnn diagnose` reports it), e.g. `--torque-scale 2=1.05`.
    #[arg(long = "torque-scale", value_name = "J=S", value_parser = crate::corrections::parse_scale)]
    pub torque_scales: Vec<(usize, f64)>,
    /// The torque is logged this many seconds after its state (as `sdnn
    /// diagnose` reports it): each torque is moved back to its state
    /// (linear interpolation); the samples left without one are dropped.
    #[arg(long = "torque-delay", value_name = "SECONDS", allow_hyphen_values = true,
          value_parser = ranges::real(-crate::corrections::MAX_DELAY, crate::corrections::MAX_DELAY, false,
          "a torque a second late is another recording"))]
    pub torque_delay: Option<f64>,
}

pub fn parse_mapping(text: &str) -> Result<(String, String), String> {
    match text.split_once('=') {
        Some((from, to)) if !from.is_empty() && !to.is_empty() => {
            if !crate::trajectory::is_contract_column(to) {
                return Err(format!(
                    "`{to}` is not a column of the contract (t, q1..qN, qd1..qdN, \
                     qdd1..qddN, tau1..tauN)"
                ));
            }
            Ok((from.to_string(), to.to_string()))
        }
        _ => Err(format!(
            "expected FILE_COLUMN=CONTRACT_COLUMN, found `{text}`"
        )),
    }
}

impl InputArgs {
    /// The torque corrections given on the command line.
    pub fn corrections(&self) -> crate::corrections::Corrections {
        crate::corrections::Corrections {
            scales: self.torque_scales.clone(),
            delay: self.torque_delay.unwrap_or(0.0),
        }
    }

    /// The options that read the files again as these did (angles are
    /// printed with the preprocessing), with `corrections` for the torque.
    pub fn command_line(&self, corrections: &crate::corrections::Corrections) -> String {
        let mut flags = String::new();
        if let Some(hz) = self.resample {
            flags.push_str(&format!(" --resample {hz}"));
        }
        for (from, to) in &self.columns {
            flags.push_str(&format!(
                " --column {}",
                shell_word(&format!("{from}={to}"))
            ));
        }
        for name in &self.ignored {
            flags.push_str(&format!(" --ignore-column {}", shell_word(name)));
        }
        if let Some(topic) = &self.topic {
            flags.push_str(&format!(" --topic {}", shell_word(topic)));
        }
        if let Some(joints) = &self.joints {
            flags.push_str(&format!(" --joints {}", shell_word(&joints.join(","))));
        }
        flags + &corrections.flags()
    }

    pub fn options(&self, dof: Option<usize>, min_samples: usize) -> ReadOptions {
        ReadOptions {
            units: self.angles.into(),
            dof,
            resample_hz: self.resample,
            min_samples,
            renames: self.columns.iter().cloned().collect(),
            ignored: self.ignored.clone(),
        }
    }

    /// Reads raw recordings (`joints`: the model's joint names, if known):
    /// CSV files, or ROS 2 bags (`.mcap`) of sensor_msgs/JointState, read
    /// by the model's joint names when the bag carries them.
    /// One recording given twice is refused (see [`reject_repeated`]).
    /// CSV files are first parsed on every core, in the files' order
    /// (parsing says nothing on standard error); what is said about each
    /// file, its checks and any second reading (a resampled one) follow
    /// file by file, as on one thread.
    pub fn read_all(&self, paths: &[PathBuf], joints: Joints) -> Result<Vec<Trajectory>> {
        let parsed = crate::parallel::map_in_order(paths, |path| {
            is_csv_file(path).then(|| self.read_at(path, joints, self.resample))
        });
        let recordings = paths
            .iter()
            .zip(parsed)
            .map(|(path, parsed)| self.read_parsed(path, joints, parsed))
            .collect::<Result<Vec<_>>>()?;
        reject_repeated(paths, &recordings)?;
        Ok(recordings)
    }

    /// One recording (see [`InputArgs::read_all`]), its values checked
    /// against [`PLAUSIBLE`].
    pub fn read(&self, path: &Path, joints: Joints) -> Result<Trajectory> {
        self.read_parsed(path, joints, None)
    }

    /// [`InputArgs::read`], given what the file's first reading at the
    /// `--resample` rate gave, if it was read already.
    fn read_parsed(
        &self,
        path: &Path,
        joints: Joints,
        parsed: Option<Result<Trajectory>>,
    ) -> Result<Trajectory> {
        let traj = self.read_unchecked(path, joints, parsed)?;
        check_plausible(path, &traj)?;
        warn_slow_sampling(path, traj.t());
        if self.torque_scales.is_empty() && self.torque_delay.is_none() {
            return Ok(traj);
        }
        let delay = self.torque_delay.unwrap_or(0.0);
        crate::corrections::correct(&traj, &self.torque_scales, delay)
            .with_context(|| path.display().to_string())
    }

    /// Reads at the given `--resample` rate; without one, a jittery file
    /// is resampled at its median rate (said on standard error), since a
    /// real log's timestamps rarely tick evenly.
    fn read_unchecked(
        &self,
        path: &Path,
        joints: Joints,
        parsed: Option<Result<Trajectory>>,
    ) -> Result<Trajectory> {
        let first = parsed.unwrap_or_else(|| self.read_at(path, joints, self.resample));
        match first {
            Err(e) if self.resample.is_none() => match e.downcast_ref::<TrajectoryError>() {
                Some(TrajectoryError::NonUniformSampling {
                    min_step,
                    max_step,
                    median_step,
                    ..
                }) => {
                    if *max_step > (GAP_STEPS * median_step).max(MIN_GAP_SECONDS) {
                        bail!(
                            "{}: a gap of {max_step:.3} s between two samples (the median step is \
                             {:.3} ms): resampling would fill it with invented samples; split the \
                             recording at the gap, or pass --resample HZ to interpolate across it",
                            path.display(),
                            1e3 * median_step
                        );
                    }
                    let hz = (1.0 / median_step).round().max(1.0);
                    crate::say!(
                        "{}: time steps range from {:.3} to {:.3} ms: resampled to {hz} Hz, the \
                         median rate, by linear interpolation (--resample HZ chooses another)",
                        path.display(),
                        1e3 * min_step,
                        1e3 * max_step
                    );
                    self.read_at(path, joints, Some(hz))
                }
                _ => Err(e),
            },
            other => other,
        }
    }

    fn read_at(&self, path: &Path, joints: Joints, resample: Option<f64>) -> Result<Trajectory> {
        let options = ReadOptions {
            resample_hz: resample,
            ..self.options(joints.map(<[_]>::len), 2)
        };
        if is_bag(path) {
            let bag = BagOptions {
                topic: self.topic.clone(),
                joints: self.joints.clone(),
                model: joints.map(|names| names.iter().map(|n| n.to_string()).collect()),
            };
            let states = read_joint_states(path, &bag)?;
            note_bag_selection(path, &states, joints);
            return joint_states_trajectory(path, states, &options);
        }
        Ok(read_csv(path, &options)?)
    }
}

/// A ROS 2 bag, read by its joint names.
fn is_bag(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("mcap"))
}

/// A CSV file that reading says nothing about on standard error, and that
/// may be read beside others: not a bag, not standard input (`-`, which
/// only one reader may take).
fn is_csv_file(path: &Path) -> bool {
    !is_bag(path) && path != Path::new("-")
}

/// Refuses two files that hold the same samples (one recording given
/// twice, under two names or one): it would count twice in a fit, and in
/// a held-out split it would be tested on itself.
pub fn reject_repeated(paths: &[PathBuf], recordings: &[Trajectory]) -> Result<()> {
    for (b, second) in recordings.iter().enumerate() {
        let same = |first: &Trajectory| first.t() == second.t() && first.q() == second.q();
        if let Some(a) = recordings[..b].iter().position(same) {
            bail!(
                "{} and {} hold the same samples: pass each recording once",
                paths[a].display(),
                paths[b].display()
            );
        }
    }
    Ok(())
}

/// Preprocessing options: a preset, and settings in physical units.
#[derive(Debug, Args, Clone)]
pub struct FilterArgs {
    /// `auto`: zero-phase low-pass of q, qd and torque at a cut-off chosen
    /// from the data's motion bandwidth, then decimation to 10x the cut-off
    /// (the report prints both); `thesis`: the thesis's 100 Hz pipeline (keep
    /// every 10th sample, 0.4 s moving average, torque unfiltered).
    #[arg(long, value_enum, default_value_t)]
    pub preset: Preset,
    /// auto: the low-pass cut-off in Hz instead of the chosen one.
    #[arg(long, value_name = "HZ", value_parser = ranges::real(0.0, 1e5, true, "no arm moves that fast"))]
    pub cutoff: Option<f64>,
    /// auto: the decimated sample rate in Hz instead of 10x the cut-off.
    #[arg(long, value_name = "HZ", value_parser = ranges::real(0.0, 1e6, true, "no joint log is sampled faster"))]
    pub rate: Option<f64>,
    /// thesis: keep every n-th sample [default: 10].
    #[arg(long, value_parser = ranges::integer(1, 10_000, "resample with --rate instead"))]
    pub downsample: Option<usize>,
    /// thesis: velocity filter, `sma` (centred moving average), `sg`
    /// (Savitzky-Golay, cubic) or `none` [default: sma].
    #[arg(long)]
    pub filter: Option<String>,
    /// thesis: filter window in seconds at the downsampled rate [default: 0.4].
    #[arg(long, value_name = "SECONDS", value_parser = ranges::real(0.0, 3600.0, true, "no filter window is that long"))]
    pub window: Option<f64>,
    /// thesis: also smooth the torque with the acceleration's filter (auto
    /// always filters the torque like the states).
    #[arg(long)]
    pub filter_torque: bool,
}

impl FilterArgs {
    /// The pipeline for these raw recordings.
    pub fn resolve(&self, recordings: &[Trajectory]) -> Result<Pipeline> {
        match self.preset {
            Preset::Auto => {
                let thesis_only = [
                    ("--downsample", self.downsample.is_some()),
                    ("--filter", self.filter.is_some()),
                    ("--window", self.window.is_some()),
                    ("--filter-torque", self.filter_torque),
                ];
                if let Some((flag, _)) = thesis_only.iter().find(|(_, set)| *set) {
                    bail!(
                        "{flag} sets the thesis pipeline: pass `--preset thesis` with it (the auto preset \
                         takes --cutoff and --rate in Hz)"
                    );
                }
                Ok(Pipeline::auto(recordings, self.cutoff, self.rate)?)
            }
            Preset::Thesis => {
                if self.cutoff.is_some() || self.rate.is_some() {
                    bail!("--cutoff and --rate belong to `--preset auto`");
                }
                let rate = recordings
                    .first()
                    .map_or(1000.0, crate::preprocess::auto::sample_rate);
                Ok(Pipeline::fixed(Preset::Thesis, self.thesis(rate)?))
            }
        }
    }

    /// These options as command-line flags (empty for the defaults), for
    /// a command the report suggests.
    pub fn command_line(&self, angles: AngleArg) -> String {
        let mut flags = String::new();
        if angles == AngleArg::Deg {
            flags.push_str(" --angles deg");
        }
        if self.preset == Preset::Thesis {
            flags.push_str(" --preset thesis");
        }
        let mut add = |name: &str, value: Option<String>| {
            if let Some(v) = value {
                flags.push_str(&format!(" --{name} {v}"));
            }
        };
        add("cutoff", self.cutoff.map(|v| v.to_string()));
        add("rate", self.rate.map(|v| v.to_string()));
        add("downsample", self.downsample.map(|v| v.to_string()));
        add("filter", self.filter.clone());
        add("window", self.window.map(|v| v.to_string()));
        if self.filter_torque {
            flags.push_str(" --filter-torque");
        }
        flags
    }

    /// The thesis settings with these overrides, for recordings at `rate` Hz.
    fn thesis(&self, rate: f64) -> Result<Preprocess> {
        let downsample = self.downsample.unwrap_or(10);
        if downsample == 0 {
            bail!("--downsample must be at least 1");
        }
        let window_s = self.window.unwrap_or(0.4);
        if !(window_s.is_finite() && window_s > 0.0) {
            bail!("--window must be a positive number of seconds, got {window_s}");
        }
        let samples = ((window_s * rate / downsample as f64).round() as usize).max(1);
        let filter = match self.filter.as_deref().unwrap_or("sma") {
            "sma" => Filter::Sma {
                window: samples,
                centered: true,
            },
            "sg" => Filter::SavitzkyGolay {
                window: (samples | 1).max(5),
                order: 3,
            },
            "none" => Filter::None,
            other => bail!("--filter must be `sma`, `sg` or `none`, not `{other}`"),
        };
        Ok(Preprocess {
            downsample,
            filter,
            filter_torque: self.filter_torque,
        })
    }
}

/// Reads measured files with the model's joint count and preprocesses them
/// with one pipeline resolved on all of them.
pub fn load(
    paths: &[PathBuf],
    joints: Joints,
    input: &InputArgs,
    filter: &FilterArgs,
) -> Result<(Vec<Trajectory>, Pipeline)> {
    let raw = input.read_all(paths, joints)?;
    let pipeline = filter.resolve(&raw)?;
    let processed = raw
        .iter()
        .zip(paths)
        .map(|(traj, path)| {
            pipeline
                .apply(traj)
                .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
        })
        .collect::<Result<Vec<_>>>()?;
    Ok((processed, pipeline))
}

/// Largest magnitudes accepted from a recording, far beyond any arm
/// (angles of 160 turns, 1000 rad/s, a million N m): a value past them is
/// a logging fault, and squared in the dynamics it would overflow.
pub const PLAUSIBLE: [(&str, f64); 3] = [
    ("q", crate::trajectory::PLAUSIBLE_ANGLE),
    ("qd", crate::trajectory::PLAUSIBLE_ANGLE),
    ("tau", crate::trajectory::PLAUSIBLE_TORQUE),
];

/// A step longer than this many median steps, and than
/// [`MIN_GAP_SECONDS`], is a gap in the log, not jitter: the automatic
/// resampling refuses to bridge it (jittery logs such as the Panda's range
/// up to 9 median steps).
const GAP_STEPS: f64 = 20.0;
const MIN_GAP_SECONDS: f64 = 0.1;

/// Joint logs tick at tens of Hz or faster; steps of 0.2 s and more most
/// often mean a time column in milliseconds, read as seconds.
fn warn_slow_sampling(path: &Path, t: &[f64]) {
    let span = t.last().zip(t.first()).map_or(0.0, |(b, a)| b - a);
    let step = span / (t.len().max(2) - 1) as f64;
    if step >= 0.2 {
        crate::say!(
            "{}: samples are {step} s apart on average ({:.3} Hz); if the time column is in \
             milliseconds, divide it by 1000 (the contract is seconds)",
            path.display(),
            1.0 / step
        );
    }
}

fn check_plausible(path: &Path, traj: &Trajectory) -> Result<()> {
    for ((name, limit), m) in PLAUSIBLE.iter().zip([traj.q(), traj.qd(), traj.tau()]) {
        if let Some(at) = m.iter().position(|v| v.abs() > *limit) {
            let (row, joint) = (at % m.nrows(), at / m.nrows() + 1);
            bail!(
                "{}: sample {} (t = {} s), column {name}{joint} = {:e}: beyond any arm (|{name}| <= {limit:e})",
                path.display(),
                row + 1,
                traj.t()[row],
                m[at]
            );
        }
    }
    Ok(())
}

/// Says on standard error what was read from a bag when it is not plain:
/// another publisher's messages skipped, or joints paired with the
/// model's by position because no name matched.
fn note_bag_selection(path: &Path, states: &JointStates, model: Joints) {
    if states.ignored_messages > 0 {
        crate::say!(
            "{}: {} message(s) carrying none of the joints read ({}) were skipped (another \
             publisher on the topic)",
            path.display(),
            states.ignored_messages,
            states.joints.join(", ")
        );
    }
    if let Some(names) = model
        && states.order == JointOrder::FirstMessage
        && states.joints.len() == names.len()
    {
        crate::say!(
            "{}: no joint name of the bag ({}) is a model joint's ({}): read in the bag's order; \
             --joints NAME,... chooses the bag's joints in the model's order",
            path.display(),
            states.joints.join(", "),
            names.join(", ")
        );
    }
}

/// A bag's joint states in the trajectory contract (ROS units are SI).
fn joint_states_trajectory(
    path: &Path,
    states: JointStates,
    options: &ReadOptions,
) -> Result<Trajectory> {
    let n = states.joints.len();
    if let Some(dof) = options.dof.filter(|&d| d != n) {
        bail!(
            "{}: the bag's JointState has {n} joints ({}), the model {dof}: pick the model's \
             joints with --joints NAME,NAME,... in the model's order",
            path.display(),
            states.joints.join(", ")
        );
    }
    let rows = states.t.len();
    let matrix = |m: &[Vec<f64>]| DMatrix::from_fn(rows, n, |r, c| m[r][c]);
    let traj = Trajectory::new(
        states.t,
        matrix(&states.position),
        matrix(&states.velocity),
        None,
        matrix(&states.effort),
    )?;
    Ok(uniform(path, traj, options)?)
}

/// One file with its own resolved pipeline (commands that process files
/// one at a time).
pub fn load_one(
    path: &Path,
    joints: Joints,
    input: &InputArgs,
    filter: &FilterArgs,
) -> Result<(Trajectory, Pipeline)> {
    let (mut trajectories, pipeline) = load(&[path.to_path_buf()], joints, input, filter)?;
    Ok((trajectories.remove(0), pipeline))
}

/// What `--preprocessed` files already had done to them when they were
/// written, so the flags that would do it again are refused beside it.
pub const PREPROCESSED_CONFLICTS: [&str; 10] = [
    "preset",
    "cutoff",
    "rate",
    "downsample",
    "filter",
    "window",
    "filter_torque",
    "resample",
    "torque_scales",
    "torque_delay",
];

/// A file that already carries filtered qd and qdd (`--preprocessed`).
pub fn load_preprocessed(path: &Path, joints: Joints, input: &InputArgs) -> Result<Trajectory> {
    let traj = read_csv(path, &input.options(joints.map(<[_]>::len), 2))?;
    if traj.qdd().is_none() {
        bail!(
            "{}: --preprocessed needs qdd1..qddN columns",
            path.display()
        );
    }
    Ok(traj)
}
