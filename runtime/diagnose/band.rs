//! The band that resolves velocity reversals: a joint's breakaway lasts as
//! long as its speed stays below the Stribeck velocity (tens to a few
//! hundred ms), and the motion band's velocity (low-passed at about three
//! times the motion's bandwidth) passes it too slowly, smearing the
//! breakaway into the Coulomb step. The reversal stage
//! ([`super::reversals`]) builds its dry-friction columns from the raw
//! velocity through the same zero-phase Butterworth at [`BAND_PER_CUTOFF`]
//! times the motion's cut-off.

use nalgebra::DMatrix;

use crate::dynamics::Dynamics;

use super::candidate::{Candidate, Place, place};
use super::kind::Kind;
use crate::preprocess::{Filter, Pipeline, Preprocess, step};
use crate::trajectory::Trajectory;

/// The reversal band's cut-off over the motion stage's: a decade above it,
/// so a breakaway of a tenth of the motion's period is passed.
pub const BAND_PER_CUTOFF: f64 = 10.0;
/// Highest reversal cut-off as a share of the sample rate (the auto
/// preset's bound on any cut-off).
const MAX_CUTOFF_PER_RATE: f64 = 0.2;

/// Which stage a stack is built for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Stage {
    /// The motion band: every kind competes but Stribeck friction.
    Motion,
    /// The reversal band: Stribeck friction is a candidate on every joint.
    Reversals,
}

/// The reversal band's cut-off for a motion cut-off and a sample rate, Hz.
pub fn cutoff(motion_cutoff_hz: f64, sample_rate_hz: f64) -> f64 {
    (BAND_PER_CUTOFF * motion_cutoff_hz)
        .min(MAX_CUTOFF_PER_RATE * sample_rate_hz)
        .max(motion_cutoff_hz)
}

/// A velocity that resolves reversals and each joint's at-rest speed in it.
pub(super) struct Band {
    pub(super) qd: DMatrix<f64>,
    pub(super) rest: Vec<f64>,
}

impl Band {
    /// The states' own velocity.
    pub(super) fn of(traj: &Trajectory, rest: &[f64]) -> Band {
        Band {
            qd: traj.qd().clone(),
            rest: rest.to_vec(),
        }
    }
}

/// The pipeline of the reversal band: the auto preset's filter at the
/// reversal cut-off, decimated to ten times it; `None` for other presets
/// (their filters are not a cut-off to raise: Stribeck friction is then not
/// tried).
pub(super) fn pipeline(motion: &Pipeline) -> Option<Pipeline> {
    let mut choice = motion.choice.clone()?;
    choice.cutoff_hz = cutoff(choice.cutoff_hz, choice.sample_rate_hz);
    choice.decimated_rate_hz =
        (crate::preprocess::auto::RATE_PER_CUTOFF * choice.cutoff_hz).min(choice.sample_rate_hz);
    let settings = Preprocess::identification(&choice, choice.sample_rate_hz);
    Some(Pipeline {
        choice: Some(choice),
        settings,
        ..motion.clone()
    })
}

/// The raw velocity through the same zero-phase Butterworth at the
/// reversal cut-off of `needs` (at the reversal band's own pipeline, the
/// states' velocity), and the at-rest speeds of its noise.
pub(super) fn velocity(
    raw: &Trajectory,
    settings: &Preprocess,
    moving: &[f64],
    needs: &Needs,
) -> anyhow::Result<Band> {
    let dt = step(raw);
    let at = |cutoff_hz: f64| Preprocess {
        filter: Filter::Butterworth { cutoff_hz },
        ..settings.clone()
    };
    let qd = at(needs.band_hz).smooth_columns(raw.qd(), dt)?;
    let mut rest = rest_speeds(raw, &qd, needs.band_hz, moving);
    if needs.motion_hz > 0.0 && needs.motion_hz < needs.band_hz {
        let slow = at(needs.motion_hz).smooth_columns(raw.qd(), dt)?;
        let between = noise_speeds(&qd, &slow, moving);
        // Each bound is high in its own way (see `noise_speeds`).
        for (r, b) in rest.iter_mut().zip(between) {
            *r = r.min(b);
        }
    }
    Ok(Band { qd, rest })
}

/// Each joint's at-rest speed in the reversal band: three deviations of
/// its velocity there from the motion band's (`slow`), at least `moving`.
/// The motion lies within the motion band, so what the reversal band adds
/// is its noise, and a stick-slip's jerks, which raise this bound. The
/// other bound ([`rest_speeds`]) scales the raw velocity's noise as if it
/// were white, which is high where velocities are differentiated from
/// noisy positions (noise rising with frequency): it put an independent
/// Panda's at-rest speed at 0.12 rad/s for a filtered noise near 0.003,
/// hiding breakaways below it. The lower of the two is used.
fn noise_speeds(fast: &DMatrix<f64>, slow: &DMatrix<f64>, moving: &[f64]) -> Vec<f64> {
    let len = fast.nrows().max(1) as f64;
    (0..fast.ncols())
        .map(|j| {
            let sigma = ((fast.column(j) - slow.column(j)).norm_squared() / len).sqrt();
            (3.0 * sigma).max(moving[j])
        })
        .collect()
}

