//! How a candidate's named parameters map to the coefficients of its
//! columns (its shape: the map, its Jacobian and its curvature), and a
//! link's standard inertial parameters: a point mass's, and whether ten of
//! them are a physical body.

use nalgebra::{DMatrix, Vector3};

/// Parameters -> column coefficients.
#[derive(Debug, Clone)]
pub(super) enum Shape {
    /// The parameters are the coefficients.
    Linear,
    /// A tilted base: theta = (a, b), the gravity components (m/s^2) along
    /// `across` of the tilted gravity, whose magnitude stays the model's:
    /// coefficients (a, b, sqrt(|g|^2 - a^2 - b^2) - |g|) of the gravity
    /// torques for unit gravity along `across[0]`, `across[1]` and the
    /// model's gravity direction.
    Tilt {
        gravity: Vector3<f64>,
        across: [Vector3<f64>; 2],
    },
    /// Linear, a delay (s): one parameter, named only beyond
    /// `sample_period` (a torque held over the sample interval reads half
    /// a sample early: the logging convention, not a delay).
    Delay { sample_period: f64 },
    /// Linear, a direction-dependent dry friction (N m): admissible only on
    /// a joint with Coulomb friction, modelled (`modelled_coulomb`) or named
    /// (a friction level cannot go negative in one direction).
    Asymmetry { modelled_coulomb: f64 },
    /// theta = (m, cx, cy, cz) over a link's ten inertial columns:
    /// coefficients m * [1, c, |c|^2 E - c c^T] + `offset`, and `base` the
    /// (mass, first moment) the linear start adds its fit to. With
    /// `own_inertia`, theta has a fifth entry j: a payload's own moment of
    /// inertia about its COM, the same about every axis (j E added).
    /// `held_com`: COM axes held at the modelled COM (the data do not
    /// determine a change along them, see [`super::com_hold`]): nothing
    /// depends on a held entry of theta (its Jacobian column is zero), so
    /// the descent never moves it from where the start puts it.
    Body {
        offset: [f64; 10],
        base_mass: f64,
        base_moment: Vector3<f64>,
        own_inertia: bool,
        held_com: Option<HeldCom>,
    },
    /// theta = the first moment h = m c of a link whose mass the data cannot
    /// identify (see [`mass_identifiable`]), the mass held at the model's
    /// `base_mass`: coefficients point_mass(base_mass, h / base_mass) +
    /// `offset`, the inertia about the COM as modelled.
    Moment {
        offset: [f64; 10],
        base_mass: f64,
        base_moment: Vector3<f64>,
    },
    /// Linear: theta = the coefficients of the combinations of a link's ten
    /// standard parameters that the data determine (`basis`, 10 x k: the
    /// change of the ten per unit of each), the whole body corrected at
    /// once (see [`super::whole`]); `gram` the Gram matrix of the link's
    /// ten columns, the data's metric of a change of the ten.
    Whole {
        basis: DMatrix<f64>,
        gram: DMatrix<f64>,
    },
}

/// A body's COM axes held at the modelled COM, and the 95% intervals of
/// the fit that left them free.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct HeldCom {
    pub(super) axes: [bool; 3],
    /// (mass, cx, cy, cz): holding axes the data do not determine does not
    /// make the rest better known, so the report's intervals are at least
    /// these.
    pub(super) free: [(f64, f64); 4],
}

/// Whether COM axis `a` is held.
pub(super) fn holds(held: &Option<HeldCom>, a: usize) -> bool {
    held.is_some_and(|h| h.axes[a])
}

/// The reported 95% interval of a body's parameter `k` (mass, cx, cy, cz)
/// whose fit gives `fitted`: a held axis's is the free fit's (which holds
/// the modelled value kept), the others' at least the free fit's.
pub(super) fn reported_interval(
    fitted: (f64, f64),
    held: &Option<HeldCom>,
    k: usize,
) -> (f64, f64) {
    match held {
        None => fitted,
        Some(h) if k > 0 && h.axes[k - 1] => h.free[k],
        Some(h) => (fitted.0.min(h.free[k].0), fitted.1.max(h.free[k].1)),
    }
}

