//! The report: what the diagnosis found, as `sdnn diagnose --format json`
//! prints it.

use serde::Serialize;

use super::identify::Identifiability;
use super::kind::Kind;
use super::sanity::Sanity;
use super::stacked::Layout;
use super::unconstrained::Unconstrained;
use super::unexplained::Unexplained;
use crate::preprocess::Pipeline;

/// A named missing effect with its fitted parameters.
#[derive(Debug, Clone, Serialize)]
pub struct Effect {
    pub kind: Kind,
    /// 1-based joint, or `None` for a payload or an inertial error.
    pub joint: Option<usize>,
    /// The link (its name in the description) of a payload or inertial error.
    pub link: Option<String>,
    pub parameters: serde_json::Map<String, serde_json::Value>,
    pub ci95: serde_json::Map<String, serde_json::Value>,
    /// Held-out MSE (N m^2) this effect removes from its joint (a link
    /// effect: summed over the joints), counted in selection order.
    pub heldout_mse_removed: f64,
    /// That drop as a fraction of the joint's (a link effect: all joints')
    /// held-out MSE before the diagnosis.
    pub heldout_share: f64,
    /// A supported (unnamed) effect's cut against what the named effects
    /// leave: the joint it helps most, whose held-out MSE it lowers by
    /// `heldout_mse_removed`; `None` for named effects.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub heldout_left: Option<HeldoutLeft>,
    /// Other effects (as "kind on joint N" / "kind of link N (`name`)")
    /// that explain the same structure almost as well on held-out data: the
    /// data barely tell them from this one (a note says what would).
    pub ambiguous_with: Vec<String>,
    /// A payload's or link's ten inertial parameters fitted freely, when
    /// that fit differs from the physical one (not realizable, or clearly
    /// better on held-out data); `None` otherwise.
    pub unconstrained: Option<Unconstrained>,
    /// Where the model already has this effect on the joint: its values of
    /// the parameters, which `parameters` corrects (they hold what is
    /// missing), and `total`, the two together: what `--apply` writes.
    #[serde(skip_serializing_if = "serde_json::Map::is_empty")]
    pub modelled: serde_json::Map<String, serde_json::Value>,
    #[serde(skip_serializing_if = "serde_json::Map::is_empty")]
    pub total: serde_json::Map<String, serde_json::Value>,
}

impl Effect {
    /// An effect with these values, nothing yet counted for it (held-out
    /// removal, runners-up, the model's values).
    pub(super) fn new(
        kind: Kind,
        (joint, link): (Option<usize>, Option<String>),
        parameters: serde_json::Map<String, serde_json::Value>,
        ci95: serde_json::Map<String, serde_json::Value>,
    ) -> Effect {
        Effect {
            kind,
            joint,
            link,
            parameters,
            ci95,
            heldout_mse_removed: 0.0,
            heldout_share: 0.0,
            heldout_left: None,
            ambiguous_with: Vec::new(),
            unconstrained: None,
            modelled: serde_json::Map::new(),
            total: serde_json::Map::new(),
        }
    }
}

/// The held-out MSE a supported effect would cut, against what is left.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct HeldoutLeft {
    /// 1-based joint it helps most.
    pub joint: usize,
    /// That joint's held-out MSE after the named effects (N m^2), scored
    /// as selection scores (Coulomb friction zero at rest), so it can
    /// exceed the report's `mse_after`.
    pub mse: f64,
    /// `heldout_mse_removed` as a fraction of `mse`.
    pub share: f64,
}

/// The diagnosis report (`sdnn diagnose --format json`).
#[derive(Debug, Clone, Serialize)]
pub struct Diagnosis {
    pub model: String,
    /// The preprocessing the recordings went through.
    pub preprocessing: Pipeline,
    /// How they were cut into cross-validation segments.
    pub layout: Layout,
    /// Decimated samples diagnosed.
    pub samples: usize,
    /// Per joint "revolute" (torques in N m, angles in rad) or "prismatic"
    /// (forces in N, positions in m).
    pub joint_kinds: Vec<String>,
    /// Residual RMS per joint (N m) and its share of the measured torque RMS.
    pub residual_rms: Vec<f64>,
    pub residual_share: Vec<f64>,
    /// Correlation of each joint's residual with its velocity, its velocity
    /// sign, its acceleration and a constant: where the residual concentrates.
    pub regimes: Vec<Regimes>,
    /// Held-out (leave-one-trajectory-out) torque MSE per joint, N m^2.
    pub mse_before: Vec<f64>,
    pub mse_after: Vec<f64>,
    /// The same with Coulomb friction zero while a joint is at rest (its
    /// speed below the velocity noise), as fitted: where a joint sticks, the
    /// friction is static and the applied model's sign(qd) follows noise, so
    /// this is what the effects explain physically.
    pub mse_after_fitted: Vec<f64>,
    pub effects: Vec<Effect>,
    /// Effects the data support that were not named (adding one to the
    /// named effects lowers some joint's held-out MSE by at least the gain
    /// floor, its parameters are identifiable beside them and its fit is
    /// physical, but it is not significant, removes less than the minimum
    /// gain, or was dropped), with their values and 95% intervals fitted
    /// with the named effects; most held-out error removed first.
    /// `ambiguous_with`, `unconstrained`, `modelled` and `total` are unset.
    pub supported: Vec<Effect>,
    /// Structure left in the residual that no candidate explains.
    pub unexplained: Vec<Unexplained>,
    /// How well these data separate the named effects' parameters.
    pub identifiability: Identifiability,
    /// Structure the data supports but no physical effect explains, e.g. a
    /// negative armature (the model's inertia about a joint is too high).
    pub notes: Vec<String>,
    /// What the sanity gate measured on these recordings (they passed it).
    pub sanity: Sanity,
    /// Every sample's residual before and after the named effects (fitted
    /// to all data), for plots; not part of the JSON report.
    #[serde(skip)]
    pub residuals: ResidualSamples,
}

/// Per sample and joint (row `sample * dof + joint`): the joint's velocity
/// and acceleration and its residual with the nominal model and with the
/// named effects added.
#[derive(Debug, Clone, Default)]
pub struct ResidualSamples {
    pub dof: usize,
    pub qd: Vec<f64>,
    pub qdd: Vec<f64>,
    pub before: Vec<f64>,
    pub after: Vec<f64>,
}

/// Residual structure of one joint.
#[derive(Debug, Clone, Serialize)]
pub struct Regimes {
    pub velocity: f64,
    pub velocity_sign: f64,
    pub acceleration: f64,
    /// Correlation with the model's gravity torque of the joint (a
    /// configuration-dependent error: mass, COM, payload).
    pub gravity_load: f64,
    pub mean: f64,
}
