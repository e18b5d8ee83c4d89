//! Command-line parsing and dispatch. Errors are `anyhow` here only; the
//! library modules below return typed errors.

use std::ffi::OsString;
use std::io::Write;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand, ValueEnum};
use nalgebra::DMatrix;

use crate::dynamics::{Dynamics, model, model_names};
use crate::trajectory::{
    AngleUnit, ReadOptions, Units, read_states_csv, write_torques, write_torques_csv,
};

/// Exact arm dynamics, physics-synthesized data and model diagnosis.
#[derive(Debug, Parser)]
#[command(name = "sdnn", version, about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

/// Output format of results printed to standard output.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Default)]
pub enum Format {
    #[default]
    Text,
    Json,
}

/// Angle unit of input files.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Default)]
pub enum AngleArg {
    #[default]
    Rad,
    Deg,
}

impl From<AngleArg> for Units {
    fn from(a: AngleArg) -> Units {
        Units {
            angles: match a {
                AngleArg::Rad => AngleUnit::Radians,
                AngleArg::Deg => AngleUnit::Degrees,
            },
        }
    }
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Evaluate a compiled model's joint torques on states
    /// (columns q1..qN,qd1..qdN,qdd1..qddN; output tau1..tauN).
    Tau {
        /// Model name (a models/*.toml file stem); see `sdnn models`.
        #[arg(long)]
        model: String,
        /// State file.
        #[arg(long)]
        input: PathBuf,
        /// Torque file to write; standard output if absent.
        #[arg(long)]
        output: Option<PathBuf>,
        /// Unit of q, qd and qdd in the input.
        #[arg(long, value_enum, default_value_t)]
        angles: AngleArg,
    },
    /// List the compiled models.
    Models {
        #[arg(long, value_enum, default_value_t)]
        format: Format,
    },
    /// Run the whole SDNN study on the virtual robot: record, preprocess,
    /// synthesize, train over seeds, compare; writes a results folder.
    Reproduce(crate::commands::ReproduceArgs),
    /// Run the SDNN study on measured recordings: train on the start of each,
    /// test on the rest (e.g. the Panda log: `--test-from 15`).
    Study(crate::commands::StudyArgs),
    /// Record trajectories on the virtual robot (CSV per trajectory).
    Simulate(crate::commands::SimulateArgs),
    /// Preprocess measured CSV files (downsample, filter, differentiate).
    Preprocess(crate::commands::PreprocessArgs),
    /// Replace measured torques by a compiled model's (analytical data).
    Synth(crate::commands::SynthArgs),
    /// Train an MLP on trajectory CSV files.
    Train(crate::commands::TrainArgs),
    /// Evaluate a compiled model or a trained network on measured CSV files.
    Evaluate(crate::commands::EvaluateArgs),
    /// Predict torques of a trained network on a state file.
    Predict(crate::commands::PredictArgs),
    /// Find where a compiled model and measured data disagree and name the
    /// missing effect (joint friction, offset, armature, payload).
    Diagnose(crate::commands::DiagnoseArgs),
    /// Convert a URDF into a TOML robot description (chain cut, locks, payloads).
    ImportUrdf(crate::imports::ImportUrdfArgs),
    /// Convert a log with one text file per channel (line-major, e.g. the
    /// Franka Panda identification log) into the trajectory CSV contract.
    ImportLog(crate::imports::ImportLogArgs),
}

/// Parses arguments and runs the command.
pub fn run(args: impl IntoIterator<Item = OsString>) -> Result<()> {
    let cli = match Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(e) if e.use_stderr() => bail!("{}", e.to_string().trim_end()),
        Err(e) => {
            // --help and --version
            print!("{e}");
            return Ok(());
        }
    };
    match cli.command {
        Command::Tau {
            model,
            input,
            output,
            angles,
        } => tau(&model, &input, output.as_deref(), angles),
        Command::Models { format } => models(format),
        Command::Reproduce(args) => crate::commands::reproduce(&args),
        Command::Study(args) => crate::commands::study_command(&args),
        Command::Simulate(args) => crate::commands::simulate(&args),
        Command::Preprocess(args) => crate::commands::preprocess(&args),
        Command::Synth(args) => crate::commands::synth(&args),
        Command::Train(args) => crate::commands::train(&args),
        Command::Evaluate(args) => crate::commands::evaluate(&args),
        Command::Predict(args) => crate::commands::predict(&args),
        Command::Diagnose(args) => crate::commands::diagnose(&args),
        Command::ImportUrdf(args) => crate::imports::import_urdf_command(&args),
        Command::ImportLog(args) => crate::imports::import_log_command(&args),
    }
}

/// The compiled model with this name, or an error listing the names.
pub fn find_model(name: &str) -> Result<&'static dyn Dynamics> {
    if let Some(path) = model_path(name) {
        return Ok(crate::described::Described::load(&path)?);
    }
    model(name).with_context(|| {
        format!(
            "no compiled model named `{name}`; compiled models: {} (add models/{name}.toml and rebuild, or pass a description file path ending in .toml)",
            model_names().join(", ")
        )
    })
}

/// The description file a `--model` argument names, when it is a path
/// (ends in `.toml`) rather than a compiled model's name.
pub fn model_path(name: &str) -> Option<std::path::PathBuf> {
    name.ends_with(".toml")
        .then(|| std::path::PathBuf::from(name))
}

fn tau(
    name: &str,
    input: &std::path::Path,
    output: Option<&std::path::Path>,
    angles: AngleArg,
) -> Result<()> {
    let model = find_model(name)?;
    let options = ReadOptions {
        units: angles.into(),
        dof: Some(model.dof()),
        min_samples: 1,
        ..ReadOptions::default()
    };
    let states = read_states_csv(input, &options)?;
    let mut tau = DMatrix::zeros(states.len(), model.dof());
    for r in 0..states.len() {
        let row = |m: &DMatrix<f64>| m.row(r).iter().copied().collect::<Vec<f64>>();
        let t = model.tau(&row(states.q()), &row(states.qd()), &row(states.qdd()))?;
        tau.set_row(r, &t.transpose());
    }
    match output {
        Some(path) => write_torques_csv(path, &tau)?,
        None => {
            let mut out = std::io::stdout().lock();
            write_torques(&mut out, &tau).context("writing to standard output")?;
            out.flush().context("writing to standard output")?;
        }
    }
    Ok(())
}

fn models(format: Format) -> Result<()> {
    let all = crate::models::MODELS;
    match format {
        Format::Json => {
            let list: Vec<serde_json::Value> = all
                .iter()
                .map(|m| {
                    serde_json::json!({
                        "name": m.name(),
                        "dof": m.dof(),
                        "joints": m.joint_names(),
                        "parameters": m.parameters().len(),
                    })
                })
                .collect();
            println!("{}", serde_json::to_string_pretty(&list)?);
        }
        Format::Text => {
            let width = all.iter().map(|m| m.name().len()).max().unwrap_or(0);
            for m in all {
                println!(
                    "{:<width$} {} DOF  joints: {}",
                    m.name(),
                    m.dof(),
                    m.joint_names().join(", ")
                );
            }
        }
    }
    Ok(())
}
