//! What the selection accepts: its thresholds and the arm's size they
//! are judged against.

use crate::dynamics::Dynamics;

/// Selection settings.
#[derive(Debug, Clone, Copy)]
pub struct Settings {
    /// Minimum relative drop of the cross-validated MSE to accept an effect.
    pub min_gain: f64,
    /// Minimum |t| statistic of every parameter of an accepted effect.
    pub min_t: f64,
    /// The arm's size (m): a payload's centre of mass must lie within it
    /// (see [`reach`]); infinite accepts any.
    pub reach: f64,
    /// A COM component whose 95% confidence half-width exceeds this fraction
    /// of the arm's size ([`reach`] of the model; 1 m when the model has no
    /// description) gets a note that the data barely determine it.
    pub com_resolution: f64,
    /// Cross-validation segments per recording; `None` chooses them (see
    /// [`super::data::segment_counts`]).
    pub segments: Option<usize>,
    /// Whether Stribeck friction is tried on every joint. By default it is
    /// tried, at the reversal stage (docs/diagnosis.md), on the joints with
    /// dry friction named or modelled: a breakaway exceeds a sliding level.
    pub stribeck: bool,
    /// Whether the sanity gate runs first (see [`super::sanity`]): on by
    /// default; off only for recordings a person has checked by hand.
    pub sanity_gate: bool,
}

/// Shortest total duration diagnosed, s: two cross-validation segments of
/// 2 s (shorter data cannot tell an effect from chance).
pub const MIN_SECONDS: f64 = 4.0;

/// Relative eigenvalue of a candidate's unit-diagonal information matrix
/// below which its parameters are taken as not identifiable.
pub const COLLINEAR: f64 = 1e-6;

/// The arm's size: the summed joint offsets of the chain, base to tip.
pub fn reach(model: &dyn Dynamics) -> f64 {
    crate::dynamics::parsed_description(model).map_or(f64::INFINITY, |d| {
        d.chain().bodies.iter().map(|b| b.translation.norm()).sum()
    })
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            min_gain: 0.10,
            min_t: 3.0,
            reach: f64::INFINITY,
            com_resolution: 0.05,
            segments: None,
            stribeck: false,
            sanity_gate: true,
        }
    }
}
