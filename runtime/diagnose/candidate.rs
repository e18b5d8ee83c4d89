//! The candidate effects: what each adds to the residual (its columns) and
//! how its named parameters map onto the coefficients of those columns.

use nalgebra::{DVector, Vector3};

use super::kind::Kind;
use super::search;
// A candidate carries its shape; the modules that fit candidates name it here.
pub(super) use super::shape::Shape;
use super::shape::point_mass;
use super::solve::ROUNDING;
use super::stacked::{Link, Stacked};
use super::whole;
use crate::parallel::map_in_order;

/// One candidate: a kind, a joint or link, its columns and how its named
/// parameters map to coefficients of those columns.
#[derive(Clone)]
pub(super) struct Candidate {
    pub(super) kind: Kind,
    pub(super) joint: Option<usize>,
    /// 0-based moving link and its name, for inertial candidates.
    pub(super) link: Option<(usize, String)>,
    /// The link's modelled standard parameters (inertial candidates; zero
    /// otherwise): the corrected body is these plus the fitted change.
    pub(super) modelled: [f64; 10],
    /// How far from the link origin its centre of mass may plausibly lie
    /// (inertial candidates; infinite otherwise), m.
    pub(super) extent: f64,
    pub(super) names: Vec<&'static str>,
    pub(super) columns: Vec<DVector<f64>>,
    /// What the generated model computes for this effect once applied, when
    /// that differs from the fitted column (Coulomb: the fit leaves out
    /// samples near rest, the model's sign(qd) does not). Held-out errors are
    /// scored with it, so they are what the applied model will show.
    pub(super) applied: Option<DVector<f64>>,
    pub(super) shape: Shape,
    /// Numbers that shape the columns, chosen from the data before the
    /// fit (a Stribeck velocity, a ripple's cycles), reported with the
    /// parameters.
    pub(super) settings: Vec<(&'static str, f64)>,
    /// How many column shapes the settings were chosen from (1: fixed):
    /// the significance threshold grows with it, so a search over many
    /// shapes does not find structure in noise.
    pub(super) searched: usize,
    /// The columns at the searched setting's neighbours on its grid (the
    /// Stribeck velocities either side of the one chosen): how far the fit
    /// moves between them bounds what the grid's resolution can cost the
    /// reported values. Empty for fixed shapes.
    pub(super) neighbours: Vec<DVector<f64>>,
}

/// A linear candidate on the first joint with one column (unit tests).
#[cfg(test)]
pub(super) fn linear(kind: Kind, column: DVector<f64>) -> Candidate {
    on_joint(kind, 0, "value", column)
}

/// A linear candidate on joint `j` (0-based) with one column, its
/// coefficient the parameter `name`.
pub(super) fn on_joint(
    kind: Kind,
    j: usize,
    name: &'static str,
    column: DVector<f64>,
) -> Candidate {
    Candidate {
        kind,
        joint: Some(j),
        link: None,
        modelled: [0.0; 10],
        extent: f64::INFINITY,
        names: vec![name],
        columns: vec![column],
        applied: None,
        shape: Shape::Linear,
        settings: Vec::new(),
        searched: 1,
        neighbours: Vec::new(),
    }
}

/// Global column indices of the selected candidates.
pub(super) fn columns_of(candidates: &[Candidate], selected: &[usize]) -> Vec<usize> {
    let offsets: Vec<usize> = candidates
        .iter()
        .scan(0, |at, c| {
            let start = *at;
            *at += c.columns.len();
            Some(start)
        })
        .collect();
    selected
        .iter()
        .flat_map(|&c| offsets[c]..offsets[c] + candidates[c].columns.len())
        .collect()
}

pub(super) fn width(candidate: &Candidate) -> usize {
    candidate.shape.width(candidate.columns.len())
}

/// How a candidate is named in notes.
pub(super) fn label(candidate: &Candidate) -> String {
    let kind = candidate.kind.name();
    match (&candidate.joint, &candidate.link) {
        (Some(j), _) => format!("{kind} on joint {}", j + 1),
        (None, Some((k, name))) => format!("{kind} of link {} (`{name}`)", k + 1),
        (None, None) => kind,
    }
}

/// The fitted columns of the stacked data, filtered like the residual.
pub(super) struct Columns {
    /// qd, moving sign, qdd, 1, q of each row's joint.
    pub(super) own: [DVector<f64>; 5],
    /// The generated model's sign(qd).
    pub(super) coulomb_applied: DVector<f64>,
    /// The regressor's inertial columns, ten per link.
    pub(super) inertial: Vec<DVector<f64>>,
    /// Gravity torques for unit gravity across the model's and along it (a
    /// tilted base), when the model has a description and gravity: the
    /// shape with the directions, and the three columns.
    pub(super) tilt: Option<(Shape, [DVector<f64>; 3])>,
    /// d/dt of the measured torque.
    pub(super) measured_rate: DVector<f64>,
    /// The model's Coulomb friction level per joint.
    pub(super) coulomb_levels: Vec<f64>,
    /// The longest sample period of the raw recordings, s.
    pub(super) sample_period: f64,
    /// Per Stribeck velocity of `search::stribeck_velocities` the fitted
    /// Stribeck column (moving sign), also the scored one (the reversal
    /// stage scores what the physics explains); empty at the motion stage.
    pub(super) stribeck: Vec<DVector<f64>>,
    /// Per joint the speed below which it counts as at rest (the largest
    /// over the recordings), rad/s.
    pub(super) rest: Vec<f64>,
    /// Per joint the cycles of the model's own ripple, if it has one.
    pub(super) modelled_ripple: Vec<Option<f64>>,
    /// Per joint the ripple's cycles when they are given (the reversal
    /// stage takes the motion stage's choice): no harmonic search then.
    pub(super) ripple_given: Option<Vec<Option<f64>>>,
    /// The only candidates built, by kind, joint and link (`None`: all):
    /// the reversal stage refits a few, and every candidate's columns at
    /// its rate would be most of its memory.
    pub(super) only: Option<Vec<Place>>,
}

/// A candidate's kind, joint and link.
pub(super) type Place = (Kind, Option<usize>, Option<usize>);

/// Where `candidate` is.
pub(super) fn place(candidate: &Candidate) -> Place {
    let link = candidate.link.as_ref().map(|(k, _)| *k);
    (candidate.kind, candidate.joint, link)
}

/// Every candidate effect: per joint viscous, Coulomb and direction-dependent
/// (asymmetric: column 1 while moving, 0 at rest) friction,
/// armature, a torque offset, a spring (columns q and 1: stiffness k and
/// -k * rest) and a torque scale (the logged torque a scaled copy s tau of
/// the applied one: the residual holds (s - 1) of the torque, column the
/// model's torque; the measured torque would hold the residual itself and
/// "explain" any of it); for all joints at once a torque-state delay
/// (column: minus the measured torque's rate, the first-order effect of
/// logging the torque late; a signal's rate is uncorrelated with it, so the
/// measured rate carries every effect the logged torque holds without
/// regressing the residual on itself) and a tilted base; per link a
/// payload (the last) or an inertial error: of its mass and COM, or of the
/// whole body (`super::whole`).
pub(super) fn candidates(data: &Stacked, columns: Columns, links: &[Link]) -> Vec<Candidate> {
    let n = data.dof;
    let Columns {
        own: [qd, sign, qdd, ones, angle],
        coulomb_applied,
        mut inertial,
        tilt,
        measured_rate,
        coulomb_levels,
        sample_period,
        stribeck,
        rest,
        modelled_ripple,
        ripple_given,
        only,
    } = columns;
    let wanted = |place: Place| only.as_ref().is_none_or(|o| o.contains(&place));
    let model_torque = &data.measured - &data.residual;
    let own = |j: usize, f: &dyn Fn(usize) -> f64| {
        DVector::from_fn(
            data.residual.len(),
            |r, _| if r % n == j { f(r) } else { 0.0 },
        )
    };
    // A link's columns not built (the reversal stage's unnamed links) are
    // empty.
    let linear: Vec<&DVector<f64>> = [&qd, &sign, &qdd, &ones, &angle, &model_torque]
        .into_iter()
        .chain(inertial.iter().filter(|c| !c.is_empty()))
        .chain(tilt.iter().flat_map(|(_, columns)| columns))
        .collect();
    let joints: Vec<usize> = (0..n).collect();
    let searched = map_in_order(&joints, |&j| {
        let at = |kind: Kind| wanted((kind, Some(j), None));
        // Built only for a search that runs: one joint's rows of every
        // linear column.
        let nuisance = std::cell::OnceCell::new();
        let nuisance = || nuisance.get_or_init(|| search::Nuisance::new(data, j, &linear));
        let at_rest = rest.get(j).copied().unwrap_or(0.0);
        let stribeck = match at(Kind::StribeckFriction) {
            true => search::stribeck_velocity(nuisance(), at_rest, data.levers[j], &stribeck),
            false => None,
        };
        let modelled = modelled_ripple.get(j).copied().flatten();
        let given = ripple_given.as_ref().map(|g| g.get(j).copied().flatten());
        let ripple = match given.unwrap_or(modelled).or(modelled) {
            _ if !at(Kind::TorqueRipple) => None,
            // A ripple the model has is refit at its harmonic (a correction
            // of its amplitudes; a description holds one harmonic per
            // joint). No search: the nuisance's model-torque column holds
            // the modelled ripple, so the search could not see that
            // harmonic, and an amplitude 4 times the model's went unnamed.
            Some(cycles) => Some((cycles, 1)),
            None if given.is_some() => None,
            None => search::ripple_cycles(data, j, &angle, nuisance()),
        };
        Searched { stribeck, ripple }
    });
    let mut list = Vec::new();
    for j in 0..n {
        let one = |kind, name, f: &dyn Fn(usize) -> f64| on_joint(kind, j, name, own(j, f));
        let at = |kind: Kind| wanted((kind, Some(j), None));
        let mut add = |kind: Kind, build: &dyn Fn() -> Candidate| {
            if at(kind) {
                list.push(build());
            }
        };
        add(Kind::ViscousFriction, &|| {
            one(Kind::ViscousFriction, "coefficient", &|r| qd[r])
        });
        add(Kind::CoulombFriction, &|| Candidate {
            applied: Some(own(j, &|r| coulomb_applied[r])),
            ..one(Kind::CoulombFriction, "level", &|r| sign[r])
        });
        add(Kind::CoulombAsymmetry, &|| Candidate {
            applied: Some(own(j, &|r| coulomb_applied[r] * coulomb_applied[r])),
            shape: Shape::Asymmetry {
                modelled_coulomb: coulomb_levels.get(j).copied().unwrap_or(0.0),
            },
            ..one(Kind::CoulombAsymmetry, "asymmetry", &|r| sign[r] * sign[r])
        });
        add(Kind::Armature, &|| {
            one(Kind::Armature, "inertia", &|r| qdd[r])
        });
        add(Kind::TorqueOffset, &|| {
            one(Kind::TorqueOffset, "offset", &|r| ones[r])
        });
        add(Kind::TorqueScale, &|| {
            one(Kind::TorqueScale, "scale_error", &|r| model_torque[r])
        });
        add(Kind::JointSpring, &|| Candidate {
            names: vec!["stiffness", "constant"],
            columns: vec![own(j, &|r| angle[r]), own(j, &|r| ones[r])],
            ..one(Kind::JointSpring, "", &|_| 0.0)
        });
        let Searched {
            stribeck: found,
            ripple,
        } = searched[j];
        if let Some((k, velocity, searched)) = found {
            // Scored as fitted (see `Columns::stribeck`).
            let fitted = &stribeck[k];
            // The searched velocities are the grid's fastest `searched`.
            let lowest = stribeck.len() - searched;
            let neighbours = [k.checked_sub(1).filter(|&n| n >= lowest), Some(k + 1)]
                .into_iter()
                .flatten()
                .filter_map(|n| stribeck.get(n))
                .map(|column| own(j, &|r| column[r]))
                .collect();
            list.push(Candidate {
                applied: Some(own(j, &|r| fitted[r])),
                settings: vec![("velocity", velocity)],
                searched,
                neighbours,
                ..one(Kind::StribeckFriction, "excess", &|r| fitted[r])
            });
        }
        if let Some((cycles, searched)) = ripple {
            list.push(Candidate {
                names: vec!["sin", "cos"],
                columns: vec![
                    own(j, &|r| (cycles * angle[r]).sin()),
                    own(j, &|r| (cycles * angle[r]).cos()),
                ],
                settings: vec![("cycles", cycles)],
                searched,
                ..one(Kind::TorqueRipple, "", &|_| 0.0)
            });
        }
    }
    let whole = |kind, names: Vec<&'static str>, columns| Candidate {
        kind,
        joint: None,
        link: None,
        modelled: [0.0; 10],
        extent: f64::INFINITY,
        names,
        columns,
        applied: None,
        shape: Shape::Linear,
        settings: Vec::new(),
        searched: 1,
        neighbours: Vec::new(),
    };
    if wanted((Kind::TorqueDelay, None, None)) {
        list.push(Candidate {
            shape: Shape::Delay { sample_period },
            ..whole(Kind::TorqueDelay, vec!["delay"], vec![-measured_rate])
        });
    }
    if let Some((shape, columns)) = tilt.filter(|_| wanted((Kind::GravityDirection, None, None))) {
        list.push(Candidate {
            shape,
            ..whole(
                Kind::GravityDirection,
                vec!["across_1", "across_2"],
                columns.to_vec(),
            )
        });
    }
    // The reversal stage builds the links' columns only when a link effect
    // was named.
    let links = if inertial.is_empty() { &[] } else { links };
    for (k, link) in links.iter().enumerate().rev() {
        let columns = without_rounding(inertial.drain(10 * k..).collect());
        if k + 1 == n && wanted((Kind::Payload, None, Some(k))) {
            list.push(payload_candidate(k, link, columns.clone()));
        }
        if wanted((Kind::InertialError, None, Some(k))) {
            list.extend(whole_candidate(k, link, &columns));
            list.push(link_candidate(k, link, columns));
        }
    }
    list
}

