//! One recording's [`Rows`] at the kept samples, produced a batch of
//! columns at a time: each batch is built at the raw rate, passes the
//! torque's zero-phase filter (parallel filtering), is trimmed and
//! decimated, and its raw memory is reused for the next batch. The exact
//! zero-phase filter needs a column's whole length at once (its backward
//! pass starts from the end), but not every column at once: the raw rate
//! holds at most [`RAW_BUDGET_BYTES`] of columns, however long the
//! recording, and what stays is the decimated data. Each value is computed
//! by the same expression as when every column was built at once, and each
//! column's filter does not depend on the others, so the kept rows are the
//! same numbers whatever the batches.

use std::ops::Range;

use nalgebra::{DMatrix, DVector};

use super::band::Band;
use super::rows::{Rows, Signal, Tilted, moving_sign};
use super::search::{RESOLVED_REST_MULTIPLE, stribeck_velocities};
use crate::dynamics::Dynamics;
use crate::oracle::{self, coulomb_sign};
use crate::preprocess::{ZeroPhaseLowPass, step};
use crate::trajectory::Trajectory;

/// Most raw-rate column memory per batch, bytes. A recording of up to
/// about a minute at 1 kHz on a 7-joint arm is built in one batch, as
/// before; longer ones compute the regressor once per batch that holds
/// some of its columns.
pub(super) const RAW_BUDGET_BYTES: usize = 256 << 20;

/// What the signals are computed from.
pub(super) struct Inputs<'a> {
    pub(super) model: &'a dyn Dynamics,
    pub(super) tilted: Option<&'a Tilted>,
    /// The states at the full rate (`None`: the dry-friction signals alone,
    /// which need only `band`).
    pub(super) traj: Option<&'a Trajectory>,
    /// The velocity the dry-friction columns follow, and its at-rest speeds.
    pub(super) band: &'a Band,
    pub(super) levers: &'a [f64],
}

/// What happens to every raw column: the torque filter's cut-off (`None`:
/// the pipeline filtered the states itself, nothing more), the sample
/// period, and the kept samples.
pub(super) struct Keep<'a> {
    pub(super) cutoff_hz: Option<f64>,
    pub(super) dt: f64,
    pub(super) samples: &'a [usize],
}

/// Per-recording signals at the raw rate that several columns read.
struct Derived<'a> {
    predicted: DMatrix<f64>,
    /// d/dt of the model torque and of the measured torque.
    rate: DMatrix<f64>,
    measured_rate: DMatrix<f64>,
    /// The model's gravity torque.
    load: DMatrix<f64>,
    /// The model's joint effects (friction, offset) in `predicted`.
    effects: DMatrix<f64>,
    accel: &'a DMatrix<f64>,
    traj: &'a Trajectory,
}

/// `out` (built with the columns of `signals`, the others left empty) at
/// the kept samples, and the first full-rate row where a checked signal is
/// not finite after filtering. `raw` is the reused raw-rate memory, at
/// most `budget` bytes of columns (at least one column).
pub(super) fn produce(
    out: &mut Rows,
    signals: &[Signal],
    inputs: &Inputs,
    keep: &Keep,
    (raw, budget): (&mut Vec<Vec<f64>>, usize),
) -> anyhow::Result<Option<usize>> {
    let n = inputs.levers.len();
    let len = inputs.band.qd.nrows();
    let derived = match inputs.traj {
        Some(traj) => Some(derived(inputs.model, traj)?),
        None => None,
    };
    let per_batch = (budget / (len * n * 8).max(1)).max(1);
    let mut first_bad: Option<usize> = None;
    for batch in signals.chunks(per_batch) {
        if raw.len() < batch.len() {
            raw.resize_with(batch.len(), || Vec::with_capacity(len * n));
        }
        let columns = &mut raw[..batch.len()];
        let parts = crate::parallel::workers();
        build_in_parts(batch, columns, (inputs, derived.as_ref()), parts)?;
        let (kept, filtered) = kept_rows(batch, columns, n, keep)?;
        let each = batch.iter().zip(columns.iter()).zip(kept).zip(filtered);
        for (((&signal, column), kept), filtered) in each {
            if signal.checked()
                && let Some(at) = first_not_finite(column, (&kept, filtered), n, keep.samples)
            {
                first_bad = Some(first_bad.map_or(at, |b| b.min(at)));
            }
            *out.signal_mut(signal) = kept;
        }
    }
    Ok(first_bad)
}

