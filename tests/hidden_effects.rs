//! The hidden-effect benchmark: the project's simulator records plants with
//! every effect kind the diagnosis knows, alone and in pairs, and the
//! diagnosis runs at its defaults on 3 or 1 recordings of 20 s, at 1 kHz and
//! logged at 100 Hz. The confusion table (true kind x named kind) and the
//! parameter errors are printed (`cargo test --release hidden_effects --
//! --nocapture`; docs/diagnosis-measured.md's table comes from it) and asserted:
//! every hidden effect named with its kind and place, nothing else named,
//! every parameter within 15%, except the known weaknesses listed by
//! [`known_weakness`] (printed, not asserted; docs/diagnosis.md).

use std::collections::BTreeMap;

use sdnn::diagnose::{Diagnosis, Effect, Kind, Settings, diagnose};
use sdnn::oracle::Model;
use sdnn::preprocess::{Pipeline, downsample};
use sdnn::trajectory::Trajectory;

use crate::diagnose::{add_point_mass, raw_recordings};
use crate::util::oracle;

const NOMINAL: &str = "kinova_gen3_lite_3dof";

/// One hidden effect: its kind, where (1-based joint, or link name), the
/// parameter checked and its true value.
#[derive(Clone, Copy)]
struct Hidden {
    kind: Kind,
    joint: Option<usize>,
    link: Option<&'static str>,
    parameter: &'static str,
    value: f64,
}

const LINK2_MASS: f64 = 1.1776 * 1.3;

/// Base tilt of the tilted-base case, degrees.
const TILT_DEG: f64 = 3.0;

const EFFECTS: [Hidden; 11] = [
    Hidden {
        kind: Kind::ViscousFriction,
        joint: Some(2),
        link: None,
        parameter: "coefficient",
        value: 0.3,
    },
    Hidden {
        kind: Kind::CoulombFriction,
        joint: Some(1),
        link: None,
        parameter: "level",
        value: 0.3,
    },
    Hidden {
        kind: Kind::Armature,
        joint: Some(3),
        link: None,
        parameter: "inertia",
        value: 0.05,
    },
    Hidden {
        kind: Kind::TorqueOffset,
        joint: Some(2),
        link: None,
        parameter: "offset",
        value: 0.25,
    },
    Hidden {
        kind: Kind::Payload,
        joint: None,
        link: Some("link3"),
        parameter: "mass",
        value: 0.5,
    },
    Hidden {
        kind: Kind::InertialError,
        joint: None,
        link: Some("link2"),
        parameter: "mass",
        value: LINK2_MASS,
    },
    Hidden {
        kind: Kind::TorqueScale,
        joint: Some(2),
        link: None,
        parameter: "scale",
        value: 1.1,
    },
    Hidden {
        kind: Kind::TorqueDelay,
        joint: None,
        link: None,
        parameter: "delay",
        value: 0.012,
    },
    Hidden {
        kind: Kind::GravityDirection,
        joint: None,
        link: None,
        parameter: "tilt_deg",
        value: TILT_DEG,
    },
    Hidden {
        kind: Kind::JointSpring,
        joint: Some(3),
        link: None,
        parameter: "stiffness",
        value: 2.0,
    },
    Hidden {
        kind: Kind::TorqueRipple,
        joint: Some(2),
        link: None,
        parameter: "sin",
        value: 0.2,
    },
];

/// The hidden ripple harmonic (periods per revolution).
const RIPPLE_CYCLES: f64 = 12.0;

