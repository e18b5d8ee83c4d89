//! A named link error moves the COM only along the axes the data
//! determine. Fitted freely, a COM component whose 95% interval holds the
//! modelled value is what the recording's noise and its unmodelled
//! leftovers put there, and applied it can be wrong elsewhere: a UR10e's
//! wrist_2 error from one 40 s recording put the COM 4 cm off the axis
//! (95% CI -8.7 .. 0.6 cm, modelled 0), and on five other recordings joint
//! 4's error was 2.13 times that of least squares. Where the held-out data
//! ask for it (there: joint 5's held-out MSE in that recording fell 85%),
//! such an axis is held as modelled and the link's mass and other axes are
//! fitted with it: joint 4 then read 0.66 times least squares.

use nalgebra::DVector;

use super::alternatives::NEAR;
use super::candidate::{Candidate, Shape, label, width};
use super::gain::relative_gain;
use super::heldout::{Scoring, cv_mse};
use super::kind::Kind;
use super::moments::Moments;
use super::report::half_widths;
use super::shape::HeldCom;

/// Holds, in each named link error with a modelled mass, the COM axes
/// whose 95% interval (`bias` widens it as the report's) includes the
/// modelled COM where the held-out data ask for it (see [`earns_hold`]).
/// Returns a note per link held.
pub(super) fn hold_undetermined(
    m: &Moments,
    dof: usize,
    candidates: &mut [Candidate],
    selected: &[usize],
    bias: &DVector<f64>,
    min_gain: f64,
) -> Vec<String> {
    let Some((fit, half)) = half_widths(m, candidates, selected, bias) else {
        return Vec::new();
    };
    let mut trials = Vec::new();
    let mut at = 0;
    for &c in selected {
        let axes = undetermined(&candidates[c], &fit.theta, &half, at);
        if !axes.is_empty() {
            let free = std::array::from_fn(|k| {
                let (value, h) = (fit.theta[at + k], half[at + k]);
                (value - h, value + h)
            });
            trials.push((c, axes, free));
        }
        at += width(&candidates[c]);
    }
    let mut current = cv_mse(m, dof, candidates, selected, Scoring::Fitted);
    let mut notes = Vec::new();
    for (c, axes, free) in trials {
        // The least determined axis first, each judged against the fit
        // with the axes held before it.
        let mut held = HeldCom {
            axes: [false; 3],
            free,
        };
        for a in axes {
            held.axes[a] = true;
            set(&mut candidates[c], held);
            let after = cv_mse(m, dof, candidates, selected, Scoring::Fitted);
            if earns_hold(&current, &after, min_gain) {
                current = after;
            } else {
                held.axes[a] = false;
            }
        }
        if held.axes.iter().any(|&h| h) {
            set(&mut candidates[c], held);
            notes.push(note(&candidates[c], &held));
        } else if let Shape::Body { held_com, .. } = &mut candidates[c].shape {
            *held_com = None;
        }
    }
    notes
}

/// Whether holding an axis is a change the held-out data ask for, as a
/// new effect must be: it cuts some joint's held-out MSE (`current` ->
/// `held`) by `min_gain` and raises none beyond [`NEAR`] times. Where the
/// held-out error does not care, the free fit stays: it is the least
/// squares estimate (a wholly wrong Panda link's COM held where the data
/// barely see it moved its mass 5% from the truth).
fn earns_hold(current: &[f64], held: &[f64], min_gain: f64) -> bool {
    let gain = relative_gain(current, held, current);
    gain.share >= min_gain && held.iter().zip(current).all(|(h, c)| *h <= NEAR * c)
}

/// Gives a link error these held axes.
fn set(candidate: &mut Candidate, held: HeldCom) {
    if let Shape::Body { held_com, .. } = &mut candidate.shape {
        *held_com = Some(held);
    }
}