/// A link's ten columns with those at rounding level (under [`ROUNDING`]
/// of the largest's norm) set to exact zeros: a parameter the joints cannot see
/// (the Panda's link 2 along its own axis), which a compiled model computes
/// as zero and the same description read at run time as 5e-16 beside 1e2.
/// Fits scale every column to unit size, and such a column became a random
/// direction, another for each way of computing the model.
fn without_rounding(mut columns: Vec<DVector<f64>>) -> Vec<DVector<f64>> {
    let largest = columns.iter().map(|c| c.norm()).fold(0.0, f64::max);
    for column in columns.iter_mut() {
        if column.norm() <= ROUNDING * largest {
            column.fill(0.0);
        }
    }
    columns
}

/// What a joint's searches chose (each independent of the other joints',
/// so they run on the machine's cores): the Stribeck velocity (index into
/// the grid, value, velocities searched) and the ripple's harmonic (cycles
/// per revolution, shapes searched).
#[derive(Clone, Copy)]
struct Searched {
    stribeck: Option<(usize, f64, usize)>,
    ripple: Option<(f64, usize)>,
}

/// The whole-body inertial error of link `k`: its ten columns replaced by
/// the combinations the data determine. `None` when they determine none.
fn whole_candidate(k: usize, link: &Link, columns: &[DVector<f64>]) -> Option<Candidate> {
    let gram = whole::gram_of(columns);
    let (basis, _) = whole::combinations(&gram, whole::WHOLE_COLLINEAR, 1e-9)?;
    if basis.ncols() == 0 {
        return None;
    }
    let combined = whole::combine(columns, &basis);
    Some(Candidate {
        kind: Kind::InertialError,
        joint: None,
        link: Some((k, link.name.clone())),
        modelled: link.parameters,
        extent: link.extent,
        names: whole::COMBINATIONS[..basis.ncols()].to_vec(),
        columns: combined,
        applied: None,
        shape: Shape::Whole { basis, gram },
        settings: Vec::new(),
        searched: 1,
        neighbours: Vec::new(),
    })
}

