//! The bias of the diagnosed Coulomb and viscous friction: random 3-DOF
//! plants (the coverage study's draws: viscous 0.05-0.6, Coulomb 0.05-0.7
//! on every joint, an armature on half), simulated and diagnosed at the
//! defaults; prints each joint's truth and fit, then the mean relative
//! error. `cargo run --release --example coulomb_bias`, with the
//! environment: SEEDS (how many, 10), FIRST (1), NOISE (a factor on the
//! default sensor noise, 0 for none), ARMATURE (0: none), LAW (`sign`, the
//! virtual robot's c sign(qd) that sticks at reversals, or `tanh`, a
//! smooth c tanh(qd / 0.01 rad/s)), RECS (recordings, 3), DECIMATE (keep
//! every n-th sample, 1).

use nalgebra::{DMatrix, DVector};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sdnn::diagnose::{Kind, Settings, diagnose};
use sdnn::oracle::Model;
use sdnn::preprocess::{Pipeline, downsample};
use sdnn::sim::models::Compiled;
use sdnn::sim::plant::Plant;
use sdnn::sim::reference::{WaypointConfig, WaypointTrajectory};
use sdnn::sim::simulate::{SimConfig, simulate};
use sdnn::study::{self, StudyConfig};

/// The oracle plant with Coulomb friction through c tanh(qd / 0.01).
struct Smooth(Model, Vec<f64>);

impl Plant for Smooth {
    fn dof(&self) -> usize {
        self.0.dof()
    }
    fn mass_matrix(&self, q: &[f64]) -> DMatrix<f64> {
        self.0.mass_matrix(q)
    }
    fn bias(&self, q: &[f64], qd: &[f64]) -> DVector<f64> {
        let mut b = self.0.bias(q, qd);
        for (j, c) in self.1.iter().enumerate() {
            b[j] += c * (qd[j] / 0.01).tanh();
        }
        b
    }
}

fn env(name: &str, default: f64) -> f64 {
    std::env::var(name)
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(default)
}

fn main() {
    let name = "kinova_gen3_lite_3dof";
    let seeds = env("SEEDS", 10.0) as u64;
    let first = env("FIRST", 1.0) as u64;
    let noise = env("NOISE", 1.0);
    let armature = env("ARMATURE", 1.0);
    let recs = env("RECS", 3.0) as u64;
    let decimate = env("DECIMATE", 1.0) as usize;
    let tanh = std::env::var("LAW").is_ok_and(|l| l == "tanh");
    let nominal = sdnn::model(name).unwrap();
    let path = format!("{}/models/{name}.toml", env!("CARGO_MANIFEST_DIR"));
    let description = codegen::Description::load(std::path::Path::new(&path)).unwrap();
    let (mut dc, mut dv, mut above, mut n) = (0.0, 0.0, 0, 0);
    for seed in first..first + seeds {
        let mut rng = ChaCha8Rng::seed_from_u64(1000 + seed);
        let mut truth = Model::from_description(&description);
        let mut levels = Vec::new();
        for body in truth.bodies.iter_mut() {
            body.effects.viscous = env("VISCOUS", 1.0) * rng.random_range(0.05..0.6);
            body.effects.coulomb = rng.random_range(0.05..0.7);
            let a = rng.random_range(0.005..0.05);
            if rng.random_bool(0.5) {
                body.effects.armature = armature * a;
            }
            levels.push(body.effects.coulomb);
        }
        let plant: Box<dyn Plant> = if tanh {
            let mut frictionless = truth.clone();
            for b in frictionless.bodies.iter_mut() {
                b.effects.coulomb = 0.0;
            }
            Box::new(Smooth(frictionless, levels.clone()))
        } else {
            Box::new(truth.clone())
        };
        let waypoints = WaypointConfig {
            limits: study::limits(nominal, &StudyConfig::default()).unwrap(),
            ..WaypointConfig::default()
        };
        let mut config = SimConfig::default();
        config.noise.torque_sigma *= noise;
        config.noise.velocity_sigma *= noise;
        config.noise.angle_sigma *= noise;
        let recordings: Vec<_> = (0..recs)
            .map(|k| {
                let s = 100 * seed + k;
                let reference = WaypointTrajectory::new(&waypoints, s).unwrap();
                let m = simulate(plant.as_ref(), &Compiled(nominal), &reference, &config, s)
                    .unwrap()
                    .measured;
                downsample(&m, decimate).unwrap()
            })
            .collect();
        let pipeline = Pipeline::auto(&recordings, None, None).unwrap();
        let d = match diagnose(nominal, &recordings, &pipeline, Settings::default()) {
            Ok(d) => d,
            Err(e) => {
                println!("seed {seed}: {e}");
                continue;
            }
        };
        for (j, body) in truth.bodies.iter().enumerate() {
            let get = |kind: Kind, p: &str| {
                d.effects
                    .iter()
                    .chain(&d.supported)
                    .find(|e| e.kind == kind && e.joint == Some(j + 1))
                    .and_then(|e| e.parameters.get(p)?.as_f64())
            };
            let c = get(Kind::CoulombFriction, "level");
            let v = get(Kind::ViscousFriction, "coefficient");
            let e = &body.effects;
            println!(
                "seed {seed} j{} coulomb {:.3} -> {:?} viscous {:.3} -> {:?} armature {:.3}",
                j + 1,
                e.coulomb,
                c.map(|x| (x * 1000.0).round() / 1000.0),
                e.viscous,
                v.map(|x| (x * 1000.0).round() / 1000.0),
                e.armature
            );
            if let (Some(c), Some(v)) = (c, v.or(Some(0.0))) {
                dc += c / e.coulomb - 1.0;
                dv += if e.viscous > 0.0 {
                    v / e.viscous - 1.0
                } else {
                    0.0
                };
                above += usize::from(c > e.coulomb);
                n += 1;
            }
        }
    }
    let m = n.max(1) as f64;
    println!(
        "joints {n}: coulomb mean rel error {:+.1}% ({above} above), viscous {:+.1}%",
        100.0 * dc / m,
        100.0 * dv / m
    );
}
