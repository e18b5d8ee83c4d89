use nalgebra::{Matrix3, Vector3};

use super::*;
use crate::description::Description;
use crate::states::uniform;
use std::path::Path;

pub(super) const PLANAR: &str = r#"
    gravity = [0.0, -9.81, 0.0]
    [[links]]
    name = "base"
    [[links]]
    name = "upper"
    mass = 2.0
    com = [0.35, 0.0, 0.0]
    inertia = { ixx = 0.002, iyy = 0.12, izz = 0.12 }
    [[links]]
    name = "fore"
    mass = 1.5
    com = [0.4, 0.0, 0.0]
    inertia = { ixx = 0.0015, iyy = 0.08, izz = 0.08 }
    [[joints]]
    name = "shoulder"
    type = "revolute"
    parent = "base"
    child = "upper"
    effects = { viscous = 0.3, coulomb = 0.2, offset = -0.1, armature = 0.01 }
    [[joints]]
    name = "elbow"
    type = "revolute"
    parent = "upper"
    child = "fore"
    origin = { xyz = [0.8, 0.0, 0.0] }
    effects = { coulomb = 0.3, coulomb_asymmetry = 0.05, spring = 2.0, spring_rest = 0.4, stribeck = 0.15, stribeck_velocity = 0.5, ripple_sin = 0.04, ripple_cos = -0.02, ripple_cycles = 6 }
"#;

/// The elbow's friction in `PLANAR` (Coulomb, asymmetry, Stribeck), and
/// its torque of the position (spring, ripple).
fn elbow_effects(q: f64, qd: f64) -> (f64, f64) {
    let sign = qd.signum();
    let friction = 0.3 * sign + 0.05 * sign * sign + 0.15 * sign * (-(qd / 0.5).powi(2)).exp();
    let position = 2.0 * (q - 0.4) + 0.04 * (6.0 * q).sin() - 0.02 * (6.0 * q).cos();
    (friction, position)
}

/// The program inputs of a state of `description`'s chain.
fn inputs_of(description: &Description, q: &[f64], qd: &[f64], qdd: &[f64]) -> Vec<f64> {
    program_inputs(description.chain(), q, qd, qdd)
}

/// The textbook closed form of the planar two-link arm (gravity along -y).
fn closed_form(q: &[f64], qd: &[f64], qdd: &[f64]) -> [f64; 2] {
    let (m1, m2, l1, c1, c2, g) = (2.0, 1.5, 0.8, 0.35, 0.4, 9.81);
    let (i1, i2) = (0.12 + m1 * c1 * c1, 0.08 + m2 * c2 * c2);
    let cos2 = q[1].cos();
    let m11 = i1 + i2 + m2 * l1 * l1 + 2.0 * m2 * l1 * c2 * cos2;
    let m12 = i2 + m2 * l1 * c2 * cos2;
    let h = -m2 * l1 * c2 * q[1].sin();
    let g1 = (m1 * c1 + m2 * l1) * g * q[0].cos() + m2 * c2 * g * (q[0] + q[1]).cos();
    let g2 = m2 * c2 * g * (q[0] + q[1]).cos();
    [
        m11 * qdd[0] + m12 * qdd[1] + h * (2.0 * qd[0] * qd[1] + qd[1] * qd[1]) + g1,
        m12 * qdd[0] + i2 * qdd[1] - h * qd[0] * qd[0] + g2,
    ]
}