fn derived<'a>(model: &dyn Dynamics, traj: &'a Trajectory) -> anyhow::Result<Derived<'a>> {
    let [predicted, load, effects] = torques(model, traj, crate::parallel::workers())?;
    let accel = traj
        .qdd()
        .ok_or_else(|| anyhow::anyhow!("a preprocessed recording has no accelerations"))?;
    Ok(Derived {
        rate: torque_rate(&predicted, step(traj)),
        measured_rate: torque_rate(traj.tau(), step(traj)),
        predicted,
        load,
        effects,
        accel,
        traj,
    })
}

/// The model's torque (`dynamics::model_torques`), gravity torque and
/// joint effects at every sample (samples x joints), on `count` contiguous
/// ranges of samples, one thread each: a sample's values are its own, the
/// same numbers as on one thread.
fn torques(
    model: &dyn Dynamics,
    traj: &Trajectory,
    count: usize,
) -> anyhow::Result<[DMatrix<f64>; 3]> {
    let qdd = traj.qdd().ok_or_else(|| {
        anyhow::anyhow!("the trajectory has no accelerations; preprocess it first")
    })?;
    let (len, n) = (traj.len(), model.dof());
    let count = count.clamp(1, len.max(1));
    let ranges: Vec<Range<usize>> = (0..count)
        .map(|k| k * len / count..(k + 1) * len / count)
        .collect();
    let row = |m: &DMatrix<f64>, s: usize| -> Vec<f64> { m.row(s).iter().copied().collect() };
    let part = |samples: &Range<usize>| -> anyhow::Result<Vec<_>> {
        let at = |s: usize| -> anyhow::Result<_> {
            let q = row(traj.q(), s);
            let qd = row(traj.qd(), s);
            let tau = model.tau(&q, &qd, &row(qdd, s))?;
            Ok([tau, model.gravity(&q)?, model.effects(&qd)?])
        };
        samples.clone().map(at).collect()
    };
    let parts = crate::parallel::map_in_order_on(&ranges, part, count);
    let mut matrices = [(); 3].map(|_| DMatrix::zeros(len, n));
    let mut s = 0;
    for part in parts {
        for columns in part? {
            for (matrix, column) in matrices.iter_mut().zip(&columns) {
                matrix.set_row(s, &column.transpose());
            }
            s += 1;
        }
    }
    Ok(matrices)
}

/// The rows of `column` at `samples` (rows are (sample, joint) pairs).
fn pick(column: &[f64], dof: usize, samples: &[usize]) -> Vec<f64> {
    // A signal not built stays empty.
    if column.is_empty() {
        return Vec::new();
    }
    let mut kept = Vec::with_capacity(samples.len() * dof);
    for &s in samples {
        kept.extend_from_slice(&column[s * dof..(s + 1) * dof]);
    }
    kept
}

/// Each column's rows at the kept samples, through the torque's
/// zero-phase filter (parallel filtering, on every core) where the signal
/// is filtered, and whether it was. Only the kept samples of a filtered
/// column are written out; the raw columns are left as they are.
fn kept_rows(
    batch: &[Signal],
    columns: &[Vec<f64>],
    dof: usize,
    keep: &Keep,
) -> anyhow::Result<(Vec<Vec<f64>>, Vec<bool>)> {
    // A column of zeros (a tilt or Stribeck velocity not built at this
    // stage) stays zero through any linear filter.
    let filtered: Vec<bool> = batch
        .iter()
        .zip(columns)
        .map(|(s, c)| keep.cutoff_hz.is_some() && s.filtered() && c.iter().any(|x| *x != 0.0))
        .collect();
    let mut through = Vec::new();
    if let Some(cutoff_hz) = keep.cutoff_hz {
        let filter = ZeroPhaseLowPass::new(cutoff_hz, keep.dt)?;
        let passing: Vec<&[f64]> = columns
            .iter()
            .zip(&filtered)
            .filter(|(_, f)| **f)
            .map(|(c, _)| c.as_slice())
            .collect();
        let workers = crate::parallel::workers();
        let parts: Vec<&[&[f64]]> = passing
            .chunks(passing.len().div_ceil(workers).max(1))
            .collect();
        let kept = |part: &&[&[f64]]| filter.apply_interleaved_at(part, dof, keep.samples);
        through = crate::parallel::map_in_order_on(&parts, kept, workers);
    }
    let mut through = through.into_iter().flatten();
    let kept = columns
        .iter()
        .zip(&filtered)
        .map(|(c, &f)| match f {
            true => through.next().unwrap_or_default(),
            false => pick(c, dof, keep.samples),
        })
        .collect();
    Ok((kept, filtered))
}

