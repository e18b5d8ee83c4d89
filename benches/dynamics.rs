//! Generated dynamics against the numeric RNEA oracle, per call.
//! `cargo bench --bench dynamics`.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use sdnn::models::kinova_gen3_lite_3dof as kinova;
use sdnn::oracle::{self, Model};
use sdnn::sim::plant::Plant;

fn oracle_model(name: &str) -> Model {
    let path = format!("{}/models/{name}.toml", env!("CARGO_MANIFEST_DIR"));
    Model::from_description(&codegen::Description::load(path).expect("description"))
}

fn kinova_3dof(c: &mut Criterion) {
    let (q, qd, qdd) = ([0.3, -0.7, 1.1], [0.5, -0.2, 0.9], [1.5, -2.0, 0.4]);
    let model = oracle_model("kinova_gen3_lite_3dof");
    let mut group = c.benchmark_group("kinova_gen3_lite_3dof");
    group.bench_function("generated tau", |b| {
        b.iter(|| kinova::tau(black_box(&q), black_box(&qd), black_box(&qdd)))
    });
    group.bench_function("generated mass_matrix", |b| {
        b.iter(|| kinova::mass_matrix(black_box(&q)))
    });
    group.bench_function("generated regressor", |b| {
        b.iter(|| kinova::regressor(black_box(&q), black_box(&qd), black_box(&qdd)))
    });
    group.bench_function("generated sin_cos x2", |b| {
        b.iter(|| {
            (
                kinova::sin_cos(black_box(q[1])),
                kinova::sin_cos(black_box(q[2])),
            )
        })
    });
    group.bench_function("std sin_cos x2", |b| {
        b.iter(|| (black_box(q[1]).sin_cos(), black_box(q[2]).sin_cos()))
    });
    group.bench_function("oracle rnea", |b| {
        b.iter(|| {
            oracle::rnea(
                black_box(&model),
                black_box(&q),
                black_box(&qd),
                black_box(&qdd),
            )
        })
    });
    group.bench_function("oracle crba", |b| {
        b.iter(|| oracle::crba(black_box(&model), black_box(&q)))
    });
    group.finish();
}

/// A generated `tau` of an N-joint model.
type Tau<const N: usize> = fn(&[f64; N], &[f64; N], &[f64; N]) -> [f64; N];

/// Generated tau against the oracle RNEA for an N-joint model, at a fixed
/// generic state.
fn tau_against_rnea<const N: usize>(c: &mut Criterion, name: &str, tau: Tau<N>) {
    let state = |k: f64| std::array::from_fn::<f64, N, _>(|i| (0.37 * (i as f64 + k)).sin());
    let (q, qd, qdd) = (state(1.0), state(2.0), state(3.0));
    let model = oracle_model(name);
    let mut group = c.benchmark_group(name);
    group.bench_function("generated tau", |b| {
        b.iter(|| tau(black_box(&q), black_box(&qd), black_box(&qdd)))
    });
    group.bench_function("oracle rnea", |b| {
        b.iter(|| {
            oracle::rnea(
                black_box(&model),
                black_box(&q),
                black_box(&qd),
                black_box(&qdd),
            )
        })
    });
    group.finish();
}

fn six_and_seven_joints(c: &mut Criterion) {
    tau_against_rnea(c, "kinova_gen3_lite", sdnn::models::kinova_gen3_lite::tau);
    tau_against_rnea(c, "panda", sdnn::models::panda::tau);
}

/// 4,096 random Panda states (uniform in +-pi, +-3 rad/s, +-10 rad/s^2 and
/// +-20 N m), as the Pinocchio figures in docs/generated-code.md use.
fn panda_states() -> Vec<[[f64; 7]; 4]> {
    let mut seed = 5u64;
    let mut draw = |scale: f64| {
        std::array::from_fn(|_| {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            scale * ((seed >> 11) as f64 / (1u64 << 52) as f64 - 1.0)
        })
    };
    (0..4096)
        .map(|_| {
            [
                draw(std::f64::consts::PI),
                draw(3.0),
                draw(10.0),
                draw(20.0),
            ]
        })
        .collect()
}

