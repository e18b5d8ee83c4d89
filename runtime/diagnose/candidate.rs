//! The candidate effects: what each adds to the residual (its columns) and
//! how its named parameters map onto the coefficients of those columns.

use nalgebra::{DMatrix, DVector, Vector3};

use super::Kind;

/// One candidate: a kind, a joint or link, its columns and how its named
/// parameters map to coefficients of those columns.
pub(super) struct Candidate {
    pub(super) kind: Kind,
    pub(super) joint: Option<usize>,
    /// 0-based moving link and its name, for inertial candidates.
    pub(super) link: Option<(usize, String)>,
    pub(super) names: Vec<&'static str>,
    pub(super) columns: Vec<DVector<f64>>,
    /// What the generated model computes for this effect once applied, when
    /// that differs from the fitted column (Coulomb: the fit leaves out
    /// samples near rest, the model's sign(qd) does not). Held-out errors are
    /// scored with it, so they are what the applied model will show.
    pub(super) applied: Option<DVector<f64>>,
    pub(super) shape: Shape,
}

/// Parameters -> column coefficients.
#[derive(Debug, Clone)]
pub(super) enum Shape {
    /// The parameters are the coefficients.
    Linear,
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
            Shape::Linear => columns,
            Shape::Body { .. } => 4,
            Shape::Moment { .. } => 3,
        }
    }

    /// Coefficients and their Jacobian at theta.
    pub(super) fn map(&self, theta: &[f64]) -> (Vec<f64>, DMatrix<f64>) {
        match self {
            Shape::Linear => (theta.to_vec(), DMatrix::identity(theta.len(), theta.len())),
            Shape::Body { offset, .. } => {
                let (m, c) = (theta[0], Vector3::new(theta[1], theta[2], theta[3]));
                let unit = point_mass(1.0, &c);
                let coefficients = (0..10).map(|k| m * unit[k] + offset[k]).collect();
                let mut jacobian = DMatrix::zeros(10, 4);
                for k in 0..10 {
                    jacobian[(k, 0)] = unit[k];
                }
                let (x, y, z) = (c.x, c.y, c.z);
                let partial = [
                    [0.0, 1.0, 0.0, 0.0, 0.0, -y, 2.0 * x, -z, 0.0, 2.0 * x],
                    [0.0, 0.0, 1.0, 0.0, 2.0 * y, -x, 0.0, 0.0, -z, 2.0 * y],
                    [0.0, 0.0, 0.0, 1.0, 2.0 * z, 0.0, 2.0 * z, -x, -y, 0.0],
                ];
                for (a, row) in partial.iter().enumerate() {
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
                let (x, y, z) = (c.x, c.y, c.z);
                let partial = [
                    [0.0, 1.0, 0.0, 0.0, 0.0, -y, 2.0 * x, -z, 0.0, 2.0 * x],
                    [0.0, 0.0, 1.0, 0.0, 2.0 * y, -x, 0.0, 0.0, -z, 2.0 * y],
                    [0.0, 0.0, 0.0, 1.0, 2.0 * z, 0.0, 2.0 * z, -x, -y, 0.0],
                ];
                let jacobian = DMatrix::from_fn(10, 3, |k, a| partial[a][k]);
                (coefficients, jacobian)
            }
        }
    }
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
