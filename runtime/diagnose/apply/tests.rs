use super::*;
use crate::diagnose::Effect;

fn diagnosis(effects: Vec<Effect>) -> Diagnosis {
    Diagnosis {
        model: "m".into(),
        preprocessing: crate::preprocess::Pipeline::fixed(
            crate::preprocess::Preset::Thesis,
            crate::preprocess::Preprocess::thesis(),
        ),
        layout: crate::diagnose::Layout {
            segments: 2,
            segment_seconds: 1.0,
            trimmed_samples: 0,
        },
        samples: 0,
        joint_kinds: vec![],
        residual_rms: vec![],
        residual_share: vec![],
        regimes: vec![],
        mse_before: vec![],
        mse_after: vec![],
        mse_after_fitted: vec![],
        effects,
        supported: Vec::new(),
        unexplained: vec![],
        identifiability: Default::default(),
        notes: vec![],
        sanity: Default::default(),
        residuals: Default::default(),
    }
}

fn effect(kind: Kind, joint: Option<usize>, params: serde_json::Value) -> Effect {
    let parameters = params.as_object().cloned().unwrap_or_default();
    Effect {
        heldout_mse_removed: 0.1,
        heldout_share: 0.5,
        ..Effect::new(kind, (joint, None), parameters, Default::default())
    }
}

const SOURCE: &str = "# my arm\n[[links]]\nname = \"base\"\n\n[[links]]\nname = \"a\" # upper arm\nmass = 1.0\ninertia = { ixx = 0.01, iyy = 0.01, izz = 0.01 }\n\n[[joints]]\nname = \"j1\"\ntype = \"revolute\"\nparent = \"base\"\nchild = \"a\"\neffects = { viscous = 0.1 }\n";

#[test]
fn an_integer_value_is_added_to_not_dropped() {
    let d = diagnosis(vec![effect(
        Kind::ViscousFriction,
        Some(1),
        serde_json::json!({"coefficient": 0.25}),
    )]);
    let source = SOURCE.replace("viscous = 0.1", "viscous = 1");
    let out = apply_to_text(&source, &d, &["j1"], "a").unwrap();
    assert!(out.contains("viscous = 1.25"), "{out}");
}

#[test]
fn a_tilt_sets_gravity_and_data_properties_leave_the_file() {
    let tilted = diagnosis(vec![effect(
        Kind::GravityDirection,
        None,
        serde_json::json!({"gravity": [0.0, 0.5, -9.797], "tilt_deg": 2.9}),
    )]);
    let out = apply_to_text(SOURCE, &tilted, &["j1"], "a").unwrap();
    assert!(out.contains("gravity = [0.0, 0.5, -9.797]"), "{out}");
    assert!(out.contains("# upper arm"), "{out}");
    let again = apply_to_text(&out, &tilted, &["j1"], "a").unwrap();
    assert_eq!(again.matches("gravity").count(), 1, "{again}");
    let data = diagnosis(vec![
        effect(
            Kind::TorqueScale,
            Some(1),
            serde_json::json!({"scale": 1.1}),
        ),
        effect(Kind::TorqueDelay, None, serde_json::json!({"delay": 0.01})),
    ]);
    assert_eq!(apply_to_text(SOURCE, &data, &["j1"], "a").unwrap(), SOURCE);
}

#[test]
fn a_spring_adds_to_the_joints_keeping_the_torque() {
    let d = diagnosis(vec![effect(
        Kind::JointSpring,
        Some(1),
        serde_json::json!({"stiffness": 3.0, "rest": 0.5, "constant": -1.5}),
    )]);
    let source = SOURCE.replace(
        "viscous = 0.1",
        "viscous = 0.1, spring = 1, spring_rest = -0.1",
    );
    let out = apply_to_text(&source, &d, &["j1"], "a").unwrap();
    // 1 (q + 0.1) + 3 (q - 0.5) = 4 (q - 0.35).
    assert!(out.contains("spring = 4.0"), "{out}");
    let rest: f64 = out
        .split("spring_rest = ")
        .nth(1)
        .and_then(|t| t.split([' ', '}']).next())
        .and_then(|t| t.parse().ok())
        .unwrap();
    assert!((rest - 0.35).abs() < 1e-12, "{out}");
    codegen::Description::parse(&out, "arm", std::path::Path::new("arm.toml")).unwrap();
}

