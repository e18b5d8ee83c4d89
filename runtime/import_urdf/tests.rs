use super::*;

fn link(name: &str) -> String {
    format!("<link name='{name}'/>")
}

fn body(name: &str, mass: f64, rpy: &str) -> String {
    format!(
        "<link name='{name}'><inertial><origin xyz='0.1 0 0' rpy='{rpy}'/><mass value='{mass}'/>\
         <inertia ixx='1' iyy='2' izz='3' ixy='0' ixz='0' iyz='0'/></inertial></link>"
    )
}

fn joint(name: &str, kind: &str, parent: &str, child: &str) -> String {
    format!(
        "<joint name='{name}' type='{kind}'><parent link='{parent}'/><child link='{child}'/>\
         <axis xyz='0 0 1'/><limit lower='-1' upper='1' effort='5' velocity='2'/></joint>"
    )
}

fn robot(parts: &[String]) -> String {
    format!("<robot name='test'>{}</robot>", parts.concat())
}

/// base -J1-> a -J2-> b, the smallest valid arm.
fn arm(extra: &[String]) -> String {
    let mut parts = vec![
        link("base"),
        body("a", 1.0, "0 0 0"),
        body("b", 1.0, "0 0 0"),
        joint("J1", "revolute", "base", "a"),
        joint("J2", "revolute", "a", "b"),
    ];
    parts.extend_from_slice(extra);
    robot(&parts)
}

fn run(urdf: &str, options: &ImportOptions) -> Result<Imported, ImportError> {
    import_urdf(urdf, "test.urdf", options)
}

fn error(urdf: &str, options: &ImportOptions) -> String {
    run(urdf, options)
        .expect_err("import should fail")
        .to_string()
}

fn options(tip: &str) -> ImportOptions {
    ImportOptions {
        tip: Some(tip.into()),
        ..Default::default()
    }
}

fn parse(toml: &str) -> codegen::Description {
    codegen::Description::parse(toml, "test", std::path::Path::new("test.toml"))
        .unwrap_or_else(|e| panic!("{e}\n{toml}"))
}

#[test]
fn a_prismatic_joint_on_the_chain_is_written_as_one() {
    let urdf = arm(&[body("c", 1.0, "0 0 0"), joint("J7", "prismatic", "b", "c")]);
    let imported = run(&urdf, &ImportOptions::default()).expect("prismatic on the chain");
    assert!(
        imported.toml.contains("type = \"prismatic\""),
        "{}",
        imported.toml
    );
    assert_eq!(parse(&imported.toml).dof(), 3);
}

#[test]
fn a_mimic_joint_on_the_chain_is_a_coupling_and_a_lock_overrides_it() {
    let mimic = "<joint name='J3' type='revolute'><parent link='b'/><child link='c'/>\
                 <limit lower='-1' upper='1' effort='1' velocity='1'/>\
                 <mimic joint='J2' multiplier='-2' offset='0.1'/></joint>";
    let urdf = arm(&[body("c", 1.0, "0 0 0"), mimic.to_string()]);
    let imported = run(&urdf, &ImportOptions::default()).expect("mimic on the chain");
    assert!(
        imported
            .toml
            .contains("mimic = { joint = \"J2\", multiplier = -2.0, offset = 0.1 }"),
        "{}",
        imported.toml
    );
    assert_eq!(parse(&imported.toml).dof(), 2);
    let locked = ImportOptions {
        lock: vec![("J3".into(), 0.0)],
        ..Default::default()
    };
    let imported = run(&urdf, &locked).expect("locked mimic joint");
    assert!(!imported.toml.contains("mimic"), "{}", imported.toml);
    assert_eq!(parse(&imported.toml).dof(), 2);
}

#[test]
fn names_with_newlines_are_refused_and_never_reach_the_toml() {
    let crafted = arm(&[]).replace("name='test'", "name='Arm&#10;pub fn injected() {}&#10;#'");
    let message = error(&crafted, &ImportOptions::default());
    assert!(
        message.contains("<robot name>") && message.contains("U+000A"),
        "{message}"
    );
    assert!(message.contains("--name"), "{message}");
    // With --name the robot name is not used, and the header escapes it.
    let options = ImportOptions {
        name: Some("arm".into()),
        ..ImportOptions::default()
    };
    let imported = run(&crafted, &options).expect("imports with --name");
    assert!(!imported.toml.contains("\npub fn"), "{}", imported.toml);
    assert!(
        imported.toml.contains("\\npub fn injected"),
        "{}",
        imported.toml
    );
    let link = arm(&[])
        .replace("body(\"b\"", "")
        .replace("name='b'", "name='b&#10;x'");
    let link = link.replace("link='b'", "link='b&#10;x'");
    let message = error(&link, &ImportOptions::default());
    assert!(
        message.contains("<link name=") && message.contains("U+000A"),
        "{message}"
    );
    let bad = ImportOptions {
        name: Some("two\nlines".into()),
        ..ImportOptions::default()
    };
    assert!(error(&arm(&[]), &bad).starts_with("--name"));
}

