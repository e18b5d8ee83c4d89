//! The map: when does SDNN help? A grid over the size of the analytical
//! model's error, the number of training trajectories and the sensor noise,
//! on the thesis situation's plant (Kinova's description of the arm plus
//! friction and armature).
//!
//! The analytical model of error size e is a torque-level blend of the
//! arm's exact rigid-body model and the thesis's model,
//! tau_e = tau_exact + e (tau_thesis - tau_exact): e = 0 is exact rigid-body
//! dynamics (missing only friction and armature), e = 1 the thesis's model,
//! e = 2 twice its error. Per noise level one pool of trajectories is
//! recorded; per cell and split the training and test trajectories are
//! drawn from it, and per seed three networks are trained: on measured data,
//! SDNN (measured plus the analytical model's torques on the same states,
//! 1:1, the thesis's recipe) and the hybrid (the analytical model plus a
//! network on its residual).

use serde::Serialize;

use super::*;

/// The grid and the training budget per network.
#[derive(Debug, Clone, Serialize)]
pub struct MapConfig {
    pub error_scales: Vec<f64>,
    pub train_counts: Vec<usize>,
    pub noise_scales: Vec<f64>,
    pub seeds: usize,
    pub splits: usize,
    /// Test trajectories per split.
    pub test: usize,
    /// Seconds per recorded trajectory.
    pub duration: f64,
    pub max_epochs: usize,
    pub hidden: Vec<usize>,
    /// Master seed of recordings, splits and networks.
    pub seed: u64,
}

impl Default for MapConfig {
    fn default() -> Self {
        MapConfig {
            error_scales: vec![0.0, 0.5, 1.0, 2.0],
            train_counts: vec![2, 5, 10, 20],
            noise_scales: vec![0.5, 1.0, 2.0],
            seeds: 5,
            splits: 3,
            test: 4,
            duration: 10.0,
            max_epochs: 15,
            hidden: vec![32, 32],
            seed: 1,
        }
    }
}

/// A mean and its standard deviation over seeds and splits.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Spread {
    pub mean: f64,
    pub std: f64,
}

impl Spread {
    fn of(values: &[f64]) -> Spread {
        let (mean, std) = mean_std(values);
        Spread { mean, std }
    }
}

/// One cell of the map: test MSEs (N m^2, mean over joints) and ratios,
/// each over every (split, seed) pair.
#[derive(Debug, Clone, Serialize)]
pub struct Cell {
    pub error_scale: f64,
    pub train: usize,
    pub noise_scale: f64,
    pub analytical: Spread,
    pub nn_measured: Spread,
    pub sdnn: Spread,
    pub hybrid: Spread,
    pub sdnn_over_analytical: Spread,
    pub sdnn_over_nn_measured: Spread,
    pub hybrid_over_analytical: Spread,
    /// The model with the lowest mean MSE.
    pub best: &'static str,
}

/// The models a cell compares, in `Cell` order.
pub const MAP_MODELS: [&str; 4] = ["analytical", "NN measured", "SDNN", "hybrid"];

/// Runs the map: `plant` records, `exact` is the arm's rigid-body model
/// (the controller's too), `thesis` the model whose error is scaled.
pub fn run_map(
    plant: &dyn Dynamics,
    exact: &dyn Dynamics,
    thesis: &dyn Dynamics,
    config: &MapConfig,
    progress: Progress<'_>,
) -> Result<Vec<Cell>> {
    let pool = config.train_counts.iter().max().copied().unwrap_or(0) + config.test;
    let study = StudyConfig {
        duration: config.duration,
        ..StudyConfig::default()
    };
    let waypoints = WaypointConfig {
        duration: config.duration,
        limits: limits(exact, &study)?,
        ..WaypointConfig::default()
    };
    let mut cells = Vec::new();
    let total = config.noise_scales.len() * config.error_scales.len() * config.train_counts.len();
    for &noise in &config.noise_scales {
        let recorded = parallel_map(pool, |k| {
            let seed = seeds::derive(config.seed, Purpose::Trajectory, k as u64);
            let recording = record_noisy(plant, exact, &waypoints, seed, noise)?;
            let processed = study.preprocess.apply(&recording.measured)?;
            let exact_torque = model_torques(exact, &processed)?;
            let thesis_torque = model_torques(thesis, &processed)?;
            Ok((processed, exact_torque, thesis_torque))
        })?;
        let grid: Vec<(f64, usize)> = config
            .error_scales
            .iter()
            .flat_map(|&e| config.train_counts.iter().map(move |&n| (e, n)))
            .collect();
        let done = cells.len();
        let computed = parallel_map(grid.len(), |i| {
            let (error, train) = grid[i];
            let cell = cell(&recorded, error, train, noise, config);
            progress(done + i + 1, total, "mapping");
            cell
        })?;
        cells.extend(computed);
    }
    Ok(cells)
}

