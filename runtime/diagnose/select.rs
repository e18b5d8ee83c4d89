//! Forward selection of effects by held-out MSE, with the identifiability
//! checks and [`super::admit`]'s significance and physical-sign checks, and
//! a backward prune.

use super::admit::{MASS_FACTOR, admits, levels_hold, physical};
use super::alternatives::{Alternative, NEAR, broadest, payload_over_link_error, runners_up};
use super::candidate::{Candidate, Shape, columns_of, label, width};
use super::companion::complete_friction;
use super::fit::{fit, identifiability};
use super::gain::{Gain, clearly_worse, relative_gain, worse_than_before};
use super::heldout::{Scoring, cv_mse};
use super::kind::Kind;
use super::moments::Moments;
use super::settings::{COLLINEAR, Settings};
use super::significance::{searched_threshold, significant};
use super::solve::pseudo_solve;
use crate::parallel::map_in_order;

/// Whether a body candidate's mass and COM are identifiable together
/// (through the second moments too, with the inertia about the COM held):
/// the fit's scaled information has no eigenvalue below [`COLLINEAR`], and
/// the mass it fits alone is a plausible one for the link (within
/// [`MASS_FACTOR`] of the model's), not the trace of another effect.
pub(super) fn body_identifiable(m: &Moments, candidates: &[Candidate], c: usize) -> bool {
    let Shape::Body { base_mass, .. } = candidates[c].shape else {
        return false;
    };
    fit(m, candidates, &[c], |_| true).is_some_and(|f| {
        identifiability(&f.information, 0..4) >= COLLINEAR
            && (base_mass / MASS_FACTOR..=base_mass * MASS_FACTOR).contains(&f.theta[0])
    })
}

/// Whether the data identify the mass of an `inertial_error` candidate's
/// link from its own regressor column, i.e. from the acceleration of the
/// link's origin (true for every other candidate). The mass is put in the
/// first moments' units by the arm's size `lever` (a mass change dm acts
/// like a first-moment change of dm * lever), which makes the link's 4x4
/// information matrix of (mass, first moment) dimensionally consistent; the
/// mass is identifiable when its information left once the first moments
/// are projected out (the Schur complement) is at least [`COLLINEAR`] times
/// that matrix's largest eigenvalue. A link whose origin lies on the axes of
/// all joints that move it has a zero mass column: its mass enters the
/// torques only through the parallel-axis terms of an assumed inertia about
/// the COM, which the data do not check.
pub(super) fn mass_identifiable(
    m: &Moments,
    candidates: &[Candidate],
    c: usize,
    lever: f64,
) -> bool {
    let candidate = &candidates[c];
    if candidate.kind != Kind::InertialError
        || !matches!(candidate.shape, Shape::Body { base_mass, .. } if base_mass > 0.0)
    {
        return true;
    }
    let columns: Vec<usize> = columns_of(candidates, &[c]).into_iter().take(4).collect();
    let (mut a, _) = m.normal_equations(&columns, |_| true);
    for k in 0..4 {
        a[(0, k)] /= lever;
        a[(k, 0)] /= lever;
    }
    let Some(eigenvalues) = crate::kernels::symmetric_eigenvalues(a.clone()) else {
        return false;
    };
    let largest = eigenvalues.max();
    if largest <= 0.0 {
        return false;
    }
    let h = a.view((1, 1), (3, 3)).into_owned();
    let coupling = a.view((1, 0), (3, 1)).column(0).into_owned();
    let schur = a[(0, 0)] - coupling.dot(&pseudo_solve(&h, &coupling));
    schur >= COLLINEAR * largest
}