/// The states the reversal band's columns other than the dry-friction ones
/// are computed from, with their preprocessing: the reversal band's own, or
/// the motion band's where the recorded torque, not the arm's acceleration,
/// holds the friction's steps at reversals. Where the torque drives a
/// motion that does not react (a prescribed motion), the acceleration
/// between the two bands is the noise of twice-differentiated positions,
/// and times a heavy joint's inertia it buries a breakaway (an independent
/// Panda's shoulder at 1 kHz: about 2 N m beside a 0.17 N m excess); where
/// the arm's acceleration follows its friction (a breakaway jerks a
/// feedback-controlled arm), the steps are in that acceleration and the
/// motion band's states would hide them.
pub(super) fn states(
    model: &dyn Dynamics,
    raw: &Trajectory,
    settings: &Preprocess,
    needs: &Needs,
) -> anyhow::Result<(Trajectory, Preprocess)> {
    let at_band = settings.states_at_full_rate(raw)?;
    if needs.motion_hz <= 0.0 || !matches!(settings.filter, Filter::Butterworth { .. }) {
        return Ok((at_band, settings.clone()));
    }
    let motion = Preprocess {
        filter: Filter::Butterworth {
            cutoff_hz: needs.motion_hz,
        },
        ..settings.clone()
    };
    let smooth = motion.states_at_full_rate(raw)?;
    let (in_torque, in_motion) = steps(
        model,
        raw,
        (&at_band, &smooth),
        (settings, &motion),
        &needs.tried(),
    )?;
    Ok(match in_torque > in_motion {
        true => (smooth, motion),
        false => (at_band, settings.clone()),
    })
}

/// How much of the friction's steps at reversals (the sign of the
/// velocity at the reversal band, less its motion-band part) the recorded
/// torque holds, and how much the inertia times the acceleration between
/// the two bands holds against them, summed over `joints` at the reversal
/// band's kept samples: with a prescribed motion the first is the dry
/// friction's level times the steps' energy and the second noise, with a
/// motion that reacts the other way round.
fn steps(
    model: &dyn Dynamics,
    raw: &Trajectory,
    (at_band, smooth): (&Trajectory, &Trajectory),
    (band, motion): (&Preprocess, &Preprocess),
    joints: &[usize],
) -> anyhow::Result<(f64, f64)> {
    let dt = step(raw);
    let sign = at_band.qd().map(f64::signum);
    let sign_steps = &sign - motion.smooth_columns(&sign, dt)?;
    let torque_steps = raw.tau() - motion.smooth_columns(raw.tau(), dt)?;
    let clear = Pipeline::clear_of_transients(motion, raw.len(), dt);
    let samples = Pipeline::kept_samples(band, raw.len(), dt);
    let row = |m: &DMatrix<f64>, s: usize| -> Vec<f64> { m.row(s).iter().copied().collect() };
    let accel = |t: &Trajectory| {
        t.qdd()
            .cloned()
            .ok_or_else(|| anyhow::anyhow!("preprocessed states have no accelerations"))
    };
    let (fast, slow) = (accel(at_band)?, accel(smooth)?);
    let (mut in_torque, mut in_motion) = (0.0, 0.0);
    for s in samples.into_iter().filter(|s| clear.contains(s)) {
        let (q, qd) = (row(smooth.q(), s), row(smooth.qd(), s));
        // The inertia times the acceleration between the bands: the
        // model's torque is linear in the acceleration.
        let inertial = model.tau(&q, &qd, &row(&fast, s))? - model.tau(&q, &qd, &row(&slow, s))?;
        for &j in joints {
            in_torque += torque_steps[(s, j)] * sign_steps[(s, j)];
            in_motion -= inertial[j] * sign_steps[(s, j)];
        }
    }
    Ok((in_torque, in_motion))
}

/// What the reversal stage needs of the motion stage's choices: each
/// joint's ripple harmonic (not searched again), the links whose columns
/// are needed and whether the tilt's are (the stack builds only those).
pub(super) struct Needs {
    pub(super) ripple: Vec<Option<f64>>,
    /// The links of the named link effects (0-based, ascending).
    pub(super) links: Vec<usize>,
    pub(super) tilt: bool,
    /// The reversal band's cut-off, Hz.
    pub(super) band_hz: f64,
    /// The motion stage's cut-off, Hz: the states every column but the
    /// dry-friction ones is computed from (see [`super::reversals`]).
    pub(super) motion_hz: f64,
    /// The candidates the stage refits (those named) and tries (Stribeck
    /// friction on the joints tried): the only ones its stack builds.
    pub(super) places: Vec<Place>,
}