/// A plain numeric recursive Newton-Euler for per-body standard
/// parameters (no joint effects), the reference for the traced programs.
fn rnea(
    chain: &Chain,
    params: &[[f64; 10]],
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    g: bool,
) -> Vec<f64> {
    type V = Vector3<f64>;
    let n = chain.bodies.len();
    // Body positions from the degrees of freedom (mimics follow theirs).
    let driven = |x: &[f64], b: usize, with_offset: bool| {
        let (d, multiplier, offset) = chain.driver(b);
        multiplier * x[d] + if with_offset { offset } else { 0.0 }
    };
    let q: Vec<f64> = (0..n).map(|b| driven(q, b, true)).collect();
    let qd: Vec<f64> = (0..n).map(|b| driven(qd, b, false)).collect();
    let qdd: Vec<f64> = (0..n).map(|b| driven(qdd, b, false)).collect();
    let base = (
        V::zeros(),
        V::zeros(),
        if g { -chain.gravity } else { V::zeros() },
    );
    let mut states: Vec<(V, V, V)> = Vec::new();
    let mut frames = Vec::new();
    let mut wrenches = Vec::new();
    let prismatic = |i: usize| chain.bodies[i].kind == crate::schema::JointKind::Prismatic;
    let origin = |i: usize| {
        let body = &chain.bodies[i];
        let slide = if prismatic(i) { q[i] } else { 0.0 };
        body.translation + body.rotation * body.axis * slide
    };
    for (i, body) in chain.bodies.iter().enumerate() {
        let (mut w, mut wd, mut a) = body.parent.map_or(base, |p| states[p]);
        let turn = if prismatic(i) { 0.0 } else { q[i] };
        let r = body.rotation * crate::reduce::axis_angle(&body.axis, turn);
        let (z, o) = (body.axis, origin(i));
        a = r.transpose() * (a + wd.cross(&o) + w.cross(&w.cross(&o)));
        let w_in = r.transpose() * w;
        if prismatic(i) {
            a += 2.0 * w_in.cross(&(z * qd[i])) + z * qdd[i];
            w = w_in;
            wd = r.transpose() * wd;
        } else {
            w = w_in + z * qd[i];
            wd = r.transpose() * wd + z * qdd[i] + w_in.cross(&(z * qd[i]));
        }
        let [m, hx, hy, hz, xx, xy, yy, xz, yz, zz] = params[i];
        let h = V::new(hx, hy, hz);
        let inertia = Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz);
        let force = m * a + wd.cross(&h) + w.cross(&w.cross(&h));
        let moment = inertia * wd + w.cross(&(inertia * w)) + h.cross(&a);
        frames.push(r);
        states.push((w, wd, a));
        wrenches.push((force, moment));
    }
    let mut tau = vec![0.0; n];
    for i in (0..n).rev() {
        let (force, moment) = wrenches[i];
        if let Some(p) = chain.bodies[i].parent {
            let f = frames[i] * force;
            wrenches[p].0 += f;
            wrenches[p].1 += frames[i] * moment + origin(i).cross(&f);
        }
        let along = if prismatic(i) { force } else { moment };
        tau[i] = chain.bodies[i].axis.dot(&along);
    }
    let mut projected = vec![0.0; chain.dof()];
    for (b, t) in tau.iter().enumerate() {
        let (d, multiplier, _) = chain.driver(b);
        projected[d] += multiplier * t;
    }
    projected
}

fn assert_close(what: &str, got: &[f64], want: &[f64]) {
    let scale = want.iter().fold(1.0_f64, |s, x| s.max(x.abs()));
    for (k, (g, w)) in got.iter().zip(want).enumerate() {
        assert!((g - w).abs() <= 1e-12 * scale, "{what}[{k}]: {g} vs {w}");
    }
}

/// Every traced function of a shipped model against the numeric reference.
fn check_against_reference(model: &str, samples: usize) {
    let path = format!("{}/../models/{model}.toml", env!("CARGO_MANIFEST_DIR"));
    check_description(&Description::load(&path).unwrap(), samples);
}

