//! Stribeck friction, named by default at the reversal stage (the same
//! filter at ten times the motion's cut-off, docs/diagnosis.md) on this
//! project's simulator: a breakaway excess on one joint of the 3-DOF arm is
//! named with its velocity, plain dry friction that sticks and breaks away
//! is not, and clean data name nothing. `tests/stribeck_planar.rs` checks
//! the same on a simulator written apart from the tool.

use sdnn::diagnose::{Diagnosis, Kind};
use sdnn::oracle::Model;

use crate::diagnose::{diagnose_auto, raw_recordings};
use crate::util::oracle;

const NOMINAL: &str = "kinova_gen3_lite_3dof";

/// The numbers: static friction 0.39 N m over a sliding level of
/// 0.16, fading past 0.08 rad/s, on joint 1.
fn breakaway() -> Model {
    let mut truth = oracle(NOMINAL);
    let e = &mut truth.bodies[0].effects;
    e.coulomb = 0.16;
    e.stribeck = 0.23;
    e.stribeck_velocity = 0.08;
    truth
}

fn named(d: &Diagnosis) -> Vec<(Kind, Option<usize>)> {
    d.effects.iter().map(|e| (e.kind, e.joint)).collect()
}

fn value(d: &Diagnosis, kind: Kind, name: &str) -> f64 {
    let effect = d.effects.iter().find(|e| e.kind == kind).unwrap();
    effect.parameters[name].as_f64().unwrap()
}

/// The 95% interval of `kind`'s `name`.
fn interval(d: &Diagnosis, kind: Kind, name: &str) -> [f64; 2] {
    let effect = d.effects.iter().find(|e| e.kind == kind).unwrap();
    let ci = effect.ci95[name].as_array().unwrap();
    [ci[0].as_f64().unwrap(), ci[1].as_f64().unwrap()]
}

/// Within `tolerance` of the truth, relative.
#[track_caller]
fn near(found: f64, truth: f64, tolerance: f64, what: &str) {
    assert!(
        (found / truth - 1.0).abs() <= tolerance,
        "{what}: {found} for {truth}"
    );
}

#[test]
fn a_breakaway_excess_is_named_by_default() {
    for count in [3, 1] {
        let d = diagnose_auto(&raw_recordings(&breakaway(), count));
        assert_eq!(
            named(&d),
            [
                (Kind::CoulombFriction, Some(1)),
                (Kind::StribeckFriction, Some(1))
            ],
            "{count} recording(s): {:#?}",
            d.notes
        );
        // The grid's step is 1.4, so the velocity is within 18% of a
        // point of it; the excess is fitted with that velocity.
        near(
            value(&d, Kind::StribeckFriction, "velocity"),
            0.08,
            0.2,
            "v_s",
        );
        near(
            value(&d, Kind::StribeckFriction, "excess"),
            0.23,
            0.25,
            "excess",
        );
        // The level beside it is the sliding one, refitted at the band.
        near(
            value(&d, Kind::CoulombFriction, "level"),
            0.16,
            0.05,
            "level",
        );
        // The intervals hold what the velocity grid's resolution costs
        // (0.08 lies between the grid's 0.075 and 0.105 rad/s).
        for (kind, name, truth) in [
            (Kind::StribeckFriction, "excess", 0.23),
            (Kind::CoulombFriction, "level", 0.16),
        ] {
            let [low, high] = interval(&d, kind, name);
            assert!(
                (low..=high).contains(&truth),
                "{count} recording(s): {name} {truth} outside [{low}, {high}]"
            );
        }
    }
}

#[test]
fn plain_dry_friction_that_sticks_is_not_a_stribeck_effect() {
    // At the static level of the case above: the joint sticks at every
    // reversal and rest of the waypoint motion and breaks away at 0.39 N m.
    for level in [0.39, 0.16] {
        let mut truth = oracle(NOMINAL);
        truth.bodies[0].effects.coulomb = level;
        for count in [3, 1] {
            let d = diagnose_auto(&raw_recordings(&truth, count));
            assert_eq!(
                named(&d),
                [(Kind::CoulombFriction, Some(1))],
                "{level} N m, {count} recording(s): {d:#?}"
            );
        }
    }
}

#[test]
fn clean_data_name_nothing() {
    let d = diagnose_auto(&raw_recordings(&oracle(NOMINAL), 3));
    assert!(d.effects.is_empty(), "{:?}", named(&d));
}
