//! Admission against what is left (issue 25, item 3): a small effect beside
//! a large one is judged against the residual at the step where it is
//! added, not against the joint's error before the diagnosis, which the
//! large effect inflates.

use sdnn::diagnose::{Diagnosis, Kind, diagnose};
use sdnn::preprocess::Pipeline;

use crate::diagnose::{add_point_mass, recordings_of};
use crate::util::oracle;

fn diagnose_panda(truth: &sdnn::oracle::Model, count: u64) -> Diagnosis {
    let recordings = recordings_of("panda", truth, count);
    let pipeline = Pipeline::auto(&recordings, None, None).unwrap();
    let nominal = sdnn::model("panda").unwrap();
    diagnose(nominal, &recordings, &pipeline, Default::default()).unwrap()
}

/// The Panda carrying 1.2 kg at its flange, with viscous friction of
/// 0.1-0.3 N m s/rad on every joint: the payload makes each joint's initial
/// error large, and each friction term removes well under 0.1% of it, yet
/// a third or more of what is left once the payload is named. All seven
/// are named, within 10%, beside the payload.
#[test]
fn viscous_friction_beside_a_heavy_payload() {
    let viscous = [0.3, 0.25, 0.2, 0.15, 0.1, 0.12, 0.1];
    let mut truth = oracle("panda");
    for (body, v) in truth.bodies.iter_mut().zip(viscous) {
        body.effects.viscous = v;
    }
    add_point_mass(&mut truth.bodies[6].parameters, 1.2, [0.0, 0.0, 0.1]);
    let d = diagnose_panda(&truth, 3);
    let text = serde_json::to_string(&d).unwrap();
    let payloads = d.effects.iter().filter(|e| e.kind == Kind::Payload);
    assert_eq!(payloads.count(), 1, "{text}");
    for (j, v) in viscous.iter().enumerate() {
        let named = d
            .effects
            .iter()
            .find(|e| e.kind == Kind::ViscousFriction && e.joint == Some(j + 1));
        let Some(e) = named else {
            panic!("viscous friction on joint {} not named: {text}", j + 1);
        };
        let fitted = e.parameters["coefficient"].as_f64().unwrap();
        assert!(
            (fitted - v).abs() <= 0.1 * v,
            "joint {}: {fitted} vs {v}",
            j + 1
        );
    }
}
