//! MLP training throughput (samples per second = 20,000 / time per
//! epoch): the study's default network (9-32-32-3), and 9-64-64-3 at batch
//! 256, the network PyTorch's figure in docs/verification.md was measured
//! on. `cargo bench --bench training`.

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::DMatrix;
use sdnn::mlp::{Dataset, Mlp};
use sdnn::study::StudyConfig;

fn training(c: &mut Criterion) {
    let samples = 20_000;
    let inputs = DMatrix::from_fn(samples, 9, |r, j| {
        ((r * 7 + j * 13) % 101) as f64 / 50.0 - 1.0
    });
    let targets = DMatrix::from_fn(samples, 3, |r, j| {
        (inputs[(r, j)] * 3.0).sin() + inputs[(r, j + 3)]
    });
    let data = Dataset::new(inputs, targets, None).expect("dataset");
    let defaults = StudyConfig::default();
    let mut group = c.benchmark_group("mlp");
    group.throughput(Throughput::Elements(samples as u64));
    group.sample_size(10);
    for (name, hidden, batch) in [
        (
            "one epoch, default study network",
            &defaults.hidden,
            defaults.batch_size,
        ),
        (
            "one epoch, default study network, batch 256",
            &defaults.hidden,
            256,
        ),
        ("one epoch, 9-64-64-3, batch 256", &vec![64, 64], 256),
    ] {
        group.bench_function(name, |b| {
            b.iter(|| {
                Mlp::params()
                    .hidden(hidden.clone())
                    .batch_size(batch)
                    .learning_rate(defaults.learning_rate)
                    .max_epochs(1)
                    .validation_fraction(0.0)
                    .patience(None)
                    .fit(black_box(&data))
                    .expect("training")
            })
        });
    }
    group.finish();
}

criterion_group!(benches, training);
criterion_main!(benches);