/// Forward selection by cross-validated MSE with a significance check: each
/// step adds the candidate that lowers some joint's held-out MSE the most
/// (relative to that joint's current MSE, so a weak joint's effect is not
/// drowned by a strong joint's torque scale). Candidates whose parameters
/// these data cannot identify on their own (see the module docs) do not
/// compete; if one would still explain structure at the end, a note says so.
pub(super) fn select(
    m: &Moments,
    dof: usize,
    candidates: &[Candidate],
    settings: Settings,
    withdrawn: &[usize],
) -> Selection {
    let all: Vec<usize> = (0..candidates.len()).collect();
    let unidentifiable: Vec<usize> = map_in_order(&all, |&c| {
        fit(m, candidates, &[c], |_| true)
            .is_none_or(|f| identifiability(&f.information, 0..width(&candidates[c])) < COLLINEAR)
    })
    .into_iter()
    .zip(&all)
    .filter_map(|(refused, &c)| refused.then_some(c))
    .collect();
    let initial = cv_mse(m, dof, candidates, &[], Scoring::Fitted);
    let mut steps = Steps {
        selected: Vec::new(),
        // Withdrawn candidates compete no more (see `choose`).
        refused: withdrawn.to_vec(),
        notes: Vec::new(),
        alternatives: Vec::new(),
    };
    // What an effect the prune drops stood in for is left unexplained (a
    // spring's constant that held a torque offset): selection goes on once
    // from the pruned effects, the first one dropped refused (it failed
    // beside everything named; the others may have failed only once it was
    // gone) and the refusals judged beside it judged again.
    let context = (dof, settings, &unidentifiable[..], &initial[..]);
    for round in 0..2 {
        let dropped = forward_and_prune(m, candidates, context, &mut steps);
        if round == 1 || dropped.is_empty() {
            steps.refused.extend(dropped);
            break;
        }
        steps.refused = [withdrawn, &dropped[..1]].concat();
    }
    let current = cv_mse(m, dof, candidates, &steps.selected, Scoring::Fitted);
    for &c in &unidentifiable {
        let mut trial = steps.selected.clone();
        trial.push(c);
        let gain = relative_gain(
            &current,
            &cv_mse(m, dof, candidates, &trial, Scoring::Fitted),
            &current,
        );
        if gain.share >= settings.min_gain {
            steps.notes.push(format!(
                "{}: {}, but these data cannot identify \
                 its parameters (they act only through a combination of them, e.g. a base \
                 parameter: only the inertia about the first joint's axis matters for the first \
                 link); not named — record motions that excite it, or look for an effect with \
                 the same signature",
                label(&candidates[c]),
                gain.would_cut()
            ));
        }
    }
    // Refusals at a step were judged beside the bodies named then.
    swap_bodies(
        m,
        candidates,
        &mut steps.selected,
        (&unidentifiable, &initial),
        settings,
    );
    one_body(
        m,
        candidates,
        &mut steps.selected,
        (&unidentifiable, &initial),
        settings,
    );
    let dropped = prune(
        m,
        candidates,
        &mut steps.selected,
        &mut steps.notes,
        settings,
    );
    if !dropped.is_empty() {
        // A body swapped in beside another body that made it plausible
        // falls with it, and what the effect it replaced explained (a
        // payload's whole torque) is left unexplained: selection goes on
        // once more, the dropped refused.
        steps.refused.extend(dropped);
        let again = forward_and_prune(m, candidates, context, &mut steps);
        steps.refused.extend(again);
    }
    let mut seen = std::collections::HashSet::new();
    steps.notes.retain(|n| seen.insert(n.clone()));
    let Steps {
        mut selected,
        refused,
        notes,
        mut alternatives,
    } = steps;
    payload_over_link_error(m, candidates, &mut selected, &mut alternatives, settings);
    alternatives.retain(|a: &Alternative| selected.contains(&a.named));
    Selection {
        selected,
        notes,
        rejected: refused,
        alternatives,
    }
}

/// [`forward`] steps from `steps`, then the backward [`prune`]; what it
/// dropped.
fn forward_and_prune(
    m: &Moments,
    candidates: &[Candidate],
    (dof, settings, unidentifiable, initial): (usize, Settings, &[usize], &[f64]),
    steps: &mut Steps,
) -> Vec<usize> {
    forward(m, dof, candidates, settings, unidentifiable, initial, steps);
    prune(
        m,
        candidates,
        &mut steps.selected,
        &mut steps.notes,
        settings,
    )
}

/// What forward selection has decided so far.
struct Steps {
    selected: Vec<usize>,
    refused: Vec<usize>,
    notes: Vec<String>,
    alternatives: Vec<Alternative>,
}