/// Every traced function against the numeric reference, on random states.
fn check_description(description: &Description, samples: usize) {
    let chain = description.chain();
    let traced = trace(chain);
    let (n, bodies) = (chain.dof(), chain.bodies.len());
    let params: Vec<[f64; 10]> = chain
        .bodies
        .iter()
        .map(|b| b.inertial.standard_parameters())
        .collect();
    let mut state = 7;
    for sample in 0..samples {
        let mut random =
            |scale: f64| -> Vec<f64> { (0..n).map(|_| scale * uniform(&mut state)).collect() };
        let (q, qd, qdd) = (random(std::f64::consts::PI), random(3.0), random(10.0));
        let x = program_inputs(chain, &q, &qd, &qdd);
        let eval = |roots: &[NodeId]| traced.dag.evaluate(roots, &x);
        let zeros = vec![0.0; n];
        let mut tau = rnea(chain, &params, &q, &qd, &qdd, true);
        let mut gravity = rnea(chain, &params, &q, &zeros, &zeros, true);
        // Each joint's effects at its own state, on its degree of freedom
        // times the multiplier (1 for a joint that moves alone).
        for (b, body) in chain.bodies.iter().enumerate() {
            let (d, m, offset) = chain.driver(b);
            let e = &body.effects;
            let (q, qd, qdd) = (m * q[d] + offset, m * qd[d], m * qdd[d]);
            let (sign, angle) = (qd.signum(), e.ripple_cycles * q);
            let position = e.spring * (q - e.spring_rest)
                + e.ripple_sin * angle.sin()
                + e.ripple_cos * angle.cos();
            let breakaway = if e.stribeck_velocity > 0.0 {
                sign * (-(qd / e.stribeck_velocity).powi(2)).exp()
            } else {
                0.0
            };
            tau[d] += m
                * (e.armature * qdd
                    + e.viscous * qd
                    + e.coulomb * sign
                    + e.coulomb_asymmetry * sign * sign
                    + e.stribeck * breakaway
                    + e.offset
                    + position);
            gravity[d] += m * position;
        }
        assert_close("tau", &eval(&traced.tau), &tau);
        assert_close("gravity", &eval(&traced.gravity), &gravity);
        let coriolis = rnea(chain, &params, &q, &qd, &zeros, false);
        assert_close("coriolis", &eval(&traced.coriolis), &coriolis);
        if sample % 10 != 0 {
            continue;
        }
        let mut mass = vec![0.0; n * n];
        for j in 0..n {
            let mut unit = zeros.clone();
            unit[j] = 1.0;
            let column = rnea(chain, &params, &q, &zeros, &unit, false);
            for i in 0..n {
                mass[i * n + j] = column[i];
            }
        }
        for (b, body) in chain.bodies.iter().enumerate() {
            let (d, m, _) = chain.driver(b);
            mass[d * n + d] += m * m * body.effects.armature;
        }
        assert_close("mass_matrix", &eval(&traced.mass_matrix), &mass);
        let y = eval(&traced.regressor);
        for (k, p) in (0..bodies).flat_map(|k| (0..10).map(move |p| (k, p))) {
            let mut unit = vec![[0.0; 10]; bodies];
            unit[k][p] = 1.0;
            let column = rnea(chain, &unit, &q, &qd, &qdd, true);
            let width = crate::schema::PARAMETERS_PER_JOINT * bodies;
            let got: Vec<f64> = (0..n).map(|i| y[i * width + 10 * k + p]).collect();
            assert_close("regressor", &got, &column);
        }
    }
}

#[test]
fn panda_matches_the_numeric_reference() {
    check_against_reference("panda", 1000);
}

#[test]
fn gen3_lite_matches_the_numeric_reference() {
    check_against_reference("kinova_gen3_lite", 1000);
    check_against_reference("kinova_gen3_lite_3dof", 1000);
}

/// A gripper-like chain: a prismatic finger slides with the arm's last
/// joint, and a revolute joint follows the first, with offsets.
#[test]
fn coupled_joints_match_the_numeric_reference() {
    let coupled = SLIDERS
        .replacen(
            "    axis = [1.0, 0.0, 0.0]\n    effects = { coulomb = 3.0, coulomb_asymmetry = 1.0, stribeck = 2.0, stribeck_velocity = 0.02, ripple_sin = 0.5, ripple_cos = 0.2, ripple_cycles = 200.0 }",
            "    axis = [1.0, 0.0, 0.0]\n    mimic = { joint = \"slide4\", multiplier = -0.7, offset = 0.02 }\n    effects = { armature = 0.4, viscous = 3.0, coulomb = 1.5, coulomb_asymmetry = 0.5, offset = 0.2, spring = 30.0, spring_rest = 0.01 }",
            1,
        )
        .replacen(
            "    axis = [0.0, 1.0, 0.0]\n",
            "    axis = [0.0, 1.0, 0.0]\n    mimic = { joint = \"slide1\", multiplier = 3.0, offset = 0.4 }\n",
            1,
        );
    assert_eq!(coupled.matches("mimic").count(), 2);
    let description = Description::parse(&coupled, "coupled", Path::new("c.toml")).unwrap();
    assert_eq!(
        (description.dof(), description.chain().bodies.len()),
        (2, 4)
    );
    check_description(&description, 300);
    // A second finger following the first joint off the chain: the moving
    // bodies form a tree.
    let finger = r#"
    [[links]]
    name = "e"
    mass = 0.3
    com = [0.02, -0.01, 0.05]
    inertia = { ixx = 0.0004, iyy = 0.0003, izz = 0.0002, ixy = 0.00001 }
    [[joints]]
    name = "twin"
    type = "revolute"
    parent = "b"
    child = "e"
    origin = { xyz = [0.1, 0.05, -0.02], rpy = [0.4, 0.1, -0.2] }
    axis = [0.0, 0.6, 0.8]
    mimic = { joint = "slide1", multiplier = -2.0, offset = 0.3 }
    "#;
    let tree = format!("{coupled}{finger}");
    let description = Description::parse(&tree, "tree", Path::new("t.toml")).unwrap();
    let chain = description.chain();
    assert_eq!((description.dof(), chain.bodies.len()), (2, 5));
    assert_eq!(
        chain.bodies.iter().filter(|b| b.parent == Some(1)).count(),
        2
    );
    check_description(&description, 300);
}

