//! Loading (parsing, validating, reducing) a description of a long serial
//! chain: linear in the joints (it was cubic: 1,000 joints 0.9 s, 4,000
//! joints 52 s): `cargo bench --bench loading`.

use std::path::Path;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};

/// A serial chain of `n` revolute joints.
fn chain(n: usize) -> String {
    let mut text = String::from("[[links]]\nname = \"l0\"\n");
    for i in 1..=n {
        text.push_str(&format!(
            "[[links]]\nname = \"l{i}\"\nmass = 0.1\ncom = [0.01, 0.0, 0.0]\n\
             inertia = {{ ixx = 0.001, iyy = 0.001, izz = 0.001 }}\n"
        ));
    }
    for i in 1..=n {
        text.push_str(&format!(
            "[[joints]]\nname = \"j{i}\"\ntype = \"revolute\"\nparent = \"l{}\"\nchild = \"l{i}\"\n\
             origin = {{ xyz = [0.01, 0.0, 0.0] }}\naxis = [0.0, 0.0, 1.0]\n",
            i - 1
        ));
    }
    text
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("load description");
    group.sample_size(10);
    for n in [1_000, 4_000] {
        let text = chain(n);
        group.bench_with_input(BenchmarkId::new("serial chain", n), &text, |b, text| {
            b.iter(|| codegen::Description::parse(text, "chain", Path::new("chain.toml")).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
