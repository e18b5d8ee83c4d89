//! Whole-body inertial errors: a link's ten standard parameters corrected
//! at once. The data determine only some combinations of the ten (its base
//! parameters: the first link, turning about one axis, shows only its
//! inertia about that axis), so the candidate fits those combinations and
//! nothing else; the body it names is the physical one (pseudo-inertia
//! positive semi-definite) nearest to the fit in the data's own metric,
//! the directions the data do not see kept as close to the model as a
//! physical body allows.

use nalgebra::{DMatrix, DVector};
use serde_json::{Map, Value, json};

use super::nearest::nearest_body;
use super::shape::physically_consistent;
use super::solve::ROUNDING;
use super::stacked::EXTENT_MARGIN;

/// Relative eigenvalue of the link's unit-diagonal Gram matrix below which
/// a combination of its parameters is not fitted: its column is under 1%
/// of the strongest combination's, so the data would fit it with noise.
pub const WHOLE_COLLINEAR: f64 = 1e-4;

/// A whole-body fit that moves the torques it explains by more than this
/// share (in the data's metric) to reach a physical body is not a body.
pub const PHYSICAL_LOSS: f64 = 0.25;

/// The ten standard parameters, in the order of `shape::point_mass`.
pub const PARAMETERS: [&str; 10] = [
    "mass", "mx", "my", "mz", "ixx", "ixy", "iyy", "ixz", "iyz", "izz",
];

/// The names of a whole-body error's parameters.
pub const COMBINATIONS: [&str; 10] = [
    "combination_1",
    "combination_2",
    "combination_3",
    "combination_4",
    "combination_5",
    "combination_6",
    "combination_7",
    "combination_8",
    "combination_9",
    "combination_10",
];

/// The Gram matrix of a link's ten columns.
pub(super) fn gram_of(columns: &[DVector<f64>]) -> DMatrix<f64> {
    DMatrix::from_fn(10, 10, |i, j| columns[i].dot(&columns[j]))
}

/// A link's ten columns combined as `basis` (10 x k) says: k columns.
pub(super) fn combine(ten: &[DVector<f64>], basis: &DMatrix<f64>) -> Vec<DVector<f64>> {
    (0..basis.ncols())
        .map(|l| (0..10).fold(ten[0].scale(0.0), |z, i| z + &ten[i] * basis[(i, l)]))
        .collect()
}

/// The unit-diagonal scaling of a Gram matrix: column norms, zero for a
/// column at rounding level (`rounding` times the largest norm).
fn column_norms(gram: &DMatrix<f64>, rounding: f64) -> Vec<f64> {
    let norms: Vec<f64> = (0..10).map(|i| gram[(i, i)].max(0.0).sqrt()).collect();
    let largest = norms.iter().copied().fold(0.0, f64::max);
    norms
        .iter()
        .map(|&n| if n > rounding * largest { n } else { 0.0 })
        .collect()
}

/// Combinations of ten parameters that a Gram matrix determines:
/// eigenvectors of its unit-diagonal scaling with eigenvalues at least
/// `threshold` times the largest, as changes of the ten (10 x k), and the
/// directions it does not see (each scaled to a largest entry of 1).
pub(super) fn combinations(
    gram: &DMatrix<f64>,
    threshold: f64,
    rounding: f64,
) -> Option<(DMatrix<f64>, Vec<[f64; 10]>)> {
    let d = column_norms(gram, rounding);
    let scaled = DMatrix::from_fn(10, 10, |i, j| {
        if d[i] > 0.0 && d[j] > 0.0 {
            gram[(i, j)] / (d[i] * d[j])
        } else {
            0.0
        }
    });
    let eigen = crate::kernels::symmetric_eigen(scaled)?;
    let largest = eigen.eigenvalues.max();
    let kept: Vec<usize> = (0..10)
        .filter(|&k| largest > 0.0 && eigen.eigenvalues[k] >= threshold * largest)
        .collect();
    let null = (0..10)
        .filter(|k| !kept.contains(k))
        .map(|k| {
            let v: [f64; 10] = std::array::from_fn(|i| {
                let x = eigen.eigenvectors[(i, k)];
                if d[i] > 0.0 { x / d[i] } else { x }
            });
            let top = v.iter().fold(0.0_f64, |t, x| t.max(x.abs()));
            v.map(|x| if top > 0.0 { x / top } else { 0.0 })
        })
        .collect();
    let basis = DMatrix::from_fn(10, kept.len(), |i, l| {
        if d[i] > 0.0 {
            eigen.eigenvectors[(i, kept[l])] / d[i]
        } else {
            0.0
        }
    });
    Some((basis, null))
}

