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

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]

        /// What is written reads back the same, to the last bit.
        #[test]
        fn a_written_plan_reads_back(
            dof in 1usize..4,
            rows in 2usize..20,
            values in proptest::collection::vec(-500.0f64..500.0, 240),
        ) {
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join("plan.csv");
            let t: Vec<f64> = (0..rows).map(|i| i as f64 * 0.001).collect();
            let m = |k: usize| DMatrix::from_fn(rows, dof, |r, c| values[(k * 60 + r * dof + c) % 240]);
            let plan = Trajectory::new(t, m(0), m(1), Some(m(2)), DMatrix::zeros(rows, dof)).unwrap();
            write_plan_csv(&path, &plan).unwrap();
            let back = read_plan_csv(&path, &ReadOptions::default()).unwrap();
            prop_assert_eq!(back, plan);
        }
    }

    #[test]
    fn a_plan_without_accelerations_is_named_with_what_is_expected() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("plan.csv");
        std::fs::write(&path, "t,q1,qd1\n0,0,0\n0.001,0,0\n").unwrap();
        let e = read_plan_csv(&path, &ReadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("plan.csv") && e.contains("qdd1"), "{e}");
    }
}