/// A payload on the last link: a point mass added to it (mass and COM).
pub(super) fn payload_candidate(k: usize, link: &Link, columns: Vec<DVector<f64>>) -> Candidate {
    Candidate {
        kind: Kind::Payload,
        shape: Shape::Body {
            offset: [0.0; 10],
            base_mass: 0.0,
            base_moment: Vector3::zeros(),
            own_inertia: false,
            held_com: None,
        },
        ..link_candidate(k, link, columns)
    }
}

/// An inertial error of any link: its mass and COM moved, its inertia
/// about the COM as modelled. On the last link it competes with a payload
/// (the same ten columns; only the second moments tell them apart).
fn link_candidate(k: usize, link: &Link, columns: Vec<DVector<f64>>) -> Candidate {
    let (mass, moment) = (
        link.parameters[0],
        Vector3::new(link.parameters[1], link.parameters[2], link.parameters[3]),
    );
    let com = if mass > 0.0 {
        moment / mass
    } else {
        Vector3::zeros()
    };
    Candidate {
        kind: Kind::InertialError,
        joint: None,
        link: Some((k, link.name.clone())),
        modelled: link.parameters,
        extent: link.extent,
        names: vec!["mass", "cx", "cy", "cz"],
        columns,
        applied: None,
        shape: Shape::Body {
            offset: point_mass(-mass, &com),
            base_mass: mass,
            base_moment: moment,
            own_inertia: false,
            held_com: None,
        },
        settings: Vec::new(),
        searched: 1,
        neighbours: Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A link's column at rounding level becomes an exact zero; the others
    /// are kept bit for bit.
    #[test]
    fn a_link_column_at_rounding_level_is_zero() {
        let physical = DVector::from_fn(50, |i, _| (i as f64 * 0.1).cos() * 1e2);
        let rounding = DVector::from_fn(50, |i, _| (i as f64 * 0.7).sin() * 1e-16);
        let kept = without_rounding(vec![physical.clone(), rounding, DVector::zeros(50)]);
        assert_eq!(kept[0], physical);
        assert!(kept[1].iter().all(|x| *x == 0.0));
        assert!(kept[2].iter().all(|x| *x == 0.0));
    }
}