/// The body a whole-body fit names: the physical body nearest to the
/// fitted one (the model's parameters plus `basis * combinations`) in the
/// metric of the data (`gram`) with its centre of mass within `radius` of
/// the link origin (infinite: anywhere), and the share of the fitted
/// change's torques that reaching it gives up (0 when the fit is such a
/// body).
pub(super) fn named_body(
    modelled: &[f64; 10],
    (basis, gram): (&DMatrix<f64>, &DMatrix<f64>),
    combinations: &[f64],
    radius: f64,
) -> ([f64; 10], f64) {
    let change = basis * DVector::from_column_slice(combinations);
    let fitted: [f64; 10] = std::array::from_fn(|i| modelled[i] + change[i]);
    let body = nearest_body(&fitted, modelled, gram, radius);
    let moved = DVector::from_fn(10, |i, _| body[i] - fitted[i]);
    let signal = change.dot(&(gram * &change));
    let lost = moved.dot(&(gram * &moved));
    let share = if signal > 0.0 { lost / signal } else { 0.0 };
    (body, share)
}

/// The body a whole-body fit names on a link whose centre of mass is
/// plausible within `extent` of its origin: the nearest physical body, or,
/// where that body's COM lies beyond the extent, the nearest one within it.
pub(super) struct Named {
    pub body: [f64; 10],
    /// The share of the fitted change's torques that reaching `body` gives up.
    pub lost: f64,
    /// Where the nearest physical body had its COM beyond the extent: that
    /// distance (m) and the share reaching it gave up.
    pub beyond: Option<(f64, f64)>,
}

/// See [`Named`].
pub(super) fn named_within(
    modelled: &[f64; 10],
    (basis, gram): (&DMatrix<f64>, &DMatrix<f64>),
    combinations: &[f64],
    extent: f64,
) -> Named {
    let (body, lost) = named_body(modelled, (basis, gram), combinations, f64::INFINITY);
    let distance = com_distance(&body);
    if distance <= extent {
        return Named {
            body,
            lost,
            beyond: None,
        };
    }
    let (within, lost_within) = named_body(modelled, (basis, gram), combinations, extent);
    Named {
        body: within,
        lost: lost_within,
        beyond: Some((distance, lost)),
    }
}

/// The distance of a body's centre of mass from its link origin (m).
pub(super) fn com_distance(p: &[f64; 10]) -> f64 {
    if p[0] > 0.0 {
        (p[1] * p[1] + p[2] * p[2] + p[3] * p[3]).sqrt() / p[0]
    } else {
        f64::INFINITY
    }
}

/// A body's mass, centre of mass and inertia about it ([ixx, ixy, ixz,
/// iyy, iyz, izz], link axes) from its standard parameters.
pub fn about_com(p: &[f64; 10]) -> (f64, [f64; 3], [f64; 6]) {
    let m = p[0];
    let c = if m.abs() > 0.0 {
        [p[1] / m, p[2] / m, p[3] / m]
    } else {
        [0.0; 3]
    };
    let shifted = super::shape::point_mass(-m, &nalgebra::Vector3::from(c));
    let i: [f64; 10] = std::array::from_fn(|k| p[k] + shifted[k]);
    (m, c, [i[4], i[5], i[7], i[6], i[8], i[9]])
}

/// An inertia's entries under [`ROUNDING`] of its largest as exact
/// zeros: the products of inertia a symmetric body lacks, which the shift
/// to the COM leaves as 1e-20 beside 1e-3, other digits for each way the
/// model is computed.
fn without_rounding(inertia: [f64; 6]) -> [f64; 6] {
    let largest = inertia.iter().fold(0.0, |m: f64, x| m.max(x.abs()));
    inertia.map(|x| {
        if x.abs() <= ROUNDING * largest {
            0.0
        } else {
            x
        }
    })
}