#[test]
fn deep_nesting_and_massless_arms_are_refused() {
    let deep = format!(
        "<robot name='r'>{}{}</robot>",
        "<x>".repeat(30_000),
        "</x>".repeat(30_000)
    );
    assert!(error(&deep, &ImportOptions::default()).contains("nested more than"));
    let shallow = arm(&["<gazebo><plugin><a/></plugin></gazebo>".to_string()]);
    assert!(run(&shallow, &ImportOptions::default()).is_ok());
    let massless = robot(&[
        link("base"),
        link("a"),
        link("b"),
        joint("J1", "revolute", "base", "a"),
        joint("J2", "revolute", "a", "b"),
    ]);
    let message = error(&massless, &ImportOptions::default());
    assert!(message.contains("massless"), "{message}");
}

#[test]
fn unknown_names_in_options_are_errors() {
    let urdf = arm(&[]);
    let with = |f: fn(&mut ImportOptions)| {
        let mut o = ImportOptions::default();
        f(&mut o);
        error(&urdf, &o)
    };
    assert_eq!(
        with(|o| o.base = Some("nope".into())),
        "--base: no link named 'nope' in the URDF"
    );
    assert_eq!(
        with(|o| o.tip = Some("nope".into())),
        "--tip: no link named 'nope' in the URDF"
    );
    assert_eq!(
        with(|o| o.lock = vec![("nope".into(), 0.0)]),
        "--lock: no joint named 'nope' in the URDF"
    );
    assert_eq!(
        with(|o| o.attach = vec!["nope:mass=1".parse().unwrap()]),
        "--attach: no link named 'nope' in the URDF"
    );
    assert_eq!(
        with(|o| o.tip = Some("base".into())),
        "--tip: no joint moves between base 'base' and tip 'base'"
    );
    assert_eq!(
        with(|o| {
            o.base = Some("b".into());
            o.tip = Some("a".into());
        }),
        "--tip: link 'a' is not below the base 'b'"
    );
}

#[test]
fn a_split_after_a_moving_joint_is_the_default_tip_and_its_branches_are_held() {
    let urdf = arm(&[body("c", 1.0, "0 0 0"), joint("J3", "revolute", "a", "c")]);
    let imported = run(&urdf, &ImportOptions::default()).expect("split at a");
    let d = parse(&imported.toml);
    assert_eq!(d.dof(), 1);
    assert!((d.chain().bodies[0].inertial.mass - 3.0).abs() < 1e-15);
    assert!(
        imported
            .notes
            .iter()
            .any(|n| n.starts_with("kept 2 branches at link 'a' (J2, J3;"))
    );
    // A tip keeps one branch moving; the other is held at 0 or its --lock.
    let imported = run(&urdf, &options("b")).expect("tip given");
    assert!(imported.toml.contains("locked = 0.0"));
    let lock = ImportOptions {
        lock: vec![("J3".into(), 0.5)],
        ..options("b")
    };
    let imported = run(&urdf, &lock).expect("branch locked");
    assert!(imported.toml.contains("locked = 0.5"));
    assert!((parse(&imported.toml).chain().bodies[0].inertial.mass - 2.0).abs() < 1e-15);
    // A split before anything moves needs a tip.
    let urdf = robot(&[
        link("base"),
        body("a", 1.0, "0 0 0"),
        body("b", 1.0, "0 0 0"),
        joint("J1", "revolute", "base", "a"),
        joint("J2", "revolute", "base", "b"),
    ]);
    assert_eq!(
        error(&urdf, &ImportOptions::default()),
        "--tip: the URDF branches at link 'base' into several moving branches; choose the tip \
         with --tip (leaves: a, b)"
    );
}

