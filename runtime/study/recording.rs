//! The virtual robot's recordings: random-waypoint motions inside the
//! controller model's limits, tracked on the plant and recorded with sensor
//! noise; and the open-loop replay of each model's torques on the plant.

use codegen::JointKind;

use super::*;

/// Joint limits of the random trajectories: the description's position
/// limits (+-pi for a revolute joint without limits, +-0.1 m for a
/// prismatic one), its velocity limits capped at the study's velocity cap,
/// and the study's acceleration cap.
pub fn limits(model: &dyn Dynamics, config: &StudyConfig) -> Result<JointLimits> {
    let description = parsed_description(model)?;
    let bodies: Vec<&codegen::Body> = description.chain().free_bodies().collect();
    let position = bodies
        .iter()
        .map(|b| {
            let unlimited = match b.kind {
                JointKind::Prismatic => (-0.1, 0.1),
                _ => (-PI, PI),
            };
            b.limits.and_then(|l| l.position()).unwrap_or(unlimited)
        })
        .collect();
    let velocity = bodies
        .iter()
        .map(|b| {
            let limit = b.limits.and_then(|l| l.velocity).unwrap_or(f64::INFINITY);
            config.max_velocity.min(limit)
        })
        .collect();
    Ok(JointLimits {
        position,
        velocity,
        acceleration: vec![config.max_acceleration; model.dof()],
    })
}

/// Records the trajectories (in parallel, two at a time) and preprocesses them.
pub(super) fn record(
    plant: &dyn Dynamics,
    controller: &dyn Dynamics,
    config: &StudyConfig,
    out: &Path,
    progress: Progress<'_>,
) -> Result<Data> {
    let waypoints = WaypointConfig {
        duration: config.duration,
        limits: limits(controller, config)?,
        ..WaypointConfig::default()
    };
    progress(0, config.trajectories, "recording trajectories");
    let recordings = parallel_map(
        config.trajectories,
        |k| -> Result<(Trajectory, Trajectory)> {
            let seed = trajectory_seed(config.seed, k);
            let recording = record_noisy(plant, controller, &waypoints, seed, config.noise_scale)?;
            progress(k + 1, config.trajectories, "recording trajectories");
            Ok((recording.measured, recording.reference))
        },
    )?;
    let mut raw = Vec::new();
    let mut references = Vec::new();
    let mut processed = Vec::new();
    for (k, (measured, reference)) in recordings.into_iter().enumerate() {
        write_csv(
            out.join("data")
                .join(format!("trajectory_{:02}.csv", k + 1)),
            &measured,
        )?;
        processed.push(config.preprocess.apply(&measured)?);
        raw.push(measured);
        references.push(reference);
    }
    let (train, test) = split(config, 0);
    Ok(Data {
        raw,
        processed,
        references,
        train,
        test,
        test_from: None,
    })
}

/// Train/test split `index` of the recorded trajectories (sorted indices).
pub(super) fn split(config: &StudyConfig, index: usize) -> (Vec<usize>, Vec<usize>) {
    let mut order: Vec<usize> = (0..config.trajectories).collect();
    order.shuffle(&mut ChaCha8Rng::seed_from_u64(seeds::derive(
        config.seed,
        Purpose::Split,
        index as u64,
    )));
    let (train, test) = order.split_at(config.train);
    let (mut train, mut test) = (train.to_vec(), test.to_vec());
    train.sort_unstable();
    test.sort_unstable();
    (train, test)
}

impl Data {
    /// The same recordings under train/test split `index`.
    pub(super) fn resplit(&self, config: &StudyConfig, index: usize) -> Data {
        let (train, test) = split(config, index);
        Data {
            raw: self.raw.clone(),
            processed: self.processed.clone(),
            references: self.references.clone(),
            train,
            test,
            test_from: self.test_from,
        }
    }
}

/// The seed of trajectory `k` of a recording session.
pub fn trajectory_seed(seed: u64, k: usize) -> u64 {
    seeds::derive(seed, Purpose::Trajectory, k as u64)
}

/// Records one random-waypoint trajectory on the virtual robot, its
/// controller tracking with `controller`'s dynamics.
pub fn record_trajectory(
    plant: &dyn Dynamics,
    controller: &dyn Dynamics,
    waypoints: &WaypointConfig,
    seed: u64,
) -> Result<crate::sim::simulate::Recording> {
    record_noisy(plant, controller, waypoints, seed, 1.0)
}

