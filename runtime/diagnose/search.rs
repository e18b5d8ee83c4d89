//! Shapes of the columns that are not linear in their parameters, chosen
//! from the data before the fit: a joint's Stribeck velocity and the
//! harmonic of its torque ripple. Each is the profile least-squares choice
//! (the shape whose columns, fitted with the joint's own simple columns,
//! leave the least residual), and the candidate records how many shapes
//! were tried, so its significance threshold grows with the search.

use nalgebra::{DMatrix, DVector};

use super::stacked::Stacked;

/// Stribeck velocities tried, rad/s: ratio 1.4 from 0.01 to 0.79, so the
/// chosen one is within 18% of any velocity in that range. Below 0.01 rad/s
/// a joint's velocity is not resolved from a logged state; above 0.8 rad/s
/// the shape is a slope of viscous friction, not a breakaway.
pub fn stribeck_velocities() -> Vec<f64> {
    (0..14).map(|k| 0.01 * 1.4_f64.powi(k)).collect()
}

/// A Stribeck velocity is resolved from the recorded speeds at this
/// multiple of the joint's at-rest speed (three noise deviations): below,
/// its column is the samples just past the at-rest threshold, where a
/// joint that sticks and slips (any dry friction) leaves structure too.
pub(super) const RESOLVED_REST_MULTIPLE: f64 = 3.0;

/// Most ripple periods per joint revolution searched; and the least number
/// of periods over the range the joint travelled (fewer are a smooth
/// function of the position: a spring, gravity, an offset). Half a period
/// already bends the torque against the position in a way a spring or the
/// rigid body's first and second harmonics cannot; two (the first choice)
/// missed 6 and 4 cycles per revolution on joints that travelled 1-1.5 rad.
const MOST_CYCLES: usize = 64;
const LEAST_PERIODS_TRAVELLED: f64 = 0.5;
/// Harmonics of the position up to the second are gravity and inertial
/// terms of the rigid body: a ripple starts at the third.
const LEAST_CYCLES: usize = 3;

/// What the other candidates could explain on one joint's rows: the
/// search profiles the residual and each trial shape after projecting
/// these out, so a large other effect (a payload, a scale error) does not
/// choose the shape.
pub(super) struct Nuisance {
    rows: Vec<usize>,
    basis: DMatrix<f64>,
    residual: DVector<f64>,
}

impl Nuisance {
    /// The joint's rows of `columns`, made orthonormal (columns without
    /// independent content are dropped), and the residual with them
    /// projected out.
    pub(super) fn new(data: &Stacked, j: usize, columns: &[&DVector<f64>]) -> Nuisance {
        let rows = data.rows_of(j).collect::<Vec<_>>();
        let restricted = DMatrix::from_fn(rows.len(), columns.len(), |i, k| columns[k][rows[i]]);
        let basis = orthonormal_basis(restricted);
        let mut nuisance = Nuisance {
            residual: DVector::zeros(0),
            basis,
            rows,
        };
        nuisance.residual = nuisance.project_out(&data.residual);
        nuisance
    }

    /// The joint's rows of `column` minus their projection on the basis.
    fn project_out(&self, column: &DVector<f64>) -> DVector<f64> {
        let v = DVector::from_iterator(self.rows.len(), self.rows.iter().map(|&r| column[r]));
        self.project_rows_out(v)
    }

    /// `v`, the joint's rows of a column, minus its projection on the basis.
    fn project_rows_out(&self, v: DVector<f64>) -> DVector<f64> {
        let coefficients = self.basis.tr_mul(&v);
        v - &self.basis * coefficients
    }

    /// Residual sum of squares left by a least-squares fit of `shape`'s
    /// columns after the projection (infinite when they vanish).
    fn leaves(&self, shape: &[DVector<f64>]) -> f64 {
        self.leaves_projected(shape.iter().map(|c| self.project_out(c)).collect())
    }

