//! The generated functions beyond tau: forward dynamics and `solve_mass`
//! against tau and M, the exact derivatives against dual numbers through
//! an independent Newton-Euler (`dual.rs`, 1e-10) and central differences
//! (1e-6), the kinematics against the oracle's placements and against
//! differences of the tip pose and of the Jacobian along a motion.

mod dual;

use nalgebra::{DMatrix, DVector};
use sdnn::oracle::{self, Model};

use crate::util::{States, oracle};

/// Largest difference relative to the largest magnitude of `want` (or 1).
fn relative_error(got: &[f64], want: &[f64]) -> f64 {
    let scale = want.iter().fold(1.0_f64, |s, x| s.max(x.abs()));
    got.iter()
        .zip(want)
        .map(|(g, w)| (g - w).abs() / scale)
        .fold(0.0, f64::max)
}

fn assert_relative(what: &str, got: &[f64], want: &[f64], tolerance: f64) {
    let error = relative_error(got, want);
    assert!(
        error <= tolerance,
        "{what}: relative error {error:e}\n got {got:?}\nwant {want:?}"
    );
}

/// A state with speeds at least 0.2 from zero, so that no difference step
/// crosses a Coulomb sign change.
fn state(states: &mut States) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let (q, mut qd, qdd) = states.next();
    for v in &mut qd {
        *v += 0.2 * v.signum();
    }
    (q, qd, qdd)
}

#[test]
fn forward_dynamics_inverts_tau_for_every_compiled_model() {
    for model in sdnn::models::MODELS {
        let reference = oracle(model.name());
        let n = model.dof();
        let mut states = States::new(n, 3);
        let singular = (0..n).any(|d| {
            let m = oracle::crba(&reference, &vec![0.3; n]);
            m[(d, d)] == 0.0
        });
        for _ in 0..500 {
            let (q, qd, qdd) = states.next();
            let tau = model.tau(&q, &qd, &qdd).unwrap();
            let mut solved = vec![0.0; n];
            model
                .forward_dynamics(&q, &qd, tau.as_slice(), &mut solved)
                .unwrap();
            if singular {
                // A joint that moves no mass and has no armature.
                assert!(solved.iter().any(|x| !x.is_finite()), "{}", model.name());
                continue;
            }
            let back = model.tau(&q, &qd, &solved).unwrap();
            let what = format!("{} tau(forward_dynamics(tau))", model.name());
            assert_relative(&what, back.as_slice(), tau.as_slice(), 1e-10);
            let by_oracle = oracle::forward_dynamics(&reference, &q, &qd, tau.as_slice()).unwrap();
            let what = format!("{} forward dynamics against the oracle", model.name());
            assert_relative(&what, &solved, by_oracle.as_slice(), 1e-8);
            let pose = model.tip_pose(&q).unwrap();
            let (r, p) = oracle::placements(&reference, &q)[oracle::tip(&reference)];
            let got: Vec<f64> = pose
                .rotation
                .iter()
                .flatten()
                .chain(&pose.position)
                .copied()
                .collect();
            let want: Vec<f64> = (0..9)
                .map(|k| r[(k / 3, k % 3)])
                .chain(p.iter().copied())
                .collect();
            assert_relative(&format!("{} tip pose", model.name()), &got, &want, 1e-13);
        }
    }
}

/// A function of q, of (q, qd) and of a state, on slices.
type OfQ<T> = Box<dyn Fn(&[f64]) -> T>;
type OfTwo<T> = Box<dyn Fn(&[f64], &[f64]) -> T>;
type OfThree<T> = Box<dyn Fn(&[f64], &[f64], &[f64]) -> T>;

