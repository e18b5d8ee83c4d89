//! Independent work on the machine's cores, results in input order: what
//! each item gives does not depend on which thread ran it, so the output
//! is identical to a one-thread run.

/// The machine's cores as the standard library counts them (at least 1).
pub fn workers() -> usize {
    std::thread::available_parallelism().map_or(1, |p| p.get())
}

/// `f` of every item, in order, on the work-stealing pool (rayon): a call
/// from inside another item's `f` shares the same threads, so nested maps
/// (candidates, then their cross-validation folds) keep every core busy
/// whatever their costs.
pub fn map_in_order<T: Sync, R: Send>(items: &[T], f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    use rayon::prelude::*;
    items.par_iter().map(&f).collect()
}

/// [`map_in_order`] on at most `workers` threads.
pub fn map_in_order_on<T: Sync, R: Send>(
    items: &[T],
    f: impl Fn(&T) -> R + Sync,
    workers: usize,
) -> Vec<R> {
    let workers = workers.min(items.len());
    if workers <= 1 {
        return items.iter().map(f).collect();
    }
    let chunk = items.len().div_ceil(workers);
    let f = &f;
    std::thread::scope(|scope| {
        let handles: Vec<_> = items
            .chunks(chunk)
            .map(|part| scope.spawn(move || part.iter().map(f).collect::<Vec<R>>()))
            .collect();
        handles
            .into_iter()
            // A worker's panic is the caller's: pass it on.
            .flat_map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect()
    })
}

/// `f` on contiguous parts of `items`, one part per thread (up to
/// `available_parallelism`), for work that changes each item on its own:
/// the result does not depend on how the items are split.
pub fn for_parts_mut<T: Send>(items: &mut [T], f: impl Fn(&mut [T]) + Sync) {
    let workers = workers().min(items.len());
    if workers <= 1 {
        return f(items);
    }
    let chunk = items.len().div_ceil(workers);
    let f = &f;
    // A worker's panic is passed on when the scope ends.
    std::thread::scope(|scope| {
        for part in items.chunks_mut(chunk) {
            scope.spawn(move || f(part));
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn results_come_back_in_input_order() {
        let items: Vec<u64> = (0..1001).collect();
        let squares = map_in_order(&items, |x| x * x);
        assert_eq!(squares, items.iter().map(|x| x * x).collect::<Vec<_>>());
        assert!(map_in_order(&[] as &[u64], |x| *x).is_empty());
    }

    /// Maps inside maps (candidates, then their folds) share the pool and
    /// give what one thread gives, sums in the same order included.
    #[test]
    fn nested_maps_give_the_one_thread_results() {
        let inner = |x: &f64| -> Vec<f64> {
            let folds: Vec<f64> = (0..7).map(|k| x + f64::from(k) * 0.1).collect();
            map_in_order(&folds, |y| (y * 1.3).sin() / (1.0 + y))
        };
        let items: Vec<f64> = (0..40).map(|i| f64::from(i) * 0.37).collect();
        let nested: Vec<f64> = map_in_order(&items, |x| inner(x).iter().sum());
        let serial: Vec<f64> = items
            .iter()
            .map(|x| {
                let folds: Vec<f64> = (0..7).map(|k| x + f64::from(k) * 0.1).collect();
                folds.iter().map(|y| (y * 1.3).sin() / (1.0 + y)).sum()
            })
            .collect();
        assert_eq!(nested, serial);
    }

    #[test]
    fn every_part_is_changed_once() {
        let mut items: Vec<u64> = (0..101).collect();
        for_parts_mut(&mut items, |part| part.iter_mut().for_each(|x| *x *= 3));
        assert_eq!(items, (0..101).map(|x| 3 * x).collect::<Vec<u64>>());
    }

    #[test]
    fn the_thread_count_does_not_change_the_results() {
        let f = |x: &f64| x.sin() * 0.5 * x;
        let items: Vec<f64> = (0..9).map(f64::from).collect();
        let one = map_in_order_on(&items, f, 1);
        assert_eq!(one, map_in_order_on(&items, f, 2));
        assert_eq!(one, map_in_order_on(&items, f, 4));
    }
}
