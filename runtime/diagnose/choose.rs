//! Which effects the data name: forward selection on the candidates, then
//! the checks that prune what it named (the friction's second term, the
//! backward check, held-out help, the widened intervals, friction that
//! rounds off, offset or direction-dependent friction at rest).

use super::alternatives::Alternative;
use super::candidate::{Candidate, Shape, columns_of, label, width};
use super::fit::fit;
use super::kind::Kind;
use super::moments::Moments;
use super::select::{body_identifiable, mass_identifiable, select};
use super::settings::Settings;
use super::stacked::Stacked;
use super::{com_hold, companion, dry, held, heldout, payload_body, report, smooth, supported};

/// What the data name, and what the report needs of how.
pub(super) struct Chosen {
    pub(super) moments: Moments,
    pub(super) selected: Vec<usize>,
    pub(super) notes: Vec<String>,
    /// The effects the data support beside the final selection.
    pub(super) supported: Vec<supported::Supported>,
    pub(super) alternatives: Vec<Alternative>,
    /// Links whose mass is fitted through their second moments.
    pub(super) second_moments: Vec<usize>,
}

/// Names the effects among `candidates` (a link whose mass the data do
/// not determine is changed to fit its first moment alone).
pub(super) fn choose(
    data: &Stacked,
    candidates: &mut [Candidate],
    settings: Settings,
    size: f64,
) -> Chosen {
    let moments = Moments::new(data, candidates).noise_weighted(candidates);
    // A link whose origin does not accelerate has no mass column of its
    // own: its mass acts only through its second moments, which identify it
    // if the inertia about the COM is as modelled (noted); where they do not,
    // or where the body it fits is rejected, only the first moment is fitted.
    let (mut second_moments, massless): (Vec<usize>, Vec<usize>) = (0..candidates.len())
        .filter(|&c| !mass_identifiable(&moments, candidates, c, size))
        .partition(|&c| body_identifiable(&moments, candidates, c));
    hold_mass(candidates, &massless);
    // A torque scale beyond the plausible in the final selection is
    // withdrawn and the selection run again without it: dropped alone, the
    // effects it was fitted with (a link's first moment) stay as fitted
    // beside it.
    let (mut untried, friction_note) = friction_scales(data, &moments, candidates);
    let (still, still_note) = still_joints(data, candidates);
    untried.extend(still);
    let mut withdrawn = untried.clone();
    let mut withdrawal: Vec<String> = friction_note.into_iter().chain(still_note).collect();
    let (alternatives, mut selected, mut notes) = loop {
        let mut selection = select(&moments, data.dof, candidates, settings, &withdrawn);
        let retry: Vec<usize> = second_moments
            .iter()
            .copied()
            .filter(|c| selection.rejected.contains(c))
            .collect();
        if !retry.is_empty() {
            hold_mass(candidates, &retry);
            second_moments.retain(|c| !retry.contains(c));
            selection = select(&moments, data.dof, candidates, settings, &withdrawn);
        }
        if let Some(note) = payload_body::give_inertia(
            &moments,
            data.dof,
            candidates,
            &selection.selected,
            settings,
        ) {
            let with_body = select(&moments, data.dof, candidates, settings, &withdrawn);
            if payload_body::body_named(candidates, &with_body.selected) {
                selection = with_body;
                selection.notes.push(note);
            } else {
                // Its moment failed beside the later effects and the
                // backward check dropped the payload, and with it the
                // effects its gravity had held up: the point mass's
                // selection stands.
                selection
                    .notes
                    .extend(payload_body::withdraw_inertia(candidates));
            }
        }
        let (mut selected, mut notes) = (selection.selected, selection.notes);
        // Pruning and the body swaps may have changed the selection since
        // its last step.
        companion::complete_friction(
            &moments,
            data.dof,
            candidates,
            &mut selected,
            &mut notes,
            settings,
        );
        super::select::prune(&moments, candidates, &mut selected, &mut notes, settings);
        let large = large_scales(&moments, candidates, &selected);
        if large.is_empty() {
            break (selection.alternatives, selected, notes);
        }
        withdrawal.extend(large.iter().map(|&(c, error)| {
            format!(
                "{}: the data fit a torque scale error of {error:.3} beside the other named \
                 effects, beyond the {NAMED_SCALE_ERROR} a torque sensor or drive gain is off \
                 by: the trace of another effect (a link's mass traded with gravity on a slow \
                 motion); not named, and the effects chosen again without it",
                label(&candidates[c])
            )
        }));
        withdrawn.extend(large.iter().map(|l| l.0));
    };
    notes.extend(withdrawal);
    drop_unhelpful(&moments, candidates, &mut selected, &mut notes);
    // The last selection judged is the final one: its supported effects
    // are the report's.
    let mut supported = drop_unheld(
        &moments,
        data.dof,
        candidates,
        &mut selected,
        &mut notes,
        (settings, &untried),
    );
    let judged = selected.len();
    smooth::drop_friction_traces(
        data,
        &moments,
        candidates,
        &mut selected,
        &mut notes,
        settings,
    );
    dry::settle_by_rest(data, &moments, candidates, &mut selected, &mut notes);
    if selected.len() < judged {
        // An effect named beside one dropped here may have fitted its
        // leftover (viscous friction on a joint at the noise floor, named
        // after a torque delay that stood in for Stribeck friction).
        supported = drop_unheld(
            &moments,
            data.dof,
            candidates,
            &mut selected,
            &mut notes,
            (settings, &untried),
        );
    }
    let parameters = selected.iter().map(|&c| width(&candidates[c])).sum();
    let timing = supported::timing_shift(&moments, candidates, &selected);
    let bias = supported::bias(&supported, timing, parameters);
    let held = com_hold::hold_undetermined(
        &moments,
        data.dof,
        candidates,
        &selected,
        &bias,
        settings.min_gain,
    );
    if !held.is_empty() {
        notes.extend(held);
        supported = supported::supported(
            &moments,
            data.dof,
            candidates,
            &selected,
            (settings, &untried),
        );
    }
    notes.extend(payload_body::stand_ins(&moments, candidates, &selected));
    Chosen {
        moments,
        selected,
        notes,
        supported,
        alternatives,
        second_moments,
    }
}

