//! The parameters an excitation is designed for and the information a
//! motion gives about them.
//!
//! They are the columns of the model's own regressor: every link's ten
//! inertial parameters and, per joint, armature, viscous and Coulomb
//! friction, a torque offset and direction-dependent friction. Many
//! inertial parameters act only in combinations, so the columns are
//! reduced once, from random states inside the limits, to base parameters
//! (Gautier's numerical method): a pivoted Cholesky factorization of their
//! unit-scaled Gram matrix keeps the columns independent of those kept
//! before (residual above [`STRUCTURAL`] of the column), and every other
//! column is regrouped into them (`izz1` stands for `izz1 + armature1`).
//! A motion's information matrix is that of the base columns; its
//! condition number is taken scaled to a unit diagonal, as the diagnosis
//! reports identifiability: 1 when the motion tells every base parameter
//! from every other, large when some combination barely changes the torque.

use anyhow::{Context, Result, bail};
use nalgebra::{DMatrix, DVector};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::fourier::Bounds;
use crate::dynamics::Dynamics;

/// Share of a column's norm that must be left once the columns kept
/// before are projected out for it to be a base parameter (structural
/// dependencies leave rounding, about 1e-16; real ones far more).
pub const STRUCTURAL: f64 = 1e-8;

/// RMS of a column, relative to the largest of its link's or joint's,
/// below which it is rounding (as in the diagnosis's free inertial fit).
pub const ROUNDING: f64 = 1e-9;

/// A joint slower than this (rad/s; times the lever on a prismatic joint)
/// is at rest for dry friction, as in the diagnosis: it sticks or creeps.
pub const MOVING: f64 = 0.02;

const INERTIAL: [&str; 10] = [
    "m", "mx", "my", "mz", "ixx", "ixy", "iyy", "ixz", "iyz", "izz",
];
const EFFECTS: [&str; 5] = [
    "armature",
    "viscous",
    "coulomb",
    "offset",
    "coulomb_asymmetry",
];

/// A motion's sampled states.
pub struct Samples {
    pub q: Vec<Vec<f64>>,
    pub qd: Vec<Vec<f64>>,
    pub qdd: Vec<Vec<f64>>,
}

/// The base parameters the excitation is designed for.
pub struct Parameters {
    /// Names of the base parameters (their regressor column's parameter).
    pub names: Vec<String>,
    /// What each stands for: itself plus these (name, coefficient) terms.
    pub regrouped: Vec<Vec<(String, f64)>>,
    /// Their regressor columns.
    columns: Vec<usize>,
    /// Per base parameter: the joint whose dry friction it is, with whether
    /// it is the direction-dependent part (column |sign|) or Coulomb (sign).
    dry: Vec<Option<(usize, bool)>>,
    /// Per joint the speed below which it is at rest.
    rest: Vec<f64>,
    /// Per base parameter the RMS of its column over the random states per
    /// sample: the size a rich motion gives it.
    pub typical: Vec<f64>,
}

/// The suffix number of a parameter name (`ixx3` -> ("ixx", 3)).
fn split_name(name: &str) -> Option<(&str, usize)> {
    let digits = name.len() - name.trim_end_matches(|c: char| c.is_ascii_digit()).len();
    let (prefix, number) = name.split_at(name.len() - digits);
    Some((prefix, number.parse().ok()?))
}