#[test]
fn lift_arm_matches_the_numeric_reference() {
    check_against_reference("lift_arm", 1000);
}

/// Prismatic joints first, between and last, along tilted axes, behind
/// tilted frames, with every effect.
pub(super) const SLIDERS: &str = r#"
    gravity = [0.3, -1.2, -9.7]
    [[links]]
    name = "base"
    [[links]]
    name = "a"
    mass = 3.0
    com = [0.1, -0.05, 0.2]
    inertia = { ixx = 0.05, iyy = 0.04, izz = 0.03, ixy = 0.002, ixz = -0.001, iyz = 0.003 }
    [[links]]
    name = "b"
    mass = 1.5
    com = [0.2, 0.01, -0.03]
    inertia = { ixx = 0.01, iyy = 0.02, izz = 0.015, ixy = -0.001 }
    [[links]]
    name = "c"
    mass = 0.8
    com = [0.05, 0.1, 0.0]
    inertia = { ixx = 0.004, iyy = 0.003, izz = 0.005, iyz = 0.0004 }
    [[links]]
    name = "d"
    mass = 0.5
    com = [0.0, 0.02, 0.07]
    inertia = { ixx = 0.002, iyy = 0.002, izz = 0.001 }
    [[joints]]
    name = "slide1"
    type = "prismatic"
    parent = "base"
    child = "a"
    origin = { xyz = [0.1, 0.2, 0.3], rpy = [0.2, -0.4, 0.7] }
    axis = [0.3, -0.5, 0.8]
    effects = { armature = 1.5, viscous = 20.0, coulomb = 5.0, offset = -2.0, spring = 100.0, spring_rest = 0.05 }
    [[joints]]
    name = "turn2"
    type = "revolute"
    parent = "a"
    child = "b"
    origin = { xyz = [0.3, 0.0, 0.1], rpy = [1.0, 0.2, -0.3] }
    axis = [0.0, 1.0, 0.0]
    [[joints]]
    name = "slide3"
    type = "prismatic"
    parent = "b"
    child = "c"
    origin = { xyz = [0.25, -0.1, 0.0], rpy = [0.0, 0.5, 0.0] }
    axis = [1.0, 0.0, 0.0]
    effects = { coulomb = 3.0, coulomb_asymmetry = 1.0, stribeck = 2.0, stribeck_velocity = 0.02, ripple_sin = 0.5, ripple_cos = 0.2, ripple_cycles = 200.0 }
    [[joints]]
    name = "slide4"
    type = "prismatic"
    parent = "c"
    child = "d"
    origin = { xyz = [0.0, 0.1, 0.05], rpy = [-0.6, 0.0, 1.1] }
    axis = [0.6, 0.0, -0.8]
"#;

#[test]
fn prismatic_joints_anywhere_match_the_numeric_reference() {
    let description = Description::parse(SLIDERS, "sliders", Path::new("s.toml")).unwrap();
    check_description(&description, 500);
}