    /// [`Nuisance::leaves`] for shapes given on the joint's rows only.
    fn leaves_on_rows(&self, shape: [DVector<f64>; 2]) -> f64 {
        self.leaves_projected(shape.map(|v| self.project_rows_out(v)).into())
    }

    fn leaves_projected(&self, projected: Vec<DVector<f64>>) -> f64 {
        let k = projected.len();
        let normal = DMatrix::from_fn(k, k, |a, b| projected[a].dot(&projected[b]));
        let moment = DVector::from_fn(k, |a, _| projected[a].dot(&self.residual));
        match normal.cholesky() {
            Some(c) => self.residual.norm_squared() - moment.dot(&c.solve(&moment)),
            None => f64::INFINITY,
        }
    }
}

/// A column's share of its norm (or of the largest column's) below which
/// it adds no direction of its own (see [`orthonormal_basis`]).
const DEPENDENT: f64 = 1e-9;

/// Columns orthogonalized together against the basis found so far: one
/// matrix product per pass instead of a pass over the basis per column
/// (at the reversal band a joint's basis is tens of megabytes).
const PANEL: usize = 16;

/// An orthonormal basis of the column space of `x`: block Gram-Schmidt
/// twice over the columns scaled to unit norm, in panels of [`PANEL`]
/// (each projected off the basis so far, then orthogonalized within); a
/// column with under 1e-9 of its norm left is dependent and dropped, and
/// so is a column under 1e-9 of the largest column's norm: rounding (a
/// link's inertial column on a joint it cannot move, 5e-16 beside 1e2),
/// which scaled to unit norm would add a random direction, another one
/// for each way of computing the same model.
fn orthonormal_basis(x: DMatrix<f64>) -> DMatrix<f64> {
    let largest = x.column_iter().map(|c| c.norm()).fold(0.0, f64::max);
    let unit: Vec<DVector<f64>> = x
        .column_iter()
        .filter_map(|column| {
            let norm = column.norm();
            (norm > DEPENDENT * largest && norm > 0.0).then(|| column / norm)
        })
        .collect();
    let mut basis = DMatrix::zeros(x.nrows(), unit.len());
    let mut found = 0;
    for chunk in unit.chunks(PANEL) {
        let mut panel = DMatrix::from_columns(chunk);
        if found > 0 {
            let before = basis.columns(0, found);
            for _ in 0..2 {
                // The panel's transpose on the left: both products are
                // blocked matrix products (`tr_mul` is a dot per entry).
                let along = (panel.transpose() * before).transpose();
                panel -= before * along;
            }
        }
        let start = found;
        for v in panel.column_iter() {
            let mut v = v.into_owned();
            for _ in 0..2 {
                for b in basis.columns(start, found - start).column_iter() {
                    let along = b.dot(&v);
                    v.axpy(-along, &b, 1.0);
                }
            }
            let left = v.norm();
            if left > DEPENDENT {
                basis.set_column(found, &(v / left));
                found += 1;
            }
        }
    }
    basis.columns(0, found).into_owned()
}

/// The Stribeck velocity of joint `j` (index into `columns` and its value):
/// among the grid's velocities of at least [`RESOLVED_REST_MULTIPLE`] times
/// the joint's at-rest speed `rest` (slower ones are not resolved), the one
/// whose fitted column leaves the least residual once `nuisance` is
/// projected out. `None` when no velocity of the grid is resolved. The
/// grid is scaled by the joint's `lever` (m/rad on a prismatic joint).
pub(super) fn stribeck_velocity(
    nuisance: &Nuisance,
    rest: f64,
    lever: f64,
    columns: &[DVector<f64>],
) -> Option<(usize, f64, usize)> {
    let velocities: Vec<f64> = stribeck_velocities().iter().map(|v| v * lever).collect();
    if columns.len() != velocities.len() {
        return None; // Stribeck friction does not compete
    }
    let resolved: Vec<usize> = (0..velocities.len())
        .filter(|&k| velocities[k] >= RESOLVED_REST_MULTIPLE * rest)
        .collect();
    let best = resolved
        .iter()
        .map(|&k| (k, nuisance.leaves(std::slice::from_ref(&columns[k]))))
        .min_by(|x, y| x.1.total_cmp(&y.1))?;
    Some((best.0, velocities[best.0], resolved.len()))
}

