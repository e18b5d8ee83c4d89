//! A small seeded evolution strategy, block by block: the best of some
//! random starts, then rounds over the blocks (a joint's coefficients),
//! each block improved alone by (1+lambda) generations of Gaussian steps
//! whose size grows after a success and shrinks after a failure
//! (Rechenberg's success rule in its simplest form), with a step of its own.
//!
//! Why blocks: the joints' coefficients act on the criterion at very
//! different scales (a joint's step size settles 100 times larger than
//! another's), and one step for all of them left the search crawling; a
//! joint searched alone also needs 7 times fewer draws on a 7-joint arm to
//! find a better point. Why two criteria: the condition number is flat
//! wherever its smallest eigenvalues are equal, which is where the search
//! ends up, so most rounds minimize a smooth stand-in
//! ([`Criteria::smooth`]) and the last ones the criterion itself.
//! Gradient-free, so the limits, the torque check and the criterion are
//! evaluated as they are; deterministic for a seed, whatever the threads
//! do, because every step is drawn before the offspring are evaluated
//! (two at a time, on this 2-core machine's cores).

use std::ops::Range;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// How long the search runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Budget {
    /// Random starting points; the best `searches` are improved, each by a
    /// search of its own, and the best outcome is kept.
    pub starts: usize,
    pub searches: usize,
    /// Rounds over the blocks on the smooth criterion, then on the exact one.
    pub rounds: usize,
    pub exact_rounds: usize,
    /// Generations per block and round.
    pub generations: usize,
    /// Offspring per generation.
    pub offspring: usize,
}

/// What the search minimizes: a smooth stand-in, then the criterion.
pub struct Criteria<'a> {
    pub smooth: &'a (dyn Fn(&[f64]) -> f64 + Sync),
    pub exact: &'a (dyn Fn(&[f64]) -> f64 + Sync),
}

/// The outcome: the best point, its exact cost and how many points were
/// evaluated.
#[derive(Debug, Clone, PartialEq)]
pub struct Found {
    pub x: Vec<f64>,
    pub cost: f64,
    pub evaluations: usize,
}

const FIRST_STEP: f64 = 0.5;
const GROW: f64 = 1.3;
/// With few generations per visit of a block, the step must settle within
/// a visit: 0.9 per failure against 1.3 per success balances at about one
/// success in four generations.
const SHRINK: f64 = 0.9;
const SMALLEST_STEP: f64 = 1e-3;
const LARGEST_STEP: f64 = 2.0;

/// The search's state: the best point so far and its random draws.
struct Search<'a> {
    cost: &'a (dyn Fn(&[f64]) -> f64 + Sync),
    rng: ChaCha8Rng,
    best: Vec<f64>,
    best_cost: f64,
    evaluations: usize,
    offspring: usize,
}

impl Search<'_> {
    /// One generation on the coordinates `block`: `offspring` Gaussian
    /// steps of size `step`, all drawn before any is evaluated; the best
    /// replaces the parent if it is better. Returns whether it did.
    fn generation(&mut self, block: Range<usize>, step: f64) -> bool {
        let children: Vec<Vec<f64>> = (0..self.offspring)
            .map(|_| {
                let mut child = self.best.clone();
                for x in &mut child[block.clone()] {
                    *x += step * gaussian(&mut self.rng);
                }
                child
            })
            .collect();
        let costs = evaluate(self.cost, &children);
        self.evaluations += children.len();
        let k = argmin(&costs);
        if costs[k] < self.best_cost {
            self.best_cost = costs[k];
            self.best = children[k].clone();
            true
        } else {
            false
        }
    }

    /// `rounds` rounds over `blocks`, each block `generations` long from
    /// its step in `steps`, which it leaves where it settled.
    fn rounds(
        &mut self,
        blocks: &[Range<usize>],
        steps: &mut [f64],
        rounds: usize,
        generations: usize,
    ) {
        for _ in 0..rounds {
            for (block, step) in blocks.iter().zip(steps.iter_mut()) {
                for _ in 0..generations {
                    *step = if self.generation(block.clone(), *step) {
                        (*step * GROW).min(LARGEST_STEP)
                    } else {
                        (*step * SHRINK).max(SMALLEST_STEP)
                    };
                }
            }
        }
    }
}