/// The largest torque-scale error named: a torque sensor, or a drive gain
/// times a current, is calibrated far better. Selection may pass larger
/// scales on the way (one that absorbs an effect not yet named and is
/// dropped later), so the bound is on the final selection only.
const NAMED_SCALE_ERROR: f64 = 0.25;

/// Above this share of a joint's modelled torque energy (over the
/// recordings) that is the description's own friction, a torque scale on
/// it is not tried: the scale would be a friction correction.
const FRICTION_SHARE_OF_SCALE: f64 = 0.5;

/// The torque scale candidates on joints whose modelled torque is mostly
/// the description's own viscous and Coulomb friction, with a note naming
/// them: there a scale error cannot be told from a friction correction,
/// the likelier error (a description's friction values are often
/// placeholders; an imported xArm7's viscous 10 N m s/rad on joint 1 was
/// 99% of that joint's torque, and a scale of 1.39 was named for its
/// friction). A joint the description gives no friction is always tried.
fn friction_scales(
    data: &Stacked,
    moments: &Moments,
    candidates: &[Candidate],
) -> (Vec<usize>, Option<String>) {
    let mut withdrawn = Vec::new();
    let mut shares = Vec::new();
    for (c, candidate) in candidates.iter().enumerate() {
        let Some(j) = candidate
            .joint
            .filter(|_| candidate.kind == Kind::TorqueScale)
        else {
            continue;
        };
        let share = described_friction_share(data, moments, candidates, (c, j));
        if share > FRICTION_SHARE_OF_SCALE {
            withdrawn.push(c);
            shares.push(format!("{} ({:.0}%)", j + 1, 100.0 * share));
        }
    }
    let note = (!shares.is_empty()).then(|| {
        format!(
            "torque_scale is not tried on joint(s) {}: that share of each joint's modelled torque \
             is the description's own viscous and Coulomb friction, so a scale error there \
             cannot be told from a correction of that friction (the likelier error)",
            shares.join(", ")
        )
    });
    (withdrawn, note)
}