impl Needs {
    /// The joints whose Stribeck friction is tried.
    fn tried(&self) -> Vec<usize> {
        let stribeck = self.places.iter().filter(|p| p.0 == Kind::StribeckFriction);
        stribeck.filter_map(|p| p.1).collect()
    }

    /// What `selected` of `candidates` (the motion stage's) needs, with
    /// Stribeck friction tried on `joints`.
    pub(super) fn of(
        (candidates, selected): (&[Candidate], &[usize]),
        dof: usize,
        joints: &[usize],
        (motion, band): (&Pipeline, &Pipeline),
    ) -> Needs {
        let named = || selected.iter().map(|&c| &candidates[c]);
        let stribeck = joints
            .iter()
            .map(|&j| (Kind::StribeckFriction, Some(j), None));
        Needs {
            ripple: (0..dof)
                .map(|j| {
                    named().find_map(|c| {
                        (c.kind == Kind::TorqueRipple && c.joint == Some(j))
                            .then(|| c.settings[0].1)
                    })
                })
                .collect(),
            links: (0..dof)
                .filter(|&k| named().any(|c| c.link.as_ref().is_some_and(|l| l.0 == k)))
                .collect(),
            tilt: named().any(|c| c.kind == Kind::GravityDirection),
            band_hz: band.choice.as_ref().map_or(0.0, |c| c.cutoff_hz),
            motion_hz: motion.choice.as_ref().map_or(0.0, |c| c.cutoff_hz),
            places: named().map(place).chain(stribeck).collect(),
        }
    }
}

/// Each joint's at-rest speed for the velocity `filtered` (low-passed at
/// `cutoff_hz`), as `data::rest_velocities` gives it for the states: three
/// noise deviations (raw minus filtered, scaled by the share of the band
/// the filter passes), at least `moving`.
pub(super) fn rest_speeds(
    raw: &Trajectory,
    filtered: &DMatrix<f64>,
    cutoff_hz: f64,
    moving: &[f64],
) -> Vec<f64> {
    let passed = (2.0 * cutoff_hz * step(raw)).min(1.0).sqrt();
    (0..raw.dof())
        .map(|j| {
            let difference = raw.qd().column(j) - filtered.column(j);
            let sigma = (difference.norm_squared() / raw.len().max(1) as f64).sqrt();
            (3.0 * sigma * passed).max(moving[j])
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use nalgebra::DMatrix;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::*;

    /// 20 s at 1 kHz of a slow sine whose velocity is differentiated from
    /// positions noisy to 1e-4 rad: the reversal band's at-rest speed is
    /// within 30% of three deviations of its velocity noise (measured
    /// against the noise-free velocity through the same filter; the
    /// filter's ends and the motion band's share of the noise differ), and
    /// the raw noise scaled as if it were white is about six times it.
    #[test]
    fn the_rest_speed_of_differentiated_positions_is_their_filtered_noise() {
        let (len, dt): (usize, f64) = (20_000, 1e-3);
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        // Box-Muller: a standard normal draw.
        let mut normal = move || {
            let u: f64 = rng.random::<f64>().max(1e-300);
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * rng.random::<f64>()).cos()
        };
        let t: Vec<f64> = (0..len).map(|k| k as f64 * dt).collect();
        let clean = |t: f64| (std::f64::consts::TAU * 0.3 * t).sin();
        let q: Vec<f64> = t.iter().map(|&t| clean(t) + 1e-4 * normal()).collect();
        let differentiate = |x: &[f64]| -> Vec<f64> {
            (0..len)
                .map(|k| {
                    let (a, b) = (k.saturating_sub(1), (k + 1).min(len - 1));
                    (x[b] - x[a]) / ((b - a) as f64 * dt)
                })
                .collect()
        };
        let column = |v: Vec<f64>| DMatrix::from_column_slice(len, 1, &v);
        let qd = column(differentiate(&q));
        let raw = Trajectory::new(t.clone(), column(q), qd, None, DMatrix::zeros(len, 1)).unwrap();
        let needs = Needs {
            ripple: vec![None],
            links: vec![],
            tilt: false,
            band_hz: 30.0,
            motion_hz: 3.0,
            places: vec![],
        };
        let band = velocity(&raw, &Preprocess::default(), &[0.0], &needs).unwrap();
        let exact: Vec<f64> = t.iter().map(|&t| clean(t)).collect();
        let filter = Preprocess {
            filter: Filter::Butterworth { cutoff_hz: 30.0 },
            ..Preprocess::default()
        };
        let noise_free = filter
            .smooth_columns(&column(differentiate(&exact)), dt)
            .unwrap();
        let sigma = (&band.qd - noise_free).norm() / (len as f64).sqrt();
        let white = rest_speeds(&raw, &band.qd, 30.0, &[0.0])[0];
        assert!(
            (band.rest[0] / (3.0 * sigma) - 1.0).abs() < 0.3,
            "{} for 3 x {sigma}",
            band.rest[0]
        );
        assert!(white > 4.0 * band.rest[0], "{white} vs {}", band.rest[0]);
    }
}