impl Parameters {
    /// Chooses the columns of `model` and reduces them to base parameters,
    /// from random states inside `bounds` drawn from `seed`.
    pub fn new(
        model: &dyn Dynamics,
        bounds: &Bounds,
        levers: &[f64],
        seed: u64,
    ) -> Result<Parameters> {
        let mut p = Parameters {
            names: Vec::new(),
            regrouped: Vec::new(),
            columns: Vec::new(),
            dry: Vec::new(),
            rest: levers.iter().map(|l| MOVING * l).collect(),
            typical: Vec::new(),
        };
        for (c, name) in model.parameter_names().iter().enumerate() {
            let Some((prefix, number)) = split_name(name) else {
                continue;
            };
            if INERTIAL.contains(&prefix) || EFFECTS.contains(&prefix) {
                p.names.push(name.to_string());
                p.columns.push(c);
                p.dry.push(match prefix {
                    "coulomb" => Some((number.saturating_sub(1), false)),
                    "coulomb_asymmetry" => Some((number.saturating_sub(1), true)),
                    _ => None,
                });
            }
        }
        let samples = random_states(model.dof(), bounds, p.columns.len(), seed);
        let gram = p.gram(model, &samples)?;
        p.reduce(&gram)?;
        let count = samples.q.len() as f64;
        p.typical = p
            .gram(model, &samples)?
            .diagonal()
            .iter()
            .map(|g| (g / count).sqrt())
            .collect();
        Ok(p)
    }

    /// Keeps the columns above rounding that are independent of those kept
    /// before them, and regroups the rest into them.
    fn reduce(&mut self, gram: &DMatrix<f64>) -> Result<()> {
        let excited = self.excited(gram);
        if excited.is_empty() {
            bail!("no regressor column of the model moves with its joints");
        }
        let base = pivoted(gram, &excited);
        let gb = DMatrix::from_fn(base.len(), base.len(), |r, c| gram[(base[r], base[c])]);
        let chol = nalgebra::Cholesky::new(gb)
            .context("the base parameters' Gram matrix is not positive definite")?;
        let mut regrouped = vec![Vec::new(); base.len()];
        for &d in excited.iter().filter(|d| !base.contains(d)) {
            let beta = chol.solve(&DVector::from_fn(base.len(), |r, _| gram[(base[r], d)]));
            for (k, &b) in beta.iter().enumerate() {
                if b.abs() > 1e-6 {
                    regrouped[k].push((self.names[d].clone(), b));
                }
            }
        }
        self.names = base.iter().map(|&i| self.names[i].clone()).collect();
        self.columns = base.iter().map(|&i| self.columns[i]).collect();
        self.dry = base.iter().map(|&i| self.dry[i]).collect();
        self.regrouped = regrouped;
        Ok(())
    }

    /// The columns above rounding: a column whose RMS is below
    /// [`ROUNDING`] of the largest of its link's or joint's (same number)
    /// is zero but for rounding (a first moment along the only axis that
    /// moves the link), and scaled up it would be noise taken for data.
    fn excited(&self, gram: &DMatrix<f64>) -> Vec<usize> {
        let number = |i: usize| split_name(&self.names[i]).map_or(0, |(_, n)| n);
        (0..gram.nrows())
            .filter(|&i| {
                let largest = (0..gram.nrows())
                    .filter(|&k| number(k) == number(i))
                    .map(|k| gram[(k, k)])
                    .fold(0.0, f64::max);
                gram[(i, i)] > 0.0 && gram[(i, i)] > ROUNDING * ROUNDING * largest
            })
            .collect()
    }

    /// Number of base parameters.
    pub fn rank(&self) -> usize {
        self.names.len()
    }

    /// The base columns at every sample, stacked (samples x dof rows).
    fn stacked(&self, model: &dyn Dynamics, s: &Samples) -> Result<DMatrix<f64>> {
        let dof = model.dof();
        let mut a = DMatrix::zeros(s.q.len() * dof, self.columns.len());
        for i in 0..s.q.len() {
            let y = model.regressor(&s.q[i], &s.qd[i], &s.qdd[i])?;
            for (k, &c) in self.columns.iter().enumerate() {
                for j in 0..dof {
                    a[(i * dof + j, k)] = y[(j, c)];
                }
                // Dry friction as the diagnosis fits it: zero at rest.
                if let Some((joint, asymmetric)) = self.dry[k] {
                    let v = s.qd[i].get(joint).copied().unwrap_or(0.0);
                    let sign = if v.abs() > self.rest[joint] {
                        v.signum()
                    } else {
                        0.0
                    };
                    a[(i * dof + joint, k)] = if asymmetric { sign.abs() } else { sign };
                }
            }
        }
        Ok(a)
    }