/// Every generated function of the Panda on the same 4,096 states, per
/// call (criterion reports the time of the whole set: divide by 4,096),
/// beside the oracle's RNEA and CRBA.
fn panda_functions(c: &mut Criterion) {
    use sdnn::models::panda as arm;
    let states = panda_states();
    let model = oracle_model("panda");
    let mut group = c.benchmark_group("panda x4096");
    group.throughput(criterion::Throughput::Elements(states.len() as u64));
    let mut each = |name: &str, f: &dyn Fn(&[[f64; 7]; 4]) -> f64| {
        group.bench_function(name, |b| {
            b.iter(|| {
                for state in black_box(&states) {
                    black_box(f(state));
                }
            })
        });
    };
    each("generated tau", &|[q, qd, qdd, _]| arm::tau(q, qd, qdd)[0]);
    each("generated mass_matrix", &|[q, ..]| {
        arm::mass_matrix(q)[0][0]
    });
    each("generated forward_dynamics", &|[q, qd, _, tau]| {
        arm::forward_dynamics(q, qd, tau)[0]
    });
    each("generated tau_derivatives", &|[q, qd, qdd, _]| {
        black_box(arm::tau_derivatives(q, qd, qdd)).0[0][0]
    });
    each("generated forward_dynamics_derivatives", &|[
        q,
        qd,
        _,
        tau,
    ]| {
        black_box(arm::forward_dynamics_derivatives(q, qd, tau)).0[0][0]
    });
    each("generated tip_pose + tip_jacobian", &|[q, ..]| {
        arm::tip_pose(q).position[0] + arm::tip_jacobian(q)[0][0]
    });
    each("generated tip_pose_and_jacobian", &|[q, ..]| {
        let (pose, jacobian) = arm::tip_pose_and_jacobian(q);
        pose.position[0] + jacobian[0][0]
    });
    each("oracle rnea", &|[q, qd, qdd, _]| {
        oracle::rnea(&model, q, qd, qdd)[0]
    });
    each("oracle crba", &|[q, ..]| oracle::crba(&model, q)[(0, 0)]);
    each("generated regressor", &|[q, qd, qdd, _]| {
        arm::regressor(q, qd, qdd)[0][0]
    });
    each("oracle regressor", &|[q, qd, qdd, _]| {
        oracle::regressor(&model, q, qd, qdd)[(0, 0)]
    });
    each("oracle forward dynamics (crba, rnea, Cholesky)", &|[
        q,
        qd,
        _,
        tau,
    ]| {
        oracle::forward_dynamics(&model, q, qd, tau).map_or(0.0, |x| x[0])
    });
    each("oracle placements", &|[q, ..]| {
        oracle::placements(&model, q)[6].1.x
    });
    group.finish();
}

/// A compiled model integrated through the mass matrix and the bias (a
/// Cholesky solve per RK4 stage): the virtual robot before issue 23.
struct ThroughMassMatrix<'a>(sdnn::sim::models::Compiled<'a>);

impl Plant for ThroughMassMatrix<'_> {
    fn dof(&self) -> usize {
        self.0.dof()
    }
    fn mass_matrix(&self, q: &[f64]) -> nalgebra::DMatrix<f64> {
        self.0.mass_matrix(q)
    }
    fn bias(&self, q: &[f64], qd: &[f64]) -> nalgebra::DVector<f64> {
        self.0.bias(q, qd)
    }
}

/// The virtual robot recording 5 s at 1 kHz on the default 3-DOF plant and
/// on the Panda: the generated forward dynamics against the Cholesky path,
/// same trajectory, same run.
fn virtual_robot(c: &mut Criterion) {
    use sdnn::sim::models::Compiled;
    use sdnn::sim::reference::{JointLimits, WaypointConfig, WaypointTrajectory};
    use sdnn::sim::simulate::{NoiseConfig, SimConfig, simulate};
    let mut group = c.benchmark_group("virtual robot, 5 s at 1 kHz");
    group.sample_size(10);
    for name in ["kinova_gen3_lite_3dof_plant", "panda"] {
        let model = sdnn::model(name).expect("compiled model");
        let reference = WaypointTrajectory::new(
            &WaypointConfig {
                duration: 5.0,
                limits: JointLimits::uniform(model.dof(), (-1.5, 1.5), 0.8, 2.0),
                ..Default::default()
            },
            1,
        )
        .expect("reference");
        let config = SimConfig {
            noise: NoiseConfig::none(),
            ..Default::default()
        };
        let generated = Compiled(model);
        let cholesky = ThroughMassMatrix(Compiled(model));
        group.bench_function(format!("{name}, generated forward dynamics"), |b| {
            b.iter(|| simulate(&generated, &generated, &reference, &config, 1).expect("runs"))
        });
        group.bench_function(format!("{name}, mass matrix + Cholesky"), |b| {
            b.iter(|| simulate(&cholesky, &generated, &reference, &config, 1).expect("runs"))
        });
    }
    group.finish();
}

criterion_group!(
    benches,
    kinova_3dof,
    six_and_seven_joints,
    panda_functions,
    virtual_robot
);
criterion_main!(benches);
