use super::*;
use crate::sim::plant::test_plants::{Pendulum, TwoLink};
use crate::sim::reference::{
    ExcitationConfig, ExcitationTrajectory, JointLimits, WaypointConfig, WaypointTrajectory,
};

fn two_link_waypoints(seed: u64) -> WaypointTrajectory {
    let cfg = WaypointConfig {
        limits: JointLimits::uniform(2, (-2.5, 2.5), 1.0, 2.0),
        ..Default::default()
    };
    WaypointTrajectory::new(&cfg, seed).unwrap()
}

fn quiet() -> SimConfig {
    SimConfig {
        noise: NoiseConfig::none(),
        ..Default::default()
    }
}

fn rms(m: &DMatrix<f64>) -> f64 {
    (m.norm_squared() / m.len() as f64).sqrt()
}

/// Relative drift of total energy of the free double pendulum over 20 s.
fn energy_drift(h: f64) -> f64 {
    let arm = TwoLink::new();
    let (mut q, mut qd) = (DVector::from_vec(vec![0.3, 0.8]), DVector::zeros(2));
    let tau = DVector::zeros(2);
    let e0 = arm.energy(q.as_slice(), qd.as_slice());
    let scale = e0.abs().max(
        arm.energy(&[-std::f64::consts::FRAC_PI_2, 0.0], &[0.0; 2])
            .abs(),
    );
    let mut worst: f64 = 0.0;
    let mut rk4 = Rk4::new(2);
    for _ in 0..(20.0 / h).round() as usize {
        rk4.step(&arm, q.as_mut_slice(), qd.as_mut_slice(), tau.as_slice(), h)
            .unwrap();
        worst = worst.max((arm.energy(q.as_slice(), qd.as_slice()) - e0).abs());
    }
    worst / scale
}

#[test]
fn rk4_conserves_energy_of_free_double_pendulum() {
    let drift = energy_drift(1e-3);
    eprintln!("max relative energy drift over 20 s at 1 ms: {drift:e}");
    // Measured 1.65e-8.
    assert!(drift < 3e-8, "drift {drift:e}");
    // Fourth order: halving the step shrinks the drift about 16-fold.
    let coarse = energy_drift(2e-3);
    eprintln!("at 2 ms: {coarse:e}");
    assert!(coarse > 8.0 * drift);
}

#[test]
fn perfect_model_without_noise_tracks_closely() {
    let arm = TwoLink::new().with_friction(0.05, 0.0);
    let rec = simulate(&arm, &arm, &two_link_waypoints(1), &quiet(), 0).unwrap();
    assert_eq!(rec.truth.len(), 20_001);
    // Residual from the zero-order hold (half-period delay), measured 3.5e-4.
    let err = (rec.truth.q() - rec.reference.q()).amax();
    assert!(err < 1e-3, "tracking error {err:e}");
    assert_eq!(rec.measured.q(), rec.truth.q());
    assert!(rec.measured.qdd().is_none());
}

#[test]
fn coulomb_friction_sticks_briefly_at_reversals() {
    let arm = TwoLink::new().with_friction(0.05, 0.1);
    let rec = simulate(&arm, &arm, &two_link_waypoints(1), &quiet(), 0).unwrap();
    // Compensation follows sign(qd) at the sample, so a reversal can stick
    // for tens of ms until the PD term pushes through (measured 6.7e-3).
    let err = (rec.truth.q() - rec.reference.q()).amax();
    assert!(err > 1e-3 && err < 2e-2, "tracking error {err:e}");
}

#[test]
fn perfect_model_tracks_excitation() {
    let arm = TwoLink::new();
    let cfg = ExcitationConfig {
        limits: JointLimits::uniform(2, (-2.5, 2.5), 1.0, 2.0),
        ..Default::default()
    };
    let reference = ExcitationTrajectory::new(&cfg, 4).unwrap();
    let rec = simulate(&arm, &arm, &reference, &quiet(), 0).unwrap();
    assert!((rec.truth.q() - rec.reference.q()).amax() < 1e-3);
}

