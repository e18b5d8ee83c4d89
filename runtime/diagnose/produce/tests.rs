//! [`super::produce`]: the same rows whatever the batches, parts and
//! threads, each signal filtered alone then decimated.

use nalgebra::Vector3;

use super::*;
use crate::diagnose::band::Stage;
use crate::oracle::Model;

const SAMPLES: usize = 1200;
const DT: f64 = 1e-3;

/// The 3-DOF arm moving smoothly for 1.2 s at 1 kHz, its torque the
/// model's plus friction and a ripple the model lacks.
fn recording(model: &dyn Dynamics) -> Trajectory {
    let n = model.dof();
    let t: Vec<f64> = (0..SAMPLES).map(|s| s as f64 * DT).collect();
    let w = |j: usize| 2.0 + j as f64;
    let q = DMatrix::from_fn(SAMPLES, n, |s, j| 0.2 + 0.6 * (w(j) * t[s]).sin());
    let qd = DMatrix::from_fn(SAMPLES, n, |s, j| 0.6 * w(j) * (w(j) * t[s]).cos());
    let qdd = DMatrix::from_fn(SAMPLES, n, |s, j| -0.6 * w(j) * w(j) * (w(j) * t[s]).sin());
    let mut tau = DMatrix::zeros(SAMPLES, n);
    for s in 0..SAMPLES {
        let row = |m: &DMatrix<f64>| -> Vec<f64> { m.row(s).iter().copied().collect() };
        let rigid = model.tau(&row(&q), &row(&qd), &row(&qdd)).unwrap();
        for j in 0..n {
            let friction = 0.3 * qd[(s, j)] + 0.2 * qd[(s, j)].signum();
            tau[(s, j)] = rigid[j] + friction + 0.05 * (40.0 * t[s]).sin();
        }
    }
    Trajectory::new(t, q, qd, Some(qdd), tau).unwrap()
}

fn tilted(model: &dyn Dynamics) -> Tilted {
    let description = crate::dynamics::parsed_description(model).unwrap();
    Tilted {
        model: Model::from_description(&description),
        directions: [Vector3::x(), Vector3::y(), -Vector3::z()],
    }
}

/// `run` given the inputs of the 3-DOF arm's recording (a tilted base,
/// rest speed 0.05, unit levers) and the recording itself.
fn with_inputs<T>(run: impl FnOnce(&Inputs, &Trajectory) -> T) -> T {
    let model = crate::dynamics::model("kinova_gen3_lite_3dof").unwrap();
    let traj = recording(model);
    let tilted = tilted(model);
    let band = Band {
        qd: traj.qd().clone(),
        rest: vec![0.05; 3],
    };
    let levers = [1.0; 3];
    let inputs = Inputs {
        model,
        tilted: Some(&tilted),
        traj: Some(&traj),
        band: &band,
        levers: &levers,
    };
    run(&inputs, &traj)
}