fn hide(truth: &mut Model, h: &Hidden) {
    let body = |j: Option<usize>| j.map_or(0, |j| j - 1);
    match h.kind {
        Kind::ViscousFriction => truth.bodies[body(h.joint)].effects.viscous = h.value,
        Kind::CoulombFriction => truth.bodies[body(h.joint)].effects.coulomb = h.value,
        Kind::Armature => truth.bodies[body(h.joint)].effects.armature = h.value,
        Kind::TorqueOffset => truth.bodies[body(h.joint)].effects.offset = h.value,
        Kind::Payload => add_point_mass(&mut truth.bodies[2].parameters, h.value, [0.0, 0.0, 0.2]),
        Kind::InertialError => {
            // Heavier with the COM and the inertia about it unchanged.
            let p = truth.bodies[1].parameters;
            let com = [p[1] / p[0], p[2] / p[0], p[3] / p[0]];
            add_point_mass(&mut truth.bodies[1].parameters, h.value - p[0], com);
        }
        Kind::GravityDirection => {
            let g = truth.gravity.norm();
            let tilt = h.value.to_radians();
            truth.gravity = nalgebra::Vector3::new(0.0, g * tilt.sin(), -g * tilt.cos());
        }
        Kind::JointSpring => {
            let effects = &mut truth.bodies[body(h.joint)].effects;
            effects.spring = h.value;
            effects.spring_rest = 0.3;
        }
        Kind::TorqueRipple => {
            let effects = &mut truth.bodies[body(h.joint)].effects;
            effects.ripple_sin = h.value;
            effects.ripple_cycles = RIPPLE_CYCLES;
        }
        // Properties of the recording (see `distort`).
        Kind::TorqueScale | Kind::TorqueDelay => {}
        Kind::CoulombAsymmetry | Kind::StribeckFriction => {
            unreachable!("not in the benchmark (tests/diagnose.rs, tests/stribeck.rs)")
        }
    }
}

/// The recording-side effects: a joint's torque logged scaled, or every
/// torque logged `delay` s late (linear interpolation).
fn distort(recording: &Trajectory, h: &Hidden) -> Trajectory {
    let mut tau = recording.tau().clone();
    match h.kind {
        Kind::TorqueScale => {
            let j = h.joint.unwrap() - 1;
            tau.column_mut(j).scale_mut(h.value);
        }
        Kind::TorqueDelay => {
            let t = recording.t();
            let dt = t[1] - t[0];
            for s in 0..tau.nrows() {
                let at = (s as f64 - h.value / dt).max(0.0);
                let (k, f) = (at.floor() as usize, at.fract());
                let next = (k + 1).min(tau.nrows() - 1);
                for j in 0..tau.ncols() {
                    let original = recording.tau();
                    tau[(s, j)] = (1.0 - f) * original[(k, j)] + f * original[(next, j)];
                }
            }
        }
        _ => return recording.clone(),
    }
    recording.with_tau(tau).unwrap()
}

fn name(h: &Hidden) -> String {
    match (h.joint, h.link) {
        (Some(j), _) => format!("{} j{j}", h.kind.name()),
        (None, Some(link)) => format!("{} {link}", h.kind.name()),
        _ => h.kind.name(),
    }
}

fn named(e: &Effect) -> String {
    match (e.joint, &e.link) {
        (Some(j), _) => format!("{} j{j}", e.kind.name()),
        (None, Some(link)) => format!("{} {link}", e.kind.name()),
        _ => e.kind.name(),
    }
}

/// The documented weak spots (docs/diagnosis.md), listed, not asserted:
/// - a link-2 mass error (its mass acts only through second moments) with
///   another effect, or from one recording;
/// - a tilted base with a payload: the payload's columns use the model's
///   gravity, so the tilt absorbs the payload's share of the tilted load
///   (the tilt comes out about 23% large);
/// - a tilted base with a torque-scale error: from one recording the tilt
///   or the scale is missed and an offset on joint 1 and link errors are
///   named instead;
/// - a torque-scale error with a delay: the delay comes out up to 16% small;
/// - a torque-scale error with a payload (a gain error and a heavier tip
///   scale the same gravity torques): the payload comes out up to 56% heavy
///   and scales are named on the other joints;
/// - a ripple with an armature from one 100 Hz recording: a second ripple
///   at the noise floor (0.009 N m, 1.7% of the joint's error) is named on
///   the armature's joint.
fn known_weakness(hidden: &[Hidden], variant: &str) -> bool {
    let has = |kind| hidden.iter().any(|h| h.kind == kind);
    let one_recording = variant.starts_with('1');
    (has(Kind::InertialError) && (hidden.len() > 1 || one_recording))
        || (has(Kind::GravityDirection) && has(Kind::Payload))
        || (has(Kind::GravityDirection) && has(Kind::TorqueScale))
        || (has(Kind::TorqueScale) && has(Kind::TorqueDelay))
        || (has(Kind::TorqueScale) && has(Kind::Payload))
        || (has(Kind::TorqueRipple) && has(Kind::Armature) && variant == "1 x 100 Hz")
}

