//! A small seeded evolution strategy: the best of some random starts, then
//! (1+lambda) generations of Gaussian steps whose size grows after a
//! success and shrinks after a failure (Rechenberg's one-fifth rule in its
//! simplest form). Gradient-free, so the limits, the torque check and the
//! condition number can be evaluated as they are; deterministic for a seed,
//! whatever the threads do, because every step is drawn before the
//! offspring are evaluated (two at a time, on this 2-core machine's cores).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// How long the search runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Budget {
    /// Random starting points; the best is improved.
    pub starts: usize,
    /// Generations of the (1+lambda) strategy.
    pub generations: usize,
    /// Offspring per generation.
    pub offspring: usize,
}

/// The outcome: the best point, its cost and how many points were evaluated.
#[derive(Debug, Clone, PartialEq)]
pub struct Found {
    pub x: Vec<f64>,
    pub cost: f64,
    pub evaluations: usize,
}

const FIRST_STEP: f64 = 0.5;
const GROW: f64 = 1.3;
const SHRINK: f64 = 0.97;
const SMALLEST_STEP: f64 = 1e-3;
const LARGEST_STEP: f64 = 2.0;

/// Minimizes `cost` over R^dim from `seed`.
pub fn minimize(
    cost: &(dyn Fn(&[f64]) -> f64 + Sync),
    dim: usize,
    seed: u64,
    budget: Budget,
) -> Found {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut normal = |n: usize| -> Vec<f64> { (0..n).map(|_| gaussian(&mut rng)).collect() };
    let starts: Vec<Vec<f64>> = (0..budget.starts.max(1)).map(|_| normal(dim)).collect();
    let costs = evaluate(cost, &starts);
    let mut evaluations = starts.len();
    let first = argmin(&costs);
    let (mut best, mut best_cost) = (starts[first].clone(), costs[first]);
    let mut step = FIRST_STEP;
    for _ in 0..budget.generations {
        let children: Vec<Vec<f64>> = (0..budget.offspring.max(1))
            .map(|_| {
                best.iter()
                    .zip(normal(dim))
                    .map(|(x, z)| x + step * z)
                    .collect()
            })
            .collect();
        let costs = evaluate(cost, &children);
        evaluations += children.len();
        let k = argmin(&costs);
        if costs[k] < best_cost {
            best = children[k].clone();
            best_cost = costs[k];
            step = (step * GROW).min(LARGEST_STEP);
        } else {
            step = (step * SHRINK).max(SMALLEST_STEP);
        }
    }
    Found {
        x: best,
        cost: best_cost,
        evaluations,
    }
}

/// A standard normal draw (Box-Muller; the crate carries no `rand_distr`).
fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    let u: f64 = 1.0 - rng.random::<f64>();
    let v: f64 = rng.random();
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// Index of the smallest value (NaN counts as the largest).
fn argmin(values: &[f64]) -> usize {
    let key = |v: f64| if v.is_nan() { f64::INFINITY } else { v };
    (0..values.len()).fold(0, |best, k| {
        if key(values[k]) < key(values[best]) {
            k
        } else {
            best
        }
    })
}

/// The costs of `points`, in order, on up to two threads.
fn evaluate(cost: &(dyn Fn(&[f64]) -> f64 + Sync), points: &[Vec<f64>]) -> Vec<f64> {
    let workers = std::thread::available_parallelism()
        .map_or(1, |p| p.get())
        .clamp(1, 2);
    let chunk = points.len().div_ceil(workers).max(1);
    std::thread::scope(|scope| {
        let handles: Vec<_> = points
            .chunks(chunk)
            .map(|part| scope.spawn(move || part.iter().map(|x| cost(x)).collect::<Vec<f64>>()))
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap_or_else(|_| vec![f64::INFINITY; chunk]))
            .collect()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const BUDGET: Budget = Budget {
        starts: 8,
        generations: 300,
        offspring: 4,
    };

    #[test]
    fn it_finds_the_minimum_of_a_shifted_bowl() {
        let bowl = |x: &[f64]| {
            x.iter()
                .enumerate()
                .map(|(i, v)| (v - i as f64 * 0.1).powi(2))
                .sum()
        };
        let found = minimize(&bowl, 6, 7, BUDGET);
        assert!(found.cost < 1e-3, "{}", found.cost);
        assert_eq!(found.evaluations, 8 + 300 * 4);
    }

    #[test]
    fn the_same_seed_gives_the_same_point() {
        let f = |x: &[f64]| x.iter().map(|v| v.abs()).sum::<f64>() + (x[0] * 3.0).sin();
        assert_eq!(minimize(&f, 4, 11, BUDGET), minimize(&f, 4, 11, BUDGET));
    }

    #[test]
    fn infinite_and_nan_costs_are_never_chosen_over_finite_ones() {
        let f = |x: &[f64]| if x[0] > 0.0 { f64::NAN } else { x[0] * x[0] };
        let found = minimize(&f, 2, 3, BUDGET);
        assert!(found.cost.is_finite());
    }
}
