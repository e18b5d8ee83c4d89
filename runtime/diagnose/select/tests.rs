//! [`super::select`]: forward selection, the prune and the runners-up on
//! small stacked data.

use super::*;
use crate::diagnose::alternatives::note;
use crate::diagnose::candidate::linear as candidate;
use crate::diagnose::stacked::Stacked;
use nalgebra::DVector;

/// One joint over 4 segments, residual 0.5 sin(q) plus noise; the
/// candidates' columns are sin(q), sin(q) + a trace of cos(3q) and qd.
fn case(trace: f64) -> (Stacked, Vec<Candidate>) {
    let noise = |q: f64, qd: f64| 0.05 * ((q * 12.9898 + qd * 78.233).sin() * 43758.5453).fract();
    let (data, q, qd) = crate::diagnose::search::sweep(|q, qd| 0.5 * q.sin() + noise(q, qd));
    let candidates = vec![
        candidate(Kind::TorqueOffset, q.map(f64::sin)),
        candidate(
            Kind::CoulombFriction,
            q.map(|q| q.sin() + trace * (3.0 * q).cos()),
        ),
        candidate(Kind::ViscousFriction, qd),
    ];
    (data, candidates)
}

/// Residual 1 + 0.3 sin(2q): a spring (q and a constant) explains most
/// of it first, and once a torque scale's column sin(2q) is named its
/// stiffness is nothing and the prune drops it; the constant it held
/// is then named as the offset, which beside the spring was collinear.
#[test]
fn what_a_pruned_effect_held_is_named_after_it() {
    let noise = |q: f64, qd: f64| 0.002 * ((q * 12.9898 + qd * 78.233).sin() * 43758.5453).fract();
    let (data, q, _) =
        crate::diagnose::search::sweep(|q, qd| 1.0 + 0.3 * (2.0 * q).sin() + noise(q, qd));
    let ones = nalgebra::DVector::from_element(q.len(), 1.0);
    let spring = Candidate {
        names: vec!["stiffness", "constant"],
        columns: vec![q.clone(), ones.clone()],
        ..candidate(Kind::JointSpring, ones.clone())
    };
    let candidates = vec![
        spring,
        candidate(Kind::TorqueOffset, ones),
        candidate(Kind::TorqueScale, q.map(|q| (2.0 * q).sin())),
    ];
    let m = Moments::new(&data, &candidates);
    let selection = select(&m, 1, &candidates, Settings::default(), &[]);
    let mut selected = selection.selected.clone();
    selected.sort();
    assert_eq!(selected, vec![1, 2], "{:?}", selection.notes);
    assert!(
        selection
            .notes
            .iter()
            .any(|n| n.contains("joint_spring") && n.contains("dropped"))
    );
}

#[test]
fn a_runner_up_that_explains_the_same_structure_is_reported() {
    let (data, candidates) = case(0.002);
    let m = Moments::new(&data, &candidates);
    let selection = select(&m, 1, &candidates, Settings::default(), &[]);
    assert_eq!(selection.selected, vec![0]);
    let alternative = selection.alternatives.as_slice();
    assert_eq!(alternative.len(), 1, "{alternative:?}");
    assert_eq!((alternative[0].named, alternative[0].runner_up), (0, 1));
    assert!(note(&candidates, &alternative[0]).contains("coulomb_friction on joint 1"));
}

#[test]
fn a_runner_up_the_data_tell_apart_is_not() {
    let (data, candidates) = case(0.5);
    let m = Moments::new(&data, &candidates);
    let selection = select(&m, 1, &candidates, Settings::default(), &[]);
    assert_eq!(selection.selected, vec![0]);
    assert!(selection.alternatives.is_empty());
}

/// Two joints over 4 segments: a shared effect `S` (on both joints, as a
/// payload is) explains both; `X` acts on the first joint only and holds a
/// trace of its residual that, unexplained, tilts the fit of `S`. The
/// first joint is noisy, the second nearly clean. `X` does not lower the
/// first joint's held-out error; on the second it frees `S` to fit it to
/// the noise: 97% of what is left there, but 2e-4 of that joint's error
/// before the diagnosis. Only `S` is named (with the residual at the step
/// as the floor everywhere, `X` was too).
#[test]
fn a_cut_that_only_frees_a_shared_effect_names_nothing() {
    let samples = 4000;
    let t = |s: usize| s as f64 * 0.005;
    let noise = |s: usize, scale: f64| {
        scale
            * (((s as f64) * 12.9898).sin() * 43758.5453)
                .fract()
                .mul_add(2.0, -1.0)
    };
    let rows = 2 * samples;
    let at = |r: usize| (r / 2, r % 2);
    let shared = DVector::from_fn(rows, |r, _| match at(r) {
        (s, 0) => (0.7 * t(s)).sin(),
        (s, _) => (1.3 * t(s)).cos(),
    });
    let own = DVector::from_fn(rows, |r, _| match at(r) {
        (s, 0) => (0.7 * t(s)).sin() + 0.5 * (3.1 * t(s)).sin(),
        _ => 0.0,
    });
    let residual = DVector::from_fn(rows, |r, _| match at(r) {
        (s, 0) => shared[r] + 0.01 * own[r] + noise(s, 0.1),
        (s, _) => shared[r] + noise(s + samples, 1e-4),
    });
    let data = Stacked::of_residual(residual, 2);
    let shared = Candidate {
        joint: None,
        ..candidate(Kind::TorqueDelay, shared)
    };
    let candidates = vec![shared, candidate(Kind::TorqueOffset, own)];
    let m = Moments::new(&data, &candidates);
    let initial = cv_mse(&m, 2, &candidates, &[], Scoring::Fitted);
    let current = cv_mse(&m, 2, &candidates, &[0], Scoring::Fitted);
    let scored = score(&m, 2, &candidates, (&[0], &[1]), (&current, &initial));
    let (_, gain, mse) = &scored[0];
    // The cut on the second joint, as a share of what is left there.
    assert!(mse[1] < 0.5 * current[1], "{mse:?} vs {current:?}");
    assert!(gain.share < 0.1, "{gain:?} {initial:?} {current:?} {mse:?}");
    let selection = select(&m, 2, &candidates, Settings::default(), &[]);
    assert_eq!(selection.selected, vec![0], "{:?}", selection.notes);
}
