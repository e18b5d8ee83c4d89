//! Generated dynamics against the independent numeric oracle (RNEA), and
//! the identities every rigid-body model satisfies.

use nalgebra::{DMatrix, DVector};
use proptest::prelude::*;
use sdnn::Dynamics;
use sdnn::oracle::{self, Model};

use crate::util::{States, assert_close, oracle};

const RANDOM_STATES: usize = 10_000;

fn each_model(check: impl Fn(&dyn Dynamics, &Model)) {
    assert!(!sdnn::models::MODELS.is_empty(), "no compiled models");
    for model in sdnn::models::MODELS {
        check(*model, &oracle(model.name()));
    }
}

fn assert_vectors_close(a: &DVector<f64>, b: &DVector<f64>, what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: length");
    for i in 0..a.len() {
        assert_close(a[i], b[i], &format!("{what}[{i}]"));
    }
}

fn assert_matrices_close(a: &DMatrix<f64>, b: &DMatrix<f64>, what: &str) {
    assert_eq!(a.shape(), b.shape(), "{what}: shape");
    for r in 0..a.nrows() {
        for c in 0..a.ncols() {
            assert_close(a[(r, c)], b[(r, c)], &format!("{what}[{r},{c}]"));
        }
    }
}

#[test]
fn tau_equals_rnea_on_random_states() {
    each_model(|model, oracle| {
        let mut states = States::new(model.dof(), 1);
        for k in 0..RANDOM_STATES {
            let (q, qd, qdd) = states.next();
            let generated = model.tau(&q, &qd, &qdd).unwrap();
            let reference = oracle::rnea(oracle, &q, &qd, &qdd);
            assert_vectors_close(
                &generated,
                &reference,
                &format!("{} tau, state {k}", model.name()),
            );
        }
    });
}

/// False when a moving body carries neither mass nor armature (Kinova's
/// standalone URDF has no inertial past the last joint): its row of M is zero.
fn has_inertia_everywhere(model: &dyn Dynamics) -> bool {
    let description = sdnn::dynamics::parsed_description(model).expect("description");
    description.chain().bodies.iter().all(|b| {
        let i = b.inertial.inertia;
        b.effects.armature > 0.0 || (b.inertial.mass > 0.0 && i.trace() > 0.0)
    })
}

#[test]
fn mass_matrix_is_symmetric_positive_definite_and_equals_crba() {
    each_model(|model, oracle| {
        let mut states = States::new(model.dof(), 2);
        for k in 0..RANDOM_STATES / 10 {
            let (q, _, _) = states.next();
            let m = model.mass_matrix(&q).unwrap();
            assert_eq!(
                m,
                m.transpose(),
                "{} M not symmetric at state {k}",
                model.name()
            );
            if has_inertia_everywhere(model) {
                assert!(
                    m.clone().cholesky().is_some(),
                    "{} M not positive definite",
                    model.name()
                );
            } else {
                let eigen = m.clone().symmetric_eigenvalues();
                let scale = eigen.amax();
                assert!(
                    eigen.min() >= -1e-12 * scale,
                    "{} M not positive semidefinite: {eigen}",
                    model.name()
                );
            }
            assert_matrices_close(
                &m,
                &oracle::crba(oracle, &q),
                &format!("{} M, state {k}", model.name()),
            );
        }
    });
}

#[test]
fn gravity_coriolis_and_effects_decompose_tau() {
    each_model(|model, oracle| {
        let mut states = States::new(model.dof(), 3);
        let zero = vec![0.0; model.dof()];
        for k in 0..RANDOM_STATES / 10 {
            let (q, qd, qdd) = states.next();
            let name = model.name();
            let g = model.gravity(&q).unwrap();
            assert_vectors_close(
                &g,
                &oracle::gravity(oracle, &q),
                &format!("{name} g, state {k}"),
            );
            let at_rest = model.tau(&q, &zero, &zero).unwrap() - model.effects(&zero).unwrap();
            assert_vectors_close(
                &g,
                &at_rest,
                &format!("{name} g = tau(q, 0, 0) - effects(0)"),
            );
            let c = model.coriolis(&q, &qd).unwrap();
            assert_vectors_close(
                &c,
                &oracle::coriolis(oracle, &q, &qd),
                &format!("{name} c, state {k}"),
            );
            let m = model.mass_matrix(&q).unwrap();
            let sum = &m * DVector::from_column_slice(&qdd) + &c + &g + model.effects(&qd).unwrap();
            let tau = model.tau(&q, &qd, &qdd).unwrap();
            assert_vectors_close(&sum, &tau, &format!("{name} M qdd + c + g + effects = tau"));
        }
    });
}