/// The COM axes of a link error (`theta` and 95% half-widths `half` of
/// the selection, its parameters from `at`) whose interval includes the
/// modelled COM, the least determined first (smallest change in
/// half-widths); empty when there is none or the candidate is not a link
/// error with a modelled mass.
fn undetermined(
    candidate: &Candidate,
    theta: &DVector<f64>,
    half: &DVector<f64>,
    at: usize,
) -> Vec<usize> {
    let Shape::Body {
        base_mass,
        base_moment,
        held_com: None,
        ..
    } = &candidate.shape
    else {
        return Vec::new();
    };
    if candidate.kind != Kind::InertialError || *base_mass <= 0.0 {
        return Vec::new();
    }
    let mut axes: Vec<(usize, f64)> = (0..3)
        .filter_map(|a| {
            let (value, h) = (theta[at + 1 + a], half[at + 1 + a]);
            let change = (value - base_moment[a] / base_mass).abs();
            (change <= h).then_some((a, change / h))
        })
        .collect();
    axes.sort_by(|x, y| x.1.total_cmp(&y.1));
    axes.into_iter().map(|(a, _)| a).collect()
}

/// What a user reads about a link error with held COM axes.
fn note(candidate: &Candidate, held: &HeldCom) -> String {
    let Shape::Body {
        base_mass,
        base_moment,
        ..
    } = &candidate.shape
    else {
        return String::new();
    };
    let axes: Vec<String> = ["x", "y", "z"]
        .iter()
        .enumerate()
        .filter(|&(a, _)| held.axes[a])
        .map(|(a, axis)| {
            let (lo, hi) = held.free[a + 1];
            format!(
                "{axis} (free fit 95% CI {lo:.4} .. {hi:.4} m, modelled {:.4} m)",
                base_moment[a] / base_mass
            )
        })
        .collect();
    format!(
        "{}: the data do not determine a change of the centre of mass along {}: held as \
         modelled, the mass and the other axes fitted with it, their intervals at least the free \
         fit's (a component fitted within its noise is wrong on other motions)",
        label(candidate),
        axes.join(", ")
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::candidate::linear;
    use nalgebra::Vector3;

    fn link_error(base_mass: f64, com: Vector3<f64>) -> Candidate {
        Candidate {
            shape: Shape::Body {
                offset: [0.0; 10],
                base_mass,
                base_moment: com * base_mass,
                own_inertia: false,
                held_com: None,
            },
            names: vec!["mass", "cx", "cy", "cz"],
            ..linear(Kind::InertialError, DVector::zeros(4))
        }
    }

    /// An axis is tried when its interval includes the modelled COM, not
    /// when it excludes it; a payload (no modelled COM) never is.
    #[test]
    fn axes_whose_interval_includes_the_model_are_tried() {
        let candidate = link_error(2.0, Vector3::new(0.0, 0.0, 0.12));
        let theta = DVector::from_vec(vec![3.6, -0.04, 0.0166, 0.108]);
        let half = DVector::from_vec(vec![0.5, 0.047, 0.01, 0.04]);
        let axes = undetermined(&candidate, &theta, &half, 0);
        // z (0.012 of 0.04) before x (0.04 of 0.047); y (0.0166 of 0.01) not.
        assert_eq!(axes, vec![2, 0]);
        let payload = Candidate {
            kind: Kind::Payload,
            ..link_error(0.0, Vector3::zeros())
        };
        assert!(undetermined(&payload, &theta, &half, 0).is_empty());
        let tight = DVector::from_vec(vec![0.5, 0.01, 0.01, 0.001]);
        assert!(undetermined(&candidate, &theta, &tight, 0).is_empty());
    }

    /// The UR10e's 40 s recording alone: wrist_2's COM x held cuts joint 5's
    /// held-out MSE by 85% and raises joint 2's by 9%: held. A change the
    /// held-out error barely sees (the Panda's) or one that raises a joint
    /// beyond 10% is not.
    #[test]
    fn a_hold_must_cut_some_joint_and_raise_none_much() {
        let current = [13.82, 32.40, 4.10, 0.902, 0.895, 0.469];
        let ur10e = [13.89, 35.25, 4.22, 0.469, 0.130, 0.469];
        assert!(earns_hold(&current, &ur10e, 0.1));
        let indifferent = current.map(|c| c * 0.997);
        assert!(!earns_hold(&current, &indifferent, 0.1));
        let mut raised = ur10e;
        raised[1] = 1.2 * current[1];
        assert!(!earns_hold(&current, &raised, 0.1));
    }
}