impl Shape {
    /// Whether the coefficients are the parameters.
    pub(super) fn is_linear(&self) -> bool {
        matches!(
            self,
            Shape::Linear | Shape::Delay { .. } | Shape::Asymmetry { .. } | Shape::Whole { .. }
        )
    }

    pub(super) fn width(&self, columns: usize) -> usize {
        match self {
            Shape::Linear | Shape::Delay { .. } | Shape::Asymmetry { .. } | Shape::Whole { .. } => {
                columns
            }
            Shape::Tilt { .. } => 2,
            Shape::Body { own_inertia, .. } => 4 + usize::from(*own_inertia),
            Shape::Moment { .. } => 3,
        }
    }

    /// Coefficients and their Jacobian at theta.
    pub(super) fn map(&self, theta: &[f64]) -> (Vec<f64>, DMatrix<f64>) {
        match self {
            Shape::Linear | Shape::Delay { .. } | Shape::Asymmetry { .. } | Shape::Whole { .. } => {
                (theta.to_vec(), DMatrix::identity(theta.len(), theta.len()))
            }
            Shape::Tilt { gravity, .. } => {
                let (a, b, g) = (theta[0], theta[1], gravity.norm());
                // Beyond 90 degrees of tilt the root is clamped; the
                // plausibility check refuses such fits anyway.
                let along = (g * g - a * a - b * b).max(1e-12 * g * g).sqrt();
                let jacobian =
                    DMatrix::from_row_slice(3, 2, &[1.0, 0.0, 0.0, 1.0, -a / along, -b / along]);
                (vec![a, b, along - g], jacobian)
            }
            Shape::Body {
                own_inertia,
                held_com,
                ..
            } => {
                let (m, c) = (theta[0], self.body_com(theta));
                let unit = point_mass(1.0, &c);
                let held = self.held(theta);
                let coefficients = (0..10).map(|k| m * unit[k] + held[k]).collect();
                let mut jacobian = DMatrix::zeros(10, theta.len());
                for k in 0..10 {
                    jacobian[(k, 0)] = unit[k];
                }
                for (a, row) in unit_partials(&c).iter().enumerate() {
                    if holds(held_com, a) {
                        continue;
                    }
                    for k in 0..10 {
                        jacobian[(k, a + 1)] = m * row[k];
                    }
                }
                if *own_inertia {
                    for k in ISOTROPIC {
                        jacobian[(k, 4)] = 1.0;
                    }
                }
                (coefficients, jacobian)
            }
            Shape::Moment {
                offset, base_mass, ..
            } => {
                let m = *base_mass;
                let c = Vector3::new(theta[0], theta[1], theta[2]) / m;
                let unit = point_mass(1.0, &c);
                let coefficients = (0..10).map(|k| m * unit[k] + offset[k]).collect();
                // d(m unit(h / m)) / dh = d unit / dc.
                let partial = unit_partials(&c);
                let jacobian = DMatrix::from_fn(10, 3, |k, a| partial[a][k]);
                (coefficients, jacobian)
            }
        }
    }
}

impl Shape {
    /// Whether parameter `k` is fitted (not a held COM axis).
    pub(super) fn fitted(&self, k: usize) -> bool {
        match self {
            Shape::Body { held_com, .. } => !(1..4).contains(&k) || !holds(held_com, k - 1),
            _ => true,
        }
    }

    /// A body's COM at theta: a held axis is the model's whatever theta
    /// holds there (nothing depends on it).
    fn body_com(&self, theta: &[f64]) -> Vector3<f64> {
        let mut com = Vector3::new(theta[1], theta[2], theta[3]);
        if let Shape::Body {
            base_mass,
            base_moment,
            held_com,
            ..
        } = self
        {
            for a in (0..3).filter(|&a| holds(held_com, a)) {
                com[a] = base_moment[a] / base_mass;
            }
        }
        com
    }