#[test]
fn heavier_plant_shows_in_recorded_torque() {
    let nominal = TwoLink::new();
    let plant = TwoLink::new().heavier(1.5);
    let rec = simulate(
        &plant,
        &nominal,
        &two_link_waypoints(2),
        &SimConfig::default(),
        9,
    )
    .unwrap();
    let mismatch = rms(&(rec.truth.tau() - rec.reference.tau()));
    let recorded = rms(&(rec.measured.tau() - rec.reference.tau()));
    assert!(mismatch > 0.5, "applied vs nominal torque rms {mismatch}");
    assert!(recorded > 0.5, "recorded vs nominal torque rms {recorded}");
    // Feedback still holds the heavier arm near the plan.
    // (Steady error ~ gravity mismatch / (M Kp), about 0.2 rad here.)
    assert!((rec.truth.q() - rec.reference.q()).amax() < 0.3);
}

#[test]
fn truth_satisfies_plant_dynamics() {
    let plant = TwoLink::new().heavier(1.3).with_friction(0.1, 0.2);
    let rec = simulate(
        &plant,
        &TwoLink::new(),
        &two_link_waypoints(3),
        &SimConfig::default(),
        1,
    )
    .unwrap();
    let qdd = rec.truth.qdd().unwrap();
    for k in (0..rec.truth.len()).step_by(997) {
        let row = |m: &DMatrix<f64>| m.row(k).iter().copied().collect::<Vec<_>>();
        let tau =
            inverse_dynamics(&plant, &row(rec.truth.q()), &row(rec.truth.qd()), &row(qdd)).unwrap();
        assert!((tau.transpose() - rec.truth.tau().row(k)).amax() < 1e-9);
    }
}

#[test]
fn same_seed_same_recording() {
    let arm = TwoLink::new();
    let reference = two_link_waypoints(5);
    let cfg = SimConfig::default();
    let a = simulate(&arm, &arm, &reference, &cfg, 42).unwrap();
    assert_eq!(a, simulate(&arm, &arm, &reference, &cfg, 42).unwrap());
    let b = simulate(&arm, &arm, &reference, &cfg, 43).unwrap();
    assert_ne!(a.measured, b.measured);
}

#[test]
fn measured_velocity_is_visibly_noisy() {
    let arm = TwoLink::new();
    let rec = simulate(&arm, &arm, &two_link_waypoints(6), &SimConfig::default(), 3).unwrap();
    let noise = rms(&(rec.measured.qd() - rec.truth.qd()));
    assert!((noise - 0.02).abs() < 0.002, "velocity noise rms {noise}");
    let tau_noise = rms(&(rec.measured.tau() - rec.truth.tau()));
    assert!(
        (tau_noise - 0.05).abs() < 0.005,
        "torque noise rms {tau_noise}"
    );
    assert!(rms(&(rec.measured.q() - rec.truth.q())) < 2e-5);
}

#[test]
fn torque_scale_error_and_quantization() {
    let arm = TwoLink::new();
    let mut cfg = quiet();
    cfg.noise.torque_scale_sigma = 0.1;
    cfg.noise.angle_resolution = Some(1e-3);
    let rec = simulate(&arm, &arm, &two_link_waypoints(7), &cfg, 8).unwrap();
    let ratio = rec.measured.tau()[(100, 0)] / rec.truth.tau()[(100, 0)];
    let ratio_late = rec.measured.tau()[(9000, 0)] / rec.truth.tau()[(9000, 0)];
    assert!((ratio - ratio_late).abs() < 1e-9 && (ratio - 1.0).abs() > 1e-6);
    let q = rec.measured.q()[(123, 1)];
    assert!(((q / 1e-3).round() * 1e-3 - q).abs() < 1e-12);
}