/// The first full-rate row where `column` is not finite, after the
/// filter when it was `filtered`. A series holding a value that is not
/// finite is not finite at any sample once filtered (the forward pass
/// carries it to the end, the backward pass from there to the start): its
/// first such row is the first sample's, at the lowest joint with one. A
/// filter output overflowing from finite values is seen at the kept
/// samples (`kept`, the column's rows there).
fn first_not_finite(
    column: &[f64],
    (kept, filtered): (&[f64], bool),
    dof: usize,
    samples: &[usize],
) -> Option<usize> {
    let finite = |x: &f64| x.is_finite();
    if all_finite(column) && kept.iter().all(finite) {
        return None;
    }
    if !filtered || column.len() < 2 * dof {
        return column.iter().position(|x| !finite(x));
    }
    let joint = column
        .iter()
        .enumerate()
        .filter(|(_, x)| !finite(x))
        .map(|(r, _)| r % dof)
        .min();
    let overflow = kept
        .iter()
        .position(|x| !finite(x))
        .map(|k| samples[k / dof] * dof + k % dof);
    joint.or(overflow)
}

/// Whether every value of `column` is finite: its exponent bits not all
/// set, tested on every value with no early exit (an integer OR, which the
/// compiler turns into vector instructions).
fn all_finite(column: &[f64]) -> bool {
    const EXPONENT: u64 = 0x7ff0_0000_0000_0000;
    let not_finite = |x: &f64| u64::from(x.to_bits() & EXPONENT == EXPONENT);
    column.iter().fold(0, |any, x| any | not_finite(x)) == 0
}

/// Whether [`build`] gives `signal` a value at every row (without the
/// derived signals only the dry-friction ones are built; the others stay
/// empty).
fn is_built(signal: Signal, derived: bool) -> bool {
    derived || matches!(signal, Signal::Qd | Signal::Own(1) | Signal::Stribeck(_))
}

/// The rows of a range of samples of every column of a batch, built on one
/// thread.
struct Part<'a> {
    samples: Range<usize>,
    /// Each column's rows of `samples` (empty for a signal not built).
    columns: Vec<&'a mut [f64]>,
    outcome: anyhow::Result<()>,
}

/// [`build`] on `count` contiguous ranges of samples, one thread each
/// (one per core): every value is computed by the same expression from the
/// same sample whichever thread computes it, so the columns are the same
/// numbers as on one thread. Each built column is sized to every (sample,
/// joint) row first; reused memory already of that length is not written
/// twice.
fn build_in_parts(
    batch: &[Signal],
    columns: &mut [Vec<f64>],
    (inputs, derived): (&Inputs, Option<&Derived>),
    count: usize,
) -> anyhow::Result<()> {
    let (len, n) = (inputs.band.qd.nrows(), inputs.levers.len());
    for (&signal, column) in batch.iter().zip(columns.iter_mut()) {
        match is_built(signal, derived.is_some()) {
            true => {
                column.truncate(len * n);
                column.resize(len * n, 0.0);
            }
            false => column.clear(),
        }
    }
    let count = count.clamp(1, len.max(1));
    let bounds: Vec<usize> = (0..=count).map(|k| k * len / count).collect();
    let mut parts: Vec<Part> = bounds
        .windows(2)
        .map(|w| Part {
            samples: w[0]..w[1],
            columns: Vec::with_capacity(columns.len()),
            outcome: Ok(()),
        })
        .collect();
    for column in columns.iter_mut() {
        let mut rest = column.as_mut_slice();
        for part in &mut parts {
            let rows = if rest.is_empty() {
                0
            } else {
                part.samples.len() * n
            };
            let (mine, others) = std::mem::take(&mut rest).split_at_mut(rows);
            part.columns.push(mine);
            rest = others;
        }
    }
    crate::parallel::for_parts_mut(&mut parts, |parts| {
        for part in parts {
            part.outcome = build(batch, part, inputs, derived);
        }
    });
    parts.into_iter().try_for_each(|p| p.outcome)
}