    /// A body's coefficients other than its mass term m * point_mass(1, c)
    /// at theta: the offset, and a payload's own moment on the diagonal.
    /// Zero for the other shapes.
    pub(super) fn held(&self, theta: &[f64]) -> [f64; 10] {
        let Shape::Body {
            offset,
            own_inertia,
            ..
        } = self
        else {
            return [0.0; 10];
        };
        let mut held = *offset;
        if *own_inertia {
            for k in ISOTROPIC {
                held[k] += theta[4];
            }
        }
        held
    }

    /// The sum over the coefficients of `weights[k]` times coefficient k's
    /// Hessian in theta: what the Gauss-Newton Hessian leaves out. With it
    /// the descent takes exact Newton steps, which cross the valley along
    /// which a body trades mass for lever arm in a few steps where
    /// Gauss-Newton crawls (the residuals of real data are not small).
    pub(super) fn curvature(&self, theta: &[f64], weights: &[f64]) -> DMatrix<f64> {
        match self {
            Shape::Linear | Shape::Delay { .. } | Shape::Asymmetry { .. } | Shape::Whole { .. } => {
                DMatrix::zeros(theta.len(), theta.len())
            }
            Shape::Tilt { gravity, .. } => {
                let (a, b, g) = (theta[0], theta[1], gravity.norm());
                let s = (g * g - a * a - b * b).max(1e-12 * g * g).sqrt();
                let cube = s * s * s;
                let w = weights[2];
                DMatrix::from_row_slice(
                    2,
                    2,
                    &[
                        -w * (1.0 / s + a * a / cube),
                        -w * a * b / cube,
                        -w * a * b / cube,
                        -w * (1.0 / s + b * b / cube),
                    ],
                )
            }
            Shape::Body { held_com, .. } => {
                // The payload's own inertia is linear, and nothing depends
                // on a held COM axis: their rows stay zero.
                let (m, c) = (theta[0], self.body_com(theta));
                let second = unit_curvature(weights);
                let free = |a: usize| !holds(held_com, a);
                let mut h = DMatrix::zeros(theta.len(), theta.len());
                for (a, row) in unit_partials(&c)
                    .iter()
                    .enumerate()
                    .filter(|(a, _)| free(*a))
                {
                    let cross: f64 = row.iter().zip(weights).map(|(d, w)| d * w).sum();
                    h[(0, a + 1)] = cross;
                    h[(a + 1, 0)] = cross;
                    for b in (0..3).filter(|&b| free(b)) {
                        h[(a + 1, b + 1)] = m * second[a][b];
                    }
                }
                h
            }
            Shape::Moment { base_mass, .. } => {
                let second = unit_curvature(weights);
                DMatrix::from_fn(3, 3, |a, b| second[a][b] / base_mass)
            }
        }
    }
}

/// The diagonal inertia entries (ixx, iyy, izz) among the ten.
const ISOTROPIC: [usize; 3] = [4, 6, 9];

/// d point_mass(1, c) / dc_a, row a.
fn unit_partials(c: &Vector3<f64>) -> [[f64; 10]; 3] {
    let (x, y, z) = (c.x, c.y, c.z);
    [
        [0.0, 1.0, 0.0, 0.0, 0.0, -y, 2.0 * x, -z, 0.0, 2.0 * x],
        [0.0, 0.0, 1.0, 0.0, 2.0 * y, -x, 0.0, 0.0, -z, 2.0 * y],
        [0.0, 0.0, 0.0, 1.0, 2.0 * z, 0.0, 2.0 * z, -x, -y, 0.0],
    ]
}