/// A cart on a horizontal rail carrying a pendulum: the textbook cart-pole
/// equations, gravity along -z.
#[test]
fn cart_pole_matches_its_closed_form() {
    let source = r#"
        [[links]]
        name = "rail"
        [[links]]
        name = "cart"
        mass = 2.0
        inertia = { ixx = 0.01, iyy = 0.01, izz = 0.01 }
        [[links]]
        name = "pole"
        mass = 0.5
        com = [0.0, 0.0, 0.6]
        inertia = { ixx = 0.02, iyy = 0.02, izz = 0.001 }
        [[joints]]
        name = "cart"
        type = "prismatic"
        parent = "rail"
        child = "cart"
        axis = [1.0, 0.0, 0.0]
        effects = { viscous = 0.7 }
        [[joints]]
        name = "hinge"
        type = "revolute"
        parent = "cart"
        child = "pole"
        axis = [0.0, 1.0, 0.0]
    "#;
    let description = Description::parse(source, "cart_pole", Path::new("c.toml")).unwrap();
    let traced = trace(description.chain());
    let (mc, mp, l, ip, g) = (2.0, 0.5, 0.6, 0.02, 9.81);
    for (x, th, xd, thd, xdd, thdd) in [
        (0.3, 0.4, -0.5, 1.2, 0.8, -2.0),
        (-1.0, -2.5, 1.5, 0.3, -0.2, 1.0),
    ] {
        let inputs = inputs_of(&description, &[x, th], &[xd, thd], &[xdd, thdd]);
        let tau = traced.dag.evaluate(&traced.tau, &inputs);
        // The pole's centre sits at (x + l sin th, l cos th).
        let force =
            (mc + mp) * xdd + mp * l * th.cos() * thdd - mp * l * th.sin() * thd * thd + 0.7 * xd;
        let torque = mp * l * th.cos() * xdd + (ip + mp * l * l) * thdd - mp * g * l * th.sin();
        assert!((tau[0] - force).abs() < 1e-12, "{} vs {force}", tau[0]);
        assert!((tau[1] - torque).abs() < 1e-12, "{} vs {torque}", tau[1]);
    }
}

#[test]
fn planar_arm_matches_its_closed_form() {
    let description = Description::parse(PLANAR, "planar", Path::new("planar.toml")).unwrap();
    let traced = trace(description.chain());
    let (q, qd, qdd) = ([0.3, -1.1], [0.7, -0.4], [1.3, 0.5]);
    let x = inputs_of(&description, &q, &qd, &qdd);
    let tau = traced.dag.evaluate(&traced.tau, &x);
    let rigid = closed_form(&q, &qd, &qdd);
    let effects = 0.01 * qdd[0] + 0.3 * qd[0] + 0.2 - 0.1;
    assert!(
        (tau[0] - rigid[0] - effects).abs() < 1e-12,
        "{tau:?} {rigid:?}"
    );
    let (elbow, spring) = elbow_effects(q[1], qd[1]);
    assert!((tau[1] - rigid[1] - elbow - spring).abs() < 1e-12);
    // Backwards, the elbow's dry friction is coulomb - asymmetry.
    let x = inputs_of(&description, &q, &[0.7, 0.4], &qdd);
    let forwards = traced.dag.evaluate(&traced.tau, &x)[1];
    let x = inputs_of(&description, &q, &[0.7, -0.4], &qdd);
    let backwards = traced.dag.evaluate(&traced.tau, &x)[1];
    let rigid_difference =
        closed_form(&q, &[0.7, 0.4], &qdd)[1] - closed_form(&q, &[0.7, -0.4], &qdd)[1];
    let stribeck = 2.0 * 0.15 * (-(0.4_f64 / 0.5).powi(2)).exp();
    assert!((forwards - backwards - rigid_difference - 0.6 - stribeck).abs() < 1e-12);
}

