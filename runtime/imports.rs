//! `sdnn import-urdf` and `sdnn import-log`: other formats into the
//! project's contracts (TOML descriptions, trajectory CSV).

use std::io::Write;
use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;

use crate::import_log::{Columns, LineMajorSources, read_line_major, write_contract_csv};
use crate::import_urdf::{Attachment, ImportOptions, import_urdf, parse_lock};
use crate::report::atomic::write_atomic;

#[derive(Debug, Args)]
pub struct ImportUrdfArgs {
    /// The URDF file.
    pub urdf: PathBuf,
    /// The link fixed to the world (default: the URDF root link).
    #[arg(long)]
    pub base: Option<String>,
    /// The last link of the chain (default: where the only moving branch ends
    /// or splits, as at a hand's fingers, whose joints are then held at 0).
    #[arg(long)]
    pub tip: Option<String>,
    /// Hold a joint at a position (rad, or m for a prismatic joint); it is
    /// lumped like a fixed joint, and joints that mimic it follow.
    #[arg(long, value_name = "JOINT=POSITION", value_parser = parse_lock)]
    pub lock: Vec<(String, f64)>,
    /// Fix a payload to a link:
    /// `LINK:mass=KG[,com=X;Y;Z][,inertia=IXX;IYY;IZZ[;IXY;IXZ;IYZ]]` (quote it).
    #[arg(long, value_name = "LINK:mass=..,com=..")]
    pub attach: Vec<Attachment>,
    /// Keep a link's inertia that is not positive semi-definite, on purpose
    /// (written as `nonphysical_inertia`); triangle-inequality breaches are
    /// kept without it, with a warning.
    #[arg(long, value_name = "LINK")]
    pub nonphysical_inertia: Vec<String>,
    /// The description's `name` (default: the URDF robot name).
    #[arg(long)]
    pub name: Option<String>,
    /// Write the TOML here (atomically) instead of standard output.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn import_urdf_command(args: &ImportUrdfArgs) -> Result<()> {
    crate::output::note_input(&args.urdf);
    let text = crate::bounded::read_to_string(&args.urdf)
        .with_context(|| format!("reading {}", args.urdf.display()))?;
    let options = ImportOptions {
        base: args.base.clone(),
        tip: args.tip.clone(),
        lock: args.lock.clone(),
        attach: args.attach.clone(),
        nonphysical_inertia: args.nonphysical_inertia.clone(),
        name: args.name.clone(),
    };
    let label = args.urdf.display().to_string();
    let imported =
        import_urdf(&text, &label, &options).with_context(|| format!("importing {label}"))?;
    for warning in &imported.warnings {
        crate::say!("warning: {label}: {warning}");
    }
    for note in &imported.notes {
        crate::say!("note: {label}: {note}");
    }
    emit(args.out.as_ref(), imported.toml.as_bytes())?;
    if let Some(out) = &args.out {
        crate::say!(
            "wrote {}; every command takes it as is (`--model {}`); put it in models/ and run \
             `cargo build --release` for its generated, compiled dynamics",
            out.display(),
            out.display()
        );
    }
    Ok(())
}

#[derive(Debug, Args)]
pub struct ImportLogArgs {
    /// Sample times (s), one per line.
    #[arg(long)]
    pub time: PathBuf,
    /// Joint positions (rad), `dof` lines per sample.
    #[arg(long)]
    pub positions: PathBuf,
    /// Joint velocities (rad/s), `dof` lines per sample.
    #[arg(long)]
    pub velocities: PathBuf,
    /// Joint torques (N m), `dof` lines per sample.
    #[arg(long)]
    pub torques: PathBuf,
    /// Number of joints.
    #[arg(long)]
    pub dof: usize,
    /// Write the CSV here (atomically) instead of standard output.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn import_log_command(args: &ImportLogArgs) -> Result<()> {
    let columns = read_line_major(&LineMajorSources {
        time: args.time.clone(),
        positions: args.positions.clone(),
        velocities: args.velocities.clone(),
        torques: args.torques.clone(),
        dof: args.dof,
    })?;
    plausible_log(args, &columns)?;
    let mut csv = Vec::new();
    write_contract_csv(&mut csv, &columns)?;
    emit(args.out.as_ref(), &csv)?;
    if let Some(out) = &args.out {
        crate::say!(
            "wrote {} ({} samples); timestamps are as logged: pass `--resample HZ` to \
             commands that read it if they are not uniform",
            out.display(),
            columns.t.len()
        );
    }
    Ok(())
}

/// The readers' bounds on what a recording may hold (magnitudes and the
/// shortest time step), checked before the CSV is written: it would be
/// refused when read. Errors name the channel's file and line.
fn plausible_log(args: &ImportLogArgs, columns: &Columns) -> Result<()> {
    use crate::trajectory::{MIN_STEP, PLAUSIBLE_ANGLE, PLAUSIBLE_TIME, PLAUSIBLE_TORQUE};
    let channels = [
        (
            "position (rad)",
            &args.positions,
            &columns.q,
            PLAUSIBLE_ANGLE,
        ),
        (
            "velocity (rad/s)",
            &args.velocities,
            &columns.qd,
            PLAUSIBLE_ANGLE,
        ),
        (
            "torque (N m)",
            &args.torques,
            &columns.tau,
            PLAUSIBLE_TORQUE,
        ),
    ];
    let time = args.time.display();
    for (k, &t) in columns.t.iter().enumerate() {
        if t.is_nan() || t.abs() > PLAUSIBLE_TIME {
            anyhow::bail!(
                "{time}: line {}: time {t:e} s is beyond any log (|t| <= {PLAUSIBLE_TIME:e} s)",
                k + 1
            );
        }
        if let Some(&previous) = k.checked_sub(1).and_then(|p| columns.t.get(p))
            && t - previous < MIN_STEP
        {
            anyhow::bail!(
                "{time}: line {}: {:e} s after the previous sample; steps below {MIN_STEP:e} s \
                 (1 MHz) are not a joint log and the readers refuse them (time in another unit? \
                 the contract is seconds)",
                k + 1,
                t - previous
            );
        }
        for (what, path, rows, limit) in &channels {
            if let Some((j, v)) = rows[k]
                .iter()
                .enumerate()
                .find(|(_, v)| v.is_nan() || v.abs() > *limit)
            {
                anyhow::bail!(
                    "{}: line {} (sample {}, joint {}): {what} {v:e} is beyond any arm \
                     (|value| <= {limit:e}); a logging fault?",
                    path.display(),
                    k * args.dof + j + 1,
                    k + 1,
                    j + 1
                );
            }
        }
    }
    Ok(())
}

/// Writes to `out` atomically, or to standard output.
fn emit(out: Option<&PathBuf>, bytes: &[u8]) -> Result<()> {
    match out {
        Some(path) => write_atomic(path, bytes)?,
        None => {
            let mut stdout = std::io::stdout().lock();
            stdout
                .write_all(bytes)
                .context("writing to standard output")?;
            stdout.flush().context("writing to standard output")?;
        }
    }
    Ok(())
}