#[test]
fn stribeck_and_ripple_set_their_shape_and_refuse_another() {
    let stribeck = diagnosis(vec![effect(
        Kind::StribeckFriction,
        Some(1),
        serde_json::json!({"excess": 0.3, "velocity": 0.05}),
    )]);
    let out = apply_to_text(SOURCE, &stribeck, &["j1"], "a").unwrap();
    assert!(
        out.contains("stribeck = 0.3") && out.contains("stribeck_velocity = 0.05"),
        "{out}"
    );
    codegen::Description::parse(&out, "arm", std::path::Path::new("arm.toml")).unwrap();
    let ripple = |cycles: f64| {
        diagnosis(vec![effect(
            Kind::TorqueRipple,
            Some(1),
            serde_json::json!({"sin": 0.1, "cos": -0.05, "cycles": cycles}),
        )])
    };
    let source = SOURCE.replace("viscous = 0.1", "ripple_sin = 0.2, ripple_cycles = 12");
    let out = apply_to_text(&source, &ripple(12.0), &["j1"], "a").unwrap();
    assert!(
        out.contains("ripple_sin = 0.30000000000000004") || out.contains("ripple_sin = 0.3"),
        "{out}"
    );
    assert!(
        out.contains("ripple_cos = -0.05") && out.contains("ripple_cycles = 12"),
        "{out}"
    );
    let e = apply_to_text(&source, &ripple(9.0), &["j1"], "a").unwrap_err();
    assert!(format!("{e:#}").contains("ripple_cycles = 12"), "{e:#}");
}

#[test]
fn line_endings_and_a_byte_order_mark_are_kept() {
    let d = diagnosis(vec![effect(
        Kind::ViscousFriction,
        Some(1),
        serde_json::json!({"coefficient": 0.25}),
    )]);
    let source = format!("\u{feff}{}", SOURCE.replace('\n', "\r\n"));
    let out = apply_to_text(&source, &d, &["j1"], "a").unwrap();
    assert!(
        out.starts_with('\u{feff}') && out.contains("viscous = 0.35"),
        "{out}"
    );
    assert_eq!(
        out.matches('\n').count(),
        out.matches("\r\n").count(),
        "{out:?}"
    );
}

#[test]
fn changed_lines_are_listed_in_file_order() {
    let changes = changed_lines("a\nb\nc\n", "a\nB\nc\nd\n");
    assert_eq!(changes, ["- b", "+ B", "+ d"]);
}

#[test]
fn changed_lines_say_whose_table_they_are_in() {
    let old = "name = \"arm\"\n[[links]]\nname = \"l1\"\nmass = 1.0\n[[joints]]\n\
               name = \"j1\"\ntype = \"revolute\"\n[[joints]]\ntype = \"fixed\"\n";
    let new = old
        .replace("mass = 1.0", "mass = 1.5")
        .replace(
            "type = \"revolute\"",
            "type = \"revolute\"\neffects = { viscous = 0.2 }",
        )
        .replace("name = \"arm\"", "name = \"arm2\"")
        .replace("type = \"fixed\"", "type = \"fixed\"\nx = 1");
    let changes = changed_lines(old, &new);
    assert_eq!(
        changes,
        [
            "- name = \"arm\"",
            "+ name = \"arm2\"",
            "link `l1`: - mass = 1.0",
            "link `l1`: + mass = 1.5",
            "joint `j1`: + effects = { viscous = 0.2 }",
            "+ x = 1",
        ]
    );
}

#[test]
fn joint_effects_add_to_existing_values_and_keep_comments() {
    let d = diagnosis(vec![
        effect(
            Kind::ViscousFriction,
            Some(1),
            serde_json::json!({"coefficient": 0.25}),
        ),
        effect(
            Kind::CoulombFriction,
            Some(1),
            serde_json::json!({"level": 0.5}),
        ),
    ]);
    let out = apply_to_text(SOURCE, &d, &["j1"], "a").unwrap();
    assert!(
        out.contains("# my arm") && out.contains("# upper arm"),
        "{out}"
    );
    assert!(
        out.contains("viscous = 0.35") && out.contains("coulomb = 0.5"),
        "{out}"
    );
    codegen::Description::parse(&out, "m", Path::new("m.toml")).unwrap();
}