/// Forward steps from `steps.selected`: each adds the open candidate that
/// lowers some joint's held-out MSE the most, while that cut reaches
/// `min_gain` (`initial`: the held-out MSE before any effect).
fn forward(
    m: &Moments,
    dof: usize,
    candidates: &[Candidate],
    settings: Settings,
    unidentifiable: &[usize],
    initial: &[f64],
    steps: &mut Steps,
) {
    let mut current = cv_mse(m, dof, candidates, &steps.selected, Scoring::Fitted);
    loop {
        let open: Vec<usize> = (0..candidates.len())
            .filter(|c| {
                !steps.selected.contains(c)
                    && !steps.refused.contains(c)
                    && !unidentifiable.contains(c)
                    && admissible(candidates, *c, &steps.selected)
            })
            .collect();
        let scored = score(
            m,
            dof,
            candidates,
            (&steps.selected, &open),
            (&current, initial),
        );
        let best = scored
            .iter()
            .max_by(|a, b| a.1.share.total_cmp(&b.1.share))
            .map(|best| {
                let is_link = |c: usize| candidates[c].link.is_some();
                let broad = broadest(&scored, best, &current, &is_link);
                fewer_parameters(candidates, &scored, broad)
            })
            .cloned();
        let Some((c, gain, mse)) = best else { break };
        let mut trial = steps.selected.clone();
        trial.push(c);
        if gain.share < settings.min_gain {
            break;
        }
        if let Some((joint, factor)) = worse_than_before(&mse, (&current, initial)) {
            steps.notes.push(format!(
                "{}: {} at this step, but it leaves joint {}'s at {:.1} times its held-out MSE \
                 before the diagnosis, a fit trading one joint's structure for another's; not \
                 named",
                label(&candidates[c]),
                gain.would_cut(),
                joint + 1,
                factor
            ));
            steps.refused.push(c);
            continue;
        }
        let Some(full) = fit(m, candidates, &trial, |_| true) else {
            break;
        };
        let offset: usize = steps.selected.iter().map(|&s| width(&candidates[s])).sum();
        let w = width(&candidates[c]);
        if identifiability(&full.information, offset..offset + w) < COLLINEAR {
            steps.notes.push(format!(
                "{}: {} at this step, but its parameters are collinear with the effects \
                 already named ({}); not named",
                label(&candidates[c]),
                gain.would_cut(),
                steps
                    .selected
                    .iter()
                    .map(|&s| label(&candidates[s]))
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
            steps.refused.push(c);
            continue;
        }
        // A nonlinear candidate (a payload trading mass for lever arm) can
        // win on fit yet leave its parameters undetermined: refuse it and let
        // the others compete.
        let Some(values) = significant(m, candidates, &trial, &full, settings.min_t) else {
            steps.notes.push(format!(
                "{}: {} at this step, but its parameters are not significant (|t| <= {:.1}); \
                 not named",
                label(&candidates[c]),
                gain.would_cut(),
                searched_threshold(settings.min_t, candidates[c].searched)
            ));
            steps.refused.push(c);
            continue;
        };
        let plausible = physical(&candidates[c], &values, gain, settings.reach)
            .and_then(|()| levels_hold(candidates, &trial, full.theta.as_slice()));
        if let Err(note) = plausible {
            steps.notes.push(note);
            steps.refused.push(c);
            continue;
        }
        steps.alternatives.extend(runners_up(
            m,
            candidates,
            &steps.selected,
            c,
            gain,
            &mse,
            initial,
            &scored,
            settings,
        ));
        steps.selected = trial;
        current = mse;
        if complete_friction(
            m,
            dof,
            candidates,
            &mut steps.selected,
            &mut steps.notes,
            settings,
        ) {
            current = cv_mse(m, dof, candidates, &steps.selected, Scoring::Fitted);
        }
    }
}

/// What forward selection and pruning decided.
pub(super) struct Selection {
    pub(super) selected: Vec<usize>,
    pub(super) notes: Vec<String>,
    /// Candidates refused (not significant, not physical, collinear) or
    /// dropped by the prune.
    pub(super) rejected: Vec<usize>,
    /// Named effects' runners-up that the data barely tell from them.
    pub(super) alternatives: Vec<Alternative>,
}

/// Backward check of the forward selection: an effect named early can lose
/// its significance (or its physical sign) once later effects share its
/// work. Such effects are dropped, weakest first, until every named effect
/// holds up in the final joint fit.
pub(super) fn prune(
    m: &Moments,
    candidates: &[Candidate],
    selected: &mut Vec<usize>,
    notes: &mut Vec<String>,
    settings: Settings,
) -> Vec<usize> {
    let mut dropped_all = Vec::new();
    loop {
        // The last named failing effect goes first: it removed the least
        // error when named, and dropping it may restore the others'
        // significance (an early strong effect must not go for a late one).
        // Every effect is checked (in parallel): most often none fails.
        let fails = map_in_order(selected, |&c| {
            let mut trial: Vec<usize> = selected.iter().copied().filter(|&s| s != c).collect();
            trial.push(c);
            let Some(full) = fit(m, candidates, &trial, |_| true) else {
                return true;
            };
            match significant(m, candidates, &trial, &full, settings.min_t) {
                Some(values) => {
                    physical(&candidates[c], &values, Gain::NONE, settings.reach).is_err()
                        || levels_hold(candidates, &trial, full.theta.as_slice()).is_err()
                }
                None => true,
            }
        });
        let Some(position) = fails.iter().rposition(|&fail| fail) else {
            return dropped_all;
        };
        let dropped = selected.remove(position);
        dropped_all.push(dropped);
        notes.push(format!(
            "{}: named while selecting, but not significant or not physical once the other \
             effects are fitted with it; dropped",
            label(&candidates[dropped])
        ));
    }
}

/// A link's whole-body error chosen at a step yields to its mass-and-COM
/// error when that leaves every joint's held-out MSE within [`NEAR`] of it:
/// fewer parameters for the same structure.
fn fewer_parameters<'a>(
    candidates: &[Candidate],
    scored: &'a [(usize, Gain, Vec<f64>)],
    chosen: &'a (usize, Gain, Vec<f64>),
) -> &'a (usize, Gain, Vec<f64>) {
    let whole = &candidates[chosen.0];
    if !matches!(whole.shape, Shape::Whole { .. }) {
        return chosen;
    }
    scored
        .iter()
        .find(|(c, _, mse)| {
            let other = &candidates[*c];
            other.kind == Kind::InertialError
                && other.link == whole.link
                && !matches!(other.shape, Shape::Whole { .. })
                && mse.iter().zip(&chosen.2).all(|(o, w)| *o <= NEAR * w)
        })
        .unwrap_or(chosen)
}

