//! Diagnosis of 3 raw recordings of 20 s at 1 kHz at the defaults (the
//! preprocessing chosen from the data, filtering, parallel filtering of
//! every column, selection): `cargo bench --bench diagnose`.

use criterion::{Criterion, criterion_group, criterion_main};
use sdnn::diagnose::{Settings, diagnose};
use sdnn::preprocess::Pipeline;
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
    let recordings: Vec<_> = (0..3)
        .map(|seed| {
            study::record_trajectory(plant, nominal, &waypoints, seed)
                .expect("simulation")
                .measured
        })
        .collect();
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

criterion_group!(benches, bench);
criterion_main!(benches);
