//! The physical body nearest to a fitted one: the projection of a
//! whole-body fit onto bodies a real link can be (pseudo-inertia positive
//! semi-definite, and the centre of mass within the link), in the data's
//! metric.

use nalgebra::{DMatrix, DVector, Matrix3, Matrix4, Vector3};

/// Natural scales of the ten parameters for a body of mass `m` and size
/// `l`: kg, kg m, kg m^2.
fn scales(m: f64, l: f64) -> [f64; 10] {
    std::array::from_fn(|i| match i {
        0 => m,
        1..=3 => m * l,
        _ => m * l * l,
    })
}

/// Minimizes (p - fitted)^T G (p - fitted) + eps |(p - modelled) / s|^2
/// over physical bodies p with their centre of mass within `radius` of the
/// link origin, parametrized by the log-Cholesky factor of the
/// pseudo-inertia (Rucker and Wensing 2022: every parameter vector is a
/// physical body and every body with a definite pseudo-inertia is
/// reached), by damped Gauss-Newton steps. The small second term keeps
/// what the data do not see at the model's values where the body allows.
/// The COM bound (|h| <= radius m, a convex cone) is an exterior penalty
/// raised tenfold until the COM is within it to 1e-9.
pub(super) fn nearest_body(
    fitted: &[f64; 10],
    modelled: &[f64; 10],
    gram: &DMatrix<f64>,
    radius: f64,
) -> [f64; 10] {
    let mass = modelled[0].abs().max(fitted[0].abs()).max(1e-3);
    let size = (modelled[1].powi(2) + modelled[2].powi(2) + modelled[3].powi(2)).sqrt() / mass;
    let s = scales(mass, size.max(0.05));
    let curvature: f64 = (0..10).map(|i| gram[(i, i)] * s[i] * s[i]).sum::<f64>() / 10.0;
    let eps = 1e-8 * curvature.max(f64::MIN_POSITIVE);
    let mut target = Target {
        weight: DMatrix::from_fn(10, 10, |i, j| {
            gram[(i, j)] + if i == j { eps / (s[i] * s[i]) } else { 0.0 }
        }),
        pull: gram * DVector::from_column_slice(fitted)
            + DVector::from_fn(10, |i, _| eps * modelled[i] / (s[i] * s[i])),
        radius,
        penalty: 0.0,
    };
    let mut theta = descend(log_cholesky(&start(fitted, modelled)), &target);
    if radius.is_finite() {
        // The penalty starts at the data's own curvature of the first moment.
        target.penalty = (1..4).map(|i| target.weight[(i, i)]).fold(eps, f64::max);
        for _ in 0..16 {
            let (p, _) = parameters(&theta);
            if target.excess(&p).0 <= 1e-9 * radius * p[0].abs() {
                break;
            }
            theta = descend(theta, &target);
            target.penalty *= 10.0;
        }
    }
    let (p, _) = parameters(&theta);
    std::array::from_fn(|i| p[i])
}

/// The objective of [`nearest_body`]: p^T W p - 2 p^T pull plus the
/// penalty times the square of how far the first moment exceeds radius m.
struct Target {
    weight: DMatrix<f64>,
    pull: DVector<f64>,
    radius: f64,
    penalty: f64,
}

impl Target {
    /// |h| - radius m where positive (else 0), and its gradient in p.
    fn excess(&self, p: &DVector<f64>) -> (f64, DVector<f64>) {
        let moment = (p[1] * p[1] + p[2] * p[2] + p[3] * p[3]).sqrt();
        let excess = moment - self.radius * p[0];
        let mut gradient = DVector::zeros(10);
        if !(excess > 0.0 && self.penalty > 0.0) {
            return (0.0, gradient);
        }
        gradient[0] = -self.radius;
        for i in 1..4 {
            gradient[i] = p[i] / moment;
        }
        (excess, gradient)
    }

    fn value(&self, p: &DVector<f64>) -> f64 {
        let (excess, _) = self.excess(p);
        p.dot(&(&self.weight * p)) - 2.0 * p.dot(&self.pull) + self.penalty * excess * excess
    }

    /// Half the gradient and the Gauss-Newton Hessian in p.
    fn slope(&self, p: &DVector<f64>) -> (DVector<f64>, DMatrix<f64>) {
        let (excess, a) = self.excess(p);
        let gradient = &self.weight * p - &self.pull + &a * (self.penalty * excess);
        let hessian = &self.weight + &a * a.transpose() * self.penalty;
        (gradient, hessian)
    }
}