/// Below this share of a joint's samples moving faster than its at-rest
/// speed, friction is not tried on the joint.
const MOVING_SHARE: f64 = 0.1;

/// How the note on joints that barely move begins (the report ranks it by
/// the held-out error those joints keep).
pub(super) const STILL_JOINTS: &str = "friction is not tried on joint(s) ";

/// The friction candidates of joints that barely move (faster than their
/// at-rest speed on under [`MOVING_SHARE`] of the samples), with a note
/// naming them: at such speeds dry friction is static or in its
/// transition, which no column resolves, and a viscous term fitted there
/// stands for it (a Kinova Gen3's joints dithering by 0.02 rad were given
/// 40-115 N m s/rad, where the truth was 0.3-0.9 beside Coulomb 0.5-1.4).
fn still_joints(data: &Stacked, candidates: &[Candidate]) -> (Vec<usize>, Option<String>) {
    let moving = |j: usize| {
        let rest = data.rest.get(j).copied().unwrap_or(0.0);
        let rows: Vec<usize> = data.rows_of(j).collect();
        let fast = rows.iter().filter(|&&r| data.qd[r].abs() > rest).count();
        fast as f64 / rows.len().max(1) as f64
    };
    let still: Vec<(usize, f64)> = (0..data.dof)
        .map(|j| (j, moving(j)))
        .filter(|&(_, share)| share < MOVING_SHARE)
        .collect();
    let friction = [
        Kind::ViscousFriction,
        Kind::CoulombFriction,
        Kind::CoulombAsymmetry,
        Kind::StribeckFriction,
    ];
    let withdrawn = (0..candidates.len())
        .filter(|&c| {
            friction.contains(&candidates[c].kind)
                && still.iter().any(|&(j, _)| candidates[c].joint == Some(j))
        })
        .collect();
    let note = (!still.is_empty()).then(|| {
        let joints: Vec<String> = still
            .iter()
            .map(|(j, share)| format!("{} ({:.0}%)", j + 1, 100.0 * share))
            .collect();
        format!(
            "{STILL_JOINTS}{}: they move faster than their at-rest speed on \
             under {:.0}% of the samples (the share given), where dry friction is static or in \
             its transition and a viscous term fitted there stands for it; record motions that \
             move them to diagnose their friction",
            joints.join(", "),
            100.0 * MOVING_SHARE
        )
    });
    (withdrawn, note)
}

/// The energy of the description's viscous and Coulomb friction torque on
/// joint `j`'s rows (the generated model's sign(qd)) over the energy of the
/// model's torque there (the column of torque scale candidate `scale`),
/// at most 1; 0 where the description gives the joint no friction.
fn described_friction_share(
    data: &Stacked,
    moments: &Moments,
    candidates: &[Candidate],
    (scale, j): (usize, usize),
) -> f64 {
    let [viscous, coulomb] = data.friction.get(j).copied().unwrap_or([0.0; 2]);
    let column = |kind: Kind| {
        let c = candidates
            .iter()
            .position(|c| c.kind == kind && c.joint == Some(j))?;
        moments
            .applied(&columns_of(candidates, &[c]))
            .first()
            .copied()
    };
    let levels = [
        (column(Kind::ViscousFriction), viscous),
        (column(Kind::CoulombFriction), coulomb),
    ];
    let energy = |a: usize, b: usize| moments.xx.iter().map(|g| g[j][(a, b)]).sum::<f64>();
    let Some(&torque) = columns_of(candidates, &[scale]).first() else {
        return 0.0;
    };
    let total = energy(torque, torque);
    let friction: f64 = levels
        .iter()
        .flat_map(|&(a, va)| levels.iter().map(move |&(b, vb)| (a, va, b, vb)))
        .filter_map(|(a, va, b, vb)| Some(va * vb * energy(a?, b?)))
        .sum();
    if total <= 0.0 || friction <= 0.0 {
        return 0.0;
    }
    (friction / total).min(1.0)
}