    fn gram(&self, model: &dyn Dynamics, s: &Samples) -> Result<DMatrix<f64>> {
        let a = self.stacked(model, s)?;
        Ok(a.transpose() * &a)
    }

    /// The information matrix of the base parameters over the samples, each
    /// sample counted `weight` times (unit torque noise).
    pub fn information(
        &self,
        model: &dyn Dynamics,
        s: &Samples,
        weight: f64,
    ) -> Result<DMatrix<f64>> {
        Ok(self.gram(model, s)? * weight)
    }
}

/// Greedy pivoted Cholesky of `gram` over the candidate columns, scaled to a
/// unit diagonal: the columns in the order kept, each the one with most left
/// once the kept ones are projected out (ties to the earlier column), while
/// that share exceeds [`STRUCTURAL`].
fn pivoted(gram: &DMatrix<f64>, candidates: &[usize]) -> Vec<usize> {
    let n = candidates.len();
    let d: Vec<f64> = candidates.iter().map(|&i| gram[(i, i)].sqrt()).collect();
    let g = DMatrix::from_fn(n, n, |r, c| {
        gram[(candidates[r], candidates[c])] / (d[r] * d[c])
    });
    let mut left: Vec<f64> = (0..n).map(|i| g[(i, i)]).collect();
    let mut factors: Vec<DVector<f64>> = Vec::new();
    let mut kept = Vec::new();
    loop {
        let free = (0..n).filter(|i| !kept.contains(i));
        let Some(k) = free.fold(None, |best: Option<usize>, i| match best {
            // Ties (up to rounding) go to the earlier column: `izz1` stays
            // and `armature1` is regrouped into it, not the other way.
            Some(b) if left[b] * (1.0 + 1e-9) >= left[i] => Some(b),
            _ => Some(i),
        }) else {
            break;
        };
        if left[k] <= STRUCTURAL {
            break;
        }
        let pivot = left[k].sqrt();
        let mut column = DVector::from_fn(n, |r, _| g[(r, k)]);
        for f in &factors {
            column -= f * f[k];
        }
        column /= pivot;
        for (i, l) in left.iter_mut().enumerate() {
            *l -= column[i] * column[i];
        }
        factors.push(column);
        kept.push(k);
    }
    kept.iter().map(|&k| candidates[k]).collect()
}

/// Random states inside the bounds; a quarter of each joint's velocities
/// are zero (a joint at rest), so an offset and direction-dependent friction
/// are told apart.
fn random_states(dof: usize, bounds: &Bounds, parameters: usize, seed: u64) -> Samples {
    let count = (4 * parameters / dof.max(1)).max(400);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut s = Samples {
        q: Vec::new(),
        qd: Vec::new(),
        qdd: Vec::new(),
    };
    for _ in 0..count {
        let mut draw = |f: &dyn Fn(usize) -> (f64, f64), rest: bool| -> Vec<f64> {
            (0..dof)
                .map(|j| {
                    let (lo, hi) = f(j);
                    if rest && rng.random_bool(0.25) {
                        0.0
                    } else {
                        rng.random_range(lo..=hi)
                    }
                })
                .collect()
        };
        s.q.push(draw(&|j| bounds.position[j], false));
        s.qd.push(draw(&|j| (-bounds.velocity[j], bounds.velocity[j]), true));
        s.qdd.push(draw(
            &|j| (-bounds.acceleration[j], bounds.acceleration[j]),
            false,
        ));
    }
    s
}

/// `f` scaled to a unit diagonal (a zero diagonal entry stays zero).
pub fn unit_diagonal(f: &DMatrix<f64>) -> DMatrix<f64> {
    let d: Vec<f64> = (0..f.nrows())
        .map(|i| {
            if f[(i, i)] > 0.0 {
                1.0 / f[(i, i)].sqrt()
            } else {
                0.0
            }
        })
        .collect();
    DMatrix::from_fn(f.nrows(), f.ncols(), |r, c| f[(r, c)] * d[r] * d[c])
}