#[test]
fn regressor_times_parameters_equals_tau() {
    each_model(|model, oracle| {
        let parameters = DVector::from_column_slice(model.parameters());
        assert_vectors_close(
            &parameters,
            &oracle.parameters(),
            &format!("{} PARAMETERS", model.name()),
        );
        assert_eq!(model.parameter_names().len(), parameters.len());
        let mut states = States::new(model.dof(), 4);
        for k in 0..RANDOM_STATES / 10 {
            let (q, qd, qdd) = states.next();
            let y = model.regressor(&q, &qd, &qdd).unwrap();
            let tau = model.tau(&q, &qd, &qdd).unwrap();
            assert_vectors_close(
                &(&y * &parameters),
                &tau,
                &format!("{} Y * p, state {k}", model.name()),
            );
            let reference = oracle::regressor(oracle, &q, &qd, &qdd);
            assert_matrices_close(&y, &reference, &format!("{} Y, state {k}", model.name()));
        }
    });
}

/// Along any motion, the power of the non-gravity rigid-body torque equals
/// the rate of change of kinetic energy: qd . (tau - g - effects) = dK/dt
/// (armature counted as kinetic energy of the rotors).
#[test]
fn power_balances_kinetic_energy_rate() {
    each_model(|model, _| {
        let mut states = States::new(model.dof(), 5);
        let energy = |q: &[f64], qd: &[f64]| {
            let v = DVector::from_column_slice(qd);
            0.5 * v.dot(&(model.mass_matrix(q).unwrap() * &v))
        };
        for k in 0..200 {
            let (q, qd, qdd) = states.next();
            let h = 1e-6;
            let step = |sign: f64| -> (Vec<f64>, Vec<f64>) {
                // The h^2 terms cancel in the central difference.
                let q = q.iter().zip(&qd).map(|(x, v)| x + sign * h * v).collect();
                let qd = qd.iter().zip(&qdd).map(|(v, a)| v + sign * h * a).collect();
                (q, qd)
            };
            let (q_plus, qd_plus) = step(1.0);
            let (q_minus, qd_minus) = step(-1.0);
            let rate = (energy(&q_plus, &qd_plus) - energy(&q_minus, &qd_minus)) / (2.0 * h);
            let tau = model.tau(&q, &qd, &qdd).unwrap();
            let passive = tau - model.gravity(&q).unwrap() - model.effects(&qd).unwrap();
            let power = passive.dot(&DVector::from_column_slice(&qd));
            let scale = power.abs().max(rate.abs()).max(1.0);
            assert!(
                (power - rate).abs() <= 1e-6 * scale,
                "{} state {k}: power {power} vs dK/dt {rate}",
                model.name()
            );
        }
    });
}

