use super::*;
use proptest::prelude::*;

/// Checks limits on a 5 ms grid, with a tolerance for rounding only.
fn assert_within_limits(r: &dyn Reference, limits: &JointLimits, margin: f64) {
    let steps = (r.duration() / 0.005) as usize;
    for i in 0..=steps {
        let (q, qd, qdd) = r.sample(i as f64 * 0.005);
        for j in 0..r.dof() {
            let (lo, hi) = limits.position[j];
            assert!(
                q[j] >= lo + margin - 1e-12 && q[j] <= hi - margin + 1e-12,
                "q{j}={}",
                q[j]
            );
            assert!(
                qd[j].abs() <= limits.velocity[j] * (1.0 + 1e-9),
                "qd{j}={}",
                qd[j]
            );
            assert!(
                qdd[j].abs() <= limits.acceleration[j] * (1.0 + 1e-9),
                "qdd{j}={}",
                qdd[j]
            );
        }
    }
}

/// Central differences of q and qd against the exact qd and qdd.
fn assert_exact_derivatives(r: &dyn Reference) {
    let h = 1e-5;
    for i in 0..400 {
        let t = 0.0137 + i as f64 * 0.049;
        let (_, qd, qdd) = r.sample(t);
        let (q_p, qd_p, _) = r.sample(t + h);
        let (q_m, qd_m, _) = r.sample(t - h);
        let fd_qd = (q_p - q_m) / (2.0 * h);
        let fd_qdd = (qd_p - qd_m) / (2.0 * h);
        assert!((fd_qd - qd).amax() < 1e-7, "qd at t={t}");
        assert!((fd_qdd - qdd).amax() < 1e-7, "qdd at t={t}");
    }
}

#[test]
fn minimum_jerk_peaks_match_constants() {
    let seg = Segment {
        start: 0.0,
        length: 2.0,
        q0: 0.0,
        dq: 1.0,
    };
    let (_, v, _) = seg.eval(1.0);
    assert!((v - MIN_JERK_PEAK_VELOCITY / 2.0).abs() < 1e-12);
    let s_peak = 0.5 - 3f64.sqrt() / 6.0;
    let (_, _, a) = seg.eval(2.0 * s_peak);
    assert!((a - MIN_JERK_PEAK_ACCELERATION / 4.0).abs() < 1e-12);
    assert_eq!(seg.eval(2.0), (1.0, 0.0, 0.0));
}

#[test]
fn waypoint_derivatives_are_exact() {
    let r = WaypointTrajectory::new(&WaypointConfig::default(), 3).unwrap();
    assert_exact_derivatives(&r);
}

#[test]
fn excitation_derivatives_are_exact() {
    let r = ExcitationTrajectory::new(&ExcitationConfig::default(), 3).unwrap();
    assert_exact_derivatives(&r);
}

#[test]
fn same_seed_same_trajectory_other_seed_differs() {
    let cfg = WaypointConfig::default();
    let a = WaypointTrajectory::new(&cfg, 11).unwrap();
    assert_eq!(a, WaypointTrajectory::new(&cfg, 11).unwrap());
    assert_ne!(a, WaypointTrajectory::new(&cfg, 12).unwrap());
    let ecfg = ExcitationConfig::default();
    let e = ExcitationTrajectory::new(&ecfg, 11).unwrap();
    assert_eq!(e, ExcitationTrajectory::new(&ecfg, 11).unwrap());
}

#[test]
fn waypoints_cover_duration_and_rest_afterwards() {
    let r = WaypointTrajectory::new(&WaypointConfig::default(), 5).unwrap();
    for segments in &r.joints {
        let last = segments.last().unwrap();
        assert!(last.start + last.length >= 20.0);
        let (q, qd, qdd) = r.sample(1e6);
        assert!(qd.amax() == 0.0 && qdd.amax() == 0.0 && q.iter().all(|x| x.is_finite()));
    }
    let (q0, qd0, _) = r.sample(-1.0);
    assert_eq!((q0, qd0), {
        let (q, qd, _) = r.sample(0.0);
        (q, qd)
    });
}

