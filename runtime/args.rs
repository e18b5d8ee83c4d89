//! Argument types the commands share (output format, angle unit) and the
//! lookup of `--model`: a compiled model's name or a description file.

use std::path::Path;

use anyhow::{Context, Result};
use clap::ValueEnum;

use crate::dynamics::{Dynamics, model, model_names};
use crate::shell::shell_word;
use crate::trajectory::{AngleUnit, Units};

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

/// The compiled model with this name, or the description file at this
/// path; an error names the near names (a typo) or the missing file.
pub fn find_model(name: &str) -> Result<&'static dyn Dynamics> {
    if let Some(path) = model_path(name) {
        if !path.exists() {
            anyhow::bail!("{}", missing_description(&path));
        }
        return Ok(crate::described::Described::load(&path)?);
    }
    model(name).with_context(|| unknown_model(name))
}

/// A `.toml` argument that names no file; a compiled model's name written
/// as a file (`panda.toml` outside the repository) says so.
fn missing_description(path: &Path) -> String {
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned());
    let compiled = stem.filter(|s| model(s).is_some());
    let hint = match compiled {
        Some(stem) => format!("; `{stem}` is a compiled model: name it without `.toml`"),
        None => " (a path from the current folder; `--model` also takes a compiled \
                  model's name, `sdnn models` lists them)"
            .to_owned(),
    };
    format!("model description file {} not found{hint}", path.display())
}

/// No compiled model by this name: the near names, then every name.
fn unknown_model(name: &str) -> String {
    let names = model_names();
    if let Some(stem) = name
        .strip_suffix(".urdf")
        .filter(|_| Path::new(name).is_file())
    {
        let (urdf, toml) = (shell_word(name), shell_word(&format!("{stem}.toml")));
        return format!(
            "`{name}` is a URDF: convert it once with `sdnn import-urdf {urdf} --out {toml}` \
             and pass `--model {toml}`"
        );
    }
    let with_toml = format!("{name}.toml");
    if (name.contains('/') || name.contains('\\')) && Path::new(&with_toml).is_file() {
        return format!(
            "`{name}` is a path without `.toml`: did you mean `{with_toml}`? (a description \
             file's path ends in .toml)"
        );
    }
    let near =
        crate::suggest::did_you_mean(name, &names).map_or(String::new(), |s| format!(" ({s})"));
    format!(
        "no compiled model named `{name}`{near}; compiled models: {} (add models/{name}.toml \
         and rebuild, or pass a description file path ending in .toml)",
        names.join(", ")
    )
}

/// Refuses `--angles deg` for a model with prismatic joints: their columns
/// are metres, which the option would convert as degrees. Convert the
/// revolute columns to radians first.
pub fn check_angle_units(model: &dyn Dynamics, units: Units) -> Result<()> {
    let degrees = matches!(units.angles, AngleUnit::Degrees);
    let levers = crate::dynamics::joint_levers(model);
    if let Some(j) = levers.iter().position(|&l| l != 1.0).filter(|_| degrees) {
        anyhow::bail!(
            "--angles deg converts every joint's q, qd and qdd from degrees, but joint {} of \
             model `{}` is prismatic (metres): convert the revolute joints' columns to radians \
             and leave out --angles",
            j + 1,
            model.name()
        );
    }
    Ok(())
}

/// The description file a `--model` argument names, when it is a path
/// (ends in `.toml`) rather than a compiled model's name.
pub fn model_path(name: &str) -> Option<std::path::PathBuf> {
    name.ends_with(".toml")
        .then(|| std::path::PathBuf::from(name))
}
