//! A named ripple's harmonic, searched again beside the effects the data
//! name. The first search projects out every linear column a joint could
//! need (the links' inertial columns among them, so a payload does not
//! choose the harmonic); over a short travel those many columns soak up
//! part of a low harmonic, and a neighbour is chosen: the Panda's 8 cycles
//! per revolution on a joint that travelled 0.9 rad were searched as 6 from
//! one recording, and an armature was named for what the wrong harmonic
//! left. Beside only what was named, the search sees the harmonic itself.

use nalgebra::DVector;

use super::candidate::{Candidate, label};
use super::kind::Kind;
use super::search::{Nuisance, ripple_cycles};
use super::stacked::Stacked;

/// For each named ripple whose harmonic was searched, the candidate and
/// its harmonic searched again with the joint's own linear columns and
/// every other named effect projected out, where that differs.
pub(super) fn researched(
    data: &Stacked,
    candidates: &[Candidate],
    selected: &[usize],
) -> Vec<(usize, f64)> {
    selected
        .iter()
        .filter_map(|&c| {
            let ripple = &candidates[c];
            let j = ripple.joint.filter(|_| ripple.kind == Kind::TorqueRipple)?;
            let current = cycles(ripple)?;
            if ripple.searched <= 1 {
                return None;
            }
            let own = candidates
                .iter()
                .filter(|o| o.joint == Some(j) && own_linear(o.kind));
            let named = selected
                .iter()
                .filter(|&&s| s != c)
                .map(|&s| &candidates[s]);
            let columns: Vec<&DVector<f64>> =
                own.chain(named).flat_map(|o| o.columns.iter()).collect();
            let nuisance = Nuisance::new(data, j, &columns);
            let (again, _) = ripple_cycles(data, j, &data.angle, &nuisance)?;
            (again != current).then_some((c, again))
        })
        .collect()
}

/// Gives each candidate of `harmonics` its new harmonic; the notes that
/// say so.
pub(super) fn set_harmonics(
    data: &Stacked,
    candidates: &mut [Candidate],
    harmonics: &[(usize, f64)],
) -> Vec<String> {
    let mut notes = Vec::new();
    for &(c, again) in harmonics {
        let ripple = &mut candidates[c];
        let (Some(j), Some(first)) = (ripple.joint, cycles(ripple)) else {
            continue;
        };
        let own = |f: &dyn Fn(f64) -> f64| {
            data.angle
                .map_with_location(|r, _, q| if r % data.dof == j { f(q) } else { 0.0 })
        };
        ripple.columns = vec![own(&|q| (again * q).sin()), own(&|q| (again * q).cos())];
        ripple.settings = vec![("cycles", again)];
        notes.push(format!(
            "{}: the harmonic searched beside every column the joint could need was {first} \
             cycles per revolution; searched again beside the effects named, {again}: named \
             at {again}",
            label(ripple)
        ));
    }
    notes
}

/// The cycles per revolution a ripple candidate was built with.
fn cycles(ripple: &Candidate) -> Option<f64> {
    ripple
        .settings
        .iter()
        .find(|(name, _)| *name == "cycles")
        .map(|s| s.1)
}

/// The kinds whose columns are the joint's own simple signals (velocity,
/// moving sign, acceleration, 1, position, the model's torque).
fn own_linear(kind: Kind) -> bool {
    matches!(
        kind,
        Kind::ViscousFriction
            | Kind::CoulombFriction
            | Kind::Armature
            | Kind::TorqueOffset
            | Kind::TorqueScale
            | Kind::JointSpring
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::candidate::linear;

    /// A ripple of 8 cycles per revolution with noise on a joint that
    /// travels 0.9 rad, named at 60 cycles (what a search beside the
    /// fourteen powers of the position chose): searched again beside the
    /// effects named, it is 8, and the candidate is rebuilt at 8.
    #[test]
    fn a_named_ripple_is_searched_again_beside_what_is_named() {
        let (mut data, q, _) = crate::diagnose::search::sweep(|_, _| 0.0);
        data.angle = q.map(|q| 0.375 * q);
        let noise = |r: usize| 0.2 * ((r as f64 * 12.9898).sin() * 43758.5453).fract();
        data.residual = DVector::from_fn(q.len(), |r, _| {
            0.2 * (8.0 * data.angle[r] + 0.3).sin() + noise(r)
        });
        let mut ripple = linear(Kind::TorqueRipple, data.angle.map(|a| (60.0 * a).sin()));
        ripple.columns.push(data.angle.map(|a| (60.0 * a).cos()));
        ripple.settings = vec![("cycles", 60.0)];
        ripple.searched = 124;
        let offset = linear(Kind::TorqueOffset, data.angle.map(|_| 1.0));
        let mut candidates = vec![offset, ripple];
        let harmonics = researched(&data, &candidates, &[0, 1]);
        assert_eq!(harmonics, vec![(1, 8.0)]);
        set_harmonics(&data, &mut candidates, &harmonics);
        assert_eq!(cycles(&candidates[1]), Some(8.0));
        let expected = data.angle.map(|a| (8.0 * a).sin());
        assert!((&candidates[1].columns[0] - expected).norm() < 1e-12);
    }
}