/// The torque scales of `selected` whose fitted error, beside the other
/// named effects, is beyond [`NAMED_SCALE_ERROR`], with that error: on a
/// slow motion gravity times a scale trades with a link's first moment
/// (the UR10e's public 20 s, five-harmonic recording alone named 1.41 and
/// 1.44 on joints 2 and 3 beside an upper-arm error).
fn large_scales(
    moments: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
) -> Vec<(usize, f64)> {
    let Some(full) = fit(moments, candidates, selected, |_| true) else {
        return Vec::new();
    };
    let mut at = 0;
    let mut large = Vec::new();
    for &c in selected {
        let error = full.theta[at];
        at += width(&candidates[c]);
        if candidates[c].kind == Kind::TorqueScale && error.abs() > NAMED_SCALE_ERROR {
            large.push((c, error.abs()));
        }
    }
    large
}

/// Drops, one at a time, a named effect that removes no held-out error
/// from its joints once applied (the generated model's columns, counted in
/// selection order): selection scores the fitted columns, and an effect at
/// the noise floor can pass it yet make the applied model no better.
fn drop_unhelpful(
    m: &Moments,
    candidates: &[Candidate],
    selected: &mut Vec<usize>,
    notes: &mut Vec<String>,
) {
    while let Some(position) = report::heldout_removals(m, candidates, selected)
        .iter()
        .enumerate()
        .position(|(k, &(removed, _))| {
            removed <= 0.0 && !helps_the_rest(m, candidates, selected, k)
        })
    {
        let dropped = selected.remove(position);
        notes.push(format!(
            "{}: significant in the fit, but once applied it removes no held-out error from its \
             joints; dropped",
            label(&candidates[dropped])
        ));
    }
}

/// Whether the effect at `position` of `selected` lowers its joints'
/// held-out MSE (applied columns) beside all the others. Counted in the
/// order named, an effect can seem to remove nothing because one named
/// after it does the work it needed: viscous friction named beside a
/// joint's Coulomb friction before a payload that dominates the joint's
/// residual (a Panda with friction on every joint and 0.8 kg at the
/// flange: joint 4's held-out MSE 0.0018 with it in the final model,
/// 0.0100 without it, and -0.009 of 15 "removed" where it was named).
fn helps_the_rest(
    m: &Moments,
    candidates: &[Candidate],
    selected: &[usize],
    position: usize,
) -> bool {
    let (with, without) = heldout::with_and_without(m, candidates, selected, position);
    without > with
}

/// [`held::drop_unheld`] with the bias of the supported effects beside
/// each selection judged; the supported effects of the last.
fn drop_unheld(
    m: &Moments,
    dof: usize,
    candidates: &[Candidate],
    selected: &mut Vec<usize>,
    notes: &mut Vec<String>,
    (settings, untried): (Settings, &[usize]),
) -> Vec<supported::Supported> {
    let mut supported = Vec::new();
    held::drop_unheld(m, candidates, selected, notes, |s| {
        supported = supported::supported(m, dof, candidates, s, (settings, untried));
        let timing = supported::timing_shift(m, candidates, s);
        held::bias_elsewhere(candidates, s, &supported, timing)
    });
    supported
}