#[test]
fn rigid_branches_are_kept_and_links_above_the_base_dropped() {
    let urdf = robot(&[
        link("world"),
        link("base"),
        body("a", 1.0, "0 0 0"),
        body("gripper", 0.5, "0 0 0"),
        link("camera"),
        joint("mount", "fixed", "world", "base"),
        joint("J1", "continuous", "base", "a"),
        joint("grip", "fixed", "a", "gripper"),
        joint("cam", "fixed", "base", "camera"),
    ]);
    let all = run(&urdf, &ImportOptions::default()).expect("default chain");
    assert!(all.toml.contains("name = \"gripper\""), "{}", all.toml);
    let d = parse(&all.toml);
    assert_eq!((d.dof(), d.chain().bodies[0].inertial.mass), (1, 1.5));
    let limits = d.joints[1].limits.expect("velocity and effort kept");
    assert_eq!(
        (limits.position(), limits.velocity, limits.effort),
        (None, Some(2.0), Some(5.0)),
        "continuous: no position limits"
    );
    let base = ImportOptions {
        base: Some("base".into()),
        ..Default::default()
    };
    let cut = run(&urdf, &base).expect("base below the root");
    assert!(!cut.toml.contains("world"));
    assert!(cut.toml.contains("camera"));
    assert!(
        cut.notes[0].contains("1 link(s) above it are dropped"),
        "{:?}",
        cut.notes
    );
}

#[test]
fn gravity_is_expressed_in_a_rotated_base() {
    let mount = "<joint name='mount' type='fixed'><parent link='world'/><child link='base'/>\
                 <origin rpy='1.5707963267948966 0 0'/></joint>";
    let urdf = arm(&[link("world"), mount.to_string()]);
    let base = ImportOptions {
        base: Some("base".into()),
        ..Default::default()
    };
    let imported = run(&urdf, &base).expect("rotated base");
    assert_eq!(parse(&imported.toml).gravity, [0.0, -9.81, 0.0]);
}

/// The rotation itself is tested in `inertia.rs`; here through the import.
#[test]
fn inertia_is_rotated_from_the_inertial_origin_into_the_link_frame() {
    let urdf = arm(&[]).replace(
        &body("b", 1.0, "0 0 0"),
        &body("b", 1.0, "1.5707963267948966 0 1.5707963267948966"),
    );
    let d = parse(&run(&urdf, &ImportOptions::default()).expect("import").toml);
    let i = d.link("b").and_then(|l| l.inertia).expect("inertia");
    assert!(
        (i.ixx - 3.0).abs() < 1e-15 && (i.iyy - 1.0).abs() < 1e-15 && (i.izz - 2.0).abs() < 1e-15
    );
}

#[test]
fn dynamics_become_effects_and_are_dropped_when_locked() {
    let urdf = arm(&[]).replace(
        "</joint></robot>",
        "<dynamics damping='0.3' friction='0.1'/></joint></robot>",
    );
    let imported = run(&urdf, &ImportOptions::default()).expect("import");
    assert!(
        imported
            .toml
            .contains("effects = { viscous = 0.3, coulomb = 0.1 }")
    );
    let lock = ImportOptions {
        lock: vec![("J2".into(), 0.0)],
        ..Default::default()
    };
    let imported = run(&urdf, &lock).expect("import");
    assert!(!imported.toml.contains("effects"));
    assert!(
        imported
            .notes
            .iter()
            .any(|n| n == "<dynamics> of 1 joint(s) that do not move left out: J2"),
        "{:?}",
        imported.notes
    );
    assert_eq!(parse(&imported.toml).dof(), 1);
}

#[test]
fn irrelevant_elements_are_one_note() {
    let urdf = arm(&[
        "<transmission name='t1'><type>x</type></transmission>".into(),
        "<transmission name='t2'><type>x</type></transmission>".into(),
        "<!-- <transmission name='hidden'/> -->".into(),
        "<gazebo reference='a'><material>x</material></gazebo>".into(),
    ]);
    let imported = run(&urdf, &ImportOptions::default()).expect("import");
    assert!(imported.warnings.is_empty(), "{:?}", imported.warnings);
    assert_eq!(
        imported.notes,
        ["skipped 1 <gazebo>, 2 <transmission>: no rigid-body dynamics in them"]
    );
}

#[test]
fn errors_name_the_same_line_whatever_the_line_endings() {
    let bad = arm(&[]).replacen("value='1'", "value='-1'", 1);
    // One element a line; the bad mass is on the line an editor shows.
    let lines = bad.replace("><", ">\n<");
    let at = lines.find("<mass value='-1'/>").unwrap();
    let line = lines[..at].matches('\n').count() + 1;
    for ending in ["\n", "\r\n", "\r"] {
        let text = lines.replace('\n', ending);
        let message = error(&text, &options("b"));
        let named = format!("<mass> (line {line})");
        assert!(
            message.contains(&named),
            "{ending:?}: {message}, not {named}"
        );
    }
}

