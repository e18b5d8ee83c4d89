//! The traced programs beyond tau against independent numbers: the bias
//! and the factor against tau and M, the derivatives against central
//! differences of tau, the placements against a plain forward kinematics,
//! the Jacobian against differences of the placements and its drift
//! against the Jacobian's change along a motion.

use nalgebra::{Matrix3, Vector3};

use super::tests::{PLANAR, SLIDERS};
use super::*;
use crate::description::Description;
use crate::schema::JointKind;
use crate::states::uniform;
use std::path::Path;

fn shipped(model: &str) -> Description {
    Description::load(format!(
        "{}/../models/{model}.toml",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap()
}

/// The descriptions every check runs on: revolute, prismatic, coupled.
fn descriptions() -> Vec<Description> {
    let parsed = |toml: &str| Description::parse(toml, "t", Path::new("t.toml")).unwrap();
    let coupled = SLIDERS.replacen(
        "    axis = [0.0, 1.0, 0.0]\n",
        "    axis = [0.0, 1.0, 0.0]\n    mimic = { joint = \"slide1\", multiplier = 3.0, offset = 0.4 }\n",
        1,
    );
    vec![
        shipped("panda"),
        shipped("lift_arm"),
        shipped("kinova_gen3_lite_3dof_plant"),
        parsed(PLANAR),
        parsed(SLIDERS),
        parsed(&coupled),
    ]
}

/// Evaluates `roots` of `traced` at a state.
fn at(
    traced: &Traced,
    chain: &Chain,
    roots: &[NodeId],
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
) -> Vec<f64> {
    traced
        .dag
        .evaluate(roots, &program_inputs(chain, q, qd, qdd))
}

/// Random states (q, qd, qdd) of `n` joints, speeds away from zero so no
/// difference step crosses a sign change.
fn states(n: usize, count: usize) -> Vec<[Vec<f64>; 3]> {
    let mut seed = 11;
    (0..count)
        .map(|_| {
            let mut draw = |scale: f64, floor: f64| -> Vec<f64> {
                (0..n)
                    .map(|_| {
                        let x = uniform(&mut seed);
                        scale * x + floor * x.signum()
                    })
                    .collect()
            };
            [draw(1.5, 0.0), draw(1.0, 0.2), draw(5.0, 0.0)]
        })
        .collect()
}

fn assert_near(what: &str, got: &[f64], want: &[f64], relative: f64) {
    let scale = want.iter().fold(1.0_f64, |s, x| s.max(x.abs()));
    for (k, (g, w)) in got.iter().zip(want).enumerate() {
        assert!(
            (g - w).abs() <= relative * scale,
            "{what}[{k}]: {g} vs {w} (scale {scale})"
        );
    }
}

/// Central difference of `f` along `direction`, Richardson-extrapolated
/// (error of order h^4).
fn difference(f: &dyn Fn(f64) -> Vec<f64>, h: f64) -> Vec<f64> {
    let central = |h: f64| -> Vec<f64> {
        let (plus, minus) = (f(h), f(-h));
        plus.iter()
            .zip(&minus)
            .map(|(p, m)| (p - m) / (2.0 * h))
            .collect()
    };
    let (coarse, fine) = (central(h), central(h / 2.0));
    fine.iter()
        .zip(&coarse)
        .map(|(f, c)| (4.0 * f - c) / 3.0)
        .collect()
}

fn moved(x: &[f64], j: usize, by: f64) -> Vec<f64> {
    let mut x = x.to_vec();
    x[j] += by;
    x
}

#[test]
fn bias_and_factor_agree_with_tau_and_the_mass_matrix() {
    for description in descriptions() {
        let chain = description.chain();
        let traced = trace(chain);
        let n = chain.dof();
        for [q, qd, qdd] in states(n, 50) {
            let zero = vec![0.0; n];
            let bias = at(&traced, chain, &traced.bias, &q, &qd, &qdd);
            let tau0 = at(&traced, chain, &traced.tau, &q, &qd, &zero);
            assert_near("bias", &bias, &tau0, 1e-13);
            let m = at(&traced, chain, &traced.mass_matrix, &q, &qd, &qdd);
            let f = at(&traced, chain, &traced.mass_factor, &q, &qd, &qdd);
            let l = |i: usize, k: usize| {
                if i == k {
                    1.0
                } else if i > k {
                    f[i * n + k]
                } else {
                    0.0
                }
            };
            let rebuilt: Vec<f64> = (0..n * n)
                .map(|ij| {
                    (0..n)
                        .map(|k| l(ij / n, k) * l(ij % n, k) / f[k * n + k])
                        .sum()
                })
                .collect();
            assert_near("L D L^T", &rebuilt, &m, 1e-12);
        }
    }
}

#[test]
fn tau_derivatives_equal_differences_of_tau() {
    for description in descriptions() {
        let chain = description.chain();
        let traced = trace(chain);
        let n = chain.dof();
        for [q, qd, qdd] in states(n, 20) {
            let by_q = at(&traced, chain, &traced.tau_by_q, &q, &qd, &qdd);
            let by_qd = at(&traced, chain, &traced.tau_by_qd, &q, &qd, &qdd);
            for j in 0..n {
                let tau = |x: &[f64], v: &[f64]| at(&traced, chain, &traced.tau, x, v, &qdd);
                let column = |m: &[f64]| (0..n).map(|i| m[i * n + j]).collect::<Vec<_>>();
                let dq = difference(&|h| tau(&moved(&q, j, h), &qd), 1e-4);
                assert_near("d tau / d q", &column(&by_q), &dq, 1e-9);
                let dqd = difference(&|h| tau(&q, &moved(&qd, j, h)), 1e-4);
                assert_near("d tau / d qd", &column(&by_qd), &dqd, 1e-9);
            }
        }
    }
}

#[test]
fn the_two_lane_derivatives_equal_the_scalar_ones() {
    for description in descriptions() {
        let chain = description.chain();
        let traced = trace(chain);
        let n = chain.dof();
        for [q, qd, qdd] in states(n, 5) {
            let x = program_inputs(chain, &q, &qd, &qdd);
            let by_q = traced.dag.evaluate(&traced.tau_by_q, &x);
            let by_qd = traced.dag.evaluate(&traced.tau_by_qd, &x);
            let lanes = traced.tau_lanes.evaluate(&traced.dag, &x);
            let mut got = (vec![f64::NAN; n * n], vec![f64::NAN; n * n]);
            for (pair, group) in traced.pairs.iter().zip(&lanes) {
                for (direction, lane) in pair.iter().zip(0..) {
                    let (matrix, j) = match *direction {
                        Direction::Angle(j) => (&mut got.0, j),
                        Direction::Speed(j) => (&mut got.1, j),
                    };
                    for i in 0..n {
                        matrix[i * n + j] = group[i][lane];
                    }
                }
            }
            assert_near("d tau / d q, two lanes", &got.0, &by_q, 1e-12);
            assert_near("d tau / d qd, two lanes", &got.1, &by_qd, 1e-12);
        }
    }
}

/// Each moving body's frame by plain matrix products.
fn placements(chain: &Chain, q: &[f64]) -> Vec<(Matrix3<f64>, Vector3<f64>)> {
    let mut out: Vec<(Matrix3<f64>, Vector3<f64>)> = Vec::new();
    for (b, body) in chain.bodies.iter().enumerate() {
        let (d, multiplier, offset) = chain.driver(b);
        let x = multiplier * q[d] + offset;
        let (r0, p0) = body
            .parent
            .map_or((Matrix3::identity(), Vector3::zeros()), |p| out[p]);
        let (turn, slide) = match body.kind {
            JointKind::Prismatic => (0.0, x),
            _ => (x, 0.0),
        };
        let local = body.rotation * crate::reduce::axis_angle(&body.axis, turn);
        let origin = body.translation + body.rotation * body.axis * slide;
        out.push((r0 * local, p0 + r0 * origin));
    }
    out
}

fn pose_entries(r: &Matrix3<f64>, p: &Vector3<f64>) -> Vec<f64> {
    let mut v: Vec<f64> = (0..9).map(|k| r[(k / 3, k % 3)]).collect();
    v.extend(p.iter());
    v
}

#[test]
fn placements_jacobian_and_drift_equal_plain_kinematics() {
    for description in descriptions() {
        let chain = description.chain();
        let traced = trace(chain);
        let (n, tip) = (chain.dof(), traced.tip);
        for [q, qd, _] in states(n, 20) {
            let poses = at(&traced, chain, &traced.link_poses, &q, &qd, &qd);
            let want: Vec<f64> = placements(chain, &q)
                .iter()
                .flat_map(|(r, p)| pose_entries(r, p))
                .collect();
            assert_near("link poses", &poses, &want, 1e-13);
            let jacobian = |q: &[f64]| at(&traced, chain, &traced.tip_jacobian, q, &qd, &qd);
            let j = jacobian(&q);
            for d in 0..n {
                let column: Vec<f64> = (0..6).map(|k| j[k * n + d]).collect();
                let tip_at = |h: f64| {
                    let (r, p) = placements(chain, &moved(&q, d, h))[tip];
                    pose_entries(&r, &p)
                };
                let rate = difference(&tip_at, 1e-3);
                let r = placements(chain, &q)[tip].0;
                let r_dot = Matrix3::from_fn(|a, b| rate[3 * a + b]);
                let spin = r_dot * r.transpose();
                let angular = [spin[(2, 1)], spin[(0, 2)], spin[(1, 0)]];
                let want: Vec<f64> = rate[9..12].iter().copied().chain(angular).collect();
                assert_near("tip jacobian", &column, &want, 1e-9);
            }
            let drift = at(&traced, chain, &traced.tip_jacobian_dot_qd, &q, &qd, &qd);
            let along = |h: f64| {
                let x: Vec<f64> = q.iter().zip(&qd).map(|(q, v)| q + h * v).collect();
                let j = jacobian(&x);
                (0..6)
                    .map(|k| (0..n).map(|d| j[k * n + d] * qd[d]).sum())
                    .collect()
            };
            assert_near("J-dot qd", &drift, &difference(&along, 1e-3), 1e-9);
        }
    }
}

#[test]
fn a_tool_frame_fixed_to_the_tip_is_placed_and_its_jacobian_is_exact() {
    // A flange and a tool centre point after the last joint, through two
    // fixed joints; a second fixed leaf listed earlier is not the tool.
    let toml = format!(
        "{SLIDERS}{}",
        r#"
    [[links]]
    name = "flange"
    [[links]]
    name = "tcp"
    [[links]]
    name = "camera"
    [[joints]]
    name = "to_camera"
    type = "fixed"
    parent = "d"
    child = "camera"
    origin = { xyz = [0.0, 0.05, 0.0] }
    [[joints]]
    name = "to_flange"
    type = "fixed"
    parent = "d"
    child = "flange"
    origin = { xyz = [0.0, 0.0, 0.1], rpy = [0.3, 0.0, 0.0] }
    [[joints]]
    name = "to_tcp"
    type = "fixed"
    parent = "flange"
    child = "tcp"
    origin = { xyz = [0.02, 0.0, 0.15], rpy = [0.0, 0.5, -0.2] }
    "#
    );
    let description = Description::parse(&toml, "t", Path::new("t.toml")).unwrap();
    let tool = description.tool_frame().expect("a tool frame");
    assert_eq!(tool.link, "tcp");
    let chain = description.chain();
    let traced = trace_with_tool(chain, Some(&tool));
    let (_, pose, jacobian) = traced.tool.clone().unwrap();
    let n = chain.dof();
    let tool_at = |q: &[f64]| {
        let (r, p) = placements(chain, q)[traced.tip];
        pose_entries(&(r * tool.rotation), &(p + r * tool.translation))
    };
    for [q, qd, _] in states(n, 20) {
        let got = at(&traced, chain, &pose, &q, &qd, &qd);
        assert_near("tool pose", &got, &tool_at(&q), 1e-13);
        let j = at(&traced, chain, &jacobian, &q, &qd, &qd);
        for d in 0..n {
            let rate = difference(&|h| tool_at(&moved(&q, d, h)), 1e-3);
            let r = Matrix3::from_fn(|a, b| got[3 * a + b]);
            let spin = Matrix3::from_fn(|a, b| rate[3 * a + b]) * r.transpose();
            let want: Vec<f64> = rate[9..12]
                .iter()
                .copied()
                .chain([spin[(2, 1)], spin[(0, 2)], spin[(1, 0)]])
                .collect();
            let column: Vec<f64> = (0..6).map(|k| j[k * n + d]).collect();
            assert_near("tool jacobian", &column, &want, 1e-9);
        }
    }
    assert!(shipped("planar_2link").tool_frame().is_none());
}

#[test]
fn the_lanes_do_fewer_operations_than_the_scalar_passes() {
    let description = shipped("panda");
    let traced = trace(description.chain());
    let scalar = traced
        .dag
        .negation_aware_count(&[traced.tau_by_q.clone(), traced.tau_by_qd.clone()].concat());
    let lanes = &traced.tau_lanes;
    let primal = traced.dag.negation_aware_count(&lanes.primal_uses());
    // Panda: 5,439 scalar operations; 599 primal and 3,083 lane ones.
    assert!(
        primal + lanes.operation_count() < scalar * 7 / 10,
        "{primal} + {} against {scalar}",
        lanes.operation_count()
    );
}