#[test]
fn velocity_cap_lengthens_segments() {
    assert_eq!(capped_length(2.0, 0.1, 1.0, 1.0), 2.0);
    let long = capped_length(1.5, 4.0, 0.5, 10.0);
    assert!((long - 1.875 * 4.0 / 0.5).abs() < 1e-12);
}

#[test]
fn excitation_base_frequency_in_range() {
    let r = ExcitationTrajectory::new(&ExcitationConfig::default(), 8).unwrap();
    assert!((0.05..=0.1).contains(&r.base_hz()));
}

#[test]
fn invalid_configs_are_errors() {
    let mut cfg = WaypointConfig::default();
    cfg.limits.velocity.pop();
    assert!(matches!(
        WaypointTrajectory::new(&cfg, 0),
        Err(ReferenceError::LengthMismatch { .. })
    ));
    // A margin wider than the range shrinks to a quarter of it (a
    // gripper's short stroke); a reversed range is empty.
    let mut cfg = WaypointConfig {
        margin: 3.0,
        ..Default::default()
    };
    assert!(WaypointTrajectory::new(&cfg, 0).is_ok());
    cfg.limits.position[0] = (1.0, -1.0);
    assert!(matches!(
        WaypointTrajectory::new(&cfg, 0),
        Err(ReferenceError::EmptyRange { joint: 0, .. })
    ));
    let cfg = WaypointConfig {
        min_segment: 5.0,
        ..Default::default()
    };
    assert!(matches!(
        WaypointTrajectory::new(&cfg, 0),
        Err(ReferenceError::Order { .. })
    ));
    let cfg = WaypointConfig {
        duration: f64::NAN,
        ..Default::default()
    };
    assert!(matches!(
        WaypointTrajectory::new(&cfg, 0),
        Err(ReferenceError::NotPositive { .. })
    ));
    let cfg = WaypointConfig {
        duration: 1e12,
        ..Default::default()
    };
    assert!(matches!(
        WaypointTrajectory::new(&cfg, 0),
        Err(ReferenceError::TooLong { .. })
    ));
    for harmonics in [0, MAX_HARMONICS + 1] {
        let cfg = ExcitationConfig {
            harmonics,
            ..Default::default()
        };
        assert!(ExcitationTrajectory::new(&cfg, 0).is_err());
    }
    let cfg = ExcitationConfig {
        limits: JointLimits::uniform(0, (0.0, 1.0), 1.0, 1.0),
        ..Default::default()
    };
    assert_eq!(
        ExcitationTrajectory::new(&cfg, 0),
        Err(ReferenceError::NoJoints)
    );
}

#[test]
fn config_round_trips_through_serde_with_defaults() {
    let cfg: WaypointConfig = serde_json_like_default();
    assert_eq!(cfg, WaypointConfig::default());
}

/// serde(default) lets an empty map deserialize to the defaults.
fn serde_json_like_default() -> WaypointConfig {
    use serde::de::value::{Error, MapDeserializer};
    let empty: Vec<(&str, f64)> = Vec::new();
    WaypointConfig::deserialize(MapDeserializer::<_, Error>::new(empty.into_iter())).unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn waypoints_stay_within_limits(seed in any::<u64>()) {
        let cfg = WaypointConfig::default();
        let r = WaypointTrajectory::new(&cfg, seed).unwrap();
        assert_within_limits(&r, &cfg.limits, cfg.margin);
    }

    #[test]
    fn excitation_stays_within_limits(seed in any::<u64>()) {
        let cfg = ExcitationConfig::default();
        let r = ExcitationTrajectory::new(&cfg, seed).unwrap();
        assert_within_limits(&r, &cfg.limits, cfg.margin);
    }

    #[test]
    fn fast_waypoints_stay_within_limits(seed in any::<u64>()) {
        let cfg = WaypointConfig {
            limits: JointLimits::uniform(2, (-1.0, 2.0), 3.0, 8.0),
            min_segment: 0.3,
            max_segment: 1.0,
            ..Default::default()
        };
        let r = WaypointTrajectory::new(&cfg, seed).unwrap();
        assert_within_limits(&r, &cfg.limits, cfg.margin);
    }
}