/// The ripple harmonic of joint `j` (periods per revolution) and how many
/// column shapes were searched (two per harmonic): integers from the third
/// harmonic (and [`LEAST_PERIODS_TRAVELLED`] periods over the range the
/// joint travelled) to [`MOST_CYCLES`], the one
/// whose sine and cosine of `cycles * q` leave the least residual once
/// `nuisance` is projected out. `None` when the joint travelled too little
/// for any.
pub(super) fn ripple_cycles(
    data: &Stacked,
    j: usize,
    angle: &DVector<f64>,
    nuisance: &Nuisance,
) -> Option<(f64, usize)> {
    let (low, high) = data
        .rows_of(j)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), r| {
            (l.min(angle[r]), h.max(angle[r]))
        });
    let travelled = high - low;
    if travelled.is_nan() || travelled <= 0.0 {
        return None;
    }
    let fewest = (LEAST_PERIODS_TRAVELLED * std::f64::consts::TAU / travelled).ceil();
    let first = LEAST_CYCLES.max(fewest.min(MOST_CYCLES as f64 + 1.0) as usize);
    if first > MOST_CYCLES {
        return None;
    }
    // The shapes on the joint's rows only: the other joints' are not fitted.
    let angle =
        DVector::from_iterator(nuisance.rows.len(), nuisance.rows.iter().map(|&r| angle[r]));
    let best = (first..=MOST_CYCLES)
        .map(|h| {
            let h = h as f64;
            let shape = [angle.map(|q| (h * q).sin()), angle.map(|q| (h * q).cos())];
            (h, nuisance.leaves_on_rows(shape))
        })
        .min_by(|x, y| x.1.total_cmp(&y.1))?;
    // Either column may pass the significance test: two tests per harmonic.
    Some((best.0, 2 * (MOST_CYCLES - first + 1)))
}

/// A deterministic white noise of unit RMS (uniform, a linear congruential
/// generator from `seed`) for the diagnosis's unit tests.
#[cfg(test)]
pub(super) fn white_noise(seed: u64) -> impl FnMut() -> f64 {
    let mut state = seed;
    move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 12f64.sqrt()
    }
}

