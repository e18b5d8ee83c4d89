//! `sdnn evaluate`: the test error of a model or a network on recordings,
//! after the sanity gate's checks on the recordings as logged.

use super::*;
use crate::diagnose::{Gated, checks_as_logged, refuse};
use crate::trajectory::Trajectory;

#[derive(Debug, Args)]
pub struct EvaluateArgs {
    /// The model: a compiled model's name or a TOML description (the
    /// analytical model, or the nominal model with --nn).
    #[arg(long, default_value = DEFAULT_NOMINAL)]
    pub model: String,
    /// Measured CSV files.
    #[arg(long, required = true, num_args = 1..)]
    pub data: Vec<PathBuf>,
    /// Evaluate this trained network instead of the analytical model.
    #[arg(long)]
    pub nn: Option<PathBuf>,
    /// The files already carry filtered qd and qdd (written by `sdnn
    /// preprocess` or `sdnn synth`): compared as they are, not filtered
    /// again (the filter, resampling and torque corrections were applied
    /// when they were written).
    #[arg(long, conflicts_with_all = crate::inputs::PREPROCESSED_CONFLICTS)]
    pub preprocessed: bool,
    #[command(flatten)]
    pub input: InputArgs,
    #[command(flatten)]
    pub filter: FilterArgs,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
    /// Evaluate even when the recordings fail the sanity gate's checks on
    /// positions and velocities (beyond the limits, degrees, time in ms);
    /// the findings are printed as warnings.
    #[arg(long)]
    pub no_sanity_gate: bool,
}

/// Fewer compared samples than this are warned about (a tenth of a
/// second at 1 kHz).
const FEWEST_SAMPLES: usize = 100;

pub fn evaluate(args: &EvaluateArgs) -> Result<()> {
    let model = find_model(&args.model)?;
    check_angle_units(model, args.input.angles.into())?;
    let network = args.nn.as_ref().map(Mlp::load).transpose()?;
    if let (Some(n), Some(path)) = (&network, &args.nn) {
        check_network(n, path, model)?;
    }
    let predict = |traj: &Trajectory| match &network {
        Some(n) => Ok(n.predict(&Dataset::from_trajectory(traj, 0)?.inputs)?),
        None => model_torques(model, traj),
    };
    let (compared, (preprocessing, summary)) = if args.preprocessed {
        compare_as_given(args, model, predict)?
    } else {
        compare_filtered(args, model, predict)?
    };
    let stacked = |f: fn(&Compared) -> &DMatrix<f64>| {
        study::stack(compared.iter().map(|c| f(c).clone()).collect())
    };
    let (p, m) = (stacked(|c| &c.predicted), stacked(|c| &c.measured));
    if m.nrows() < FEWEST_SAMPLES {
        crate::say!(
            "warning: only {} samples compared (after the filter's trim at each end): an MSE of \
             so few says little about the model; record longer",
            m.nrows()
        );
    }
    let mse = mse_per_joint(&p, &m);
    let mse_as_logged = mse_as_logged(args, &compared, model.dof());
    let mean = mse.iter().sum::<f64>() / mse.len().max(1) as f64;
    let name = args
        .nn
        .as_ref()
        .map_or(model.name().to_string(), |p| p.display().to_string());
    match args.format {
        Format::Json => crate::output::print_line(
            &serde_json::json!({
                "model": name, "samples": m.nrows(), "mse": mse, "mse_mean": mean,
                "mse_torque_as_logged": mse_as_logged, "preprocessing": preprocessing,
            })
            .to_string(),
        )?,
        Format::Text => {
            let text = text_report(model, &name, m.nrows(), &summary, &mse, &mse_as_logged);
            crate::output::print(&text)?;
        }
    }
    Ok(())
}

/// How the recordings were preprocessed: as the report's JSON and as its
/// one line of text.
type Preprocessing = (serde_json::Value, String);

/// Raw recordings through the resolved pipeline (see `Pipeline::compare`),
/// after the sanity gate.
fn compare_filtered(
    args: &EvaluateArgs,
    model: &dyn Dynamics,
    predict: impl Fn(&Trajectory) -> Result<DMatrix<f64>>,
) -> Result<(Vec<Compared>, Preprocessing)> {
    let recordings = args.input.read_all(&args.data, Some(model.joint_names()))?;
    gate(args, model, &recordings)?;
    for (raw, path) in recordings.iter().zip(&args.data) {
        if raw.qdd().is_some() {
            crate::say!(
                "note: {} carries qdd columns (a preprocessed file?): filtered again as a raw \
                 recording; pass --preprocessed to compare it as it is",
                path.display()
            );
        }
    }
    let pipeline = args.filter.resolve(&recordings)?;
    let compared = recordings
        .iter()
        .zip(&args.data)
        .map(|(raw, path)| {
            pipeline
                .compare(raw, &predict)
                .with_context(|| path.display().to_string())
        })
        .collect::<Result<Vec<_>>>()?;
    Ok((
        compared,
        (serde_json::to_value(&pipeline)?, pipeline.summary()),
    ))
}

