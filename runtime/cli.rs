//! Command-line parsing and dispatch. Errors are `anyhow` here only; the
//! library modules below return typed errors.

use std::ffi::OsString;

use anyhow::{Result, bail};
use clap::{Parser, Subcommand};

pub use crate::args::{AngleArg, Format, find_model, model_path};

/// Exact arm dynamics, physics-synthesized data and model diagnosis.
#[derive(Debug, Parser)]
#[command(name = "sdnn", version, about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Joint torques of a model on states (inverse dynamics): columns
    /// q1..qN,qd1..qdN,qdd1..qddN; output tau1..tauN.
    Tau(crate::commands::PointwiseArgs),
    /// Joint accelerations of a model under torques (forward dynamics):
    /// columns q1..qN,qd1..qdN,tau1..tauN; output qdd1..qddN.
    Qdd(crate::commands::PointwiseArgs),
    /// The tip frame of a model at joint positions (forward kinematics):
    /// columns q1..qN; output x,y,z (m) and the rotation r11..r33.
    Pose(crate::commands::PointwiseArgs),
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
            crate::output::print(&e.to_string())?;
            return Ok(());
        }
    };
    match cli.command {
        Command::Tau(args) => crate::commands::tau(&args),
        Command::Qdd(args) => crate::commands::qdd(&args),
        Command::Pose(args) => crate::commands::pose(&args),
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

fn models(format: Format) -> Result<()> {
    let all = crate::dynamics::compiled();
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
            crate::output::print_line(&serde_json::to_string_pretty(&list)?)?;
        }
        Format::Text => {
            let width = all.iter().map(|m| m.name().len()).max().unwrap_or(0);
            let lines: Vec<String> = all
                .iter()
                .map(|m| {
                    format!(
                        "{:<width$} {} DOF  joints: {}\n",
                        m.name(),
                        m.dof(),
                        m.joint_names().join(", ")
                    )
                })
                .collect();
            crate::output::print(&lines.concat())?;
        }
    }
    Ok(())
}