#[test]
fn functions_are_consistent() {
    let description = Description::parse(PLANAR, "planar", Path::new("planar.toml")).unwrap();
    let traced = trace(description.chain());
    let params: Vec<f64> = description
        .chain()
        .bodies
        .iter()
        .flat_map(|b| b.inertial.standard_parameters())
        .chain(
            description
                .chain()
                .bodies
                .iter()
                .flat_map(|b| b.effects.parameters()),
        )
        .collect();
    let (q, qd, qdd) = ([-0.6, 2.0], [1.5, 0.9], [-0.2, 0.8]);
    let x = inputs_of(&description, &q, &qd, &qdd);
    let eval = |roots: &[NodeId]| traced.dag.evaluate(roots, &x);
    let (tau, m, g, c) = (
        eval(&traced.tau),
        eval(&traced.mass_matrix),
        eval(&traced.gravity),
        eval(&traced.coriolis),
    );
    let y = eval(&traced.regressor);
    let width = params.len();
    for i in 0..2 {
        // g includes the elbow's spring.
        let effects = if i == 0 {
            0.3 * qd[0] + 0.2 - 0.1
        } else {
            elbow_effects(q[1], qd[1]).0
        };
        let split = m[2 * i] * qdd[0] + m[2 * i + 1] * qdd[1] + c[i] + g[i] + effects;
        let regressed: f64 = (0..width).map(|k| y[width * i + k] * params[k]).sum();
        assert!(
            (tau[i] - split).abs() < 1e-12,
            "joint {i}: {} vs {split}",
            tau[i]
        );
        assert!((tau[i] - regressed).abs() < 1e-12);
    }
    assert_eq!(m[1], m[2]);
}

/// The traced programs of `toml` with `from` replaced by `to` (once).
fn traced_with_edit(toml: &str, from: &str, to: &str) -> Traced {
    assert_eq!(toml.matches(from).count(), 1, "{from} must occur once");
    let edited = toml.replacen(from, to, 1);
    let description = Description::parse(&edited, "panda", Path::new("panda.toml")).unwrap();
    trace(description.chain())
}

#[test]
fn one_number_edits_keep_the_program_shape() {
    // The emitted text is a function of the DAG, the constants' names and
    // the listed values: equal DAGs and names mean one changed line.
    let path = format!("{}/../models/panda.toml", env!("CARGO_MANIFEST_DIR"));
    let toml = std::fs::read_to_string(path).unwrap();
    let base = traced_with_edit(&toml, "mass = 0.735522", "mass = 0.735522");
    let edits = [
        ("mass = 0.735522", "mass = 0.80"),
        ("com = [0.010517, -0.004252", "com = [0.02, -0.004252"),
        ("izz = 0.004815", "izz = 0.005"),
        ("xyz = [0.0, -0.316, 0.0]", "xyz = [0.0, -0.32, 0.0]"),
        ("xyz = [0.088, 0.0, 0.0]", "xyz = [0.09, 0.0, 0.0]"),
    ];
    for (from, to) in edits {
        let edited = traced_with_edit(&toml, from, to);
        assert_eq!(base.dag.nodes, edited.dag.nodes, "{from} -> {to}");
        assert_eq!(base.dag.derived, edited.dag.derived, "{from} -> {to}");
        assert_eq!(
            base.tau_lanes.tangents, edited.tau_lanes.tangents,
            "{from} -> {to}"
        );
        assert_eq!(
            base.tau_lanes.roots, edited.tau_lanes.roots,
            "{from} -> {to}"
        );
        let names =
            |t: &Traced| -> Vec<String> { t.dag.params.iter().map(|p| p.name.clone()).collect() };
        assert_eq!(names(&base), names(&edited), "{from} -> {to}");
        let changed: Vec<(&str, f64, f64)> = base
            .groups
            .iter()
            .flat_map(|g| &g.items)
            .zip(edited.groups.iter().flat_map(|g| &g.items))
            .filter(|(a, b)| a.1 != b.1)
            .map(|(a, b)| match (&a.1, &b.1) {
                (Definition::Value(x), Definition::Value(y)) => (a.0.as_str(), *x, *y),
                _ => panic!("a formula changed: {} {:?} {:?}", a.0, a.1, b.1),
            })
            .collect();
        assert_eq!(changed.len(), 1, "{from} -> {to}: {changed:?}");
    }
}

#[test]
fn a_zero_becoming_non_zero_is_a_structural_change() {
    let path = format!("{}/../models/planar_2link.toml", env!("CARGO_MANIFEST_DIR"));
    let toml = std::fs::read_to_string(path).unwrap();
    let description = Description::parse(&toml, "planar", Path::new("planar.toml")).unwrap();
    let before = trace(description.chain()).dag.params.len();
    let chain = {
        let mut chain = description.chain().clone();
        chain.bodies[1].effects.viscous = 0.25;
        chain
    };
    let after = trace(&chain).dag.params.len();
    assert_eq!(
        after,
        before + 1,
        "the new coefficient becomes a named leaf"
    );
}