/// A processed recording and the exact and thesis models' torques on it.
type Recorded = (Trajectory, DMatrix<f64>, DMatrix<f64>);

fn cell(
    recorded: &[Recorded],
    error: f64,
    train: usize,
    noise: f64,
    config: &MapConfig,
) -> Result<Cell> {
    let analytical_torque =
        |(_, exact, thesis): &Recorded| -> DMatrix<f64> { exact + (thesis - exact) * error };
    let mut runs: Vec<[f64; 4]> = Vec::new();
    for split in 0..config.splits {
        let mut order: Vec<usize> = (0..recorded.len()).collect();
        order.shuffle(&mut ChaCha8Rng::seed_from_u64(seeds::derive(
            config.seed,
            Purpose::Split,
            split as u64,
        )));
        let (training, testing) = (&order[..train], &order[train..train + config.test]);
        let mut measured = Vec::new();
        let mut analytical = Vec::new();
        let mut residual = Vec::new();
        for &k in training {
            let traj = &recorded[k].0;
            let model = analytical_torque(&recorded[k]);
            measured.push(Dataset::from_trajectory(traj, k)?);
            analytical.push(Dataset::from_trajectory(&traj.with_tau(model.clone())?, k)?);
            residual.push(Dataset::from_trajectory(
                &traj.with_tau(traj.tau() - model)?,
                k,
            )?);
        }
        let measured = Dataset::concat(&measured)?;
        let sdnn = Dataset::concat(&[measured.clone(), Dataset::concat(&analytical)?])?;
        let residual = Dataset::concat(&residual)?;
        let test: Vec<(&Trajectory, DMatrix<f64>)> = testing
            .iter()
            .map(|&k| (&recorded[k].0, analytical_torque(&recorded[k])))
            .collect();
        let mean = |pairs: &[(DMatrix<f64>, &Trajectory)]| {
            let mse = pooled_mse(pairs);
            mse.iter().sum::<f64>() / mse.len().max(1) as f64
        };
        let analytical_mse = mean(
            &test
                .iter()
                .map(|(t, a)| (a.clone(), *t))
                .collect::<Vec<_>>(),
        );
        for seed in 0..config.seeds {
            let network_seed = seeds::derive(
                config.seed,
                Purpose::Network,
                (split * config.seeds + seed) as u64,
            );
            let score = |data: &Dataset, add_model: bool| -> Result<f64> {
                let network = Mlp::params()
                    .hidden(config.hidden.clone())
                    .max_epochs(config.max_epochs)
                    .seed(network_seed)
                    .fit(data)?;
                let pairs = test
                    .iter()
                    .map(|(t, a)| {
                        let inputs = Dataset::from_trajectory(t, 0)?.inputs;
                        let mut predicted = network.predict(&inputs)?;
                        if add_model {
                            predicted += a;
                        }
                        Ok((predicted, *t))
                    })
                    .collect::<Result<Vec<_>>>()?;
                Ok(mean(&pairs))
            };
            runs.push([
                analytical_mse,
                score(&measured, false)?,
                score(&sdnn, false)?,
                score(&residual, true)?,
            ]);
        }
    }
    let column = |k: usize| -> Vec<f64> { runs.iter().map(|r| r[k]).collect() };
    let ratio = |a: usize, b: usize| -> Vec<f64> { runs.iter().map(|r| r[a] / r[b]).collect() };
    let spreads: Vec<Spread> = (0..4).map(|k| Spread::of(&column(k))).collect();
    let best = (0..4)
        .min_by(|&a, &b| spreads[a].mean.total_cmp(&spreads[b].mean))
        .map_or("-", |k| MAP_MODELS[k]);
    Ok(Cell {
        error_scale: error,
        train,
        noise_scale: noise,
        analytical: spreads[0],
        nn_measured: spreads[1],
        sdnn: spreads[2],
        hybrid: spreads[3],
        sdnn_over_analytical: Spread::of(&ratio(2, 0)),
        sdnn_over_nn_measured: Spread::of(&ratio(2, 1)),
        hybrid_over_analytical: Spread::of(&ratio(3, 0)),
        best,
    })
}
