//! The validation split: held-out rows, or whole groups (recordings) when
//! the dataset has them, so no trajectory is on both sides.

use std::collections::HashSet;

use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;

use super::Dataset;
use super::error::TrainError;

/// Splits row indices into (train, validation), by whole groups when the
/// dataset has them so no trajectory appears on both sides.
pub(crate) fn split_rows(
    data: &Dataset,
    fraction: f64,
    rng: &mut ChaCha8Rng,
) -> Result<(Vec<usize>, Vec<usize>), TrainError> {
    let n = data.len();
    if fraction <= 0.0 {
        return Ok(((0..n).collect(), Vec::new()));
    }
    let Some(groups) = &data.groups else {
        if n < 2 {
            return Err(TrainError::Split(format!(
                "need at least 2 samples, found {n}"
            )));
        }
        let mut idx: Vec<usize> = (0..n).collect();
        idx.shuffle(rng);
        let mut held = idx.split_off(n - held_out(fraction, n));
        idx.sort_unstable();
        held.sort_unstable();
        return Ok((idx, held));
    };
    let mut ids = groups.clone();
    ids.sort_unstable();
    ids.dedup();
    if ids.len() < 2 {
        return Err(TrainError::Split(format!(
            "splitting by groups needs at least 2 groups (recordings), found {}: pass at least 2 recordings",
            ids.len()
        )));
    }
    ids.shuffle(rng);
    let held: HashSet<usize> = ids[..held_out(fraction, ids.len())]
        .iter()
        .copied()
        .collect();
    Ok((0..n).partition(|&i| !held.contains(&groups[i])))
}

/// Number of held-out units: rounded share, keeping at least one on each side.
fn held_out(fraction: f64, count: usize) -> usize {
    ((fraction * count as f64).round() as usize).clamp(1, count - 1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mlp::algorithm::rng;
    use nalgebra::DMatrix;
    use proptest::prelude::*;

    fn data_with_groups(groups: Vec<usize>) -> Dataset {
        let n = groups.len();
        Dataset::new(
            DMatrix::from_fn(n, 2, |r, c| (r + c) as f64),
            DMatrix::from_fn(n, 1, |r, _| r as f64),
            Some(groups),
        )
        .unwrap()
    }

    #[test]
    fn group_split_needs_two_groups() {
        let err = split_rows(&data_with_groups(vec![4; 5]), 0.3, &mut rng(0, 0)).unwrap_err();
        assert!(
            err.to_string()
                .contains("at least 2 groups (recordings), found 1"),
            "{err}"
        );
    }

    proptest! {
        #[test]
        fn group_split_never_leaks(
            groups in prop::collection::vec(0usize..6, 2..60),
            fraction in 0.05f64..0.95,
            seed in any::<u64>(),
        ) {
            let distinct: HashSet<usize> = groups.iter().copied().collect();
            prop_assume!(distinct.len() >= 2);
            let data = data_with_groups(groups.clone());
            let (train, valid) = split_rows(&data, fraction, &mut rng(seed, 0)).unwrap();
            prop_assert_eq!(train.len() + valid.len(), groups.len());
            prop_assert!(!train.is_empty() && !valid.is_empty());
            let tg: HashSet<usize> = train.iter().map(|&i| groups[i]).collect();
            let vg: HashSet<usize> = valid.iter().map(|&i| groups[i]).collect();
            prop_assert!(tg.is_disjoint(&vg));
        }
    }
}
