//! The networks of the study: how each one's training data is made (the
//! recipes: measured, analytical, synthesized, theoretical, residuals) and
//! training every one over the seeds, two at a time.

use super::*;

/// How a network's training data is made.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Recipe {
    Measured,
    Analytical,
    Synthesized {
        ratio: f64,
    },
    Theoretical,
    Residual,
    /// The residual of the model identified on the training recordings.
    IdentifiedResidual,
}

pub(super) struct Job {
    pub(super) name: String,
    pub(super) recipe: Recipe,
}

pub(super) fn jobs(config: &StudyConfig) -> Vec<Job> {
    let mut jobs = vec![
        Job {
            name: "NN on measured data".into(),
            recipe: Recipe::Measured,
        },
        Job {
            name: "NN on analytical data".into(),
            recipe: Recipe::Analytical,
        },
        Job {
            name: "SDNN (measured + analytical)".into(),
            recipe: Recipe::Synthesized { ratio: 1.0 },
        },
        Job {
            name: "Hybrid (analytical + NN residual)".into(),
            recipe: Recipe::Residual,
        },
        Job {
            name: "SDNN (measured + theoretical)".into(),
            recipe: Recipe::Theoretical,
        },
        Job {
            name: IDENTIFIED_HYBRID.into(),
            recipe: Recipe::IdentifiedResidual,
        },
    ];
    for &ratio in &config.mixing_ratios {
        jobs.push(Job {
            name: format!("SDNN, analytical:measured = {ratio}"),
            recipe: Recipe::Synthesized { ratio },
        });
    }
    jobs
}

/// Training sets per recipe, built once.
struct TrainingSets {
    measured: Dataset,
    analytical: Dataset,
    theoretical: Dataset,
    residual: Dataset,
    identified_residual: Dataset,
}

fn training_sets(
    nominal: &dyn Dynamics,
    identified: &Identified,
    data: &Data,
    config: &StudyConfig,
) -> Result<TrainingSets> {
    let mut measured = Vec::new();
    let mut analytical = Vec::new();
    let mut residual = Vec::new();
    let mut identified_residual = Vec::new();
    for &k in &data.train {
        let traj = &data.processed[k];
        let model = model_torques(nominal, traj)?;
        let fitted = identified.torques(traj)?;
        measured.push(Dataset::from_trajectory(traj, k)?);
        analytical.push(Dataset::from_trajectory(&traj.with_tau(model.clone())?, k)?);
        residual.push(Dataset::from_trajectory(
            &traj.with_tau(traj.tau() - model)?,
            k,
        )?);
        identified_residual.push(Dataset::from_trajectory(
            &traj.with_tau(traj.tau() - fitted)?,
            k,
        )?);
    }
    let theoretical = theoretical_data(nominal, config)?;
    Ok(TrainingSets {
        measured: Dataset::concat(&measured)?,
        analytical: Dataset::concat(&analytical)?,
        theoretical,
        residual: Dataset::concat(&residual)?,
        identified_residual: Dataset::concat(&identified_residual)?,
    })
}

/// Smooth excitation trajectories with exact q, qd, qdd at 100 Hz and the
/// nominal model's torque (thesis 4.3.1).
fn theoretical_data(nominal: &dyn Dynamics, config: &StudyConfig) -> Result<Dataset> {
    let excitation = ExcitationConfig {
        duration: config.duration,
        limits: limits(nominal, config)?,
        ..ExcitationConfig::default()
    };
    let dt = 0.01;
    let samples = (config.duration / dt).round() as usize + 1;
    let mut parts = Vec::new();
    for k in 0..config.theoretical_trajectories {
        let reference = ExcitationTrajectory::new(
            &excitation,
            seeds::derive(config.seed, Purpose::Theoretical, k as u64),
        )?;
        let n = reference.dof();
        let (mut q, mut qd, mut qdd) = (
            DMatrix::zeros(samples, n),
            DMatrix::zeros(samples, n),
            DMatrix::zeros(samples, n),
        );
        let t: Vec<f64> = (0..samples).map(|i| i as f64 * dt).collect();
        for (i, &ti) in t.iter().enumerate() {
            let (a, b, c) = reference.sample(ti);
            q.set_row(i, &a.transpose());
            qd.set_row(i, &b.transpose());
            qdd.set_row(i, &c.transpose());
        }
        let zeros = DMatrix::zeros(samples, n);
        let traj = Trajectory::new(t, q, qd, Some(qdd), zeros)?;
        let tau = model_torques(nominal, &traj)?;
        parts.push(Dataset::from_trajectory(&traj.with_tau(tau)?, 10_000 + k)?);
    }
    Ok(Dataset::concat(&parts)?)
}