/// Condition number of the information matrix `f` scaled to a unit
/// diagonal (infinite when singular or not decomposable).
pub fn condition_number(f: &DMatrix<f64>) -> f64 {
    match crate::kernels::symmetric_eigenvalues(unit_diagonal(f)) {
        Some(e) if e.min() > 0.0 => e.max() / e.min(),
        _ => f64::INFINITY,
    }
}

/// Condition number of the information matrix `f` (per sample) with each
/// parameter scaled by the size a rich motion gives its column
/// (`typical`): it counts how much a motion excites each parameter, not
/// only how well it tells them apart.
pub fn condition_number_fixed(f: &DMatrix<f64>, typical: &[f64]) -> f64 {
    let scaled = DMatrix::from_fn(f.nrows(), f.ncols(), |r, c| {
        f[(r, c)] / (typical[r] * typical[c])
    });
    match crate::kernels::symmetric_eigenvalues(scaled) {
        Some(e) if e.min() > 0.0 => e.max() / e.min(),
        _ => f64::INFINITY,
    }
}

/// The diagonal of `f`'s inverse, or `None` when `f` is singular.
pub fn inverse_diagonal(f: &DMatrix<f64>) -> Option<Vec<f64>> {
    let eigen = crate::kernels::symmetric_eigen(f.clone())?;
    if eigen.eigenvalues.min() <= 0.0 {
        return None;
    }
    let v = &eigen.eigenvectors;
    Some(
        (0..f.nrows())
            .map(|i| {
                (0..f.nrows())
                    .map(|k| v[(i, k)] * v[(i, k)] / eigen.eigenvalues[k])
                    .sum()
            })
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bounds(dof: usize) -> Bounds {
        Bounds {
            position: vec![(-2.0, 2.0); dof],
            velocity: vec![1.0; dof],
            acceleration: vec![2.0; dof],
            effort: vec![None; dof],
        }
    }

    #[test]
    fn names_split_into_kind_and_number() {
        assert_eq!(split_name("ixx3"), Some(("ixx", 3)));
        assert_eq!(
            split_name("coulomb_asymmetry12"),
            Some(("coulomb_asymmetry", 12))
        );
        assert_eq!(split_name("m"), None);
    }

    #[test]
    fn the_first_joint_s_armature_and_inertia_combine() {
        // Joint 1 turns about the vertical: its armature and link 1's izz
        // act only in sum, so there are fewer combinations than columns.
        let model = crate::model("kinova_gen3_lite_3dof").unwrap();
        let p = Parameters::new(model, &bounds(3), &[1.0; 3], 1).unwrap();
        assert!(p.rank() < 3 * 15, "{}", p.rank());
        assert!(!p.names.iter().any(|n| n == "armature1"));
        let k = p.names.iter().position(|n| n == "izz1").unwrap();
        assert!(
            p.regrouped[k]
                .iter()
                .any(|(n, b)| n == "armature1" && (b - 1.0).abs() < 1e-9)
        );
        assert!(p.names.iter().any(|n| n == "offset2"));
    }

    #[test]
    fn a_motion_without_rests_cannot_tell_an_offset_from_asymmetric_friction() {
        let model = crate::model("planar_2link").unwrap();
        let p = Parameters::new(model, &bounds(2), &[1.0; 2], 3).unwrap();
        let moving = Samples {
            q: (0..300)
                .map(|i| vec![(i as f64 * 0.1).sin(), (i as f64 * 0.07).cos()])
                .collect(),
            qd: (0..300)
                .map(|i| {
                    vec![
                        0.5 + 0.3 * (i as f64 * 0.3).sin(),
                        -0.4 + 0.2 * (i as f64 * 0.2).cos(),
                    ]
                })
                .collect(),
            qdd: (0..300)
                .map(|i| vec![(i as f64 * 0.13).cos(), (i as f64 * 0.17).sin()])
                .collect(),
        };
        let f = p.information(model, &moving, 1.0).unwrap();
        assert!(condition_number(&f) > 1e12);
    }
}