/// One model's fixed-size functions, as slices.
struct Functions {
    name: &'static str,
    tau: OfThree<Vec<f64>>,
    mass_matrix: OfQ<DMatrix<f64>>,
    solve_mass: OfTwo<Vec<f64>>,
    forward_dynamics: OfThree<Vec<f64>>,
    tau_derivatives: OfThree<[DMatrix<f64>; 2]>,
    forward_dynamics_derivatives: OfThree<[DMatrix<f64>; 2]>,
    /// Rotation row-major then position.
    tip_pose: OfQ<Vec<f64>>,
    tip_jacobian: OfQ<DMatrix<f64>>,
    tip_pose_and_jacobian: OfQ<(Vec<f64>, DMatrix<f64>)>,
    tip_jacobian_dot_qd: OfTwo<Vec<f64>>,
}

macro_rules! functions {
    ($module:ident) => {{
        use sdnn::models::$module as arm;
        const N: usize = arm::DOF;
        fn a(x: &[f64]) -> [f64; N] {
            x.try_into().unwrap()
        }
        fn matrix<const R: usize, const C: usize>(m: [[f64; C]; R]) -> DMatrix<f64> {
            DMatrix::from_fn(R, C, |r, c| m[r][c])
        }
        Functions {
            name: stringify!($module),
            tau: Box::new(|q, qd, qdd| arm::tau(&a(q), &a(qd), &a(qdd)).to_vec()),
            mass_matrix: Box::new(|q| matrix(arm::mass_matrix(&a(q)))),
            solve_mass: Box::new(|q, b| arm::solve_mass(&a(q), &a(b)).to_vec()),
            forward_dynamics: Box::new(|q, qd, tau| {
                arm::forward_dynamics(&a(q), &a(qd), &a(tau)).to_vec()
            }),
            tau_derivatives: Box::new(|q, qd, qdd| {
                let (by_q, by_qd) = arm::tau_derivatives(&a(q), &a(qd), &a(qdd));
                [matrix(by_q), matrix(by_qd)]
            }),
            forward_dynamics_derivatives: Box::new(|q, qd, tau| {
                let (by_q, by_qd) = arm::forward_dynamics_derivatives(&a(q), &a(qd), &a(tau));
                [matrix(by_q), matrix(by_qd)]
            }),
            tip_pose: Box::new(|q| {
                let pose = arm::tip_pose(&a(q));
                pose.rotation
                    .iter()
                    .flatten()
                    .chain(&pose.position)
                    .copied()
                    .collect()
            }),
            tip_jacobian: Box::new(|q| matrix(arm::tip_jacobian(&a(q)))),
            tip_pose_and_jacobian: Box::new(|q| {
                let (pose, jacobian) = arm::tip_pose_and_jacobian(&a(q));
                let pose = pose
                    .rotation
                    .iter()
                    .flatten()
                    .chain(&pose.position)
                    .copied();
                (pose.collect(), matrix(jacobian))
            }),
            tip_jacobian_dot_qd: Box::new(|q, qd| arm::tip_jacobian_dot_qd(&a(q), &a(qd)).to_vec()),
        }
    }};
}

/// Central difference of `f` at step h along one coordinate.
fn central(f: &dyn Fn(f64) -> Vec<f64>, h: f64) -> Vec<f64> {
    let (plus, minus) = (f(h), f(-h));
    plus.iter()
        .zip(&minus)
        .map(|(p, m)| (p - m) / (2.0 * h))
        .collect()
}

fn moved(x: &[f64], j: usize, by: f64) -> Vec<f64> {
    let mut x = x.to_vec();
    x[j] += by;
    x
}

fn column(m: &DMatrix<f64>, j: usize) -> Vec<f64> {
    m.column(j).iter().copied().collect()
}

fn flat(rows: &[Vec<f64>]) -> Vec<f64> {
    rows.concat()
}