/// Textbook planar two-link arm (Spong, Hutchinson, Vidyasagar, ch. 7).
#[test]
fn planar_two_link_matches_closed_form() {
    use sdnn::models::planar_2link as arm;
    let (m1, m2, l1, lc1, lc2, i1, i2, g) = (2.0, 1.5, 0.8, 0.35, 0.4, 0.12, 0.08, 9.81);
    let mut states = States::new(2, 6);
    for _ in 0..1000 {
        let (q, qd, qdd) = states.next();
        let (c1, c2, s2, c12) = (q[0].cos(), q[1].cos(), q[1].sin(), (q[0] + q[1]).cos());
        let m11 = m1 * lc1 * lc1 + m2 * (l1 * l1 + lc2 * lc2 + 2.0 * l1 * lc2 * c2) + i1 + i2;
        let m12 = m2 * (lc2 * lc2 + l1 * lc2 * c2) + i2;
        let m22 = m2 * lc2 * lc2 + i2;
        let h = m2 * l1 * lc2 * s2;
        let g1 = (m1 * lc1 + m2 * l1) * g * c1 + m2 * lc2 * g * c12;
        let g2 = m2 * lc2 * g * c12;
        let tau1 = m11 * qdd[0] + m12 * qdd[1] - h * (2.0 * qd[0] * qd[1] + qd[1] * qd[1]) + g1;
        // The elbow's Stribeck friction and ripple (models/planar_2link.toml).
        let stribeck = 0.3 * qd[1].signum() * (-(qd[1] / 0.1).powi(2)).exp();
        let ripple = 0.05 * (12.0 * q[1]).sin();
        let tau2 = m12 * qdd[0] + m22 * qdd[1] + h * qd[0] * qd[0] + g2 + stribeck + ripple;
        let generated = arm::tau(&[q[0], q[1]], &[qd[0], qd[1]], &[qdd[0], qdd[1]]);
        assert_close(generated[0], tau1, "planar tau1");
        assert_close(generated[1], tau2, "planar tau2");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// M(q) is symmetric positive definite and tau is linear in qdd with slope M.
    #[test]
    fn kinova_tau_is_affine_in_qdd_with_slope_m(
        q in prop::array::uniform3(-3.2f64..3.2),
        qd in prop::array::uniform3(-4.0f64..4.0),
        qdd in prop::array::uniform3(-20.0f64..20.0),
        j in 0usize..3,
    ) {
        use sdnn::models::kinova_gen3_lite_3dof as arm;
        let m = arm::mass_matrix(&q);
        let mut bumped = qdd;
        bumped[j] += 1.0;
        let (a, b) = (arm::tau(&q, &qd, &qdd), arm::tau(&q, &qd, &bumped));
        for i in 0..3 {
            prop_assert!(((b[i] - a[i]) - m[i][j]).abs() <= 1e-9 * (1.0 + a[i].abs()));
            prop_assert_eq!(m[i][j], m[j][i]);
        }
        let m = DMatrix::from_fn(3, 3, |r, c| m[r][c]);
        prop_assert!(m.cholesky().is_some());
    }
}

proptest! {
    /// The vectorized sin_cos_n gives each angle exactly `sin_cos`'s bits,
    /// whatever its lane and neighbours.
    #[test]
    fn sin_cos_n_lanes_equal_sin_cos(x in proptest::array::uniform5(-1.0e5..1.0e5f64)) {
        use sdnn::models::panda::{sin_cos, sin_cos_n};
        let (s, c) = sin_cos_n(x);
        for i in 0..5 {
            let (si, ci) = sin_cos(x[i]);
            prop_assert_eq!(s[i].to_bits(), si.to_bits());
            prop_assert_eq!(c[i].to_bits(), ci.to_bits());
        }
    }
}

/// The generated Stribeck shape (its own `exp`, `core` only) agrees with
/// std's to about one ulp, from rest to where it vanishes, both ways.
#[test]
fn generated_stribeck_matches_std() {
    use sdnn::models::planar_2link::stribeck;
    let mut worst: f64 = 0.0;
    for i in -300_000..=300_000 {
        let v = f64::from(i) * 1e-4 + 1e-9;
        for v_s in [0.013, 0.1, 1.7] {
            let want = v.signum() * (-(v / v_s).powi(2)).exp();
            worst = worst.max((stribeck(v, v_s) - want).abs() / want.abs().max(1e-200));
        }
    }
    assert!(worst <= 1e-14, "worst relative error {worst:e}");
    assert_eq!(stribeck(0.0, 0.1), 0.0);
    assert_eq!(stribeck(0.5, 0.0), 0.0);
    assert_eq!(stribeck(1e300, 0.1), 0.0);
    assert!(stribeck(f64::NAN, 0.1).is_nan());
}

/// The generated sin_cos agrees with the standard library to about one ulp
/// on joint-angle ranges and up to 1e10 rad (a slower reduction beyond
/// 1e5), and is NaN beyond, where no joint angle is meant.
#[test]
fn generated_sin_cos_matches_std() {
    use sdnn::models::planar_2link::{sin_cos, sin_cos_n};
    let mut worst: f64 = 0.0;
    for i in -200_000..=200_000 {
        let x = f64::from(i) * 1e-4 + 1e-7;
        let (s, c) = sin_cos(x);
        worst = worst.max((s - x.sin()).abs()).max((c - x.cos()).abs());
    }
    assert!(worst <= 2.3e-16, "worst error {worst:e}");
    for x in [
        0.0,
        -0.0,
        1e-300,
        1e5,
        -1e5,
        3e5,
        123_456.789,
        1e9,
        -7.5e9,
        1e10,
    ] {
        let (s, c) = sin_cos(x);
        assert!(
            (s - x.sin()).abs() <= 4.5e-16,
            "sin {x}: {s} vs {}",
            x.sin()
        );
        assert!(
            (c - x.cos()).abs() <= 4.5e-16,
            "cos {x}: {c} vs {}",
            x.cos()
        );
    }
    for x in [f64::INFINITY, f64::NEG_INFINITY, f64::NAN, 2e10, -1e300] {
        let (s, c) = sin_cos(x);
        assert!(s.is_nan() && c.is_nan(), "{x}: {s} {c}");
    }
    // One wide angle sends every lane through the slower reduction.
    let (s, c) = sin_cos_n([0.5, 2e5]);
    assert_eq!((s[0], c[0]), sin_cos(0.5));
    assert!((s[1] - 2e5f64.sin()).abs() <= 4.5e-16 && (c[1] - 2e5f64.cos()).abs() <= 4.5e-16);
}