/// Fills each column of `part` with its signal at the (sample, joint) rows
/// of its samples. The regressor, a tilted base's gravity and the generic
/// features give several columns from one evaluation: computed once per
/// sample for all of the batch's columns that need them.
fn build(
    batch: &[Signal],
    part: &mut Part,
    inputs: &Inputs,
    derived: Option<&Derived>,
) -> anyhow::Result<()> {
    let of = |wanted: fn(Signal) -> Option<usize>| -> Vec<(usize, usize)> {
        let found = batch.iter().enumerate();
        found
            .filter_map(|(c, &s)| wanted(s).map(|k| (c, k)))
            .collect()
    };
    let inertial = of(|s| match s {
        Signal::Inertial(k) => Some(k),
        _ => None,
    });
    let tilt = of(|s| match s {
        Signal::Tilt(k) => Some(k),
        _ => None,
    });
    let generic = of(|s| match s {
        Signal::Generic(k) => Some(k),
        _ => None,
    });
    let samples = part.samples.clone();
    let columns = part.columns.as_mut_slice();
    if let Some(d) = derived {
        let model = inputs.model;
        several(
            columns,
            &inertial,
            (d.traj, samples.clone()),
            |q, qd, qdd, _| Ok(model.regressor(q, qd, qdd)?),
        )?;
        if let Some(t) = inputs.tilted {
            several(columns, &tilt, (d.traj, samples.clone()), |q, _, _, _| {
                Ok(oracle::gravity_along(&t.model, q, &t.directions))
            })?;
        }
        several(
            columns,
            &generic,
            (d.traj, samples.clone()),
            |q, qd, qdd, s| {
                let features = (0..q.len()).map(|i| {
                    let sign = moving_sign(inputs.band.qd[(s, i)], inputs.band.rest[i]);
                    let (load, rate) = (d.load[(s, i)], d.rate[(s, i)]);
                    generic_features(q[i], qd[i], sign, qdd[i], load, rate)
                });
                Ok(features.collect::<Vec<[f64; 12]>>())
            },
        )?;
    }
    for (&signal, column) in batch.iter().zip(columns.iter_mut()) {
        single(signal, (column, samples.start), inputs, derived);
    }
    Ok(())
}

/// What [`several`] reads of one sample's values: by joint and index,
/// as each evaluation gives them (no copy into a matrix per sample).
trait Table {
    fn at(&self, joint: usize, index: usize) -> f64;
}

/// The regressor: joints x parameters.
impl Table for DMatrix<f64> {
    fn at(&self, joint: usize, index: usize) -> f64 {
        self[(joint, index)]
    }
}

/// Gravity torques along each direction, each over the joints.
impl<const K: usize> Table for [DVector<f64>; K] {
    fn at(&self, joint: usize, index: usize) -> f64 {
        self[index][joint]
    }
}

/// Each joint's features.
impl<const K: usize> Table for Vec<[f64; K]> {
    fn at(&self, joint: usize, index: usize) -> f64 {
        self[joint][index]
    }
}

/// Samples per tile of [`several`].
const TILE_SAMPLES: usize = 16;

/// The columns `wanted` ((column, index) pairs) of the matrix `values`
/// gives for each sample (joint x index), at the rows of `samples` (the
/// columns hold those rows alone). Rows are built a few samples at a time
/// in a tile that stays in the cache, then copied column by column:
/// written sample by sample, fifty-odd long columns took most of the time.
fn several<T: Table>(
    columns: &mut [&mut [f64]],
    wanted: &[(usize, usize)],
    (traj, samples): (&Trajectory, Range<usize>),
    values: impl Fn(&[f64], &[f64], &[f64], usize) -> anyhow::Result<T>,
) -> anyhow::Result<()> {
    if wanted.is_empty() {
        return Ok(());
    }
    let n = traj.dof();
    let accel = traj
        .qdd()
        .ok_or_else(|| anyhow::anyhow!("a preprocessed recording has no accelerations"))?;
    let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut tile = vec![Vec::with_capacity(TILE_SAMPLES * n); wanted.len()];
    let first = samples.start;
    for tile_start in samples.clone().step_by(TILE_SAMPLES) {
        for s in tile_start..(tile_start + TILE_SAMPLES).min(samples.end) {
            for i in 0..n {
                (q[i], qd[i], qdd[i]) = (traj.q()[(s, i)], traj.qd()[(s, i)], accel[(s, i)]);
            }
            let y = values(&q, &qd, &qdd, s)?;
            for i in 0..n {
                for (part, &(_, k)) in tile.iter_mut().zip(wanted) {
                    part.push(y.at(i, k));
                }
            }
        }
        let at = (tile_start - first) * n;
        for (part, &(c, _)) in tile.iter_mut().zip(wanted) {
            columns[c][at..at + part.len()].copy_from_slice(part);
            part.clear();
        }
    }
    Ok(())
}