fn check(f: &Functions, reference: &Model, samples: usize) {
    let n = reference.dof();
    let mut states = States::new(n, 17);
    for _ in 0..samples {
        let (q, qd, qdd) = state(&mut states);
        let name = f.name;
        // solve_mass and forward dynamics.
        let m = (f.mass_matrix)(&q);
        let b: Vec<f64> = qdd.iter().map(|x| 3.0 * x - 1.0).collect();
        let x = DVector::from_vec((f.solve_mass)(&q, &b));
        assert_relative(
            &format!("{name} M solve_mass(b)"),
            (&m * x).as_slice(),
            &b,
            1e-10,
        );
        let tau = (f.tau)(&q, &qd, &qdd);
        let solved = (f.forward_dynamics)(&q, &qd, &tau);
        assert_relative(
            &format!("{name} tau(fd(tau))"),
            &(f.tau)(&q, &qd, &solved),
            &tau,
            1e-10,
        );
        // d tau: dual numbers and differences.
        let [by_q, by_qd] = (f.tau_derivatives)(&q, &qd, &qdd);
        let [dual_q, dual_qd] = dual::tau_derivatives(reference, &q, &qd, &qdd);
        let rows = |m: &DMatrix<f64>| -> Vec<f64> { m.transpose().iter().copied().collect() };
        assert_relative(
            &format!("{name} d tau/d q (dual)"),
            &rows(&by_q),
            &flat(&dual_q),
            1e-10,
        );
        assert_relative(
            &format!("{name} d tau/d qd (dual)"),
            &rows(&by_qd),
            &flat(&dual_qd),
            1e-10,
        );
        for j in 0..n {
            let dq = central(&|h| (f.tau)(&moved(&q, j, h), &qd, &qdd), 1e-6);
            assert_relative(
                &format!("{name} d tau/d q{j}"),
                &column(&by_q, j),
                &dq,
                1e-6,
            );
            let dqd = central(&|h| (f.tau)(&q, &moved(&qd, j, h), &qdd), 1e-6);
            assert_relative(
                &format!("{name} d tau/d qd{j}"),
                &column(&by_qd, j),
                &dqd,
                1e-6,
            );
        }
        // d qdd: -M^-1 d tau at the forward dynamics' qdd, and differences.
        let [fd_q, fd_qd] = (f.forward_dynamics_derivatives)(&q, &qd, &tau);
        let [dual_q, dual_qd] = dual::tau_derivatives(reference, &q, &qd, &solved);
        let lu = m.clone().lu();
        for (got, dual, what) in [(&fd_q, dual_q, "q"), (&fd_qd, dual_qd, "qd")] {
            let by = DMatrix::from_fn(n, n, |i, j| -dual[i][j]);
            let want = lu.solve(&by).unwrap();
            assert_relative(
                &format!("{name} d qdd/d {what} (dual)"),
                got.as_slice(),
                want.as_slice(),
                1e-9,
            );
        }
        for j in 0..n {
            let dq = central(&|h| (f.forward_dynamics)(&moved(&q, j, h), &qd, &tau), 1e-6);
            assert_relative(
                &format!("{name} d qdd/d q{j}"),
                &column(&fd_q, j),
                &dq,
                1e-6,
            );
            let dqd = central(&|h| (f.forward_dynamics)(&q, &moved(&qd, j, h), &tau), 1e-6);
            assert_relative(
                &format!("{name} d qdd/d qd{j}"),
                &column(&fd_qd, j),
                &dqd,
                1e-6,
            );
        }
        check_kinematics(f, reference, &q, &qd);
    }
}

