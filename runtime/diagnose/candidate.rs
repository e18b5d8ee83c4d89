//! The candidate effects: what each adds to the residual (its columns) and
//! how its named parameters map onto the coefficients of those columns.

use nalgebra::{DMatrix, DVector, Vector3};

use super::kind::Kind;
use super::search;
use super::stacked::{Link, Stacked};

/// One candidate: a kind, a joint or link, its columns and how its named
/// parameters map to coefficients of those columns.
#[derive(Clone)]
pub(super) struct Candidate {
    pub(super) kind: Kind,
    pub(super) joint: Option<usize>,
    /// 0-based moving link and its name, for inertial candidates.
    pub(super) link: Option<(usize, String)>,
    /// The link's modelled standard parameters (inertial candidates; zero
    /// otherwise): the corrected body is these plus the fitted change.
    pub(super) modelled: [f64; 10],
    pub(super) names: Vec<&'static str>,
    pub(super) columns: Vec<DVector<f64>>,
    /// What the generated model computes for this effect once applied, when
    /// that differs from the fitted column (Coulomb: the fit leaves out
    /// samples near rest, the model's sign(qd) does not). Held-out errors are
    /// scored with it, so they are what the applied model will show.
    pub(super) applied: Option<DVector<f64>>,
    pub(super) shape: Shape,
    /// Numbers that shape the columns, chosen from the data before the
    /// fit (a Stribeck velocity, a ripple's cycles), reported with the
    /// parameters.
    pub(super) settings: Vec<(&'static str, f64)>,
    /// How many column shapes the settings were chosen from (1: fixed):
    /// the significance threshold grows with it, so a search over many
    /// shapes does not find structure in noise.
    pub(super) searched: usize,
}

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
    /// (mass, first moment) the linear start adds its fit to.
    Body {
        offset: [f64; 10],
        base_mass: f64,
        base_moment: Vector3<f64>,
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
}

impl Shape {
    pub(super) fn width(&self, columns: usize) -> usize {
        match self {
            Shape::Linear | Shape::Delay { .. } | Shape::Asymmetry { .. } => columns,
            Shape::Tilt { .. } => 2,
            Shape::Body { .. } => 4,
            Shape::Moment { .. } => 3,
        }
    }