/// [`record_trajectory`] with the sensor noise scaled by `noise_scale`.
pub(super) fn record_noisy(
    plant: &dyn Dynamics,
    controller: &dyn Dynamics,
    waypoints: &WaypointConfig,
    seed: u64,
    noise_scale: f64,
) -> Result<crate::sim::simulate::Recording> {
    let reference = WaypointTrajectory::new(waypoints, seed)?;
    record_reference(plant, controller, &reference, seed, noise_scale)
}

/// Records the planned motion `reference` on the virtual robot (sensor
/// noise scaled by `noise_scale`, drawn from `seed`).
pub fn record_reference(
    plant: &dyn Dynamics,
    controller: &dyn Dynamics,
    reference: &dyn crate::sim::reference::Reference,
    seed: u64,
    noise_scale: f64,
) -> Result<crate::sim::simulate::Recording> {
    let mut sim = SimConfig::default();
    let description = parsed_description(controller)?;
    let bodies: Vec<&codegen::Body> = description.chain().free_bodies().collect();
    let noise = &mut sim.noise;
    noise.torque_sigma *= noise_scale;
    noise.velocity_sigma *= noise_scale;
    noise.angle_sigma *= noise_scale;
    noise.lever = crate::dynamics::joint_levers(controller);
    sim.controller.effort_limit = effort_limits(&bodies);
    Ok(simulate(
        &Compiled(plant),
        &Compiled(controller),
        reference,
        &sim,
        seed,
    )?)
}

/// The description's effort limits, where any joint has one (the drives
/// saturate there); a joint without one is not limited.
fn effort_limits(bodies: &[&codegen::Body]) -> Option<Vec<f64>> {
    let limits: Vec<Option<f64>> = bodies
        .iter()
        .map(|b| b.limits.and_then(|l| l.effort).filter(|&e| e > 0.0))
        .collect();
    limits
        .iter()
        .any(Option::is_some)
        .then(|| limits.iter().map(|l| l.unwrap_or(f64::MAX)).collect())
}

/// Thesis 4.3.2: replay each model's torques for the planned motion of the
/// first test trajectory open-loop on the plant; RMS joint-angle error over
/// the window.
pub(super) fn open_loop_evaluation(
    plant: &dyn Dynamics,
    nominal: &dyn Dynamics,
    identified: &Identified,
    data: &Data,
    config: &StudyConfig,
    (jobs, networks): (&[Job], &Trained),
    models: &mut [ModelResult],
) -> Result<()> {
    let reference = &data.references[data.test[0]];
    let dt = reference.t()[1] - reference.t()[0];
    let steps = ((config.open_loop_seconds / dt).round() as usize).min(reference.len());
    let window = Trajectory::new(
        reference.t()[..steps].to_vec(),
        reference.q().rows(0, steps).into_owned(),
        reference.qd().rows(0, steps).into_owned(),
        reference.qdd().map(|a| a.rows(0, steps).into_owned()),
        reference.tau().rows(0, steps).into_owned(),
    )?;
    let inputs = Dataset::from_trajectory(&window, 0)?.inputs;
    let analytical = model_torques(nominal, &window)?;
    let replay = |torques: &DMatrix<f64>| -> Result<f64> {
        let q0: Vec<f64> = window.q().row(0).iter().copied().collect();
        let qd0: Vec<f64> = window.qd().row(0).iter().copied().collect();
        let q = open_loop(&Compiled(plant), &q0, &qd0, torques, dt)?;
        let rows = q.nrows().min(steps);
        let err = q.rows(0, rows) - window.q().rows(0, rows);
        Ok((err.norm_squared() / (rows * err.ncols()) as f64).sqrt())
    };
    let fitted = identified.torques(&window)?;
    let mut set = |name: &str, torques: &DMatrix<f64>| -> Result<()> {
        if let Some(m) = models.iter_mut().find(|m| m.name == name) {
            m.open_loop_rms = Some(replay(torques)?);
        }
        Ok(())
    };
    set(ANALYTICAL, &analytical)?;
    set(IDENTIFIED, &fitted)?;
    for (job, seeds) in jobs.iter().zip(networks) {
        let mut torques = seeds[0].1.predict(&inputs)?;
        match job.recipe {
            Recipe::Residual => torques += &analytical,
            Recipe::IdentifiedResidual => torques += &fitted,
            _ => {}
        }
        set(&job.name, &torques)?;
    }
    Ok(())
}