/// Damped Gauss-Newton descent of `target` from log-Cholesky parameters
/// `theta`, until a step no longer lowers it.
fn descend(mut theta: DVector<f64>, target: &Target) -> DVector<f64> {
    let (mut p, _) = parameters(&theta);
    let mut value = target.value(&p);
    let mut damping = 1e-3;
    for _ in 0..200 {
        let (_, jacobian) = parameters(&theta);
        let (slope, curvature) = target.slope(&p);
        let gradient = jacobian.transpose() * slope;
        let hessian = jacobian.transpose() * curvature * &jacobian;
        let mut improved = false;
        while damping < 1e12 {
            let mut damped = hessian.clone();
            for i in 0..10 {
                damped[(i, i)] += damping * hessian[(i, i)].max(1e-300);
            }
            let Some(step) = damped.cholesky().map(|c| c.solve(&gradient)) else {
                damping *= 10.0;
                continue;
            };
            let trial = &theta - &step;
            let (q, _) = parameters(&trial);
            let v = target.value(&q);
            if v.is_finite() && v < value {
                let small = (value - v) <= 1e-14 * value.abs().max(f64::MIN_POSITIVE);
                (theta, p, value, improved) = (trial, q, v, !small);
                damping = (damping / 10.0).max(1e-12);
                break;
            }
            damping *= 10.0;
        }
        if !improved {
            break;
        }
    }
    theta
}

/// A start with a definite pseudo-inertia: the fitted body's, its
/// eigenvalues raised to a small floor (the model's scale) where needed.
fn start(fitted: &[f64; 10], modelled: &[f64; 10]) -> Matrix4<f64> {
    let pseudo = pseudo_inertia(fitted);
    let reference = pseudo_inertia(modelled)
        .norm()
        .max(pseudo.norm())
        .max(1e-12);
    let floor = 1e-6 * reference;
    let eigen = pseudo.symmetric_eigen();
    let raised = eigen.eigenvalues.map(|l| l.max(floor));
    eigen.eigenvectors * Matrix4::from_diagonal(&raised) * eigen.eigenvectors.transpose()
}

/// [[tr(I)/2 E - I, h], [h^T, m]] of standard parameters p.
fn pseudo_inertia(p: &[f64; 10]) -> Matrix4<f64> {
    let [m, hx, hy, hz, ixx, ixy, iyy, ixz, iyz, izz] = *p;
    let half = 0.5 * (ixx + iyy + izz);
    Matrix4::new(
        half - ixx,
        -ixy,
        -ixz,
        hx,
        -ixy,
        half - iyy,
        -iyz,
        hy,
        -ixz,
        -iyz,
        half - izz,
        hz,
        hx,
        hy,
        hz,
        m,
    )
}

/// Standard parameters of a pseudo-inertia (the inverse of
/// [`pseudo_inertia`], linear).
fn from_pseudo(j: &Matrix4<f64>) -> DVector<f64> {
    let trace = j[(0, 0)] + j[(1, 1)] + j[(2, 2)];
    DVector::from_vec(vec![
        j[(3, 3)],
        j[(0, 3)],
        j[(1, 3)],
        j[(2, 3)],
        trace - j[(0, 0)],
        -j[(0, 1)],
        trace - j[(1, 1)],
        -j[(0, 2)],
        -j[(1, 2)],
        trace - j[(2, 2)],
    ])
}

/// The (row, column) of each log-Cholesky parameter in the upper-triangular
/// factor U (J = U U^T): the four diagonal entries (as logarithms), then
/// the six above it.
const ENTRIES: [(usize, usize); 10] = [
    (0, 0),
    (1, 1),
    (2, 2),
    (3, 3),
    (0, 1),
    (0, 2),
    (0, 3),
    (1, 2),
    (1, 3),
    (2, 3),
];

/// The log-Cholesky parameters of a definite pseudo-inertia: the Cholesky
/// factor of the index-reversed matrix, reversed, is upper triangular.
fn log_cholesky(j: &Matrix4<f64>) -> DVector<f64> {
    let reversed = Matrix4::from_fn(|a, b| j[(3 - a, 3 - b)]);
    let l = reversed
        .cholesky()
        .map(|c| c.l())
        .unwrap_or_else(|| Matrix4::identity() * j.norm().max(1e-12).sqrt());
    let u = Matrix4::from_fn(|a, b| l[(3 - a, 3 - b)]);
    DVector::from_fn(10, |k, _| {
        let (a, b) = ENTRIES[k];
        if a == b {
            u[(a, a)].max(1e-300).ln()
        } else {
            u[(a, b)]
        }
    })
}

/// Standard parameters of log-Cholesky parameters theta, and their
/// Jacobian (10 x 10).
fn parameters(theta: &DVector<f64>) -> (DVector<f64>, DMatrix<f64>) {
    let mut u = Matrix4::zeros();
    for (k, &(a, b)) in ENTRIES.iter().enumerate() {
        u[(a, b)] = if a == b { theta[k].exp() } else { theta[k] };
    }
    let p = from_pseudo(&(u * u.transpose()));
    let mut jacobian = DMatrix::zeros(10, 10);
    for (k, &(a, b)) in ENTRIES.iter().enumerate() {
        let mut du = Matrix4::zeros();
        du[(a, b)] = if a == b { u[(a, a)] } else { 1.0 };
        let dj = du * u.transpose() + u * du.transpose();
        jacobian.set_column(k, &from_pseudo(&dj));
    }
    (p, jacobian)
}

