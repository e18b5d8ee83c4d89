//! `sdnn diagnose`: the report, and `--apply` with the command that shows
//! the gap shrink.

use super::*;
use crate::diagnose::Refusal;

#[derive(Debug, Args)]
pub struct DiagnoseArgs {
    /// The model to check: a compiled model's name, or a TOML description
    /// (evaluated by the numeric dynamics, no rebuild needed) [default:
    /// kinova_gen3_lite_3dof, the virtual robot's].
    #[arg(long)]
    pub model: Option<String>,
    /// Raw measured CSV files: one or more recordings, each cut into
    /// cross-validation segments.
    #[arg(long, required = true, num_args = 1..)]
    pub data: Vec<PathBuf>,
    #[command(flatten)]
    pub input: InputArgs,
    #[command(flatten)]
    pub filter: FilterArgs,
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
    /// Cross-validation segments per recording [default: about 12 in all,
    /// 2-30 s each].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=100))]
    pub segments: Option<u32>,
    /// Try Stribeck friction on every joint: by default it is tried, where
    /// velocity reversals are resolved, on the joints with Coulomb friction
    /// named or modelled (see docs/diagnosis.md).
    #[arg(long)]
    pub stribeck: bool,
    /// Name effects even when the recordings fail the sanity gate (a torque
    /// against the model's, positions beyond the limits, two joints that look
    /// exchanged; see docs/diagnosis.md): only for recordings checked by hand.
    #[arg(long)]
    pub no_sanity_gate: bool,
    /// The whole text report: every note, each joint's residual regimes and
    /// every pair of parameters the data barely tell apart (by default the
    /// five notes that concern the most held-out error).
    #[arg(long)]
    pub verbose: bool,
    /// Write the named effects into the model's TOML (a `.bak` copy is kept).
    #[arg(long)]
    pub apply: bool,
    /// The description to update with --apply (default: the model's TOML).
    #[arg(long)]
    pub toml: Option<PathBuf>,
    /// Write residual-vs-velocity and residual-vs-acceleration plots (SVG,
    /// per joint, before and after the named effects) into this folder.
    #[arg(long)]
    pub plots: Option<PathBuf>,
}

impl DiagnoseArgs {
    /// The model's name or file, as given or the default.
    fn model_name(&self) -> &str {
        self.model.as_deref().unwrap_or(DEFAULT_NOMINAL)
    }
}

pub fn diagnose(args: &DiagnoseArgs) -> Result<()> {
    let model = find_model(args.model_name())?;
    crate::args::check_angle_units(model, args.input.angles.into())?;
    // Checked before the fit, which can take minutes: a missing file is
    // found now, not at the end.
    let toml = args
        .apply
        .then(|| description_to_update(args, model))
        .transpose()?;
    let recordings = args
        .input
        .read_all(&args.data, Some(model.joint_names()))
        .map_err(|e| name_the_model(e, args, model))?;
    let pipeline = args.filter.resolve(&recordings)?;
    let diagnosed = crate::diagnose::diagnose(
        model,
        &recordings,
        &pipeline,
        crate::diagnose::Settings {
            reach: crate::diagnose::reach(model),
            segments: args.segments.map(|s| s as usize),
            stribeck: args.stribeck,
            sanity_gate: !args.no_sanity_gate,
            ..crate::diagnose::Settings::default()
        },
    );
    let report = match diagnosed {
        Ok(report) => report,
        Err(error) => {
            if let (Some(refusal), Format::Json) = (error.downcast_ref::<Refusal>(), args.format) {
                crate::output::print_line(&serde_json::to_string_pretty(refusal)?)?;
            }
            return Err(error);
        }
    };
    match args.format {
        Format::Json => crate::output::print_line(&serde_json::to_string_pretty(&report)?)?,
        Format::Text => crate::output::print(&report.text(args.verbose))?,
    }
    if let Some(dir) = &args.plots {
        for path in crate::diagnose::plots::write(dir, &report)? {
            crate::say!("wrote {}", path.display());
        }
    }
    if let Some(toml) = toml.filter(|_| !report.effects.is_empty()) {
        apply(args, model, &report, &toml)?;
    }
    Ok(())
}

/// A recording whose joint count is not the model's: the error names the
/// model it was read for (the default when `--model` was not given) and
/// how to choose another.
fn name_the_model(
    error: anyhow::Error,
    args: &DiagnoseArgs,
    model: &dyn Dynamics,
) -> anyhow::Error {
    let wrong_count = error.chain().any(|e| {
        matches!(
            e.downcast_ref::<crate::trajectory::TrajectoryError>(),
            Some(crate::trajectory::TrajectoryError::WrongDof { .. })
        )
    });
    if !wrong_count {
        return error;
    }
    let which = match &args.model {
        None => format!(
            "model `{}`, the default when `--model` is not given,",
            model.name()
        ),
        Some(_) => format!("model `{}`", model.name()),
    };
    anyhow::anyhow!(
        "{}: {which} has {} joints; pass `--model NAME` for your arm (`sdnn models` lists the \
         compiled ones) or `--model FILE.toml` (a description; `sdnn import-urdf` makes one)",
        crate::errors::message(&error),
        model.dof()
    )
}