const ARM: &str = "[[links]]\nname = \"base\"\n\n[[links]]\nname = \"a\"\nmass = 1.0 # measured\ncom = [0.0, 0.0, 0.1]\ninertia = { ixx = 0.01, iyy = 0.01, izz = 0.01 }\n\n[[links]]\nname = \"b\"\nmass = 0.5\ninertia = { ixx = 0.01, iyy = 0.01, izz = 0.01 }\n\n[[joints]]\nname = \"j1\"\ntype = \"revolute\"\nparent = \"base\"\nchild = \"a\"\n\n[[joints]]\nname = \"j2\"\ntype = \"revolute\"\nparent = \"a\"\nchild = \"b\"\norigin = { xyz = [0.0, 0.0, 0.2] }\naxis = [0.0, 1.0, 0.0]\n";

fn link_error(params: serde_json::Value) -> Diagnosis {
    let mut e = effect(Kind::InertialError, None, params);
    e.link = Some("a".into());
    diagnosis(vec![e])
}

#[test]
fn inertial_error_corrects_the_links_mass_and_com() {
    let d = link_error(serde_json::json!({
        "mass": 1.2, "com": [0.02, null, 0.12],
        "nominal_mass": 1.0, "nominal_com": [0.0, 0.0, 0.1]
    }));
    let out = apply_to_text(ARM, &d, &["j1", "j2"], "b").unwrap();
    assert!(out.contains("# measured"), "{out}");
    let parsed = codegen::Description::parse(&out, "m", Path::new("m.toml")).unwrap();
    let body = &parsed.chain().bodies[0].inertial;
    assert!((body.mass - 1.2).abs() < 1e-12, "{out}");
    // The null y component stays as modelled.
    let com = body.standard_parameters();
    for (k, c) in [0.02, 0.0, 0.12].iter().enumerate() {
        assert!((com[1 + k] / com[0] - c).abs() < 1e-12, "com[{k}]: {out}");
    }
}

#[test]
fn an_unidentifiable_mass_is_kept_and_the_first_moment_moves_the_com() {
    let d = link_error(serde_json::json!({
        "mass": null, "com": [null, null, null],
        "first_moment": [0.03, null, 0.15],
        "nominal_mass": 1.0, "nominal_com": [0.0, 0.0, 0.1]
    }));
    let out = apply_to_text(ARM, &d, &["j1", "j2"], "b").unwrap();
    let parsed = codegen::Description::parse(&out, "m", Path::new("m.toml")).unwrap();
    let p = parsed.chain().bodies[0].inertial.standard_parameters();
    assert!((p[0] - 1.0).abs() < 1e-12, "mass changed: {out}");
    for (k, h) in [0.03, 0.0, 0.15].iter().enumerate() {
        assert!((p[1 + k] - h).abs() < 1e-12, "m*c[{k}]: {out}");
    }
}

#[test]
fn payload_becomes_a_fixed_child_body() {
    let d = diagnosis(vec![effect(
        Kind::Payload,
        None,
        serde_json::json!({"mass": 0.4, "com": [0.0, 0.01, 0.2]}),
    )]);
    let out = apply_to_text(SOURCE, &d, &["j1"], "a").unwrap();
    let parsed = codegen::Description::parse(&out, "m", Path::new("m.toml")).unwrap();
    let body = &parsed.chain().bodies[0];
    assert!((body.inertial.mass - 1.4).abs() < 1e-12);
    assert!(
        out.contains("name = \"payload\"") && out.contains("type = \"fixed\""),
        "{out}"
    );
}