/// Minimizes over R^dim from `seed`; the coordinates fall into `blocks`
/// consecutive blocks of equal size.
pub fn minimize(
    criteria: Criteria<'_>,
    dim: usize,
    blocks: usize,
    seed: u64,
    budget: Budget,
) -> Found {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let starts: Vec<Vec<f64>> = (0..budget.starts.max(1))
        .map(|_| (0..dim).map(|_| gaussian(&mut rng)).collect())
        .collect();
    let costs = evaluate(criteria.smooth, &starts);
    let size = dim.div_ceil(blocks.max(1)).max(1);
    let ranges: Vec<Range<usize>> = (0..dim)
        .step_by(size)
        .map(|start| start..(start + size).min(dim))
        .collect();
    // Each search draws from a generator of its own, seeded in order: the
    // outcome does not depend on how the searches are run.
    let seeds: Vec<u64> = (0..budget.searches.max(1)).map(|_| rng.random()).collect();
    let mut evaluations = starts.len();
    let mut best: Option<(Search, Vec<f64>)> = None;
    for (&i, &seed) in best_first(&costs).iter().zip(&seeds) {
        let mut search = Search {
            cost: criteria.smooth,
            rng: ChaCha8Rng::seed_from_u64(seed),
            best: starts[i].clone(),
            best_cost: costs[i],
            evaluations: 0,
            offspring: budget.offspring.max(1),
        };
        let mut steps = vec![FIRST_STEP; ranges.len()];
        search.rounds(&ranges, &mut steps, budget.rounds, budget.generations);
        // The searches are compared by the criterion itself.
        search.cost = criteria.exact;
        search.best_cost = (criteria.exact)(&search.best);
        evaluations += search.evaluations + 1;
        if best
            .as_ref()
            .is_none_or(|(b, _)| key(search.best_cost) < key(b.best_cost))
        {
            best = Some((search, steps));
        }
    }
    let Some((mut search, mut steps)) = best else {
        unreachable!("at least one search runs")
    };
    search.evaluations = evaluations;
    search.rounds(&ranges, &mut steps, budget.exact_rounds, budget.generations);
    Found {
        x: search.best,
        cost: search.best_cost,
        evaluations: search.evaluations,
    }
}

/// A standard normal draw (Box-Muller; the crate carries no `rand_distr`).
fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    let u: f64 = 1.0 - rng.random::<f64>();
    let v: f64 = rng.random();
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// A cost as compared: NaN counts as the largest.
fn key(v: f64) -> f64 {
    if v.is_nan() { f64::INFINITY } else { v }
}

/// Index of the smallest value.
fn argmin(values: &[f64]) -> usize {
    (0..values.len()).fold(0, |best, k| {
        if key(values[k]) < key(values[best]) {
            k
        } else {
            best
        }
    })
}

/// Indices of `values` from the smallest (ties in order).
fn best_first(values: &[f64]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..values.len()).collect();
    order.sort_by(|&a, &b| key(values[a]).total_cmp(&key(values[b])));
    order
}

/// The costs of `points`, in order, on the machine's cores.
fn evaluate(cost: &(dyn Fn(&[f64]) -> f64 + Sync), points: &[Vec<f64>]) -> Vec<f64> {
    crate::parallel::map_in_order(points, |x| cost(x))
}

#[cfg(test)]
mod tests {
    use super::*;

    const BUDGET: Budget = Budget {
        starts: 8,
        searches: 2,
        rounds: 20,
        exact_rounds: 5,
        generations: 10,
        offspring: 4,
    };

    fn both<'a>(f: &'a (dyn Fn(&[f64]) -> f64 + Sync)) -> Criteria<'a> {
        Criteria {
            smooth: f,
            exact: f,
        }
    }

    #[test]
    fn it_finds_the_minimum_of_a_shifted_bowl() {
        let bowl = |x: &[f64]| {
            x.iter()
                .enumerate()
                .map(|(i, v)| (v - i as f64 * 0.1).powi(2))
                .sum()
        };
        let found = minimize(both(&bowl), 6, 2, 7, BUDGET);
        assert!(found.cost < 1e-3, "{}", found.cost);
        assert_eq!(
            found.evaluations,
            8 + 2 * (1 + 20 * 2 * 10 * 4) + 5 * 2 * 10 * 4
        );
    }

    #[test]
    fn blocks_with_different_scales_each_find_their_step() {
        // The second block's coordinates act 100 times more strongly; each
        // block's step settles at its own scale.
        let skewed = |x: &[f64]| {
            x.iter()
                .enumerate()
                .map(|(i, v)| {
                    if i < 3 {
                        (v - 1.0).powi(2)
                    } else {
                        100.0 * (v - 0.1).powi(2)
                    }
                })
                .sum()
        };
        let found = minimize(both(&skewed), 6, 2, 5, BUDGET);
        assert!(found.cost < 1e-3, "{}", found.cost);
    }

    #[test]
    fn the_exact_criterion_decides_the_outcome() {
        let smooth = |x: &[f64]| x.iter().map(|v| v * v).sum::<f64>();
        let exact = |x: &[f64]| x.iter().map(|v| v.abs()).fold(0.0, f64::max);
        let found = minimize(
            Criteria {
                smooth: &smooth,
                exact: &exact,
            },
            4,
            2,
            3,
            BUDGET,
        );
        assert_eq!(found.cost, exact(&found.x));
    }

    #[test]
    fn the_same_seed_gives_the_same_point() {
        let f = |x: &[f64]| x.iter().map(|v| v.abs()).sum::<f64>() + (x[0] * 3.0).sin();
        assert_eq!(
            minimize(both(&f), 4, 2, 11, BUDGET),
            minimize(both(&f), 4, 2, 11, BUDGET)
        );
    }

    #[test]
    fn infinite_and_nan_costs_are_never_chosen_over_finite_ones() {
        let f = |x: &[f64]| if x[0] > 0.0 { f64::NAN } else { x[0] * x[0] };
        let found = minimize(both(&f), 2, 1, 3, BUDGET);
        assert!(found.cost.is_finite());
    }
}
