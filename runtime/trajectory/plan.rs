//! Planned motions: `t,q1..qN,qd1..qdN,qdd1..qddN` (what `sdnn excite`
//! writes and `sdnn simulate --trajectory` tracks). A recording's `tau`
//! columns may be present (they are read and not used), so a recording's
//! own motion can be replayed too.

use super::*;

/// Reads a planned motion; its `tau` are zeros (a recording's torques are
/// not used).
pub fn read_plan_csv(
    path: impl AsRef<Path>,
    opts: &ReadOptions,
) -> Result<Trajectory, TrajectoryError> {
    let path = path.as_ref();
    no_resample(path, opts)?;
    let table = read_table(path, opts, &PLAN_SCHEMA)?;
    let t = table.checked_time(path)?;
    let q = table.required(Channel::Q, opts.units);
    let tau = DMatrix::zeros(q.nrows(), q.ncols());
    Trajectory::new(
        t,
        q,
        table.required(Channel::Qd, opts.units),
        Some(table.required(Channel::Qdd, opts.units)),
        tau,
    )
}

/// Writes a planned motion (`t`, q, qd, qdd; no torques), atomically.
pub fn write_plan_csv(path: impl AsRef<Path>, traj: &Trajectory) -> Result<(), TrajectoryError> {
    let t = DMatrix::from_column_slice(traj.len(), 1, traj.t());
    let zeros = DMatrix::zeros(traj.len(), traj.dof());
    let qdd = traj.qdd().unwrap_or(&zeros);
    let blocks = [
        (None, &t),
        (Some(Channel::Q), traj.q()),
        (Some(Channel::Qd), traj.qd()),
        (Some(Channel::Qdd), qdd),
    ];
    write_blocks(path.as_ref(), &blocks)
}