    /// Coefficients and their Jacobian at theta.
    pub(super) fn map(&self, theta: &[f64]) -> (Vec<f64>, DMatrix<f64>) {
        match self {
            Shape::Linear | Shape::Delay { .. } | Shape::Asymmetry { .. } => {
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
            Shape::Body { offset, .. } => {
                let (m, c) = (theta[0], Vector3::new(theta[1], theta[2], theta[3]));
                let unit = point_mass(1.0, &c);
                let coefficients = (0..10).map(|k| m * unit[k] + offset[k]).collect();
                let mut jacobian = DMatrix::zeros(10, 4);
                for k in 0..10 {
                    jacobian[(k, 0)] = unit[k];
                }
                for (a, row) in unit_partials(&c).iter().enumerate() {
                    for k in 0..10 {
                        jacobian[(k, a + 1)] = m * row[k];
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
    /// The sum over the coefficients of `weights[k]` times coefficient k's
    /// Hessian in theta: what the Gauss-Newton Hessian leaves out. With it
    /// the descent takes exact Newton steps, which cross the valley along
    /// which a body trades mass for lever arm in a few steps where
    /// Gauss-Newton crawls (the residuals of real data are not small).
    pub(super) fn curvature(&self, theta: &[f64], weights: &[f64]) -> DMatrix<f64> {
        match self {
            Shape::Linear | Shape::Delay { .. } | Shape::Asymmetry { .. } => {
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
            Shape::Body { .. } => {
                let (m, c) = (theta[0], Vector3::new(theta[1], theta[2], theta[3]));
                let second = unit_curvature(weights);
                let mut h = DMatrix::zeros(4, 4);
                for (a, row) in unit_partials(&c).iter().enumerate() {
                    let cross: f64 = row.iter().zip(weights).map(|(d, w)| d * w).sum();
                    h[(0, a + 1)] = cross;
                    h[(a + 1, 0)] = cross;
                    for b in 0..3 {
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

/// Global column indices of the selected candidates.
pub(super) fn columns_of(candidates: &[Candidate], selected: &[usize]) -> Vec<usize> {
    let offsets: Vec<usize> = candidates
        .iter()
        .scan(0, |at, c| {
            let start = *at;
            *at += c.columns.len();
            Some(start)
        })
        .collect();
    selected
        .iter()
        .flat_map(|&c| offsets[c]..offsets[c] + candidates[c].columns.len())
        .collect()
}

pub(super) fn width(candidate: &Candidate) -> usize {
    candidate.shape.width(candidate.columns.len())
}

/// How a candidate is named in notes.
pub(super) fn label(candidate: &Candidate) -> String {
    let kind = candidate.kind.name();
    match (&candidate.joint, &candidate.link) {
        (Some(j), _) => format!("{kind} on joint {}", j + 1),
        (None, Some((k, name))) => format!("{kind} of link {} (`{name}`)", k + 1),
        (None, None) => kind,
    }
}

/// The fitted columns of the stacked data, filtered like the residual.
pub(super) struct Columns {
    /// qd, moving sign, qdd, 1, q of each row's joint.
    pub(super) own: [DVector<f64>; 5],
    /// The generated model's sign(qd).
    pub(super) coulomb_applied: DVector<f64>,
    /// The regressor's inertial columns, ten per link.
    pub(super) inertial: Vec<DVector<f64>>,
    /// Gravity torques for unit gravity across the model's and along it (a
    /// tilted base), when the model has a description and gravity: the
    /// shape with the directions, and the three columns.
    pub(super) tilt: Option<(Shape, [DVector<f64>; 3])>,
    /// d/dt of the measured torque.
    pub(super) measured_rate: DVector<f64>,
    /// The model's Coulomb friction level per joint.
    pub(super) coulomb_levels: Vec<f64>,
    /// The longest sample period of the raw recordings, s.
    pub(super) sample_period: f64,
    /// Per Stribeck velocity of `search::STRIBECK_VELOCITIES` the fitted
    /// (moving sign) and applied (the model's sign) Stribeck columns.
    pub(super) stribeck: Vec<(DVector<f64>, DVector<f64>)>,
    /// Per joint the speed below which it counts as at rest (the largest
    /// over the recordings), rad/s.
    pub(super) rest: Vec<f64>,
    /// Per joint the cycles of the model's own ripple, if it has one.
    pub(super) modelled_ripple: Vec<Option<f64>>,
}

/// Every candidate effect: per joint viscous, Coulomb and direction-dependent
/// (asymmetric: column 1 while moving, 0 at rest) friction,
/// armature, a torque offset, a spring (columns q and 1: stiffness k and
/// -k * rest) and a torque scale (the logged torque a scaled copy s tau of
/// the applied one: the residual holds (s - 1) of the torque, column the
/// model's torque; the measured torque would hold the residual itself and
/// "explain" any of it); for all joints at once a torque-state delay
/// (column: minus the measured torque's rate, the first-order effect of
/// logging the torque late; a signal's rate is uncorrelated with it, so the
/// measured rate carries every effect the logged torque holds without
/// regressing the residual on itself) and a tilted base; per link a
/// payload (the last) or an inertial error.
pub(super) fn candidates(data: &Stacked, columns: Columns, links: &[Link]) -> Vec<Candidate> {
    let n = data.dof;
    let Columns {
        own: [qd, sign, qdd, ones, angle],
        coulomb_applied,
        mut inertial,
        tilt,
        measured_rate,
        coulomb_levels,
        sample_period,
        stribeck,
        rest,
        modelled_ripple,
    } = columns;
    let model_torque = &data.measured - &data.residual;
    let own = |j: usize, f: &dyn Fn(usize) -> f64| {
        DVector::from_fn(
            data.residual.len(),
            |r, _| if r % n == j { f(r) } else { 0.0 },
        )
    };
    let mut list = Vec::new();
    for j in 0..n {
        let one = |kind, name, f: &dyn Fn(usize) -> f64| Candidate {
            kind,
            joint: Some(j),
            link: None,
            modelled: [0.0; 10],
            names: vec![name],
            columns: vec![own(j, f)],
            applied: None,
            shape: Shape::Linear,
            settings: Vec::new(),
            searched: 1,
        };
        list.push(one(Kind::ViscousFriction, "coefficient", &|r| qd[r]));
        list.push(Candidate {
            applied: Some(own(j, &|r| coulomb_applied[r])),
            ..one(Kind::CoulombFriction, "level", &|r| sign[r])
        });
        list.push(Candidate {
            applied: Some(own(j, &|r| coulomb_applied[r] * coulomb_applied[r])),
            shape: Shape::Asymmetry {
                modelled_coulomb: coulomb_levels.get(j).copied().unwrap_or(0.0),
            },
            ..one(Kind::CoulombAsymmetry, "asymmetry", &|r| sign[r] * sign[r])
        });
        list.push(one(Kind::Armature, "inertia", &|r| qdd[r]));
        list.push(one(Kind::TorqueOffset, "offset", &|r| ones[r]));
        list.push(one(Kind::TorqueScale, "scale_error", &|r| model_torque[r]));
        list.push(Candidate {
            names: vec!["stiffness", "constant"],
            columns: vec![own(j, &|r| angle[r]), own(j, &|r| ones[r])],
            ..one(Kind::JointSpring, "", &|_| 0.0)
        });
        let linear: Vec<&DVector<f64>> = [&qd, &sign, &qdd, &ones, &angle, &model_torque]
            .into_iter()
            .chain(&inertial)
            .chain(tilt.iter().flat_map(|(_, columns)| columns))
            .collect();
        let nuisance = search::Nuisance::new(data, j, &linear);
        let at_rest = rest.get(j).copied().unwrap_or(0.0);
        if let Some((k, velocity, searched)) =
            search::stribeck_velocity(&nuisance, at_rest, data.levers[j], &stribeck)
        {
            let (fitted, applied) = &stribeck[k];
            list.push(Candidate {
                applied: Some(own(j, &|r| applied[r])),
                settings: vec![("velocity", velocity)],
                searched,
                ..one(Kind::StribeckFriction, "excess", &|r| fitted[r])
            });
        }
        let ripple = match modelled_ripple.get(j).copied().flatten() {
            // A ripple the model has is refit at its harmonic (a correction
            // of its amplitudes; a description holds one harmonic per
            // joint). No search: the nuisance's model-torque column holds
            // the modelled ripple, so the search could not see that
            // harmonic, and an amplitude 4 times the model's went unnamed.
            Some(cycles) => Some((cycles, 1)),
            None => search::ripple_cycles(data, j, &angle, &nuisance),
        };
        if let Some((cycles, searched)) = ripple {
            list.push(Candidate {
                names: vec!["sin", "cos"],
                columns: vec![
                    own(j, &|r| (cycles * angle[r]).sin()),
                    own(j, &|r| (cycles * angle[r]).cos()),
                ],
                settings: vec![("cycles", cycles)],
                searched,
                ..one(Kind::TorqueRipple, "", &|_| 0.0)
            });
        }
    }
    let whole = |kind, names: Vec<&'static str>, columns| Candidate {
        kind,
        joint: None,
        link: None,
        modelled: [0.0; 10],
        names,
        columns,
        applied: None,
        shape: Shape::Linear,
        settings: Vec::new(),
        searched: 1,
    };
    list.push(Candidate {
        shape: Shape::Delay { sample_period },
        ..whole(Kind::TorqueDelay, vec!["delay"], vec![-measured_rate])
    });
    if let Some((shape, columns)) = tilt {
        list.push(Candidate {
            shape,
            ..whole(
                Kind::GravityDirection,
                vec!["across_1", "across_2"],
                columns.to_vec(),
            )
        });
    }
    for (k, link) in links.iter().enumerate().rev() {
        let columns: Vec<DVector<f64>> = inertial.drain(10 * k..).collect();
        if k + 1 == n {
            list.push(payload_candidate(k, link, columns.clone()));
        }
        list.push(link_candidate(k, link, columns));
    }
    list
}

/// A payload on the last link: a point mass added to it (mass and COM).
fn payload_candidate(k: usize, link: &Link, columns: Vec<DVector<f64>>) -> Candidate {
    Candidate {
        kind: Kind::Payload,
        shape: Shape::Body {
            offset: [0.0; 10],
            base_mass: 0.0,
            base_moment: Vector3::zeros(),
        },
        ..link_candidate(k, link, columns)
    }
}

/// An inertial error of any link: its mass and COM moved, its inertia
/// about the COM as modelled. On the last link it competes with a payload
/// (the same ten columns; only the second moments tell them apart).
fn link_candidate(k: usize, link: &Link, columns: Vec<DVector<f64>>) -> Candidate {
    let (mass, moment) = (
        link.parameters[0],
        Vector3::new(link.parameters[1], link.parameters[2], link.parameters[3]),
    );
    let com = if mass > 0.0 {
        moment / mass
    } else {
        Vector3::zeros()
    };
    Candidate {
        kind: Kind::InertialError,
        joint: None,
        link: Some((k, link.name.clone())),
        modelled: link.parameters,
        names: vec!["mass", "cx", "cy", "cz"],
        columns,
        applied: None,
        shape: Shape::Body {
            offset: point_mass(-mass, &com),
            base_mass: mass,
            base_moment: moment,
        },
        settings: Vec::new(),
        searched: 1,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
            let body = Shape::Body { offset: zero, base_mass: m, base_moment: Vector3::zeros() };
            let theta = [m, c[0], c[1], c[2]];
            prop_assert!(close(&body.curvature(&theta, &weights), &differenced(&body, &theta, &weights)));
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
