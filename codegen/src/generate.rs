//! From a validated description to the text of its generated Rust file.
//!
//! `generate` is pure: it returns the file contents. The structured programs
//! (`recursive.rs`) over the description's named constants are emitted;
//! for chains of up to `LAGRANGIAN_MAX_DOF` joints, Symbolica's expanded
//! Lagrangian (`lagrangian.rs`) is derived too and the programs must agree
//! with it (`crosscheck.rs`) or generation fails.

use std::time::Instant;

use proc_macro2::TokenStream;
use quote::quote;

use crate::composed;
use crate::crosscheck;
use crate::description::{Description, JointKind};
use crate::emit::{Argument, Function, Input, Shape};
use crate::emit_lanes::{Forward, LaneFunction};
use crate::fingerprint::{FINGERPRINT_PREFIX, fingerprint, generator_version};
use crate::lagrangian;
use crate::listing;
use crate::program::NodeId;
use crate::recursive::{self, Traced};
use crate::support;

/// Chains up to this many joints are also derived by the expanded
/// Lagrangian and cross-checked. Beyond it the expansion swells (terms grow
/// roughly tenfold per joint) and the recursive form is checked by tests.
pub const LAGRANGIAN_MAX_DOF: usize = 4;

/// A generated model file and what it cost.
#[derive(Debug, Clone)]
pub struct Generated {
    pub name: String,
    pub code: String,
    /// Run-time arithmetic operations per generated function, in emission order.
    pub operations: Vec<Cost>,
    pub seconds: f64,
}

/// What one generated function costs at run time.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Cost {
    pub function: String,
    pub operations: usize,
}

impl std::fmt::Display for Cost {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} {}", self.function, self.operations)
    }
}

