//! Commands that evaluate a model sample by sample: `tau` (inverse
//! dynamics), `qdd` (forward dynamics) and `pose` (the tip frame).

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use nalgebra::DMatrix;

use crate::args::{AngleArg, check_angle_units, find_model};
use crate::dynamics::Dynamics;
use crate::trajectory::{
    AngleUnit, ReadOptions, TrajectoryError, read_forward_csv, read_positions_csv, read_states_csv,
    write_columns,
};

/// What the sample-by-sample commands take.
#[derive(Debug, Args)]
pub struct PointwiseArgs {
    /// Model name (a models/*.toml file stem; see `sdnn models`) or a
    /// description file ending in .toml.
    #[arg(long)]
    pub model: String,
    /// Input file (`-`: standard input); contract columns the command
    /// does not use (`t`, or a recording's other channels) are allowed.
    #[arg(long)]
    pub input: PathBuf,
    /// File to write; standard output if absent or `-`.
    #[arg(long)]
    pub output: Option<PathBuf>,
    /// Unit of q, qd and qdd in the input (and of qdd in `qdd`'s output).
    #[arg(long, value_enum, default_value_t)]
    pub angles: AngleArg,
    /// Map a file column to a contract column, e.g. `--column pos1=q1`.
    #[arg(long = "column", value_name = "FILE=CONTRACT", value_parser = crate::inputs::parse_mapping)]
    pub columns: Vec<(String, String)>,
    /// File columns to ignore (extra columns are an error otherwise).
    #[arg(long = "ignore-column", value_name = "NAME")]
    pub ignored: Vec<String>,
}

impl PointwiseArgs {
    /// The model and the reader's options for it.
    fn open(&self) -> Result<(&'static dyn Dynamics, ReadOptions)> {
        let model = find_model(&self.model)?;
        let options = ReadOptions {
            units: self.angles.into(),
            dof: Some(model.dof()),
            min_samples: 1,
            renames: self.columns.iter().cloned().collect(),
            ignored: self.ignored.clone(),
            ..ReadOptions::default()
        };
        check_angle_units(model, options.units)?;
        Ok((model, options))
    }

    /// Warns, on standard error, of joints whose positions leave the
    /// description's limits (the gate's reading of an excursion: degrees,
    /// a turn off, another joint's column); the results are still
    /// computed, as they are well defined there.
    fn warn_beyond_limits(&self, model: &dyn Dynamics, q: &DMatrix<f64>, units: AngleUnit) {
        let ranges = crate::limits::ranges(&[q]);
        let excursions = crate::limits::excursions(model, &ranges, units);
        let input = self.input.display();
        for e in &excursions {
            crate::say!("warning: {input}: {}", e.message);
        }
        if units == AngleUnit::Radians
            && let Some(hint) = crate::limits::degrees_as_a_whole(model, &ranges, &excursions)
        {
            crate::say!("warning: {input}: {hint}");
        }
    }

    fn output(&self) -> Option<&std::path::Path> {
        self.output
            .as_deref()
            .filter(|p| *p != std::path::Path::new("-"))
    }

    fn write(&self, prefix: &str, values: &DMatrix<f64>) -> Result<()> {
        let header: Vec<String> = (1..=values.ncols())
            .map(|j| format!("{prefix}{j}"))
            .collect();
        Ok(write_columns(self.output(), &header, values)?)
    }
}

/// A file without the input channel of `command` (`prefix1..`): the
/// other direction of the dynamics, `other`, may be what was meant.
fn name_the_other_command(
    error: TrajectoryError,
    prefix: &str,
    command: &str,
    other: &str,
) -> anyhow::Error {
    match &error {
        TrajectoryError::MissingColumn { column, .. } if column == &format!("{prefix}1") => {
            anyhow::anyhow!(
                "{error}: `sdnn {command}` computes {command} from q, qd and {prefix}; \
                 `sdnn {other}` computes {other} from q, qd and {command}"
            )
        }
        _ => error.into(),
    }
}

fn row(m: &DMatrix<f64>, r: usize) -> Vec<f64> {
    m.row(r).iter().copied().collect()
}

/// `sdnn tau`: q, qd, qdd -> tau1..tauN.
pub fn tau(args: &PointwiseArgs) -> Result<()> {
    let (model, options) = args.open()?;
    let states = read_states_csv(&args.input, &options)
        .map_err(|e| name_the_other_command(e, "qdd", "tau", "qdd"))?;
    args.warn_beyond_limits(model, states.q(), options.units.angles);
    let mut tau = DMatrix::zeros(states.len(), model.dof());
    for r in 0..states.len() {
        let t = model.tau(
            &row(states.q(), r),
            &row(states.qd(), r),
            &row(states.qdd(), r),
        )?;
        tau.set_row(r, &t.transpose());
    }
    args.write("tau", &tau)
}

/// `sdnn qdd`: q, qd, tau -> qdd1..qddN, in the input's angle unit.
pub fn qdd(args: &PointwiseArgs) -> Result<()> {
    let (model, options) = args.open()?;
    let [q, qd, tau] = read_forward_csv(&args.input, &options)
        .map_err(|e| name_the_other_command(e, "tau", "qdd", "tau"))?;
    args.warn_beyond_limits(model, &q, options.units.angles);
    let scale = match options.units.angles {
        AngleUnit::Degrees => 180.0 / std::f64::consts::PI,
        AngleUnit::Radians => 1.0,
    };
    let mut qdd = DMatrix::zeros(q.nrows(), model.dof());
    let mut out = vec![0.0; model.dof()];
    for r in 0..q.nrows() {
        model.forward_dynamics(&row(&q, r), &row(&qd, r), &row(&tau, r), &mut out)?;
        for (j, x) in out.iter().enumerate() {
            qdd[(r, j)] = scale * x;
        }
    }
    args.write("qdd", &qdd)
}

/// `sdnn pose`: q -> the tip frame's origin x, y, z (m) and rotation
/// r11..r33 (row-major; columns are the tip's axes in the base frame).
pub fn pose(args: &PointwiseArgs) -> Result<()> {
    let (model, options) = args.open()?;
    let q = read_positions_csv(&args.input, &options)?;
    args.warn_beyond_limits(model, &q, options.units.angles);
    let mut poses = DMatrix::zeros(q.nrows(), 12);
    for r in 0..q.nrows() {
        let pose = model.tip_pose(&row(&q, r))?;
        let entries = pose.position.iter().chain(pose.rotation.iter().flatten());
        for (k, x) in entries.enumerate() {
            poses[(r, k)] = *x;
        }
    }
    let header: Vec<String> = ["x", "y", "z"]
        .into_iter()
        .map(String::from)
        .chain((1..=3).flat_map(|i| (1..=3).map(move |j| format!("r{i}{j}"))))
        .collect();
    Ok(write_columns(args.output(), &header, &poses)?)
}
