//! Stribeck friction, which the diagnosis tries only when asked
//! (`--stribeck`): on this project's simulator the fit finds a breakaway
//! excess, but the generated model's sign(qd) of a noisy velocity at rest
//! makes the applied term no better held out, so it is dropped with a note
//! (docs/diagnosis.md); plain dry friction is never taken for it.

use sdnn::diagnose::{Diagnosis, Kind, Settings, diagnose};
use sdnn::oracle::Model;
use sdnn::preprocess::Pipeline;

use crate::diagnose::raw_recordings;
use crate::util::oracle;

const NOMINAL: &str = "kinova_gen3_lite_3dof";

fn diagnosed(truth: &Model) -> Diagnosis {
    let recordings = raw_recordings(truth, 3);
    let pipeline = Pipeline::auto(&recordings, None, None).unwrap();
    let settings = Settings {
        stribeck: true,
        ..Settings::default()
    };
    diagnose(
        sdnn::model(NOMINAL).unwrap(),
        &recordings,
        &pipeline,
        settings,
    )
    .unwrap()
}

#[test]
fn a_breakaway_excess_is_found_but_not_applied() {
    let mut truth = oracle(NOMINAL);
    truth.bodies[0].effects.stribeck = 0.4;
    truth.bodies[0].effects.stribeck_velocity = 0.08;
    let d = diagnosed(&truth);
    assert!(d.effects.is_empty(), "{:?}", d.effects);
    assert!(
        d.notes
            .iter()
            .any(|n| n.starts_with("stribeck_friction on joint 1")
                && n.contains("removes no held-out error")),
        "{:?}",
        d.notes
    );
}

#[test]
fn plain_dry_friction_is_not_a_stribeck_effect() {
    let mut truth = oracle(NOMINAL);
    truth.bodies[0].effects.coulomb = 0.3;
    let d = diagnosed(&truth);
    let named: Vec<_> = d.effects.iter().map(|e| (e.kind, e.joint)).collect();
    assert_eq!(named, [(Kind::CoulombFriction, Some(1))], "{d:#?}");
}