/// One joint's stacked data with residual `f(q, qd)` along a sweep of
/// 1.2 sin(0.7 t) over 20 s in four groups (the diagnosis's unit tests).
#[cfg(test)]
pub(super) fn sweep(f: impl Fn(f64, f64) -> f64) -> (Stacked, DVector<f64>, DVector<f64>) {
    let samples = 4000;
    let t = |s: usize| s as f64 * 0.005;
    let q = DVector::from_fn(samples, |s, _| 1.2 * (0.7 * t(s)).sin());
    let qd = DVector::from_fn(samples, |s, _| 0.84 * (0.7 * t(s)).cos());
    let residual = DVector::from_fn(samples, |s, _| f(q[s], qd[s]));
    let data = Stacked {
        angle: q.clone(),
        qd: qd.clone(),
        ..Stacked::of_residual(residual, 1)
    };
    (data, q, qd)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A column at rounding level beside physical ones (a link's inertial
    /// column on a joint it cannot move, computed two ways) adds no
    /// direction: both versions leave the same basis.
    #[test]
    fn a_column_at_rounding_level_adds_no_direction() {
        let rows = 200;
        let wave = |k: f64| DVector::from_fn(rows, |i, _| (i as f64 * 0.05 * k).sin() * 1e2);
        let noise = |seed: u64| {
            let mut draw = white_noise(seed);
            DVector::from_fn(rows, |_, _| 3e-17 * draw())
        };
        let basis = |seed: u64| {
            orthonormal_basis(DMatrix::from_columns(&[wave(1.0), noise(seed), wave(2.3)]))
        };
        let (one, other) = (basis(1), basis(2));
        assert_eq!(one.ncols(), 2);
        assert_eq!(one, other);
    }

    #[test]
    fn the_ripple_harmonic_is_found() {
        let (data, q, _) = sweep(|q, _| 0.3 * (11.0 * q).sin() - 0.1 * (11.0 * q).cos());
        let nuisance = Nuisance::new(&data, 0, &[]);
        let (cycles, searched) = ripple_cycles(&data, 0, &q, &nuisance).unwrap();
        assert_eq!(cycles, 11.0);
        // 2.4 rad travelled: half a period of any harmonic from the third.
        assert_eq!(searched, 2 * (MOST_CYCLES - LEAST_CYCLES + 1));
        // A low harmonic, 1.5 periods over the range travelled.
        let (data, q, _) = sweep(|q, _| 0.1 * (4.0 * q).sin());
        let nuisance = Nuisance::new(&data, 0, &[]);
        assert_eq!(ripple_cycles(&data, 0, &q, &nuisance).unwrap().0, 4.0);
    }

    #[test]
    fn the_stribeck_velocity_is_the_nearest_on_the_grid() {
        let velocities = stribeck_velocities();
        let shape = |v: f64, qd: f64| qd.signum() * (-(qd / v).powi(2)).exp();
        let (data, _, qd) = sweep(|_, qd| 0.4 * qd.signum() + 0.2 * shape(0.1, qd));
        let columns: Vec<_> = velocities
            .iter()
            .map(|&v| qd.map(|x| shape(v, x)))
            .collect();
        let sign = qd.map(f64::signum);
        let ones = DVector::from_element(qd.len(), 1.0);
        let nuisance = Nuisance::new(&data, 0, &[&qd, &sign, &ones]);
        let (_, velocity, _) = stribeck_velocity(&nuisance, 0.02, 1.0, &columns).unwrap();
        assert!((velocity / 0.1 - 1.0).abs() < 0.2, "{velocity}");
    }

    proptest::proptest! {
        /// Across panels: the basis is orthonormal, spans every column,
        /// and drops exactly the dependent ones (copies and combinations of
        /// earlier columns, in this panel or an earlier one, and zeros).
        #[test]
        fn the_basis_spans_the_columns_and_drops_the_dependent_ones(
            seed in 0u64..1000,
            independent in 1usize..40,
            dependent in proptest::collection::vec((0usize..40, -3.0f64..3.0), 0..12),
        ) {
            let rows = 120;
            let mut state = seed.wrapping_add(1);
            let mut draw = || {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            };
            let mut columns: Vec<DVector<f64>> = Vec::new();
            for k in 0..independent {
                // Scales from 1e-3 to 1e3: unit norms are taken first.
                let scale = 10f64.powi(k as i32 % 7 - 3);
                columns.push(DVector::from_fn(rows, |_, _| scale * draw()));
            }
            for &(at, weight) in &dependent {
                let combined = &columns[at % columns.len()] * weight
                    + &columns[(at * 7 + 3) % columns.len()] * (1.0 - weight);
                columns.push(combined);
            }
            columns.push(DVector::zeros(rows));
            let x = DMatrix::from_columns(&columns);
            let basis = orthonormal_basis(x.clone());
            proptest::prop_assert_eq!(basis.ncols(), independent);
            let gram = basis.tr_mul(&basis);
            proptest::prop_assert!((gram - DMatrix::identity(independent, independent)).amax() < 1e-12);
            for column in x.column_iter() {
                let left = column - &basis * basis.tr_mul(&column);
                proptest::prop_assert!(left.norm() <= 1e-10 * (1.0 + column.norm()));
            }
        }
    }
}
