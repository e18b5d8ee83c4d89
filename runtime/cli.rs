//! Command-line parsing and dispatch. Errors are `anyhow` here only; the
//! library modules below return typed errors.

use std::ffi::OsString;
use std::io::Write;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use nalgebra::DMatrix;

pub use crate::args::{AngleArg, Format, find_model, model_path};

use crate::trajectory::{ReadOptions, read_states_csv, write_torques, write_torques_csv};

/// Exact arm dynamics, physics-synthesized data and model diagnosis.
#[derive(Debug, Parser)]
#[command(name = "sdnn", version, about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Evaluate a compiled model's joint torques on states
    /// (columns q1..qN,qd1..qdN,qdd1..qddN; output tau1..tauN).
    Tau {
        /// Model name (a models/*.toml file stem); see `sdnn models`.
        #[arg(long)]
        model: String,
        /// State file (`-`: standard input); a recording's `t` and `tau`
        /// columns are allowed and not used.
        #[arg(long)]
        input: PathBuf,
        /// Torque file to write; standard output if absent or `-`.
        #[arg(long)]
        output: Option<PathBuf>,
        /// Unit of q, qd and qdd in the input.
        #[arg(long, value_enum, default_value_t)]
        angles: AngleArg,
        /// Map a file column to a contract column, e.g. `--column pos1=q1`.
        #[arg(long = "column", value_name = "FILE=CONTRACT", value_parser = crate::inputs::parse_mapping)]
        columns: Vec<(String, String)>,
        /// File columns to ignore (extra columns are an error otherwise).
        #[arg(long = "ignore-column", value_name = "NAME")]
        ignored: Vec<String>,
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
    /// missing effect (friction, armature, offset, payload or link error,
    /// torque scale or delay, base tilt, spring, ripple).
    Diagnose(crate::commands::DiagnoseArgs),
    /// Design the motion to record for identification: Fourier excitation
    /// inside the limits, compared with the default random recording.
    Excite(crate::commands::ExciteArgs),
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
            columns,
            ignored,
        } => {
            let options = ReadOptions {
                units: angles.into(),
                min_samples: 1,
                renames: columns.into_iter().collect(),
                ignored,
                ..ReadOptions::default()
            };
            let output = output.filter(|p| p != std::path::Path::new("-"));
            tau(&model, &input, output.as_deref(), options)
        }
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
        Command::Excite(args) => crate::commands::excite(&args),
        Command::ImportUrdf(args) => crate::imports::import_urdf_command(&args),
        Command::ImportLog(args) => crate::imports::import_log_command(&args),
    }
}

fn tau(
    name: &str,
    input: &std::path::Path,
    output: Option<&std::path::Path>,
    options: ReadOptions,
) -> Result<()> {
    let model = find_model(name)?;
    crate::args::check_angle_units(model, options.units)?;
    let options = ReadOptions {
        dof: Some(model.dof()),
        ..options
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