/// Fits the first moment alone (the mass held as modelled) for these body
/// candidates.
fn hold_mass(candidates: &mut [Candidate], which: &[usize]) {
    for &c in which {
        if let Shape::Body {
            offset,
            base_mass,
            base_moment,
            ..
        } = candidates[c].shape
        {
            candidates[c].shape = Shape::Moment {
                offset,
                base_mass,
                base_moment,
            };
            candidates[c].names = vec!["mx", "my", "mz"];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::candidate::linear as candidate;
    use crate::diagnose::search::sweep;

    /// Residual `error` sin(q) + 0.3 qd, the torque scale's column sin(q)
    /// fitted beside viscous friction: an error of 0.4 is beyond the bound,
    /// 0.1 within; withdrawn, the scale is not selected again.
    #[test]
    fn a_scale_beyond_a_quarter_is_found_and_withdrawn() {
        for (error, large) in [(0.4, true), (0.1, false)] {
            let (data, q, qd) = sweep(|q, qd| error * q.sin() + 0.3 * qd);
            let candidates = vec![
                candidate(Kind::ViscousFriction, qd),
                candidate(Kind::TorqueScale, q.map(f64::sin)),
            ];
            let m = Moments::new(&data, &candidates);
            let found = large_scales(&m, &candidates, &[0, 1]);
            match large {
                true => {
                    assert_eq!(found.len(), 1, "{found:?}");
                    assert_eq!(found[0].0, 1);
                    assert!((found[0].1 - error).abs() < 1e-9, "{found:?}");
                }
                false => assert!(found.is_empty(), "{found:?}"),
            }
            let settings = Settings::default();
            let all = select(&m, 1, &candidates, settings, &[]).selected;
            assert!(all.contains(&1), "{all:?}");
            let without = select(&m, 1, &candidates, settings, &[1]).selected;
            assert!(!without.contains(&1), "{without:?}");
        }
    }

    /// Friction is not tried on a joint that moves faster than its at-rest
    /// speed (0.02 rad/s) on none of its samples, with a note that the
    /// report ranks by the joint's held-out error; on one that moves at up
    /// to 0.84 rad/s it is.
    #[test]
    fn friction_is_not_tried_on_a_joint_that_barely_moves() {
        for (scale, tried) in [(0.01, false), (1.0, true)] {
            let (mut data, q, qd) = sweep(|_, qd| 0.3 * qd);
            data.qd *= scale;
            let candidates = vec![
                candidate(Kind::ViscousFriction, qd.clone()),
                candidate(Kind::CoulombFriction, qd.map(f64::signum)),
                candidate(Kind::TorqueOffset, q.map(|_| 1.0)),
            ];
            let (withdrawn, note) = still_joints(&data, &candidates);
            match tried {
                false => {
                    assert_eq!(withdrawn, [0, 1]);
                    let note = note.unwrap();
                    assert!(note.starts_with(STILL_JOINTS), "{note}");
                    assert!(note.contains("joint(s) 1 (0%)"), "{note}");
                }
                true => assert!(withdrawn.is_empty() && note.is_none(), "{note:?}"),
            }
        }
    }

    /// A scale whose column, the model's torque, is 10 qd + sin(q) (a
    /// description's viscous friction of 10 beside a light link) is 97% the
    /// description's friction and not tried, with a note naming the joint;
    /// at 0.5 qd + sin(q) (21%) it is tried, and so it is at 10 qd + sin(q)
    /// where the description has no friction (the qd term another torque).
    #[test]
    fn a_scale_of_a_torque_that_is_mostly_friction_is_not_tried() {
        for (viscous, described, tried) in
            [(10.0, 10.0, false), (0.5, 0.5, true), (10.0, 0.0, true)]
        {
            let (mut data, q, qd) = sweep(|q, qd| 0.1 * qd + 0.05 * q.sin());
            data.friction = vec![[described, 0.0]];
            let model = viscous * &qd + q.map(f64::sin);
            let candidates = vec![
                candidate(Kind::ViscousFriction, qd),
                candidate(Kind::TorqueScale, model),
            ];
            let m = Moments::new(&data, &candidates);
            let (withdrawn, note) = friction_scales(&data, &m, &candidates);
            match tried {
                false => {
                    assert_eq!(withdrawn, [1]);
                    let note = note.unwrap();
                    assert!(note.contains("joint(s) 1 (97%)"), "{note}");
                    // Nor is it listed as supported, which it is when tried.
                    let listed = |untried: &[usize]| {
                        let settings = (Settings::default(), untried);
                        supported::supported(&m, 1, &candidates, &[0], settings)
                            .iter()
                            .any(|s| s.candidate == 1)
                    };
                    assert!(listed(&[]) && !listed(&withdrawn));
                }
                true => assert!(withdrawn.is_empty() && note.is_none(), "{note:?}"),
            }
        }
    }
}
