//! A torque offset and direction-dependent dry friction on a joint with dry
//! friction: the same torque while the joint moves, told apart only by the
//! samples at rest.

use super::admit::levels_hold;
use super::candidate::{Candidate, Shape, columns_of, label};
use super::fit::fit;
use super::kind::Kind;
use super::moments::Moments;
use super::select::admissible;
use super::stacked::Stacked;

/// A torque offset and direction-dependent dry friction are the same torque
/// while the joint moves; only samples at rest tell them apart, and there
/// the friction is static or follows the plant's own law near zero speed,
/// which no column here knows. Where one is named on a joint with dry
/// friction and the other is not, the other is listed as ambiguous with it
/// (named candidate, other candidate) and a note says how many samples
/// could tell.
pub(super) fn offset_or_asymmetry(
    data: &Stacked,
    candidates: &[Candidate],
    selected: &[usize],
    notes: &mut Vec<String>,
) -> Vec<(usize, usize)> {
    let find = |kind: Kind, j: usize| {
        candidates
            .iter()
            .position(|c| c.kind == kind && c.joint == Some(j))
    };
    let named = |kind: Kind, j: usize| {
        selected
            .iter()
            .any(|&c| candidates[c].kind == kind && candidates[c].joint == Some(j))
    };
    let mut pairs = Vec::new();
    for j in 0..data.dof {
        let (offset, asymmetry) = (
            named(Kind::TorqueOffset, j),
            named(Kind::CoulombAsymmetry, j),
        );
        let (Some(o), Some(a)) = (find(Kind::TorqueOffset, j), find(Kind::CoulombAsymmetry, j))
        else {
            continue;
        };
        let dry = &candidates[a];
        let modelled =
            matches!(dry.shape, Shape::Asymmetry { modelled_coulomb } if modelled_coulomb > 0.0);
        if offset == asymmetry || !(modelled || named(Kind::CoulombFriction, j)) {
            continue;
        }
        // The asymmetry's column is 1 while moving, 0 at rest (filtered).
        let rows = data.rows_of(j);
        let count = rows.clone().count().max(1) as f64;
        let resting = rows.filter(|&r| dry.columns[0][r] < 0.5).count() as f64 / count;
        pairs.push(if offset { (o, a) } else { (a, o) });
        let (this, other) = if offset {
            (
                "a torque offset",
                "direction-dependent dry friction (coulomb_asymmetry)",
            )
        } else {
            ("direction-dependent dry friction", "a torque offset")
        };
        notes.push(format!(
            "joint {}: {this} and {other} are the same torque while the joint moves; only the \
             {:.0}% of samples at rest tell them apart, so {other} fits these data {}: record \
             motions that rest to tell",
            j + 1,
            100.0 * resting,
            if resting < 0.2 {
                "almost as well"
            } else {
                "less well here, but how friction behaves near zero speed decides that"
            }
        ));
    }
    pairs
}

/// Where a torque offset or direction-dependent dry friction is named on a
/// joint with dry friction and the other is not, what the samples at rest
/// say decides between them: there the offset still acts and the friction
/// does not. The residual left at rest, with the named one's own share put
/// back, is the offset's value if the torque is an offset and zero if it is
/// friction; the named one is swapped for the other when the rest residual
/// is nearer the other's prediction by more than two standard errors
/// (from the spread of the segments' means), and the other is admissible.
pub(super) fn settle_by_rest(
    data: &Stacked,
    m: &Moments,
    candidates: &[Candidate],
    selected: &mut [usize],
    notes: &mut Vec<String>,
) {
    for j in 0..data.dof {
        let find = |kind: Kind| {
            candidates
                .iter()
                .position(|c| c.kind == kind && c.joint == Some(j))
        };
        let (Some(offset), Some(asymmetry)) =
            (find(Kind::TorqueOffset), find(Kind::CoulombAsymmetry))
        else {
            continue;
        };
        let named = |c: usize| selected.iter().position(|&s| s == c);
        let (position, other) = match (named(offset), named(asymmetry)) {
            (Some(p), None) => (p, asymmetry),
            (None, Some(p)) => (p, offset),
            _ => continue,
        };
        let Some((value, rest_mean, se)) =
            rest_evidence(data, m, candidates, selected, position, asymmetry)
        else {
            continue;
        };
        let offset_named = selected[position] == offset;
        // The share of the named value the rest residual shows: 1 for an
        // offset, 0 for friction.
        let share = rest_mean / value;
        let margin = 2.0 * se / value.abs();
        let swap = match offset_named {
            true => share + margin < 0.5,
            false => share - margin > 0.5,
        };
        let was = selected[position];
        let mut trial: Vec<usize> = selected.to_vec();
        trial.remove(position);
        if !swap || !admissible(candidates, other, &trial) {
            continue;
        }
        trial.push(other);
        let holds = fit(m, candidates, &trial, |_| true)
            .is_some_and(|f| levels_hold(candidates, &trial, f.theta.as_slice()).is_ok());
        if !holds {
            continue;
        }
        selected[position] = other;
        notes.push(format!(
            "joint {}: {} named in place of {}: at rest the residual is {:.0}% of the {:.4} N m \
             fitted while moving, which {}",
            j + 1,
            label(&candidates[other]),
            label(&candidates[was]),
            100.0 * share,
            value,
            if offset_named {
                "an offset would keep and friction does not"
            } else {
                "an offset keeps"
            }
        ));
    }
}

