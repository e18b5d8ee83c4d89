//! Honest unknowns: structure left in the residual after the named effects
//! that no candidate explains.
//!
//! Per joint, the residual left by the named effects is regressed on
//! generic own-joint features ([`GENERIC_FEATURES`]: velocity, its sign and
//! a Stribeck-like decay, acceleration, the model's gravity torque,
//! harmonics of the joint angle, a constant, the model torque's rate) with
//! leave-one-segment-out cross-validation. Noise is not predictable from
//! the state, so on a clean recording these features predict nothing held
//! out; when they predict at least [`UNEXPLAINED_GAIN`] of the residual's
//! power, the joint carries structure the candidates do not explain, and
//! the regimes whose features alone predict most say where it lives.

use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use super::digits::sig;
use super::solve::pseudo_solve;
use super::stacked::{GENERIC_FEATURES, Stacked};

/// Share of a joint's remaining residual power that generic features must
/// predict held out before the joint is reported as unexplained.
pub const UNEXPLAINED_GAIN: f64 = 0.2;

/// Residual RMS (N m) below which a joint's residual is taken as exact.
pub const QUIET: f64 = 1e-6;

/// The predictable part's RMS, as a share of the joint's measured torque
/// RMS, below which it is not reported: structure that small (a
/// half-sample logging convention on an exact model) is no missing effect.
pub const MEASURABLE: f64 = 0.005;

/// Structure left on one joint.
#[derive(Debug, Clone, Serialize)]
pub struct Unexplained {
    /// 1-based joint.
    pub joint: usize,
    /// Mean square of the residual left by the named effects, N m^2.
    pub residual_mse: f64,
    /// Share of it the generic features predict held out.
    pub predictable_share: f64,
    /// Share of its power below the motion's bandwidth (the rest lies
    /// between the bandwidth and the filter's cut-off); `None` when the
    /// bandwidth is unknown.
    pub slow_share: Option<f64>,
    /// Regimes whose features alone predict at least a tenth of it, best first.
    pub regimes: Vec<RegimeShare>,
    /// The sentence the text report prints.
    pub text: String,
}

/// One regime's held-out predictable share.
#[derive(Debug, Clone, Serialize)]
pub struct RegimeShare {
    pub regime: &'static str,
    pub share: f64,
}

/// Joints whose residual `after` (per stacked row) is still predictable.
/// `band`: the motion's bandwidth and the decimated sample rate (Hz), to
/// split what is left into what varies like the motion and what is faster.
pub(super) fn unexplained(
    data: &Stacked,
    after: &[f64],
    band: Option<(f64, f64)>,
    joint_kinds: &[String],
) -> Vec<Unexplained> {
    let all: Vec<usize> = (0..GENERIC_FEATURES.len()).collect();
    let mut regimes: Vec<&'static str> = GENERIC_FEATURES.iter().map(|f| f.0).collect();
    regimes.dedup();
    (0..data.dof)
        .filter_map(|j| {
            let total: f64 = data.rows_of(j).map(|r| after[r] * after[r]).sum();
            let count = data.rows_of(j).count();
            // Below a micro-newton-metre nothing is measurable structure.
            if count == 0 || total / (count as f64) < QUIET * QUIET {
                return None;
            }
            let share = |features: &[usize]| 1.0 - cv_sse(data, after, j, features) / total;
            let predictable = share(&all);
            let torque: f64 = data.rows_of(j).map(|r| data.measured[r].powi(2)).sum();
            if predictable < UNEXPLAINED_GAIN || predictable * total < (MEASURABLE * MEASURABLE) * torque {
                return None;
            }
            let mut by_regime: Vec<RegimeShare> = regimes
                .iter()
                .map(|&regime| {
                    let features: Vec<usize> = (0..GENERIC_FEATURES.len())
                        .filter(|&k| GENERIC_FEATURES[k].0 == regime)
                        .collect();
                    RegimeShare {
                        regime,
                        share: share(&features).max(0.0),
                    }
                })
                .filter(|r| r.share >= 0.1 * predictable)
                .collect();
            by_regime.sort_by(|a, b| b.share.total_cmp(&a.share));
            let mse = total / count as f64;
            let slow_share = band.and_then(|(bandwidth, rate)| slow_share(data, after, j, bandwidth, rate));
            let frequency = match (slow_share, band) {
                (Some(share), Some((bandwidth, _))) => format!(
                    "; {:.0}% of its power varies as slowly as the motion (below {} Hz), the rest faster",
                    100.0 * share,
                    sig(bandwidth)
                ),
                _ => String::new(),
            };
            let unit = match joint_kinds.get(j).map(String::as_str) {
                Some("prismatic") => "N",
                _ => "N m",
            };
            let text = format!(
                "joint {}: {:.0}% of the residual left ({} {unit} RMS) is predictable from the state held \
                 out, but no candidate effect explains it; it lives in: {}{frequency} — an effect the \
                 model and the candidates lack (see the README's list), or a wrong inertial parameter",
                j + 1,
                100.0 * predictable,
                sig(mse.sqrt()),
                if by_regime.is_empty() {
                    "no single regime (a combination)".to_string()
                } else {
                    by_regime
                        .iter()
                        .map(|r| format!("{} ({:.0}%)", r.regime, 100.0 * r.share))
                        .collect::<Vec<_>>()
                        .join(", ")
                }
            );
            Some(Unexplained {
                joint: j + 1,
                residual_mse: mse,
                predictable_share: predictable,
                slow_share,
                regimes: by_regime,
                text,
            })
        })
        .collect()
}