/// The report's parameters of a named whole-body error (`label`, the
/// model's `modelled` link and its `extent`; `values`: each
/// combination's value and 95% half-width): the named body's mass, COM and
/// inertia about the COM beside the model's, the combinations with their
/// intervals, and which standard parameters the data determine; a note
/// says that the rest are the model's.
pub(super) fn describe(
    (label, modelled, extent): (&str, &[f64; 10], f64),
    (basis, gram): (&DMatrix<f64>, &DMatrix<f64>),
    values: &[(f64, f64)],
    (parameters, ci95): (&mut Map<String, Value>, &mut Map<String, Value>),
    notes: &mut Vec<String>,
) {
    let fitted: Vec<f64> = values.iter().map(|v| v.0).collect();
    let named = named_within(modelled, (basis, gram), &fitted, extent);
    let (body, lost) = (named.body, named.lost);
    let (mass, com, inertia) = about_com(&body);
    let inertia = without_rounding(inertia);
    let (nominal_mass, nominal_com, nominal_inertia) = about_com(modelled);
    let known = determined(gram);
    parameters.insert("mass".into(), json!(mass));
    parameters.insert("com".into(), json!(com));
    parameters.insert("inertia".into(), json!(inertia));
    parameters.insert("nominal_mass".into(), json!(nominal_mass));
    parameters.insert("nominal_com".into(), json!(nominal_com));
    parameters.insert("nominal_inertia".into(), json!(nominal_inertia));
    parameters.insert("identifiable_combinations".into(), json!(values.len()));
    parameters.insert("determined".into(), json!(known));
    parameters.insert("combinations".into(), json!(fitted));
    ci95.insert(
        "combinations".into(),
        json!(
            values
                .iter()
                .map(|(v, h)| [v - h, v + h])
                .collect::<Vec<_>>()
        ),
    );
    parameters.insert(
        "physically_consistent".into(),
        json!(physically_consistent(&body)),
    );
    let seen = if known.is_empty() {
        "none of the ten standard parameters alone".to_string()
    } else {
        known.join(", ")
    };
    notes.push(format!(
        "{}: the whole body is corrected: these data determine {} combinations of the link's ten \
         inertial parameters (alone: {seen}, about the link origin); the rest are the model's, \
         moved only as far as a physical body needs{}",
        label,
        values.len(),
        if lost > 1e-6 {
            format!(
                " (the nearest physical body gives up {:.1}% of the torque the free fit \
                 explains)",
                100.0 * lost
            )
        } else {
            String::new()
        }
    ));
    if let Some((distance, _)) = named.beyond {
        notes.push(format!(
            "{label}: the nearest physical body to the fit has its centre of mass {distance:.3} m \
             from the link origin, beyond the link's extent ({extent:.3} m: its farthest child \
             joint or modelled COM plus {EXTENT_MARGIN} m); named: the nearest body with its \
             COM within it"
        ));
    }
}

/// Which of the ten standard parameters the data determine: those whose
/// own direction lies (within 10%) in the span the Gram matrix sees.
pub(super) fn determined(gram: &DMatrix<f64>) -> Vec<&'static str> {
    let d = column_norms(gram, 1e-9);
    let Some((_, null)) = combinations(gram, WHOLE_COLLINEAR, 1e-9) else {
        return Vec::new();
    };
    // The null directions in unit-diagonal coordinates, orthonormalized.
    let unseen: Vec<DVector<f64>> = null
        .iter()
        .map(|v| DVector::from_fn(10, |i, _| if d[i] > 0.0 { v[i] * d[i] } else { v[i] }))
        .collect();
    let basis = if unseen.is_empty() {
        DMatrix::zeros(10, 0)
    } else {
        DMatrix::from_columns(&unseen).qr().q()
    };
    (0..10)
        .filter(|&i| {
            d[i] > 0.0
                && (0..basis.ncols())
                    .map(|l| basis[(i, l)].powi(2))
                    .sum::<f64>()
                    < 0.01
        })
        .map(|i| PARAMETERS[i])
        .collect()
}

#[cfg(test)]
mod tests {
    use super::super::nearest::tests::rod;
    use super::*;

    /// Data that see every parameter: a physical fit is kept as it is; an
    /// impossible one (principal moments 1, 1, 3) is moved to a body.
    #[test]
    fn the_named_body_is_the_fit_when_physical_and_a_body_otherwise() {
        let gram = DMatrix::identity(10, 10);
        let modelled = rod(1.0, [0.0, 0.0, 0.1], [0.01, 0.01, 0.01]);
        let fitted = rod(1.2, [0.0, 0.0, 0.12], [0.012, 0.012, 0.012]);
        let basis = DMatrix::identity(10, 10);
        let change: Vec<f64> = (0..10).map(|i| fitted[i] - modelled[i]).collect();
        let (body, lost) = named_body(&modelled, (&basis, &gram), &change, f64::INFINITY);
        assert!(lost < 1e-10, "{lost}");
        for i in 0..10 {
            assert!((body[i] - fitted[i]).abs() < 1e-6, "{body:?}");
        }
        let impossible = rod(1.0, [0.0; 3], [1.0, 1.0, 3.0]);
        let change: Vec<f64> = (0..10).map(|i| impossible[i] - modelled[i]).collect();
        let (body, lost) = named_body(&modelled, (&basis, &gram), &change, f64::INFINITY);
        assert_eq!(physically_consistent(&body), Some(true), "{body:?}");
        assert!(lost > 0.0 && lost < 1.0, "{lost}");
    }

    /// Data that see only the inertia about z (a link turning about one
    /// axis): one combination, izz determined, the rest from the model.
    #[test]
    fn one_axis_determines_one_combination() {
        let mut gram = DMatrix::zeros(10, 10);
        gram[(9, 9)] = 4.0;
        let (basis, null) = combinations(&gram, WHOLE_COLLINEAR, 1e-9).unwrap();
        assert_eq!((basis.ncols(), null.len()), (1, 9));
        assert_eq!(determined(&gram), ["izz"]);
    }
}