/// The first moment nearest to `fitted` (kg m) within `radius` (kg m, the
/// link's extent times its mass) in the metric `precision` (3 x 3, the
/// fit's information about the first moment with the other parameters
/// refitted): it minimizes (h - fitted)^T P (h - fitted) subject to
/// |h| <= radius, h = (P + lambda I)^-1 P fitted with lambda found by
/// bisection (the trust-region subproblem), so it moves most where the
/// data see least. Within the radius the fit is kept as it is.
pub(super) fn moment_within(fitted: [f64; 3], precision: &Matrix3<f64>, radius: f64) -> [f64; 3] {
    let fitted = Vector3::from(fitted);
    if fitted.norm() <= radius {
        return fitted.into();
    }
    let pulled = precision * fitted;
    let at = |lambda: f64| -> Vector3<f64> {
        (precision + Matrix3::identity() * lambda)
            .lu()
            .solve(&pulled)
            .unwrap_or_else(Vector3::zeros)
    };
    let scale = precision.diagonal().amax().max(f64::MIN_POSITIVE);
    let (mut low, mut high) = (0.0, scale);
    while at(high).norm() > radius && high < 1e30 * scale {
        high *= 2.0;
    }
    for _ in 0..200 {
        let middle = 0.5 * (low + high);
        if at(middle).norm() > radius {
            low = middle;
        } else {
            high = middle;
        }
    }
    at(high).into()
}

#[cfg(test)]
pub(super) mod tests {
    use super::super::shape::{physically_consistent, point_mass};
    use super::*;

    /// A body of mass `m` at `c` with principal `moments` about its COM.
    pub(in super::super) fn rod(m: f64, c: [f64; 3], moments: [f64; 3]) -> [f64; 10] {
        let mut p = point_mass(m, &Vector3::from(c));
        p[4] += moments[0];
        p[6] += moments[1];
        p[9] += moments[2];
        p
    }

    #[test]
    fn log_cholesky_parameters_round_trip_and_their_jacobian_is_exact() {
        let body = rod(1.3, [0.1, -0.05, 0.2], [0.02, 0.03, 0.015]);
        let theta = log_cholesky(&pseudo_inertia(&body));
        let (p, jacobian) = parameters(&theta);
        for i in 0..10 {
            assert!((p[i] - body[i]).abs() < 1e-12, "{p} {body:?}");
        }
        for k in 0..10 {
            let h = 1e-6;
            let (mut up, mut down) = (theta.clone(), theta.clone());
            up[k] += h;
            down[k] -= h;
            let difference = (parameters(&up).0 - parameters(&down).0) / (2.0 * h);
            assert!((difference - jacobian.column(k)).amax() < 1e-7, "{k}");
        }
    }

    /// Data that see every parameter, a fit with its COM 0.63 m out: within
    /// 0.62 m the nearest body has its COM on that sphere, is physical,
    /// and is the fit itself where the sphere holds it.
    #[test]
    fn the_nearest_body_keeps_its_com_within_the_radius() {
        let gram = DMatrix::identity(10, 10);
        let modelled = rod(3.87, [0.0, 0.0, 0.2855], [0.11, 0.11, 0.011]);
        let fitted = rod(3.9, [0.0, 0.01, 0.63], [0.12, 0.12, 0.012]);
        let body = nearest_body(&fitted, &modelled, &gram, 0.62);
        let distance = Vector3::new(body[1], body[2], body[3]).norm() / body[0];
        assert!((distance - 0.62).abs() < 1e-6, "{distance}");
        assert_eq!(physically_consistent(&body), Some(true), "{body:?}");
        let free = nearest_body(&fitted, &modelled, &gram, f64::INFINITY);
        let held = nearest_body(&fitted, &modelled, &gram, 0.7);
        for i in 0..10 {
            assert!((free[i] - fitted[i]).abs() < 1e-6, "{free:?}");
            assert!((held[i] - fitted[i]).abs() < 1e-6, "{held:?}");
        }
    }

    /// A first moment 0.70 m out at 12.93 kg with a poorly determined y
    /// component: within 0.68 m, y moves most and the COM is on the sphere.
    #[test]
    fn a_first_moment_beyond_the_radius_moves_where_the_data_see_least() {
        let fitted = [-0.24, 8.3, 3.5];
        let radius = 0.68 * 12.93 * 0.95;
        let spread = [0.27_f64, 2.1, 0.5];
        let precision = Matrix3::from_diagonal(&Vector3::from(spread.map(|s| 1.0 / (s * s))));
        let kept = moment_within(fitted, &precision, radius);
        let norm = kept.iter().map(|x| x * x).sum::<f64>().sqrt();
        assert!((norm - radius).abs() < 1e-9 * radius, "{kept:?}");
        assert!((kept[1] / fitted[1]) < (kept[2] / fitted[2]), "{kept:?}");
        let identity = Matrix3::identity();
        assert_eq!(
            moment_within([0.1, 0.2, 0.3], &identity, 1.0),
            [0.1, 0.2, 0.3]
        );
    }
}