/// Generates the Rust source of a model. `source_label` names the TOML file
/// in the header (a path relative to the crate, for stable output).
pub fn generate(
    description: &Description,
    toml_source: &str,
    source_label: &str,
) -> Result<Generated, String> {
    let start = Instant::now();
    let chain = description.chain().clone();
    let tool = description.tool_frame();
    let traced = recursive::trace_with_tool(&chain, tool.as_ref());
    // Coupled chains are checked by the tests against the numeric
    // Newton-Euler (the expanded Lagrangian has no coupling).
    let checked = chain.bodies.len() <= LAGRANGIAN_MAX_DOF && !chain.is_coupled();
    if checked {
        let derived = chain.clone();
        let rigid = crate::session::run(move || lagrangian::derive(&derived))??;
        crosscheck::against_lagrangian(&traced, &rigid, &chain)?;
    }
    let dof = chain.dof();
    let mut inputs = lagrangian::inputs(dof);
    for b in recursive::coupled_bodies(&chain) {
        let (d, _, _) = chain.driver(b);
        inputs.extend([Input::MimicSin(b, d), Input::MimicCos(b, d)]);
    }
    let mut operations = Vec::new();
    let mut items = Vec::new();
    for spec in functions(&traced, dof) {
        // The derivatives run as a two-lane program (`lanes.rs`): the primal
        // values its coefficients read, then the lane operations.
        let lanes = matches!(
            spec.name,
            "tau_derivatives" | "forward_dynamics_derivatives"
        )
        .then_some(&traced.tau_lanes);
        let through = (spec.name == "forward_dynamics_derivatives").then_some(Forward {
            factor: &traced.mass_factor,
            bias: &traced.bias,
        });
        let count = match lanes {
            Some(program) => {
                let mut primal = program.primal_uses();
                if let Some(forward) = through {
                    primal.extend(forward.factor.iter().chain(forward.bias));
                }
                traced.dag.negation_aware_count(&primal) + program.operation_count()
            }
            None => traced.dag.negation_aware_count(&spec.roots),
        };
        operations.push(Cost {
            function: spec.name.to_string(),
            operations: count,
        });
        let function = Function {
            name: spec.name,
            doc: spec.doc,
            arguments: spec.arguments,
            dof,
            inputs: &inputs,
            dag: &traced.dag,
            roots: &spec.roots,
            shape: spec.shape,
        };
        items.push(match lanes {
            Some(program) => LaneFunction {
                primal: function,
                program,
                pairs: &traced.pairs,
                through,
            }
            .tokens(),
            None => function.tokens(),
        });
    }
    let constants = listing::constants(description, &traced, &inputs);
    let composed = composed::items();
    let support = support::items();
    let kinematic_support = composed::support();
    let file: TokenStream = quote! {
        pub use generated::*;
        /// Every generated item, re-exported above. Unused ones are no
        /// warning: a program that includes this file and calls one
        /// function builds quietly.
        #[allow(dead_code)]
        mod generated {
            #constants
            #(#items)*
            #composed
            #kinematic_support
            #support
        }
    };
    let syntax = syn::parse2::<syn::File>(file)
        .map_err(|e| format!("generated code does not parse: {e}"))?;
    let body = prettyplease::unparse(&syntax);
    let header = header(description, toml_source, source_label, &operations, checked);
    Ok(Generated {
        name: description.name.clone(),
        code: format!("{header}{body}"),
        operations,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// The file's opening comment. Names from the description appear escaped
/// (Rust string syntax), so no character of theirs can end the comment.
fn header(
    description: &Description,
    toml_source: &str,
    source_label: &str,
    operations: &[Cost],
    checked: bool,
) -> String {
    let ops: Vec<String> = operations.iter().map(Cost::to_string).collect();
    let joints: Vec<String> = description
        .chain()
        .bodies
        .iter()
        .map(|b| format!("{:?}", b.joint))
        .collect();
    let sliding: Vec<String> = description
        .chain()
        .bodies
        .iter()
        .filter(|b| b.kind == JointKind::Prismatic)
        .map(|b| format!("{:?}", b.joint))
        .collect();
    let units = if sliding.is_empty() {
        String::new()
    } else {
        format!(
            "// Prismatic joints ({}): q in m, qd in m/s, qdd in m/s^2, tau in N.\n",
            sliding.join(", ")
        )
    };
    let check = if checked {
        "equal to Symbolica's expanded Lagrangian at generation (tau and regressor)"
    } else {
        "checked against a numeric Newton-Euler by the tests"
    };
    format!(
        "// This file is @generated by sdnn-codegen {version} from {label:?}. Do not edit.\n\
         {FINGERPRINT_PREFIX}{fp} (sha256 of the TOML text and the generator)\n\
         // Refresh: `cargo build --release` regenerates it when the TOML or the generator\n\
         // changes (and only then runs Symbolica).\n\
         // Robot: {robot:?}; {dof} moving joints ({joints}).\n\
         // Run-time arithmetic operations: {ops}; {check}.\n\
         // tau = M(q) qdd + c(q, qd) + g(q) + effects(qd); M includes armature.\n{units}\n",
        version = generator_version(),
        label = source_label,
        fp = fingerprint(toml_source),
        robot = description.robot,
        dof = description.dof(),
        joints = joints.join(", "),
        ops = ops.join(", "),
    )
}

/// One function to emit.
struct Spec {
    name: &'static str,
    doc: &'static str,
    arguments: &'static [Argument],
    shape: Shape,
    roots: Vec<NodeId>,
}

fn functions(traced: &Traced, n: usize) -> Vec<Spec> {
    let width = traced.regressor.len() / n;
    const Q: &[Argument] = &[Argument::Q];
    const Q_QD: &[Argument] = &[Argument::Q, Argument::Qd];
    const ALL: &[Argument] = &[Argument::Q, Argument::Qd, Argument::Qdd];
    vec![
        Spec {
            name: "tau",
            doc: " Joint torques tau = M(q) qdd + c(q, qd) + g(q) + effects(qd), N m.",
            arguments: ALL,
            shape: Shape::Vector(n),
            roots: traced.tau.clone(),
        },
        Spec {
            name: "mass_matrix",
            doc: " Joint-space inertia matrix M(q), armature on the diagonal, kg m^2.",
            arguments: Q,
            shape: Shape::Matrix(n, n),
            roots: traced.mass_matrix.clone(),
        },
        Spec {
            name: "gravity",
            doc: " Torque of the position alone g(q): gravity, joint springs and torque ripple, N m.",
            arguments: Q,
            shape: Shape::Vector(n),
            roots: traced.gravity.clone(),
        },
        Spec {
            name: "coriolis",
            doc: " Coriolis and centrifugal torques c(q, qd), N m.",
            arguments: Q_QD,
            shape: Shape::Vector(n),
            roots: traced.coriolis.clone(),
        },
        Spec {
            name: "effects",
            doc: " Joint friction and offset: viscous*qd + coulomb*sign(qd) + coulomb_asymmetry*|sign(qd)| + stribeck*stribeck(qd, stribeck_velocity) + offset, N m.",
            arguments: &[Argument::Qd],
            shape: Shape::Vector(n),
            roots: traced.effects.clone(),
        },
        Spec {
            name: "regressor",
            doc: " Regressor Y(q, qd, qdd) with tau = Y * PARAMETERS (see PARAMETER_NAMES).",
            arguments: ALL,
            shape: Shape::Matrix(n, width),
            roots: traced.regressor.clone(),
        },
        Spec {
            name: "bias",
            doc: " tau at qdd = 0: c(q, qd) + g(q) + effects(qd), N m (forward dynamics solves M qdd = tau - bias).",
            arguments: Q_QD,
            shape: Shape::Vector(n),
            roots: traced.bias.clone(),
        },
        Spec {
            name: "mass_factor",
            doc: " M(q) = L D L^T as one matrix: L (unit lower triangular) below the diagonal, 1/D on it, zeros above (see `solve_factored`).",
            arguments: Q,
            shape: Shape::Matrix(n, n),
            roots: traced.mass_factor.clone(),
        },
        Spec {
            name: "tau_derivatives",
            doc: " Exact (d tau / d q, d tau / d qd) at (q, qd, qdd): row i is tau_i, column j is q_j or qd_j (d tau / d qdd is the mass matrix). d sign(qd) / d qd is taken as 0.",
            arguments: ALL,
            shape: Shape::Pair(n, n),
            roots: [traced.tau_by_q.clone(), traced.tau_by_qd.clone()].concat(),
        },
        Spec {
            name: "forward_dynamics_derivatives",
            doc: " Exact (d qdd / d q, d qdd / d qd) of `forward_dynamics` at (q, qd, tau): row i is qdd_i, column j is q_j or qd_j; d qdd / d tau is M^-1 (`solve_mass`). From tau(q, qd, qdd(q, qd, tau)) = tau: d qdd / d x = -M^-1 d tau / d x at the forward dynamics' qdd, traced with `mass_factor` and `bias` in one pass (they share sines and velocities).",
            arguments: &[Argument::Q, Argument::Qd, Argument::Tau],
            shape: Shape::Pair(n, n),
            roots: Vec::new(),
        },
        Spec {
            name: "link_poses",
            doc: " Every moving link's frame in the base frame (LINK_NAMES order).",
            arguments: Q,
            shape: Shape::Poses(traced.link_poses.len() / 12),
            roots: traced.link_poses.clone(),
        },
        Spec {
            name: "tip_pose",
            doc: " The tip frame (TIP_LINK's) in the base frame.",
            arguments: Q,
            shape: Shape::Pose,
            roots: traced.link_poses[12 * traced.tip..12 * traced.tip + 12].to_vec(),
        },
        Spec {
            name: "tip_jacobian",
            doc: " The tip frame's Jacobian: rows 0-2 the linear velocity of its origin, rows 3-5 its angular velocity, both in base axes (Pinocchio's LOCAL_WORLD_ALIGNED); column j is qd_j.",
            arguments: Q,
            shape: Shape::Matrix(6, n),
            roots: traced.tip_jacobian.clone(),
        },
        Spec {
            name: "tip_pose_and_jacobian",
            doc: " `tip_pose` and `tip_jacobian` in one pass (they share the joints' placements): what a task-space controller needs each cycle.",
            arguments: Q,
            shape: Shape::PoseAndMatrix(6, n),
            roots: [
                traced.link_poses[12 * traced.tip..12 * traced.tip + 12].to_vec(),
                traced.tip_jacobian.clone(),
            ]
            .concat(),
        },
        Spec {
            name: "tip_jacobian_dot_qd",
            doc: " J-dot qd of `tip_jacobian`: the tip origin's acceleration and the tip's angular acceleration at qdd = 0 (no gravity), base axes.",
            arguments: Q_QD,
            shape: Shape::Vector(6),
            roots: traced.tip_jacobian_dot_qd.clone(),
        },
    ]
    .into_iter()
    .chain(tool_functions(traced, n))
    .collect()
}

/// `tool_pose` and `tool_jacobian`, for a description with a tool frame.
fn tool_functions(traced: &Traced, n: usize) -> Vec<Spec> {
    let Some((_, pose, jacobian)) = &traced.tool else {
        return Vec::new();
    };
    vec![
        Spec {
            name: "tool_pose",
            doc: " The tool frame (TOOL_LINK's, fixed to the tip link) in the base frame.",
            arguments: &[Argument::Q],
            shape: Shape::Pose,
            roots: pose.clone(),
        },
        Spec {
            name: "tool_jacobian",
            doc: " The tool frame's Jacobian, as `tip_jacobian` at the tool frame's origin.",
            arguments: &[Argument::Q],
            shape: Shape::Matrix(6, n),
            roots: jacobian.clone(),
        },
    ]
}