/// Every signal of `stage`, produced with at most `budget` bytes of raw
/// columns at once.
fn produced(stage: Stage, budget: usize) -> Rows {
    with_inputs(|inputs, _| {
        let samples: Vec<usize> = (50..SAMPLES - 50).step_by(10).collect();
        let keep = Keep {
            cutoff_hz: Some(15.0),
            dt: DT,
            samples: &samples,
        };
        let mut rows = Rows::with_columns(3, (stage, &[0, 1, 2]));
        let signals = rows.signals();
        let bad = produce(
            &mut rows,
            &signals,
            inputs,
            &keep,
            (&mut Vec::new(), budget),
        );
        assert_eq!(bad.unwrap(), None);
        rows
    })
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

#[test]
fn batches_of_any_size_give_the_same_rows() {
    let column = SAMPLES * 3 * 8;
    for stage in [Stage::Motion, Stage::Reversals] {
        let mut whole = produced(stage, usize::MAX);
        for budget in [1, 7 * column] {
            let mut batched = produced(stage, budget);
            for signal in whole.signals() {
                let (a, b) = (whole.signal_mut(signal).clone(), batched.signal_mut(signal));
                assert_eq!(a.len(), 110 * 3, "{signal:?}");
                assert_eq!(bits(&a), bits(b), "{stage:?} {signal:?} at {budget} bytes");
            }
        }
    }
}

#[test]
fn any_number_of_parts_builds_the_same_columns() {
    with_inputs(|inputs, traj| {
        let derived = derived(inputs.model, traj).unwrap();
        for stage in [Stage::Motion, Stage::Reversals] {
            let signals = Rows::with_columns(3, (stage, &[0, 1, 2])).signals();
            let built = |count: usize, with: Option<&Derived>| {
                // Memory reused from a longer build must not show through
                // (it holds a different value for each count).
                let stale = count as f64 + 0.5;
                let mut columns = vec![vec![stale; 4 * SAMPLES * 3]; signals.len()];
                build_in_parts(&signals, &mut columns, (inputs, with), count).unwrap();
                columns.iter().map(|c| bits(c)).collect::<Vec<_>>()
            };
            for with in [Some(&derived), None] {
                let one = built(1, with);
                assert!(one.iter().any(|c| c.len() == SAMPLES * 3));
                for count in [2, 3, 7] {
                    assert_eq!(one, built(count, with), "{stage:?} in {count} parts");
                }
            }
        }
    })
}

#[test]
fn torques_in_parts_are_the_models_at_each_sample() {
    let model = crate::dynamics::model("kinova_gen3_lite_3dof").unwrap();
    let traj = recording(model);
    let predicted = crate::dynamics::model_torques(model, &traj).unwrap();
    for count in [1, 2, 5] {
        let [tau, load, effects] = torques(model, &traj, count).unwrap();
        assert_eq!(
            bits(tau.as_slice()),
            bits(predicted.as_slice()),
            "{count} parts"
        );
        for s in [0, 517, SAMPLES - 1] {
            let q: Vec<f64> = traj.q().row(s).iter().copied().collect();
            let qd: Vec<f64> = traj.qd().row(s).iter().copied().collect();
            let gravity = model.gravity(&q).unwrap();
            assert_eq!(
                bits(load.row(s).transpose().as_slice()),
                bits(gravity.as_slice())
            );
            let joint_effects = model.effects(&qd).unwrap();
            assert_eq!(
                bits(effects.row(s).transpose().as_slice()),
                bits(joint_effects.as_slice())
            );
        }
    }
}

/// A signal's raw value at a (sample, joint).
type Value<'a> = Box<dyn Fn(usize, usize) -> f64 + 'a>;

/// Joint `j`'s series of `value` (sample, joint), filtered alone by the
/// torque filter, at the kept samples; and those of `rows`' signal.
fn alone_and_kept(
    rows: &mut Rows,
    signal: Signal,
    j: usize,
    value: impl Fn(usize, usize) -> f64,
) -> (Vec<u64>, Vec<u64>) {
    let series: Vec<f64> = (0..SAMPLES).map(|s| value(s, j)).collect();
    let filtered = match signal.filtered() {
        true => ZeroPhaseLowPass::new(15.0, DT).unwrap().apply(&series),
        false => series,
    };
    let expected = (50..SAMPLES - 50).step_by(10).map(|s| filtered[s]);
    let kept = rows.signal_mut(signal).iter().skip(j).step_by(3).copied();
    (
        bits(&expected.collect::<Vec<_>>()),
        bits(&kept.collect::<Vec<_>>()),
    )
}

#[test]
fn kept_rows_are_each_signal_filtered_alone_then_decimated() {
    let model = crate::dynamics::model("kinova_gen3_lite_3dof").unwrap();
    let traj = recording(model);
    let predicted = crate::dynamics::model_torques(model, &traj).unwrap();
    let mut rows = produced(Stage::Reversals, 5 * SAMPLES * 3 * 8);
    let state = |s: usize, m: &DMatrix<f64>| -> Vec<f64> { m.row(s).iter().copied().collect() };
    let regressor = |s: usize, i: usize, k: usize| {
        let qdd = traj.qdd().unwrap();
        let y = model.regressor(&state(s, traj.q()), &state(s, traj.qd()), &state(s, qdd));
        y.unwrap()[(i, k)]
    };
    let v = stribeck_velocities()[9];
    for j in 0..3 {
        let checks: [(Signal, Value); 5] = [
            (
                Signal::Residual,
                Box::new(|s, i| traj.tau()[(s, i)] - predicted[(s, i)]),
            ),
            (Signal::Own(3), Box::new(|_, _| 1.0)),
            (Signal::Inertial(17), Box::new(|s, i| regressor(s, i, 17))),
            (Signal::Qd, Box::new(|s, i| traj.qd()[(s, i)])),
            (
                Signal::Stribeck(9),
                Box::new(|s, i| {
                    let qd = traj.qd()[(s, i)];
                    stribeck_shape(v, (moving_sign(qd, 0.05), qd), 1.0)
                }),
            ),
        ];
        for (signal, value) in checks {
            let (alone, kept) = alone_and_kept(&mut rows, signal, j, value);
            assert_eq!(alone, kept, "{signal:?} joint {}", j + 1);
        }
    }
}