fn run(recordings: &[Trajectory]) -> Diagnosis {
    let nominal = sdnn::model(NOMINAL).unwrap();
    let pipeline = Pipeline::auto(recordings, None, None).unwrap();
    diagnose(nominal, recordings, &pipeline, Settings::default()).unwrap()
}

#[test]
fn every_hidden_effect_alone_and_in_pairs() {
    let mut cases: Vec<Vec<Hidden>> = EFFECTS.iter().map(|h| vec![*h]).collect();
    for (a, first) in EFFECTS.iter().enumerate() {
        for second in &EFFECTS[a + 1..] {
            cases.push(vec![*first, *second]);
        }
    }
    cases.push(vec![]);
    // confusion[true][named] counts; errors[kind] the worst relative error.
    let mut confusion: BTreeMap<String, BTreeMap<String, usize>> = BTreeMap::new();
    let mut worst: BTreeMap<String, f64> = BTreeMap::new();
    let mut failures = Vec::new();
    let mut known = Vec::new();
    for (index, hidden) in cases.iter().enumerate() {
        let mut truth = oracle(NOMINAL);
        for h in hidden {
            hide(&mut truth, h);
        }
        let mut khz = raw_recordings(&truth, 3);
        for h in hidden {
            khz = khz.iter().map(|r| distort(r, h)).collect();
        }
        let hz100: Vec<Trajectory> = khz.iter().map(|t| downsample(t, 10).unwrap()).collect();
        let variants = [
            ("3 x 1 kHz", khz.clone()),
            ("1 x 1 kHz", khz[..1].to_vec()),
            ("3 x 100 Hz", hz100.clone()),
            ("1 x 100 Hz", hz100[..1].to_vec()),
        ];
        for (variant, recordings) in variants {
            let weak = known_weakness(hidden, variant);
            let failures = if weak { &mut known } else { &mut failures };
            let d = run(&recordings);
            let found: Vec<String> = d.effects.iter().map(named).collect();
            let truths: Vec<String> = hidden.iter().map(name).collect();
            for h in hidden {
                let row = confusion.entry(name(h)).or_default();
                match d.effects.iter().find(|e| named(e) == name(h)) {
                    Some(e) => {
                        *row.entry(name(h)).or_default() += 1;
                        let fitted = e.parameters[h.parameter].as_f64().unwrap_or(f64::NAN);
                        let error = (fitted - h.value).abs() / h.value;
                        let w = worst.entry(name(h)).or_default();
                        *w = w.max(error);
                        // A NaN (parameter missing) fails too.
                        if error.is_nan() || error > 0.15 {
                            failures.push(format!(
                                "case {index} {truths:?} {variant}: {} {fitted} vs {}",
                                name(h),
                                h.value
                            ));
                        }
                    }
                    None => {
                        *row.entry("(missed)".into()).or_default() += 1;
                        failures.push(format!(
                            "case {index} {truths:?} {variant}: missed {}; named {found:?}",
                            name(h)
                        ));
                    }
                }
            }
            for f in found.iter().filter(|f| !truths.contains(f)) {
                let row = if hidden.is_empty() {
                    "none".to_string()
                } else {
                    "(any)".to_string()
                };
                *confusion
                    .entry(row)
                    .or_default()
                    .entry(f.clone())
                    .or_default() += 1;
                failures.push(format!("case {index} {truths:?} {variant}: also named {f}"));
            }
            if hidden.is_empty() && found.is_empty() {
                *confusion
                    .entry("none".into())
                    .or_default()
                    .entry("(nothing)".into())
                    .or_default() += 1;
            }
        }
    }
    println!("true kind | named (count over 4 variants x the cases it is in)");
    for (truth, row) in &confusion {
        let cells: Vec<String> = row.iter().map(|(k, n)| format!("{k}: {n}")).collect();
        println!("{truth} | {}", cells.join(", "));
    }
    for (effect, error) in &worst {
        println!("{effect}: worst parameter error {:.1}%", 100.0 * error);
    }
    println!("known weakness ({}):\n{}", known.len(), known.join("\n"));
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