/// Files that already carry filtered qd and qdd (`--preprocessed`): the
/// prediction on their states against their torque, every sample.
fn compare_as_given(
    args: &EvaluateArgs,
    model: &dyn Dynamics,
    predict: impl Fn(&Trajectory) -> Result<DMatrix<f64>>,
) -> Result<(Vec<Compared>, Preprocessing)> {
    let recordings = args
        .data
        .iter()
        .map(|path| load_preprocessed(path, Some(model.joint_names()), &args.input))
        .collect::<Result<Vec<_>>>()?;
    crate::inputs::reject_repeated(&args.data, &recordings)?;
    gate(args, model, &recordings)?;
    let compared = recordings
        .iter()
        .zip(&args.data)
        .map(|(traj, path)| {
            let predicted = predict(traj).with_context(|| path.display().to_string())?;
            Ok(Compared {
                measured: traj.tau().clone(),
                predicted: predicted.clone(),
                measured_as_logged: traj.tau().clone(),
                predicted_unfiltered: predicted,
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let said = "preprocessed files (--preprocessed): compared as they are, not filtered again";
    Ok((compared, (serde_json::Value::from(said), said.to_string())))
}

/// A network must map the model's states to its torques.
fn check_network(network: &Mlp, path: &Path, model: &dyn Dynamics) -> Result<()> {
    let dof = model.dof();
    if network.n_inputs() != 3 * dof || network.n_outputs() != dof {
        bail!(
            "{}: the network maps {} inputs to {} torques; model `{}` has {dof} joints \
             (3 x {dof} inputs q, qd, qdd and {dof} torques): pass the --model it was trained for",
            path.display(),
            network.n_inputs(),
            network.n_outputs(),
            model.name()
        );
    }
    Ok(())
}

/// The sanity gate's checks on the recordings as logged: angles in
/// degrees, two joints' positions exchanged or time in milliseconds give
/// errors that blame the model for the data. Refused (exit 3, the
/// findings in JSON on standard output with `--format json`) unless
/// `--no-sanity-gate`, which prints them as warnings.
fn gate(args: &EvaluateArgs, model: &dyn Dynamics, recordings: &[Trajectory]) -> Result<()> {
    let findings = checks_as_logged(model, recordings);
    if args.no_sanity_gate {
        for finding in &findings {
            crate::say!(
                "warning: {} (--no-sanity-gate: evaluated anyway)",
                finding.message
            );
        }
        return Ok(());
    }
    if let Err(refusal) = refuse(model, &findings, Gated::Evaluation) {
        if args.format == Format::Json {
            crate::output::print_line(&serde_json::to_string_pretty(&refusal)?)?;
        }
        return Err(refusal.into());
    }
    Ok(())
}

/// Per joint, the error against the torque as logged, each recording
/// weighed as in `mse` (by its kept samples, i.e. by its duration)
/// whatever rate it was logged at.
fn mse_as_logged(args: &EvaluateArgs, compared: &[Compared], dof: usize) -> Vec<f64> {
    let weights: Vec<f64> = compared.iter().map(|c| c.measured.nrows() as f64).collect();
    let total: f64 = weights.iter().sum::<f64>().max(1.0);
    let mut mse_as_logged = vec![0.0; dof];
    for (c, w) in compared.iter().zip(&weights) {
        let each = mse_per_joint(&c.predicted_unfiltered, &c.measured_as_logged);
        for (sum, v) in mse_as_logged.iter_mut().zip(each) {
            *sum += v * w / total;
        }
    }
    // `--torque-scale J=S` divided joint J's torque by S when it was read:
    // against the torque as logged the error is S times the corrected one
    // (the prediction scaled as the sensor scales), so the as-logged MSE
    // stays comparable with and without the correction.
    for &(joint, scale) in &args.input.torque_scales {
        if let Some(mse) = mse_as_logged.get_mut(joint - 1) {
            *mse *= scale * scale;
        }
    }
    mse_as_logged
}

/// The text report: per joint both errors, in N m^2 (N^2 on a prismatic
/// joint), and their mean.
fn text_report(
    model: &dyn Dynamics,
    name: &str,
    samples: usize,
    preprocessing: &str,
    mse: &[f64],
    mse_as_logged: &[f64],
) -> String {
    use std::fmt::Write as _;
    let noun = if samples == 1 { "sample" } else { "samples" };
    let mut text = format!("model {name}: {samples} {noun}\n");
    let _ = writeln!(text, "{preprocessing}");
    let levers = crate::dynamics::joint_levers(model);
    let unit = |j: usize| match levers.get(j) {
        Some(&l) if l != 1.0 => "N^2",
        _ => "N m^2",
    };
    for (j, v) in mse.iter().enumerate() {
        let _ = writeln!(
            text,
            "  joint {}: MSE {v:.6} {} (against the torque as logged: {:.6})",
            j + 1,
            unit(j),
            mse_as_logged[j]
        );
    }
    let mean = mse.iter().sum::<f64>() / mse.len().max(1) as f64;
    let mixed = (0..mse.len()).any(|j| unit(j) != unit(0));
    let mean_unit = if mixed {
        "(N m^2 and N^2 mixed)"
    } else {
        unit(0)
    };
    let _ = writeln!(text, "  mean:    MSE {mean:.6} {mean_unit}");
    text
}