/// The sum over k of weights[k] d^2 point_mass(1, c)_k / dc_a dc_b: the
/// inertia entries are quadratic in c, so it is constant.
fn unit_curvature(weights: &[f64]) -> [[f64; 3]; 3] {
    let [ixx, ixy, iyy, ixz, iyz, izz] = [4, 5, 6, 7, 8, 9].map(|k| weights[k]);
    [
        [2.0 * (iyy + izz), -ixy, -ixz],
        [-ixy, 2.0 * (ixx + izz), -iyz],
        [-ixz, -iyz, 2.0 * (ixx + iyy)],
    ]
}

/// Standard parameters (m, m*c, inertia about the origin in the order
/// ixx, ixy, iyy, ixz, iyz, izz) of a point mass m at c.
pub(super) fn point_mass(m: f64, c: &Vector3<f64>) -> [f64; 10] {
    let (x, y, z) = (c.x, c.y, c.z);
    [
        m,
        m * x,
        m * y,
        m * z,
        m * (y * y + z * z),
        -m * x * y,
        m * (x * x + z * z),
        -m * x * z,
        -m * y * z,
        m * (x * x + y * y),
    ]
}

/// Whether a payload's own moment of inertia `moment` about its COM can be
/// a body's of mass `m` within `reach` of the link origin: not negative,
/// and at most a thin shell's of that radius (2/3 m r^2).
pub(super) fn plausible_moment(moment: f64, m: f64, reach: f64) -> bool {
    (0.0..=2.0 / 3.0 * m * reach * reach).contains(&moment)
}

/// Whether standard parameters (m, m*c, inertia about the origin in the
/// order of [`point_mass`]) are those of a physical body: the pseudo-inertia
/// [[tr(I)/2 E - I, h], [h^T, m]] is positive semi-definite (Wensing, Kim
/// and Slotine 2017: positive mass, and the triangle inequality of the
/// principal moments about the centre of mass). `None` when its
/// eigenvalues cannot be computed.
pub(super) fn physically_consistent(p: &[f64; 10]) -> Option<bool> {
    pseudo_inertia_margin(p).map(|margin| margin >= 0.0)
}

/// The smallest eigenvalue of the pseudo-inertia of `p` (see
/// [`physically_consistent`]) plus a rounding allowance: not negative for a
/// physical body. Concave in `p`, the pseudo-inertia being linear in it.
pub(super) fn pseudo_inertia_margin(p: &[f64; 10]) -> Option<f64> {
    let [m, hx, hy, hz, ixx, ixy, iyy, ixz, iyz, izz] = *p;
    let half_trace = 0.5 * (ixx + iyy + izz);
    let pseudo = DMatrix::from_row_slice(
        4,
        4,
        &[
            half_trace - ixx,
            -ixy,
            -ixz,
            hx,
            -ixy,
            half_trace - iyy,
            -iyz,
            hy,
            -ixz,
            -iyz,
            half_trace - izz,
            hz,
            hx,
            hy,
            hz,
            m,
        ],
    );
    let scale = pseudo.iter().fold(0.0_f64, |s, x| s.max(x.abs()));
    let eigenvalues = crate::kernels::symmetric_eigenvalues(pseudo)?;
    Some(eigenvalues.min() + 1e-12 * scale)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sphere's moment is a payload's; a negative one, or one larger than
    /// a body within reach can have, is not.
    #[test]
    fn a_payload_moment_is_a_body_within_reach() {
        let sphere = 0.4 * 1.5 * 0.04 * 0.04;
        assert!(plausible_moment(sphere, 1.5, 1.0));
        assert!(!plausible_moment(-1e-4, 1.5, 1.0));
        assert!(!plausible_moment(2.0, 1.5, 1.0));
    }

    /// A solid box's standard parameters about its centre, offset to `c`.
    fn box_at(m: f64, sides: [f64; 3], c: [f64; 3]) -> [f64; 10] {
        let [a, b, h] = sides.map(|s| s * s);
        let mut p = point_mass(m, &Vector3::from(c));
        p[4] += m * (b + h) / 12.0;
        p[6] += m * (a + h) / 12.0;
        p[9] += m * (a + b) / 12.0;
        p
    }

    #[test]
    fn bodies_are_consistent_and_impossible_ones_are_not() {
        assert_eq!(
            physically_consistent(&box_at(2.0, [0.1, 0.2, 0.3], [0.1, 0.0, 0.2])),
            Some(true)
        );
        assert_eq!(
            physically_consistent(&point_mass(0.5, &Vector3::new(0.0, 0.1, 0.3))),
            Some(true)
        );
        // Negative mass.
        assert_eq!(
            physically_consistent(&box_at(-1.0, [0.1, 0.1, 0.1], [0.0; 3])),
            Some(false)
        );
        // Principal moments 1, 1, 3 about the COM break the triangle inequality.
        let mut p = point_mass(1.0, &Vector3::zeros());
        (p[4], p[6], p[9]) = (1.0, 1.0, 3.0);
        assert_eq!(physically_consistent(&p), Some(false));
        assert_eq!(physically_consistent(&[f64::NAN; 10]), None);
    }
}

