//! Diagnosis of 3 raw recordings of 20 s at 1 kHz at the defaults (the
//! preprocessing chosen from the data, filtering, parallel filtering of
//! every column, selection), and the design of the recording that comes
//! before it (`sdnn excite` on the Panda, 20 s, defaults):
//! `cargo bench --bench diagnose`.

use criterion::{Criterion, criterion_group, criterion_main};
use sdnn::Dynamics;
use sdnn::diagnose::{Settings, diagnose};
use sdnn::preprocess::Pipeline;
use sdnn::sim::reference::WaypointConfig;
use sdnn::study::{self, StudyConfig};
use sdnn::trajectory::Trajectory;

/// Three recordings of 20 s at 1 kHz: `plant` simulated, tracking the
/// default waypoints within `nominal`'s limits (seeds 0-2).
fn recordings(plant: &dyn Dynamics, nominal: &dyn Dynamics) -> Vec<Trajectory> {
    let waypoints = WaypointConfig {
        limits: study::limits(nominal, &StudyConfig::default()).expect("limits"),
        ..WaypointConfig::default()
    };
    (0..3)
        .map(|seed| {
            study::record_trajectory(plant, nominal, &waypoints, seed)
                .expect("simulation")
                .measured
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let plant = sdnn::model("kinova_gen3_lite_3dof_plant").expect("plant");
    let nominal = sdnn::model("kinova_gen3_lite_3dof").expect("nominal");
    let recordings = recordings(plant, nominal);
    let mut group = c.benchmark_group("diagnose");
    group.sample_size(10);
    group.bench_function("3 recordings x 20 s at 1 kHz", |b| {
        b.iter(|| {
            let pipeline = Pipeline::auto(&recordings, None, None).expect("pipeline");
            diagnose(nominal, &recordings, &pipeline, Settings::default()).expect("diagnosis")
        })
    });
    group.finish();
}

/// The Panda diagnosed from 3 recordings of 20 s at 1 kHz (the compiled
/// model simulated, no effect hidden) with the model compiled and with
/// the same model read from its TOML file (the numeric dynamics, as for
/// an imported URDF): the same recordings, the same run.
fn panda(c: &mut Criterion) {
    let compiled = sdnn::model("panda").expect("panda");
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/panda.toml");
    let described = sdnn::described::Described::load(&path).expect("panda.toml");
    let recordings = recordings(compiled, compiled);
    let pipeline = Pipeline::auto(&recordings, None, None).expect("pipeline");
    let mut group = c.benchmark_group("diagnose panda, 3 recordings x 20 s at 1 kHz");
    group.sample_size(10);
    group.bench_function("compiled model", |b| {
        b.iter(|| {
            diagnose(compiled, &recordings, &pipeline, Settings::default()).expect("diagnosis")
        })
    });
    group.bench_function("model from its TOML", |b| {
        b.iter(|| {
            diagnose(described, &recordings, &pipeline, Settings::default()).expect("diagnosis")
        })
    });
    group.finish();
}

/// `sdnn excite --model panda --duration 20` without the files: the
/// design and its comparison with one default recording.
fn excite(c: &mut Criterion) {
    use sdnn::excite::{Config, design, fourier::Bounds};
    use sdnn::sim::reference::{Reference, WaypointTrajectory};
    let model = sdnn::model("panda").expect("panda");
    let config = StudyConfig::default();
    let limits = study::limits(model, &config).expect("limits");
    let dof = model.dof();
    let description = sdnn::dynamics::parsed_description(model).expect("description");
    let bounds = Bounds {
        position: (0..dof)
            .map(|j| {
                let (lo, hi) = limits.position[j];
                let m = limits.margin(j, 0.1);
                (lo + m, hi - m)
            })
            .collect(),
        velocity: limits.velocity.clone(),
        acceleration: limits.acceleration.clone(),
        effort: description
            .chain()
            .free_bodies()
            .map(|b| b.limits.and_then(|l| l.effort))
            .collect(),
    };
    let waypoints = WaypointConfig {
        limits,
        ..WaypointConfig::default()
    };
    let reference = WaypointTrajectory::new(&waypoints, 1).expect("reference");
    let default = |t: f64| {
        let (q, qd, qdd) = reference.sample(t);
        (
            q.as_slice().to_vec(),
            qd.as_slice().to_vec(),
            qdd.as_slice().to_vec(),
        )
    };
    let levers = vec![1.0; dof];
    let mut group = c.benchmark_group("excite");
    group.sample_size(10);
    group.bench_function("panda, 20 s, defaults", |b| {
        b.iter(|| {
            design(
                model,
                &bounds,
                &levers,
                &Config::new(20.0, dof),
                &[&default],
                &[],
            )
            .expect("design")
        })
    });
    group.finish();
}

criterion_group!(benches, bench, panda, excite);
criterion_main!(benches);
