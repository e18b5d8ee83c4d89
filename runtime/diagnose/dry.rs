//! The Coulomb friction column near rest.
//!
//! A joint slower than its at-rest speed holds static friction: anywhere
//! between the levels, set by whatever else acts on it. Fitting it as zero
//! there (the moving sign alone) biased the fitted levels high (median +5%
//! in the coverage study, the viscous coefficients low to match): the
//! parallel filter spreads each stretch at rest into the neighbouring
//! moving samples, and static friction stays near the level the joint
//! stopped with until it breaks away at the level of its next motion, so
//! the zero the column claims is wrong in a way correlated with the column
//! itself. Filling the stretch with a ramp from the sign before to the sign
//! after biased them low instead (-6% where zero gave +3%: a joint that
//! holds a waypoint relaxes its friction below the level). So the column
//! at rest is the ramp times a share the data choose ([`rest_share`]), not
//! a guess (docs/diagnosis.md, "The Coulomb column at rest").

use nalgebra::{DMatrix, DVector};

use super::search::Nuisance;

/// [`rest_ramp`] of each joint's velocity (a column of `qd`, samples x
/// joints) with its at-rest speed.
pub(super) fn rest_ramps(qd: &DMatrix<f64>, rest: &[f64]) -> Vec<Vec<f64>> {
    qd.column_iter()
        .zip(rest)
        .map(|(v, &r)| rest_ramp(&v.iter().copied().collect::<Vec<f64>>(), r))
        .collect()
}

/// Zero where the joint moves (faster than `rest`); across each stretch at
/// rest a linear ramp in time from the sign of the motion before it to the
/// sign of the motion after it (zero beyond a recording's ends, where the
/// motion is unknown).
pub(super) fn rest_ramp(qd: &[f64], rest: f64) -> Vec<f64> {
    let sign = |v: f64| if v.abs() > rest { v.signum() } else { 0.0 };
    let mut ramp = vec![0.0; qd.len()];
    let mut start = 0;
    while start < qd.len() {
        if sign(qd[start]) != 0.0 {
            start += 1;
            continue;
        }
        let end = (start..qd.len())
            .find(|&k| sign(qd[k]) != 0.0)
            .unwrap_or(qd.len());
        let before = start.checked_sub(1).map_or(0.0, |k| sign(qd[k]));
        let after = qd.get(end).map_or(0.0, |&v| sign(v));
        let span = (end - start + 1) as f64;
        for (k, r) in ramp[start..end].iter_mut().enumerate() {
            *r = before + (after - before) * (k + 1) as f64 / span;
        }
        start = end;
    }
    ramp
}

/// The share of the ramp that static friction follows on one joint: the
/// ramp's coefficient over the moving sign's when both are fitted with the
/// joint's other columns (`nuisance`), within 0 (friction gone the moment
/// the joint stops) and 1 (carried over the whole stretch); 0 when the
/// joint shows no dry friction to share.
pub(super) fn rest_share(nuisance: &Nuisance, sign: &DVector<f64>, ramp: &DVector<f64>) -> f64 {
    match nuisance.coefficients(&[sign.clone(), ramp.clone()]) {
        Some(c) if c[0] > 0.0 => (c[1] / c[0]).clamp(0.0, 1.0),
        _ => 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::rest_ramp;

    #[test]
    fn a_stretch_at_rest_ramps_from_the_sign_before_to_the_sign_after() {
        let qd = [-0.5, -0.01, 0.0, 0.01, 0.5, 0.005, 0.4];
        let ramp = rest_ramp(&qd, 0.02);
        let expected = [0.0, -0.5, 0.0, 0.5, 0.0, 1.0, 0.0];
        for (r, e) in ramp.iter().zip(expected) {
            assert!((r - e).abs() < 1e-12, "{ramp:?}");
        }
    }

    #[test]
    fn the_ends_of_a_recording_ramp_from_and_to_zero() {
        let ramp = rest_ramp(&[0.0, 0.0, 0.0, 1.0, 0.0], 0.02);
        let expected = [0.25, 0.5, 0.75, 0.0, 0.5];
        for (r, e) in ramp.iter().zip(expected) {
            assert!((r - e).abs() < 1e-12, "{ramp:?}");
        }
    }
}