/// The description `--apply` will write: `--toml`, the `--model` file, or
/// `models/NAME.toml` under the current folder; read and checked now, so
/// that a missing or edited file stops the command before the fit.
fn description_to_update(args: &DiagnoseArgs, model: &dyn Dynamics) -> Result<PathBuf> {
    let toml = match (&args.toml, crate::args::model_path(args.model_name())) {
        (Some(path), _) => path.clone(),
        (None, Some(path)) => path,
        (None, None) => PathBuf::from(format!("models/{}.toml", model.name())),
    };
    let on_disk = match crate::bounded::read_description(&toml) {
        Ok(text) => text,
        Err(e) if args.toml.is_none() && crate::args::model_path(args.model_name()).is_none() => {
            return Err(anyhow::Error::new(e).context(format!(
                "{}: cannot read the description of compiled model `{}` that --apply would \
                 update (it is looked for under the current folder): run from the repository \
                 the model was built in, or pass `--toml FILE` (a copy of the description to \
                 update)",
                toml.display(),
                model.name()
            )));
        }
        Err(e) => {
            return Err(anyhow::Error::new(e).context(format!("{}: cannot read", toml.display())));
        }
    };
    if let Err(e) = codegen::Description::parse(&on_disk, model.name(), &toml) {
        bail!(
            "--toml {}: not a robot description this tool reads: {e}",
            toml.display()
        );
    }
    let plain = |text: &str| text.trim_start_matches('\u{feff}').replace("\r\n", "\n");
    if plain(&on_disk) != plain(model.description()) {
        bail!(
            "{}: the file is not the description `{}` was built from (an earlier --apply \
             or an edit since the build), so applying this diagnosis would count its effects \
             twice; rebuild (`cargo build --release`) or diagnose the file itself \
             (`--model {}`), then --apply",
            toml.display(),
            model.name(),
            toml.display()
        );
    }
    Ok(toml)
}

/// Writes the named effects into the description and says how to see the
/// gap shrink.
fn apply(args: &DiagnoseArgs, model: &dyn Dynamics, report: &Diagnosis, toml: &Path) -> Result<()> {
    let description = crate::dynamics::parsed_description(model)?;
    let last = description
        .chain()
        .bodies
        .last()
        .map(|b| b.link.clone())
        .unwrap_or_default();
    let applied = crate::diagnose::apply::apply_to_file(toml, report, model.joint_names(), &last)?;
    let backup = applied.backup;
    if applied.changes.is_empty() {
        crate::say!(
            "{}: unchanged (no effect of the robot was named)",
            toml.display()
        );
    } else {
        crate::say!("changed in {}:", toml.display());
    }
    for line in &applied.changes {
        crate::say!("  {line}");
    }
    for e in report.effects.iter().filter(|e| {
        e.parameters.get("physically_consistent") == Some(&serde_json::Value::Bool(false))
    }) {
        crate::say!(
            "  warning: the {} of link `{}` is written as fitted, but the corrected body is not \
             physically realizable (the report's note says why): correct that link's inertia too",
            e.kind.name(),
            e.link.as_deref().unwrap_or("?")
        );
    }
    let data: Vec<String> = args
        .data
        .iter()
        .map(|p| shell_word(&p.display().to_string()))
        .collect();
    let corrections = args
        .input
        .corrections()
        .then(&Corrections::diagnosed(report));
    let options =
        args.input.command_line(&corrections) + &args.filter.command_line(args.input.angles);
    if corrections != args.input.corrections() {
        crate::say!(
            "the recordings need correcting too (properties of the data, not of the robot, so not \
             in the TOML):{}",
            Corrections::diagnosed(report).flags()
        );
    }
    let done = if applied.changes.is_empty() {
        "the gap with the corrections".to_string()
    } else {
        format!(
            "updated {} (backup {}); the gap with the effects, no rebuild needed",
            toml.display(),
            backup.display()
        )
    };
    crate::say!(
        "{done}:\n  sdnn evaluate --model {} --data {}{options}\n(on these recordings, the ones \
         diagnosed: give recordings the diagnosis did not see for a held-out check; `cargo build \
         --release` makes it the compiled model `{}` when the file is under models/)",
        shell_word(&toml.display().to_string()),
        data.join(" "),
        toml.file_stem()
            .map_or(String::new(), |s| s.to_string_lossy().into_owned()),
    );
    Ok(())
}