#[cfg(test)]
mod curvature_tests {
    use super::*;
    use nalgebra::DVector;
    use proptest::prelude::*;

    /// d/dtheta_b of sum_k w_k d coefficient_k / d theta_a, by central
    /// differences of the shape's own Jacobian.
    fn differenced(shape: &Shape, theta: &[f64], weights: &[f64]) -> DMatrix<f64> {
        let n = theta.len();
        let pulled = |t: &[f64]| {
            let (_, jacobian) = shape.map(t);
            jacobian.transpose() * DVector::from_column_slice(weights)
        };
        DMatrix::from_fn(n, n, |a, b| {
            let h = 1e-6 * theta[b].abs().max(1e-2);
            let (mut up, mut down) = (theta.to_vec(), theta.to_vec());
            up[b] += h;
            down[b] -= h;
            (pulled(&up)[a] - pulled(&down)[a]) / (2.0 * h)
        })
    }

    fn close(exact: &DMatrix<f64>, differenced: &DMatrix<f64>) -> bool {
        let scale = differenced.amax().max(1.0);
        (exact - differenced).amax() <= 1e-6 * scale
    }

    proptest! {
        #[test]
        fn curvature_is_the_derivative_of_the_weighted_jacobian(
            m in 0.1f64..5.0,
            c in prop::array::uniform3(-0.5f64..0.5),
            tilt in prop::array::uniform2(-2.0f64..2.0),
            weights in prop::collection::vec(-3.0f64..3.0, 10),
        ) {
            let zero = [0.0; 10];
            let body = Shape::Body { offset: zero, base_mass: m, base_moment: Vector3::zeros(), own_inertia: true, held_com: None };
            let theta = [m, c[0], c[1], c[2], 0.01];
            prop_assert!(close(&body.curvature(&theta, &weights), &differenced(&body, &theta, &weights)));
            let held_y = Shape::Body { offset: zero, base_mass: m, base_moment: Vector3::zeros(), own_inertia: false, held_com: Some(HeldCom { axes: [false, true, false], free: [(0.0, 1.0); 4] }) };
            let theta = [m, c[0], c[1], c[2]];
            prop_assert!(close(&held_y.curvature(&theta, &weights), &differenced(&held_y, &theta, &weights)));
            let moment = Shape::Moment { offset: zero, base_mass: m, base_moment: Vector3::zeros() };
            let h = [m * c[0], m * c[1], m * c[2]];
            prop_assert!(close(&moment.curvature(&h, &weights), &differenced(&moment, &h, &weights)));
            let gravity = Vector3::new(0.0, 0.0, -9.81);
            let tilted = Shape::Tilt { gravity, across: [Vector3::x(), Vector3::y()] };
            let w3 = &weights[..3];
            prop_assert!(close(&tilted.curvature(&tilt, w3), &differenced(&tilted, &tilt, w3)));
        }
    }
}
