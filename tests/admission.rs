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

/// The Panda with its description's friction law written as Coulomb plus
/// viscous friction on every joint (`values`: (coulomb, viscous) per
/// joint), simulated with `sdnn simulate` (seed 1, random waypoint motions
/// of 20 s at 1 kHz) and diagnosed from two recordings with no flags: the
/// named effects as (kind, joint, first parameter).
fn panda_with_friction(values: [(f64, f64); 7]) -> Vec<(String, usize, f64)> {
    let dir = crate::util::Dir::new();
    let description = std::fs::read_to_string(crate::util::root().join("models/panda.toml"))
        .expect("models/panda.toml");
    let mut joints = description.split("[[joints]]");
    let mut plant = joints.next().unwrap().to_string();
    for (k, block) in joints.enumerate() {
        plant.push_str("[[joints]]");
        match values.get(k) {
            Some((c, v)) => {
                let (head, rest) = block.split_once('\n').unwrap();
                let effects = match *v {
                    0.0 => format!("effects = {{ coulomb = {c} }}"),
                    _ => format!("effects = {{ coulomb = {c}, viscous = {v} }}"),
                };
                plant.push_str(&format!("{head}\n{effects}\n{rest}"));
            }
            None => plant.push_str(block),
        }
    }
    let plant = dir.write("panda_plant.toml", &plant);
    let out = dir.path().join("rec");
    let simulated = crate::util::sdnn(&[
        "simulate",
        "--plant",
        plant.to_str().unwrap(),
        "--nominal",
        "panda",
        "--count",
        "2",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(simulated.status.success(), "{:?}", simulated);
    let files: Vec<String> = (1..=2)
        .map(|k| {
            out.join(format!("trajectory_{k:02}.csv"))
                .display()
                .to_string()
        })
        .collect();
    let report = crate::util::sdnn_json(&[
        "diagnose", "--model", "panda", "--data", &files[0], &files[1], "--format", "json",
    ]);
    report["effects"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| {
            let kind = e["kind"].as_str().unwrap().to_string();
            let value = e["parameters"]
                .as_object()
                .unwrap()
                .values()
                .next()
                .unwrap();
            (
                kind,
                e["joint"].as_u64().unwrap_or(0) as usize,
                value.as_f64().unwrap_or(f64::NAN),
            )
        })
        .collect()
}

/// Viscous friction beside Coulomb friction on the same joint, on motions
/// whose speed varies little: once the level is named, the viscous term
/// removes only 3-5% of what is left held out on joints 1 and 3 (below the
/// 10% a new effect needs), and the level absorbs it (0.455 N m for 0.40
/// and 0.397 for 0.35 before the friction law's second term was named
/// beside it). Now it is named there and the levels come within 8%. On the
/// same motions with Coulomb friction alone no viscous friction is named.
#[test]
fn viscous_friction_beside_the_coulomb_level_that_absorbs_it() {
    let coulomb = [0.40, 0.45, 0.35, 0.50, 0.30, 0.20, 0.25];
    let viscous = [0.10, 0.08, 0.08, 0.06, 0.05, 0.04, 0.03];
    let named = panda_with_friction(std::array::from_fn(|j| (coulomb[j], viscous[j])));
    let find = |kind: &str, joint: usize| {
        named
            .iter()
            .find(|(k, j, _)| *k == kind && *j == joint)
            .map(|(_, _, v)| *v)
    };
    for joint in [1, 3] {
        let Some(v) = find("viscous_friction", joint) else {
            panic!("viscous friction on joint {joint} not named: {named:?}");
        };
        let truth = viscous[joint - 1];
        assert!(
            (v - truth).abs() <= 0.4 * truth,
            "joint {joint}: {v} for {truth}"
        );
        let level = find("coulomb_friction", joint).unwrap();
        let truth = coulomb[joint - 1];
        assert!(
            (level - truth).abs() <= 0.08 * truth,
            "joint {joint}: Coulomb level {level} for {truth}: {named:?}"
        );
    }
    let dry = panda_with_friction(std::array::from_fn(|j| (coulomb[j], 0.0)));
    assert!(
        dry.iter().all(|(k, _, _)| k != "viscous_friction"),
        "viscous friction named on a plant without it: {dry:?}"
    );
}