/// A payload with a fitted moment of inertia of its own carries it; one
/// without gets a small sphere's.
#[test]
fn a_payload_carries_its_fitted_moment_of_inertia() {
    let inertia_of = |parameters: serde_json::Value| {
        let d = diagnosis(vec![effect(Kind::Payload, None, parameters)]);
        let out = apply_to_text(SOURCE, &d, &["j1"], "a").unwrap();
        let parsed = codegen::Description::parse(&out, "m", Path::new("m.toml")).unwrap();
        let before = codegen::Description::parse(SOURCE, "m", Path::new("m.toml")).unwrap();
        let (p, q) = (
            parsed.chain().bodies[0].inertial.standard_parameters(),
            before.chain().bodies[0].inertial.standard_parameters(),
        );
        // izz about the origin grows by the point mass's m (x^2 + y^2)
        // and the payload's own moment.
        p[9] - q[9] - 0.4 * 0.01 * 0.01
    };
    let fitted =
        inertia_of(serde_json::json!({"mass": 0.4, "com": [0.0, 0.01, 0.2], "inertia": 0.003}));
    assert!((fitted - 0.003).abs() < 1e-12, "{fitted}");
    let point = inertia_of(serde_json::json!({"mass": 0.4, "com": [0.0, 0.01, 0.2]}));
    assert!((point - 0.4 * 0.4 * 0.02 * 0.02).abs() < 1e-12, "{point}");
}

/// A comment after a value `--apply` changes stays on its line, in an
/// `[joints.effects]` table and in an inline one.
#[test]
fn trailing_comments_on_changed_lines_are_kept() {
    let d = diagnosis(vec![effect(
        Kind::CoulombFriction,
        Some(1),
        serde_json::json!({"level": 0.1}),
    )]);
    let table = SOURCE.replace(
        "effects = { viscous = 0.1 }\n",
        "[joints.effects]\ncoulomb = 0.2  # measured on the bench\n",
    );
    let out = apply_to_text(&table, &d, &["j1"], "a").unwrap();
    assert!(
        out.contains("coulomb = 0.30000000000000004  # measured on the bench")
            || out.contains("coulomb = 0.3  # measured on the bench"),
        "{out}"
    );
    let inline = SOURCE.replace(
        "effects = { viscous = 0.1 }\n",
        "effects = { coulomb = 0.2 } # measured on the bench\n",
    );
    let out = apply_to_text(&inline, &d, &["j1"], "a").unwrap();
    assert!(out.contains("} # measured on the bench"), "{out}");
    codegen::Description::parse(&out, "m", Path::new("m.toml")).unwrap();
}

/// A correction of a ripple the joint has adds to its amplitudes, leaves
/// its harmonic's line as written, and a new key goes before the space
/// that closes the inline table.
#[test]
fn a_ripple_correction_adds_and_keeps_the_harmonic_as_written() {
    let d = diagnosis(vec![effect(
        Kind::TorqueRipple,
        Some(1),
        serde_json::json!({"sin": 0.25, "cos": 0.125, "cycles": 6.0}),
    )]);
    let source = SOURCE.replace("viscous = 0.1", "ripple_sin = 0.125, ripple_cycles = 6");
    let out = apply_to_text(&source, &d, &["j1"], "a").unwrap();
    assert!(
        out.contains("effects = { ripple_sin = 0.375, ripple_cycles = 6, ripple_cos = 0.125 }"),
        "{out}"
    );
}

/// On a joint with a torque scale the report gives the effects in the
/// robot's torque (`applied_units`): the TOML takes them as reported, and
/// the totals add them to the model's as they are.
#[test]
fn a_scaled_joints_effects_are_written_as_reported() {
    let d = diagnosis(vec![
        effect(
            Kind::TorqueScale,
            Some(1),
            serde_json::json!({"scale": 1.25}),
        ),
        effect(
            Kind::ViscousFriction,
            Some(1),
            serde_json::json!({"coefficient": 0.4}),
        ),
        effect(
            Kind::JointSpring,
            Some(1),
            serde_json::json!({"stiffness": 2.0, "rest": 0.3}),
        ),
    ]);
    let out = apply_to_text(SOURCE, &d, &["j1"], "a").unwrap();
    // 0.1 + 0.4, and 2.0 about 0.3.
    assert!(out.contains("viscous = 0.5"), "{out}");
    assert!(out.contains("spring = 2.0"), "{out}");
    assert!(out.contains("spring_rest = 0.3"), "{out}");
    let mut effects = d.effects.clone();
    let modelled = vec![codegen::JointEffects {
        viscous: 0.1,
        ..Default::default()
    }];
    crate::diagnose::modelled::add_totals(&mut effects, &modelled);
    assert_eq!(effects[1].total["coefficient"], serde_json::json!(0.5));
}
