//! Diagnosis of 14 trajectories of 20 s at 1 kHz (preprocessed to 100 Hz):
//! `cargo bench --bench diagnose`.

use criterion::{Criterion, criterion_group, criterion_main};
use sdnn::diagnose::{Settings, diagnose};
use sdnn::sim::reference::WaypointConfig;
use sdnn::study::{self, StudyConfig};

fn bench(c: &mut Criterion) {
    let plant = sdnn::model("kinova_gen3_lite_3dof_plant").expect("plant");
    let nominal = sdnn::model("kinova_gen3_lite_3dof").expect("nominal");
    let config = StudyConfig::default();
    let waypoints = WaypointConfig {
        limits: study::limits(nominal, &config).expect("limits"),
        ..WaypointConfig::default()
    };
    let trajectories: Vec<_> = (0..14)
        .map(|seed| {
            let recording =
                study::record_trajectory(plant, nominal, &waypoints, seed).expect("simulation");
            config
                .preprocess
                .apply(&recording.measured)
                .expect("preprocess")
        })
        .collect();
    let mut group = c.benchmark_group("diagnose");
    group.sample_size(10);
    group.bench_function("14 trajectories x 20 s", |b| {
        b.iter(|| diagnose(nominal, &trajectories, Settings::default()).expect("diagnosis"))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