/// The share of joint `j`'s residual power that a zero-phase low-pass at
/// the motion's bandwidth keeps, segment by segment (each is contiguous).
fn slow_share(data: &Stacked, after: &[f64], j: usize, bandwidth: f64, rate: f64) -> Option<f64> {
    let filter = crate::preprocess::ZeroPhaseLowPass::new(bandwidth, 1.0 / rate).ok()?;
    let (mut slow, mut total) = (0.0, 0.0);
    let rows: Vec<usize> = data.rows_of(j).collect();
    for segment in rows.chunk_by(|&a, &b| data.group[a] == data.group[b]) {
        let x: Vec<f64> = segment.iter().map(|&r| after[r]).collect();
        slow += filter.apply(&x).iter().map(|v| v * v).sum::<f64>();
        total += x.iter().map(|v| v * v).sum::<f64>();
    }
    (total > 0.0).then(|| (slow / total).min(1.0))
}

/// Leave-one-segment-out SSE of `after` on joint `j` fitted by `features`.
fn cv_sse(data: &Stacked, after: &[f64], j: usize, features: &[usize]) -> f64 {
    let groups = data.group.iter().max().map_or(0, |g| g + 1);
    let k = features.len();
    let mut xx = vec![DMatrix::<f64>::zeros(k, k); groups];
    let mut xy = vec![DVector::<f64>::zeros(k); groups];
    let mut yy = vec![0.0; groups];
    for r in data.rows_of(j) {
        let g = data.group[r];
        let x = DVector::from_iterator(k, features.iter().map(|&f| data.generic[f][r]));
        xx[g].ger(1.0, &x, &x, 1.0);
        xy[g].axpy(after[r], &x, 1.0);
        yy[g] += after[r] * after[r];
    }
    let (sum_xx, sum_xy) = (
        xx.iter().fold(DMatrix::zeros(k, k), |a, b| a + b),
        xy.iter().fold(DVector::zeros(k), |a, b| a + b),
    );
    (0..groups)
        .map(|h| {
            let theta = pseudo_solve(&(&sum_xx - &xx[h]), &(&sum_xy - &xy[h]));
            (yy[h] - 2.0 * theta.dot(&xy[h]) + theta.dot(&(&xx[h] * &theta))).max(0.0)
        })
        .sum()
}