#[test]
fn effort_limit_saturates_torque() {
    let arm = TwoLink::new();
    let mut cfg = quiet();
    cfg.controller.effort_limit = Some(vec![1.0]);
    match simulate(&arm, &arm, &two_link_waypoints(8), &cfg, 0) {
        Ok(rec) => assert!(rec.truth.tau().amax() <= 1.0),
        Err(SimError::Diverged { .. }) => {}
        Err(e) => panic!("unexpected error {e}"),
    }
}

/// Waypoints of one joint within +-1 rad, at most 1 rad/s and 1 rad/s^2.
fn one_joint_waypoints() -> WaypointTrajectory {
    let limits = JointLimits::uniform(1, (-1.0, 1.0), 1.0, 1.0);
    WaypointTrajectory::new(
        &WaypointConfig {
            limits,
            ..Default::default()
        },
        0,
    )
    .unwrap()
}

#[test]
fn divergence_reports_time() {
    // A pendulum with negative damping gains energy until it trips the bound.
    let plant = Pendulum {
        mass: 1.0,
        length: 0.5,
        viscous: -2.0,
    };
    let reference = one_joint_waypoints();
    let mut cfg = quiet();
    cfg.controller.kp = vec![0.0];
    cfg.controller.kd = vec![0.0];
    cfg.controller.effort_limit = Some(vec![1e-9]);
    cfg.divergence_velocity = 5.0;
    let err = simulate(&plant, &plant, &reference, &cfg, 0).unwrap_err();
    let SimError::Diverged {
        time, joint: 0, qd, ..
    } = err
    else {
        panic!("{err}")
    };
    assert!(time > 0.0 && time < 20.0 && qd.abs() > 5.0);
    assert!(err.to_string().contains("diverged at t ="));
}

/// A light link with strong viscous friction (1e-4 kg m^2, 2 N m s/rad:
/// an imported wrist) decays at 20,000 1/s, beyond RK4's bound at one step
/// per millisecond, where the run diverged: it now takes the steps it
/// needs. It tracks loosely (a torque held for 1 ms moves a joint whose
/// friction settles it in 50 us only I / (b dt) = 5% of the commanded
/// acceleration), as a real drive would without rotor inertia.
#[test]
fn a_stiff_plant_is_integrated_in_enough_steps() {
    let plant = Pendulum {
        mass: 0.01,
        length: 0.1,
        viscous: 2.0,
    };
    let q = DVector::from_element(1, 0.3);
    assert_eq!(stable_substeps(&plant, &q, 1e-3).unwrap(), 20);
    let reference = one_joint_waypoints();
    let rec = simulate(&plant, &plant, &reference, &quiet(), 0).unwrap();
    let error = rec.truth.q() - rec.reference.q();
    assert!(error.amax() < 0.5, "tracking error {}", error.amax());
    let (joint, worst, time) = rec.worst_tracking().unwrap();
    assert_eq!((joint, worst), (0, error.amax()));
    assert!(time > 0.0 && time <= *rec.truth.t().last().unwrap());
    assert!(rec.truth.qd().amax() < 2.0);
}

#[test]
fn bad_inputs_are_errors() {
    let arm = TwoLink::new();
    let pendulum = Pendulum {
        mass: 1.0,
        length: 1.0,
        viscous: 0.0,
    };
    let reference = two_link_waypoints(0);
    let err = simulate(&arm, &pendulum, &reference, &quiet(), 0).unwrap_err();
    assert!(matches!(
        err,
        SimError::DofMismatch {
            what: "nominal model",
            ..
        }
    ));
    let mut cfg = quiet();
    cfg.controller.kp = vec![1.0, 2.0, 3.0];
    assert!(matches!(
        simulate(&arm, &arm, &reference, &cfg, 0),
        Err(SimError::DofMismatch { what: "kp", .. })
    ));
    let cfg = SimConfig {
        control_dt: 0.0,
        ..quiet()
    };
    assert!(matches!(
        simulate(&arm, &arm, &reference, &cfg, 0),
        Err(SimError::Config { .. })
    ));
    let cfg = SimConfig {
        control_dt: 1e-12,
        ..quiet()
    };
    assert!(matches!(
        simulate(&arm, &arm, &reference, &cfg, 0),
        Err(SimError::Config { .. })
    ));
    let cfg = SimConfig {
        substeps: 0,
        ..quiet()
    };
    assert!(simulate(&arm, &arm, &reference, &cfg, 0).is_err());
    let mut cfg = quiet();
    cfg.noise.velocity_sigma = -1.0;
    assert!(simulate(&arm, &arm, &reference, &cfg, 0).is_err());
    let torques = DMatrix::zeros(10, 3);
    assert!(open_loop(&arm, &[0.0; 2], &[0.0; 2], &torques, 1e-3).is_err());
    assert!(open_loop(&arm, &[0.0; 2], &[0.0; 2], &DMatrix::zeros(10, 2), f64::NAN).is_err());
}