/// `column`, the rows of the samples from `first` on, set to `value` of
/// each (sample, joint).
fn fill(column: &mut [f64], (dof, first): (usize, usize), value: impl Fn(usize, usize) -> f64) {
    for (row, s) in column.chunks_exact_mut(dof).zip(first..) {
        for (i, x) in row.iter_mut().enumerate() {
            *x = value(s, i);
        }
    }
}

/// A column that one value of one (sample, joint) row gives, at the rows
/// `column` holds (those of the samples from `first` on); columns
/// [`several`] builds and those without their inputs are left as they are.
fn single(
    signal: Signal,
    (column, first): (&mut [f64], usize),
    inputs: &Inputs,
    derived: Option<&Derived>,
) {
    let band = inputs.band;
    let at = (inputs.levers.len(), first);
    let sign = |s: usize, i: usize| moving_sign(band.qd[(s, i)], band.rest[i]);
    if let Signal::Stribeck(k) = signal {
        let v = stribeck_velocities()[k];
        let shape = |s, i| stribeck_shape(v, (sign(s, i), band.qd[(s, i)]), inputs.levers[i]);
        return fill(column, at, shape);
    }
    match (signal, derived) {
        (Signal::Qd, _) => fill(column, at, |s, i| band.qd[(s, i)]),
        (Signal::Own(1), _) => fill(column, at, sign),
        (_, None) => {}
        (Signal::Residual, Some(d)) => fill(column, at, |s, i| {
            d.traj.tau()[(s, i)] - d.predicted[(s, i)]
        }),
        (Signal::Measured, Some(d)) => fill(column, at, |s, i| d.traj.tau()[(s, i)]),
        (Signal::Qdd | Signal::Own(2), Some(d)) => fill(column, at, |s, i| d.accel[(s, i)]),
        (Signal::Gravity, Some(d)) => fill(column, at, |s, i| d.load[(s, i)]),
        (Signal::Effects, Some(d)) => fill(column, at, |s, i| d.effects[(s, i)]),
        (Signal::CoulombApplied, Some(_)) => fill(column, at, |s, i| coulomb_sign(band.qd[(s, i)])),
        (Signal::Own(0), Some(d)) => fill(column, at, |s, i| d.traj.qd()[(s, i)]),
        (Signal::Own(3), Some(_)) => fill(column, at, |_, _| 1.0),
        (Signal::Own(4), Some(d)) => fill(column, at, |s, i| d.traj.q()[(s, i)]),
        // Without a tilted model its columns are zero.
        (Signal::Tilt(_), Some(_)) if inputs.tilted.is_none() => fill(column, at, |_, _| 0.0),
        (Signal::MeasuredRate, Some(d)) => fill(column, at, |s, i| d.measured_rate[(s, i)]),
        _ => {}
    }
}

/// A Stribeck column's value for a joint moving with `sign` at the
/// `resolved` velocity, for the grid velocity `v`.
fn stribeck_shape(v: f64, (sign, resolved): (f64, f64), lever: f64) -> f64 {
    // Velocities below the least at-rest speed's resolved multiple are
    // never searched: a zero column, not filtered.
    if v < RESOLVED_REST_MULTIPLE * super::rows::MOVING {
        0.0
    } else {
        sign * (-(resolved / (v * lever)).powi(2)).exp()
    }
}

fn generic_features(q: f64, qd: f64, sign: f64, qdd: f64, load: f64, rate: f64) -> [f64; 12] {
    [
        qd,
        qd * qd.abs(),
        sign,
        sign * (-qd.abs() / 0.1).exp(),
        qdd,
        load,
        q.sin(),
        q.cos(),
        (2.0 * q).sin(),
        (2.0 * q).cos(),
        1.0,
        rate,
    ]
}

/// Time derivative of every column of `tau` (central differences).
fn torque_rate(tau: &DMatrix<f64>, dt: f64) -> DMatrix<f64> {
    let mut rate = DMatrix::zeros(tau.nrows(), tau.ncols());
    for j in 0..tau.ncols() {
        let x: Vec<f64> = tau.column(j).iter().copied().collect();
        if let Ok(d) = crate::preprocess::central_difference(&x, dt) {
            rate.column_mut(j).copy_from_slice(&d);
        }
    }
    rate
}

#[cfg(test)]
mod tests;