/// Takes `ratio * len(measured)` analytical rows (cycling if more are needed).
fn mix(measured: &Dataset, analytical: &Dataset, ratio: f64, seed: u64) -> Result<Dataset> {
    let wanted = (ratio * measured.len() as f64).round() as usize;
    let mut rows: Vec<usize> = (0..analytical.len()).collect();
    rows.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
    let picked: Vec<usize> = rows.iter().cycle().take(wanted).copied().collect();
    let pick =
        |m: &DMatrix<f64>| DMatrix::from_fn(picked.len(), m.ncols(), |r, c| m[(picked[r], c)]);
    let groups = analytical
        .groups
        .as_ref()
        .map(|g| picked.iter().map(|&r| g[r]).collect());
    let part = Dataset::new(pick(&analytical.inputs), pick(&analytical.targets), groups)?;
    Ok(Dataset::concat(&[measured.clone(), part])?)
}

fn dataset_for(recipe: &Recipe, sets: &TrainingSets, seed: u64) -> Result<Dataset> {
    Ok(match recipe {
        Recipe::Measured => sets.measured.clone(),
        Recipe::Analytical => sets.analytical.clone(),
        Recipe::Residual => sets.residual.clone(),
        Recipe::IdentifiedResidual => sets.identified_residual.clone(),
        Recipe::Synthesized { ratio } => mix(&sets.measured, &sets.analytical, *ratio, seed)?,
        Recipe::Theoretical => Dataset::concat(&[sets.measured.clone(), sets.theoretical.clone()])?,
    })
}

/// Per job, per seed: (test MSE per joint, the trained network).
pub(super) type Trained = Vec<Vec<(Vec<f64>, Mlp)>>;

/// A test trajectory, its network inputs, and the analytical and identified
/// models' torques along it.
type TestCase<'a> = (&'a Trajectory, DMatrix<f64>, DMatrix<f64>, DMatrix<f64>);

pub(super) fn train_all(
    nominal: &dyn Dynamics,
    identified: &Identified,
    data: &Data,
    config: &StudyConfig,
    jobs: &[Job],
    progress: Progress<'_>,
) -> Result<Trained> {
    let sets = training_sets(nominal, identified, data, config)?;
    let test: Vec<TestCase> = data
        .test
        .iter()
        .map(|&k| {
            let traj = &data.processed[k];
            Ok((
                traj,
                Dataset::from_trajectory(traj, k)?.inputs,
                model_torques(nominal, traj)?,
                identified.torques(traj)?,
            ))
        })
        .collect::<Result<_>>()?;
    let total = jobs.len() * config.seeds;
    progress(0, total, "training networks");
    let done = Mutex::new(0usize);
    let results = parallel_map(total, |i| -> Result<(Vec<f64>, Mlp)> {
        let (job, seed) = (&jobs[i / config.seeds], (i % config.seeds) as u64);
        let training = dataset_for(
            &job.recipe,
            &sets,
            seeds::derive(config.seed, Purpose::Mix, seed),
        )?;
        let network = Mlp::params()
            .hidden(config.hidden.clone())
            .max_epochs(config.max_epochs)
            .patience(config.patience)
            .batch_size(config.batch_size)
            .learning_rate(config.learning_rate)
            .seed(seeds::derive(config.seed, Purpose::Network, seed))
            .fit(&training)
            .with_context(|| format!("training {} (seed {seed})", job.name))?;
        let pairs = test
            .iter()
            .map(|(traj, inputs, analytical, fitted)| {
                let mut predicted = network.predict(inputs)?;
                match job.recipe {
                    Recipe::Residual => predicted += analytical,
                    Recipe::IdentifiedResidual => predicted += fitted,
                    _ => {}
                }
                Ok((predicted, *traj))
            })
            .collect::<Result<Vec<_>>>()?;
        let mse = pooled_mse(&pairs);
        let mut count = done
            .lock()
            .map_err(|_| anyhow::anyhow!("progress counter poisoned"))?;
        *count += 1;
        progress(*count, total, "training networks");
        Ok((mse, network))
    })?;
    let mut by_job: Trained = Vec::new();
    for (i, result) in results.into_iter().enumerate() {
        if i % config.seeds == 0 {
            by_job.push(Vec::new());
        }
        by_job.last_mut().expect("pushed above").push(result);
    }
    Ok(by_job)
}

/// Saves each job's seed-0 network below `out/networks`.
pub(super) fn save_networks(jobs: &[Job], networks: &Trained, out: &Path) -> Result<()> {
    std::fs::create_dir_all(out.join("networks"))?;
    for (job, seeds) in jobs.iter().zip(networks) {
        let file = out
            .join("networks")
            .join(format!("{}.json", slug(&job.name)));
        seeds[0]
            .1
            .save(&file)
            .with_context(|| format!("saving {}", file.display()))?;
    }
    Ok(())
}