#[test]
fn config_defaults_fill_missing_fields() {
    use serde::de::value::{Error, MapDeserializer};
    let empty: Vec<(&str, f64)> = Vec::new();
    let cfg = SimConfig::deserialize(MapDeserializer::<_, Error>::new(empty.into_iter())).unwrap();
    assert_eq!(cfg, SimConfig::default());
    assert_eq!(cfg.controller.kp, vec![100.0]);
}

#[test]
fn controller_is_computed_torque_plus_pd() {
    let arm = TwoLink::new();
    let cfg = ControllerConfig {
        kp: vec![4.0, 9.0],
        kd: vec![1.0],
        effort_limit: None,
    };
    let ctrl = Controller::new(&arm, &cfg).unwrap();
    let (q, qd) = (
        DVector::from_vec(vec![0.1, 0.2]),
        DVector::from_vec(vec![0.3, -0.1]),
    );
    let (qr, qdr, qddr) = (
        DVector::from_vec(vec![0.2, 0.0]),
        DVector::zeros(2),
        DVector::from_vec(vec![1.0, 1.0]),
    );
    let tau = ctrl.torque((&q, &qd), (&qr, &qdr, &qddr)).unwrap();
    let command = [1.0 + 4.0 * 0.1 - 0.3, 1.0 - 9.0 * 0.2 + 0.1];
    let expected = inverse_dynamics(&arm, q.as_slice(), qd.as_slice(), &command).unwrap();
    assert!((tau - expected).amax() < 1e-12);
}

#[test]
fn open_loop_reproduces_simulated_motion() {
    let arm = TwoLink::new().with_friction(0.05, 0.0);
    let rec = simulate(&arm, &arm, &two_link_waypoints(10), &quiet(), 0).unwrap();
    let q0: Vec<f64> = rec.truth.q().row(0).iter().copied().collect();
    let qd0: Vec<f64> = rec.truth.qd().row(0).iter().copied().collect();
    // Same torques, same hold, same integrator: the same motion.
    let q = open_loop(&arm, &q0, &qd0, rec.truth.tau(), 1e-3).unwrap();
    assert!((&q - rec.truth.q()).amax() < 1e-6);
    // Nominal inverse-dynamics torques follow the plan open-loop for a while.
    let short = rec.reference.tau().rows(0, 1000).into_owned();
    let planned = open_loop(&arm, &q0, &qd0, &short, 1e-3).unwrap();
    // Open loop drifts (unstable under gravity): measured 2.1e-4 after 1 s.
    assert!((planned - rec.reference.q().rows(0, 1000)).amax() < 1e-3);
}

#[test]
fn substeps_agree_with_single_step() {
    let arm = TwoLink::new();
    let reference = two_link_waypoints(12);
    let one = simulate(&arm, &arm, &reference, &quiet(), 0).unwrap();
    let four = simulate(
        &arm,
        &arm,
        &reference,
        &SimConfig {
            substeps: 4,
            ..quiet()
        },
        0,
    )
    .unwrap();
    assert!((one.truth.q() - four.truth.q()).amax() < 1e-8);
}
