//! `sdnn diagnose`: the report, and `--apply` with the command that shows
//! the gap shrink.

use super::*;

#[derive(Debug, Args)]
pub struct DiagnoseArgs {
    /// The model to check: a compiled model's name, or a TOML description
    /// (evaluated by the numeric dynamics, no rebuild needed).
    #[arg(long, default_value = DEFAULT_NOMINAL)]
    pub model: String,
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
    /// Let Stribeck friction compete too (off by default: from recordings
    /// its signature, confined to velocity reversals, is confounded with the
    /// stick-slip of plain dry friction; see docs/diagnosis.md).
    #[arg(long)]
    pub stribeck: bool,
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

pub fn diagnose(args: &DiagnoseArgs) -> Result<()> {
    let model = find_model(&args.model)?;
    crate::args::check_angle_units(model, args.input.angles.into())?;
    let recordings = args.input.read_all(&args.data, Some(model.joint_names()))?;
    let pipeline = args.filter.resolve(&recordings)?;
    let report = crate::diagnose::diagnose(
        model,
        &recordings,
        &pipeline,
        crate::diagnose::Settings {
            reach: crate::diagnose::reach(model),
            segments: args.segments.map(|s| s as usize),
            stribeck: args.stribeck,
            ..crate::diagnose::Settings::default()
        },
    )?;
    match args.format {
        Format::Json => crate::output::print_line(&serde_json::to_string_pretty(&report)?)?,
        Format::Text => crate::output::print(&report.text())?,
    }
    if let Some(dir) = &args.plots {
        for path in crate::diagnose::plots::write(dir, &report)? {
            crate::say!("wrote {}", path.display());
        }
    }
    if args.apply && !report.effects.is_empty() {
        apply(args, model, &report)?;
    }
    Ok(())
}

/// Writes the named effects into the description and says how to see the
/// gap shrink.
fn apply(args: &DiagnoseArgs, model: &dyn Dynamics, report: &Diagnosis) -> Result<()> {
    let toml = match (&args.toml, crate::args::model_path(&args.model)) {
        (Some(path), _) => path.clone(),
        (None, Some(path)) => path,
        (None, None) => PathBuf::from(format!("models/{}.toml", model.name())),
    };
    let on_disk = crate::bounded::read_description(&toml)
        .with_context(|| format!("{}: cannot read", toml.display()))?;
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
    let description = crate::dynamics::parsed_description(model)?;
    let last = description
        .chain()
        .bodies
        .last()
        .map(|b| b.link.clone())
        .unwrap_or_default();
    let applied = crate::diagnose::apply::apply_to_file(&toml, report, model.joint_names(), &last)?;
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
        "{done}:\n  sdnn evaluate --model {} --data {}{options}\n(`cargo build --release` makes \
         it the compiled model `{}` when the file is under models/)",
        shell_word(&toml.display().to_string()),
        data.join(" "),
        toml.file_stem()
            .map_or(String::new(), |s| s.to_string_lossy().into_owned()),
    );
    Ok(())
}
