//! Inertia tensors as URDFs carry them: rotated into the link frame and
//! judged physical or not. Real files hold point masses (zero inertia),
//! thin rods (one zero moment) and values rounded to a few digits, all of
//! which are physical; a triangle-inequality breach is not, but makers ship
//! them (Kinova's Gen3 Lite link 3), so it is imported with a warning.

use codegen::description::{INERTIA_FLOOR, INERTIA_ROUNDING};
use codegen::reduce::rpy_matrix;
use nalgebra::{Matrix3, SymmetricEigen};

/// Below this relative breach a triangle violation is the file's rounding.
const ROUNDING_BREACH: f64 = 1e-3;

pub(super) fn matrix(i: &[f64; 6]) -> Matrix3<f64> {
    let [xx, yy, zz, xy, xz, yz] = *i;
    Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz)
}

/// Principal moments, smallest first; None for non-finite entries.
pub(super) fn principal_moments(i: &[f64; 6]) -> Option<[f64; 3]> {
    if !i.iter().all(|x| x.is_finite()) {
        return None;
    }
    let e = SymmetricEigen::new(matrix(i)).eigenvalues;
    let mut p = [e[0], e[1], e[2]];
    p.sort_by(f64::total_cmp);
    p.iter().all(|x| x.is_finite()).then_some(p)
}

/// The inertia given in the `<inertial><origin rpy>` frame, in link axes:
/// R I R^T. Left untouched when rpy is zero so the values stay exact.
pub(super) fn rotate(inertia: &[f64; 6], rpy: &[f64; 3]) -> [f64; 6] {
    if rpy.iter().all(|&a| a == 0.0) {
        return *inertia;
    }
    let r = rpy_matrix(rpy);
    let m = r * matrix(inertia) * r.transpose();
    [
        m[(0, 0)],
        m[(1, 1)],
        m[(2, 2)],
        m[(0, 1)],
        m[(0, 2)],
        m[(1, 2)],
    ]
}

/// What a rigid body's inertia is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Judgement {
    /// Positive semi-definite within rounding, triangle inequality held.
    Physical,
    /// Positive semi-definite, but p0 + p1 < p2: no rigid body has it.
    Triangle([f64; 3]),
    /// A principal moment below zero beyond rounding (or no moments).
    Negative(Option<[f64; 3]>),
}

pub(super) fn judge(i: &[f64; 6]) -> Judgement {
    let Some(p) = principal_moments(i) else {
        return Judgement::Negative(None);
    };
    // The generator's own rounding allowance: what it accepts without
    // `nonphysical_inertia` is physical here too.
    let rounding = INERTIA_ROUNDING * p[2].max(0.0) + INERTIA_FLOOR;
    if p[0] < -rounding {
        return Judgement::Negative(Some(p));
    }
    if p[0] + p[1] < p[2] - rounding {
        return Judgement::Triangle(p);
    }
    Judgement::Physical
}

/// `a + b < c` with the moments, for messages and the description's
/// `nonphysical_inertia` reason.
pub(super) fn breach(p: &[f64; 3]) -> String {
    let relative = (p[2] - p[0] - p[1]) / p[2];
    let rounding = if relative < ROUNDING_BREACH {
        format!(
            " (short by {:.2}%: the file's rounding of a thin body?)",
            100.0 * relative
        )
    } else {
        String::new()
    };
    format!(
        "principal moments {:.6e} + {:.6e} < {:.6e} kg m^2{rounding}",
        p[0], p[1], p[2]
    )
}

pub(super) fn moments(p: &[f64; 3]) -> String {
    format!(
        "principal moments {:.6e}, {:.6e}, {:.6e} kg m^2",
        p[0], p[1], p[2]
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn point_masses_rods_and_rounding_are_physical() {
        assert_eq!(judge(&[0.0; 6]), Judgement::Physical);
        // A thin rod along x: moments 0, I, I.
        assert_eq!(judge(&[0.0, 0.5, 0.5, 0.0, 0.0, 0.0]), Judgement::Physical);
        // Rounding below zero.
        assert_eq!(
            judge(&[-1e-12, 0.5, 0.5, 0.0, 0.0, 0.0]),
            Judgement::Physical
        );
        assert!(matches!(
            judge(&[1e-4, 1e-4, 0.5, 0.0, 0.0, 0.0]),
            Judgement::Triangle(_)
        ));
        assert!(matches!(
            judge(&[-0.1, 0.5, 0.5, 0.0, 0.0, 0.0]),
            Judgement::Negative(Some(_))
        ));
        assert_eq!(
            judge(&[f64::NAN, 0.5, 0.5, 0.0, 0.0, 0.0]),
            Judgement::Negative(None)
        );
    }

    #[test]
    fn a_rounded_rod_says_so() {
        let p = principal_moments(&[0.0, 0.08333, 0.083333, 0.0, 0.0, 0.0]).unwrap();
        assert!(breach(&p).contains("rounding"), "{}", breach(&p));
        let p = principal_moments(&[0.01, 0.01, 0.5, 0.0, 0.0, 0.0]).unwrap();
        assert!(!breach(&p).contains("rounding"), "{}", breach(&p));
    }

    /// Hand computation: roll 90 deg then yaw 90 deg (fixed axes) is
    /// R = Rz(90) Rx(90) = [[0,0,1],[1,0,0],[0,1,0]]: link x is the inertial
    /// frame's z, link y its x, link z its y, so diag(1, 2, 3) becomes
    /// diag(3, 1, 2). The other order, Rx Rz, would give diag(2, 3, 1).
    #[test]
    fn inertia_is_rotated_from_the_inertial_origin_into_the_link_frame() {
        let half_pi = std::f64::consts::FRAC_PI_2;
        let close = |a: [f64; 6], b: [f64; 6]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-15);
        let rotated = rotate(&[1.0, 2.0, 3.0, 0.0, 0.0, 0.0], &[half_pi, 0.0, half_pi]);
        assert!(
            close(rotated, [3.0, 1.0, 2.0, 0.0, 0.0, 0.0]),
            "{rotated:?}"
        );
        // Roll 90 deg maps a product of inertia ixy to ixz: R I R^T with
        // R = [[1,0,0],[0,0,-1],[0,1,0]] on [[a,d,0],[d,b,0],[0,0,c]] is
        // [[a,0,d],[0,c,0],[d,0,b]].
        let rotated = rotate(&[1.0, 2.0, 3.0, 0.5, 0.0, 0.0], &[half_pi, 0.0, 0.0]);
        assert!(
            close(rotated, [1.0, 3.0, 2.0, 0.0, 0.5, 0.0]),
            "{rotated:?}"
        );
    }
}