/// Each `open` candidate added to `base`, scored by its held-out gain over
/// `current` (the residual at this step, also the gain floor's reference
/// on the joints the candidate acts on); candidates whose gain is
/// undefined are left out. Each candidate's cross-validation is
/// independent of the others'.
///
/// On a joint the candidate does not act on (`Moments::acts_on`), a cut
/// comes only from refitting the effects named beside it (a shoulder's
/// link error frees a payload to fit the wrist better), and it counts only
/// above the floor of that joint's error before the diagnosis (`initial`):
/// measured against the residual at the step, a wrist at the noise level
/// credited a UR10e's upper arm with a third of its 4e-5 N m^2, and the
/// arm had no error there.
fn score(
    m: &Moments,
    dof: usize,
    candidates: &[Candidate],
    (base, open): (&[usize], &[usize]),
    (current, initial): (&[f64], &[f64]),
) -> Vec<(usize, Gain, Vec<f64>)> {
    map_in_order(open, |&c| {
        let trial = [base, &[c]].concat();
        let mse = cv_mse(m, dof, candidates, &trial, Scoring::Fitted);
        let columns = columns_of(candidates, &[c]);
        let reference: Vec<f64> = (0..current.len())
            .map(|j| match m.acts_on(&columns, j) {
                true => current[j],
                false => current[j].max(initial[j]),
            })
            .collect();
        (c, relative_gain(current, &mse, &reference), mse)
    })
    .into_iter()
    .filter(|(_, gain, _)| gain.share.is_finite())
    .collect()
}