/// The fitted value of the effect at `position` of `selected` (a torque
/// offset or direction-dependent friction), and the mean residual over the
/// joint's samples at rest (where `asymmetry`'s column is below one half)
/// with that effect's own share put back, with its standard error from
/// the spread of the segments' means; `None` with fewer than three
/// segments that rest.
fn rest_evidence(
    data: &Stacked,
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
    position: usize,
    asymmetry: usize,
) -> Option<(f64, f64, f64)> {
    let fitted = fit(m, candidates, selected, |_| true)?;
    let columns = columns_of(candidates, selected);
    let all: Vec<&nalgebra::DVector<f64>> =
        candidates.iter().flat_map(|c| c.columns.iter()).collect();
    let member = columns_of(candidates, &[selected[position]])[0];
    let at = columns.iter().position(|&k| k == member)?;
    let value = fitted.coefficients[at];
    let j = candidates[asymmetry].joint?;
    let resting = &candidates[asymmetry].columns[0];
    let groups = data.group.iter().max().map_or(0, |g| g + 1);
    let (mut sum, mut count) = (vec![0.0; groups], vec![0usize; groups]);
    for r in data.rows_of(j).filter(|&r| resting[r] < 0.5) {
        let explained: f64 = columns
            .iter()
            .enumerate()
            .filter(|&(k, _)| k != at)
            .map(|(k, &c)| fitted.coefficients[k] * all[c][r])
            .sum();
        sum[data.group[r]] += data.residual[r] - explained;
        count[data.group[r]] += 1;
    }
    let means: Vec<f64> = (0..groups)
        .filter(|&g| count[g] > 0)
        .map(|g| sum[g] / count[g] as f64)
        .collect();
    if means.len() < 3 {
        return None;
    }
    let total: usize = count.iter().sum();
    let mean = sum.iter().sum::<f64>() / total as f64;
    let n = means.len() as f64;
    let spread = means.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    Some((value, mean, (spread / n).sqrt()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::candidate::linear as candidate;
    use crate::diagnose::rows::moving_sign;

    /// One joint with Coulomb friction 0.3 and 0.1 N m more whenever it
    /// moves (`at_rest` false) or always (`at_rest` true: an offset), plus
    /// noise; named: Coulomb friction and `named` (the offset or the
    /// direction-dependent friction). The kinds named after the rest check.
    fn settled(at_rest: bool, named: Kind) -> Vec<Kind> {
        let noise =
            |q: f64, qd: f64| 0.01 * ((q * 12.9898 + qd * 78.233).sin() * 43758.5453).fract();
        let rest = 0.1;
        let moving = |qd: f64| moving_sign(qd, rest);
        let (data, _, qd) = crate::diagnose::search::sweep(|q, qd| {
            let extra = if at_rest { 0.1 } else { 0.1 * moving(qd).abs() };
            0.3 * moving(qd) + extra + noise(q, qd)
        });
        let mut asymmetry = candidate(Kind::CoulombAsymmetry, qd.map(|v| moving(v).abs()));
        asymmetry.shape = Shape::Asymmetry {
            modelled_coulomb: 0.0,
        };
        let candidates = vec![
            candidate(Kind::CoulombFriction, qd.map(moving)),
            candidate(Kind::TorqueOffset, qd.map(|_| 1.0)),
            asymmetry,
        ];
        let m = Moments::new(&data, &candidates);
        let at = candidates.iter().position(|c| c.kind == named).unwrap();
        let mut selected = vec![0, at];
        settle_by_rest(&data, &m, &candidates, &mut selected, &mut Vec::new());
        selected.iter().map(|&c| candidates[c].kind).collect()
    }

    #[test]
    fn a_torque_that_vanishes_at_rest_is_friction() {
        let friction = vec![Kind::CoulombFriction, Kind::CoulombAsymmetry];
        assert_eq!(settled(false, Kind::TorqueOffset), friction);
        assert_eq!(settled(false, Kind::CoulombAsymmetry), friction);
    }

    #[test]
    fn a_torque_that_stays_at_rest_is_an_offset() {
        let offset = vec![Kind::CoulombFriction, Kind::TorqueOffset];
        assert_eq!(settled(true, Kind::CoulombAsymmetry), offset);
        assert_eq!(settled(true, Kind::TorqueOffset), offset);
    }
}