fn check_kinematics(f: &Functions, reference: &Model, q: &[f64], qd: &[f64]) {
    let (name, n) = (f.name, q.len());
    let pose = (f.tip_pose)(q);
    let (r, p) = oracle::placements(reference, q)[oracle::tip(reference)];
    let want: Vec<f64> = (0..9)
        .map(|k| r[(k / 3, k % 3)])
        .chain(p.iter().copied())
        .collect();
    assert_relative(&format!("{name} tip pose"), &pose, &want, 1e-13);
    let jacobian = (f.tip_jacobian)(q);
    // The same program, to rounding (the compiler may order it differently).
    let (together, jacobian_too) = (f.tip_pose_and_jacobian)(q);
    assert_relative(
        &format!("{name} tip_pose_and_jacobian"),
        &together,
        &pose,
        1e-14,
    );
    let what = format!("{name} tip_pose_and_jacobian's Jacobian");
    assert_relative(&what, jacobian_too.as_slice(), jacobian.as_slice(), 1e-14);
    for j in 0..n {
        let rate = central(&|h| (f.tip_pose)(&moved(q, j, h)), 1e-6);
        // The angular velocity from R-dot R^T.
        let spin = |a: usize, b: usize| {
            (0..3)
                .map(|k| rate[3 * a + k] * pose[3 * b + k])
                .sum::<f64>()
        };
        let want = [
            rate[9],
            rate[10],
            rate[11],
            spin(2, 1),
            spin(0, 2),
            spin(1, 0),
        ];
        assert_relative(
            &format!("{name} tip jacobian column {j}"),
            &column(&jacobian, j),
            &want,
            1e-6,
        );
    }
    let along = |h: f64| {
        let x: Vec<f64> = q.iter().zip(qd).map(|(q, v)| q + h * v).collect();
        ((f.tip_jacobian)(&x) * DVector::from_column_slice(qd))
            .as_slice()
            .to_vec()
    };
    let drift = (f.tip_jacobian_dot_qd)(q, qd);
    assert_relative(
        &format!("{name} J-dot qd"),
        &drift,
        &central(&along, 1e-6),
        1e-6,
    );
}

#[test]
fn panda_functions_beyond_tau_are_exact() {
    check(&functions!(panda), &oracle("panda"), 40);
}

#[test]
fn prismatic_and_coupled_models_functions_beyond_tau_are_exact() {
    check(&functions!(lift_arm), &oracle("lift_arm"), 40);
    check(
        &functions!(kinova_gen3_lite_finger),
        &oracle("kinova_gen3_lite_finger"),
        40,
    );
}

#[test]
fn effects_and_ripple_derivatives_are_exact() {
    check(
        &functions!(kinova_gen3_lite_3dof_plant),
        &oracle("kinova_gen3_lite_3dof_plant"),
        40,
    );
    check(&functions!(planar_2link), &oracle("planar_2link"), 40);
}

#[test]
fn the_panda_tool_frame_sits_on_its_tip_and_its_jacobian_is_exact() {
    use sdnn::models::panda as arm;
    let description = codegen::Description::load(crate::util::root().join("models/panda.toml"))
        .expect("description");
    let tool = description
        .tool_frame()
        .expect("panda_link8 is fixed to link 7");
    assert_eq!(arm::TOOL_LINK, tool.link);
    let mut states = States::new(arm::DOF, 23);
    let pose_of = |q: &[f64]| {
        let q: [f64; 7] = q.try_into().unwrap();
        let pose = arm::tool_pose(&q);
        pose.rotation
            .iter()
            .flatten()
            .chain(&pose.position)
            .copied()
            .collect::<Vec<f64>>()
    };
    for _ in 0..50 {
        let (q, _, _) = states.next();
        let x: [f64; 7] = q.as_slice().try_into().unwrap();
        let tip = arm::tip_pose(&x);
        let r = nalgebra::Matrix3::from_fn(|i, j| tip.rotation[i][j]);
        let p = nalgebra::Vector3::from(tip.position);
        let (rt, pt) = (r * tool.rotation, p + r * tool.translation);
        let want: Vec<f64> = (0..9)
            .map(|k| rt[(k / 3, k % 3)])
            .chain(pt.iter().copied())
            .collect();
        assert_relative("panda tool pose", &pose_of(&q), &want, 1e-13);
        let jacobian = DMatrix::from_fn(6, 7, |r, c| arm::tool_jacobian(&x)[r][c]);
        let pose = pose_of(&q);
        for j in 0..7 {
            let rate = central(&|h| pose_of(&moved(&q, j, h)), 1e-6);
            let spin = |a: usize, b: usize| {
                (0..3)
                    .map(|k| rate[3 * a + k] * pose[3 * b + k])
                    .sum::<f64>()
            };
            let want = [
                rate[9],
                rate[10],
                rate[11],
                spin(2, 1),
                spin(0, 2),
                spin(1, 0),
            ];
            assert_relative("panda tool jacobian", &column(&jacobian, j), &want, 1e-6);
        }
    }
}