/// Bodies (payloads, inertial errors) named while joint effects were
/// still missing were chosen against residuals those dominated, where one
/// link's error looks like its neighbour's and a whole-body error like a
/// mass-and-COM one. Once the rest are named, each named body is chosen
/// again among all bodies: the one that, in its place, cuts some joint's
/// held-out MSE the most replaces it when that cut is at least half of
/// `min_gain`, no joint is worse by more than [`NEAR`], and it is
/// significant and physical (near ties go to fewer parameters).
fn swap_bodies(
    m: &Moments,
    candidates: &[Candidate],
    selected: &mut [usize],
    (excluded, initial): (&[usize], &[f64]),
    settings: Settings,
) {
    let dof = initial.len();
    let is_body = |c: usize| candidates[c].link.is_some();
    for at in 0..selected.len() {
        if !is_body(selected[at]) {
            continue;
        }
        let others: Vec<usize> = (0..selected.len())
            .filter(|&i| i != at)
            .map(|i| selected[i])
            .collect();
        let current = cv_mse(m, dof, candidates, selected, Scoring::Fitted);
        let open: Vec<usize> = (0..candidates.len())
            .filter(|&c| {
                is_body(c)
                    && !selected.contains(&c)
                    && !excluded.contains(&c)
                    && admissible(candidates, c, &others)
            })
            .collect();
        let scored = score(m, dof, candidates, (&others, &open), (&current, initial));
        let Some(best) = scored.iter().max_by(|a, b| a.1.share.total_cmp(&b.1.share)) else {
            continue;
        };
        let (c, gain, mse) = fewer_parameters(candidates, &scored, best);
        // A replacement adds no parameters' worth of effects: half the bar,
        // and no joint clearly worse.
        let worse = clearly_worse(mse, &current, initial, NEAR);
        if gain.share < 0.5 * settings.min_gain || worse {
            continue;
        }
        let mut trial = others;
        trial.push(*c);
        let admitted = admits(m, candidates, &trial, settings);
        if admitted {
            selected[at] = *c;
        }
    }
}

/// Several named bodies whose errors one body explains as well (no
/// joint's held-out MSE clearly worse: [`clearly_worse`] by [`NEAR`]) are
/// that one body: a wholly wrong
/// link acts partly through combinations it shares with its neighbours
/// (the base parameters regroup them), so forward selection, which names
/// the neighbour's mass first, ends with two bodies for one error. Among
/// the single bodies that pass, significant and physical, the one with the
/// lowest summed held-out MSE.
fn one_body(
    m: &Moments,
    candidates: &[Candidate],
    selected: &mut Vec<usize>,
    (excluded, initial): (&[usize], &[f64]),
    settings: Settings,
) {
    let dof = m.xx.first().map_or(0, Vec::len);
    let is_body = |c: usize| candidates[c].link.is_some();
    if selected.iter().filter(|&&c| is_body(c)).count() < 2 {
        return;
    }
    let current = cv_mse(m, dof, candidates, selected, Scoring::Fitted);
    let others: Vec<usize> = selected.iter().copied().filter(|&c| !is_body(c)).collect();
    let open: Vec<usize> = (0..candidates.len())
        .filter(|&c| is_body(c) && !excluded.contains(&c))
        .collect();
    let passing: Vec<(usize, f64)> = map_in_order(&open, |&c| {
        let mut trial = others.clone();
        trial.push(c);
        let mse = cv_mse(m, dof, candidates, &trial, Scoring::Fitted);
        let near = !clearly_worse(&mse, &current, initial, NEAR);
        let admitted = near && admits(m, candidates, &trial, settings);
        admitted.then(|| (c, mse.iter().sum::<f64>()))
    })
    .into_iter()
    .flatten()
    .collect();
    if let Some(&(c, _)) = passing.iter().min_by(|a, b| a.1.total_cmp(&b.1)) {
        let first = selected.iter().position(|&s| is_body(s)).unwrap_or(0);
        selected.retain(|&s| !is_body(s));
        selected.insert(first.min(selected.len()), c);
    }
}

/// Whether a candidate may compete given the effects already named: an
/// asymmetry of dry friction only on a joint that has Coulomb friction, one
/// inertial error per link.
pub(super) fn admissible(candidates: &[Candidate], c: usize, selected: &[usize]) -> bool {
    let candidate = &candidates[c];
    if candidate.kind == Kind::InertialError
        && selected.iter().any(|&s| {
            candidates[s].kind == Kind::InertialError && candidates[s].link == candidate.link
        })
    {
        return false;
    }
    let Shape::Asymmetry { modelled_coulomb } = candidate.shape else {
        return true;
    };
    modelled_coulomb > 0.0
        || selected.iter().any(|&s| {
            candidates[s].kind == Kind::CoulombFriction && candidates[s].joint == candidate.joint
        })
}

#[cfg(test)]
mod tests;