#[test]
fn bad_urdf_values_and_structure_are_errors() {
    let cases = [
        (
            arm(&[]).replace("value='1'", "value='-1'"),
            "link 'a' <mass> (line 1): mass must be",
        ),
        (
            arm(&[]).replace("lower='-1' upper='1'", "lower='1' upper='-1'"),
            "joint 'J1' <limit> (line 1): lower 1 > upper -1",
        ),
        (
            arm(&[]).replace("<axis xyz='0 0 1'/>", "<axis xyz='0 0 0'/>"),
            "joint 'J1' (line 1): its <axis> is zero",
        ),
        (
            arm(&[joint("J9", "fixed", "b", "a")]),
            "URDF structure: link 'a' is the child of two joints",
        ),
        (
            arm(&[link("island")]),
            "URDF structure: 2 links have no parent (base, island)",
        ),
        (
            arm(&[link("a")]),
            "URDF structure: link 'a' is defined twice",
        ),
        (
            arm(&[joint("J3", "fixed", "b", "ghost")]),
            "URDF structure: joint 'J3' (line 1): child link 'ghost'",
        ),
        (
            "<robot name='x'><link name='a'>".to_string(),
            "cannot parse the URDF",
        ),
        (String::new(), "cannot parse the URDF"),
        (
            arm(&[])
                .replace("<robot", "<sdf")
                .replace("</robot>", "</sdf>"),
            "cannot parse the URDF: the root element is <sdf> (line 1), not <robot>",
        ),
        (
            arm(&[]).replace("value='1'", "value='1,5'"),
            "link 'a' <mass> (line 1): value='1,5': expected a finite number",
        ),
        (
            arm(&[]).replace("xyz='0 0 1'", "xyz='0 ${pi} 1'"),
            "joint 'J1' <axis> (line 1): xyz='0 ${pi} 1': expected 3 finite numbers (an \
             unexpanded xacro expression",
        ),
        (
            arm(&[]).replace("type='revolute'", "type='hinge'"),
            "joint 'J1' <joint> (line 1): type 'hinge' is not a URDF joint type",
        ),
    ];
    for (urdf, expected) in cases {
        let message = error(&urdf, &ImportOptions::default());
        assert!(message.starts_with(expected), "{message}");
    }
}

#[test]
fn attachment_adds_a_fixed_payload_link() {
    let attach = ImportOptions {
        attach: vec![
            "b:mass=0.5,com=0;0;0.1".parse().unwrap(),
            "b:mass=0.25".parse().unwrap(),
        ],
        ..Default::default()
    };
    let imported = run(&arm(&[]), &attach).expect("import");
    let d = parse(&imported.toml);
    assert!(d.link("b_payload").is_some() && d.link("b_payload_2").is_some());
    assert!((d.chain().bodies[1].inertial.mass - 1.75).abs() < 1e-15);
    assert!(
        imported
            .toml
            .contains("inertia = { ixx = 2e-7, iyy = 2e-7, izz = 2e-7")
    );
}

/// Kinova's URDF, vendored with its licence in data/gen3_lite/.
const GEN3_LITE: &str = "../data/gen3_lite/GEN3-LITE.urdf";

fn gen3_lite() -> String {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(GEN3_LITE);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn gen3_lite_round_trips_through_the_description_parser() {
    let urdf = gen3_lite();
    let label = GEN3_LITE;
    let imported = import_urdf(&urdf, label, &ImportOptions::default()).expect("import");
    assert!(imported.warnings.is_empty(), "{:?}", imported.warnings);
    assert!(imported.toml.starts_with(&format!(
        "# Imported by `sdnn import-urdf` from {label:?}\n"
    )));
    let d = parse(&imported.toml);
    assert_eq!(d.dof(), 6);
    assert_eq!(d.links.len(), 8);
    let again = import_urdf(&urdf, label, &ImportOptions::default()).expect("import");
    assert_eq!(again, imported, "deterministic");
    let locked = ImportOptions {
        lock: ["J3", "J4", "J5"]
            .iter()
            .map(|j| (j.to_string(), 0.0))
            .collect(),
        attach: vec!["END_EFFECTOR:mass=0.2018,com=0;0;0.05".parse().unwrap()],
        ..Default::default()
    };
    let three = parse(&import_urdf(&urdf, label, &locked).expect("import").toml);
    assert_eq!(three.dof(), 3);
    let mass: f64 = three.chain().bodies[2].inertial.mass;
    assert!((mass - (0.59767669 + 0.52693412 + 0.58097325 + 0.2018)).abs() < 1e-12);
}
