//! The top of a generated file: sizes, names, and every number of the
//! description as a named constant, then the derived constants (formulas
//! over those names) and the regressor's parameter vector by name.

use std::collections::HashMap;

use proc_macro2::{Literal, TokenStream};
use quote::{format_ident, quote};

use crate::description::Description;
use crate::emit::{Input, Printer, int, literal};
use crate::recursive::{Definition, Traced};
use crate::schema::{EFFECT_CONSTANTS, EFFECT_NAMES, PARAMETERS_PER_JOINT};

/// Names of the ten inertial parameters of body i, Pinocchio's order (the
/// `PARAMETER_NAMES` stems).
pub const INERTIAL_NAMES: [&str; 10] = [
    "m", "mx", "my", "mz", "ixx", "ixy", "iyy", "ixz", "iyz", "izz",
];
/// The Rust constants holding those parameters, with `{i}` the 1-based index.
const INERTIAL_CONSTANTS: [&str; 10] = [
    "MASS", "MX", "MY", "MZ", "IXX", "IXY", "IYY", "IXZ", "IYZ", "IZZ",
];

/// The constant items, in file order.
pub fn constants(description: &Description, traced: &Traced, inputs: &[Input]) -> TokenStream {
    let chain = description.chain();
    let (n, dofs) = (chain.bodies.len(), chain.dof_bodies());
    let (dof, count) = (int(dofs.len()), int(PARAMETERS_PER_JOINT * n));
    let joints = dofs
        .iter()
        .map(|&b| Literal::string(&chain.bodies[b].joint));
    let bodies = int(n);
    let links = chain.bodies.iter().map(|b| Literal::string(&b.link));
    let tip = Literal::string(&chain.bodies[traced.tip].link);
    let tool = traced.tool.as_ref().map(|(link, ..)| {
        let link = Literal::string(link);
        quote! {
            /// The tool frame's link: fixed to the tip link, nothing after it
            /// (`tool_pose`, `tool_jacobian`).
            pub const TOOL_LINK: &str = #link;
        }
    });
    let groups = traced.groups.iter().map(|group| {
        let doc = format!(" {}", group.doc);
        let items = group
            .items
            .iter()
            .enumerate()
            .map(|(k, (name, definition))| {
                let ident = format_ident!("{name}");
                let value = match definition {
                    Definition::Value(v) => literal(*v),
                    Definition::Formula(f) => f.parse().expect("formulas are Rust expressions"),
                };
                let doc = (k == 0).then(|| quote! { #[doc = #doc] });
                quote! { #doc pub const #ident: f64 = #value; }
            });
        quote! { #(#items)* }
    });
    let derived = derived(traced, inputs);
    let names: Vec<String> = (1..=n)
        .flat_map(|i| INERTIAL_NAMES.map(|p| format!("{p}{i}")))
        .chain((1..=n).flat_map(|i| EFFECT_NAMES.map(|p| format!("{p}{i}"))))
        .collect();
    let values = (1..=n)
        .flat_map(|i| INERTIAL_CONSTANTS.map(|q| format_ident!("LINK{i}_{q}")))
        .chain((1..=n).flat_map(|i| EFFECT_CONSTANTS.map(|q| format_ident!("JOINT{i}_{q}"))));
    quote! {
        /// Number of moving joints (degrees of freedom).
        pub const DOF: usize = #dof;
        /// Number of regressor parameters: 10 inertial per link, 9 effects per joint.
        pub const NUM_PARAMETERS: usize = #count;
        /// Names of the moving joints, base first.
        pub const JOINT_NAMES: [&str; #dof] = [#(#joints),*];
        /// Names of the moving links (the frames of `link_poses`), base first.
        pub const LINK_NAMES: [&str; #bodies] = [#(#links),*];
        /// The tip link: the last moving joint's (`tip_pose`, `tip_jacobian`).
        pub const TIP_LINK: &str = #tip;
        #tool
        #(#groups)*
        #derived
        /// Parameter values of this description, in regressor column order:
        /// per link m, m*c (x, y, z), inertia about the link origin (xx, xy, yy,
        /// xz, yz, zz); then per joint armature, viscous, coulomb, offset,
        /// coulomb_asymmetry, spring, stribeck, ripple_sin, ripple_cos.
        pub const PARAMETERS: [f64; #count] = [#(#values),*];
        /// Names of PARAMETERS, suffixed by the 1-based link or joint.
        pub const PARAMETER_NAMES: [&str; #count] = [#(#names),*];
    }
}

/// The regrouped parameters the functions use, as formulas.
fn derived(traced: &Traced, inputs: &[Input]) -> TokenStream {
    let printer = Printer {
        dag: &traced.dag,
        inputs,
    };
    let none = HashMap::new();
    let items = traced
        .dag
        .derived
        .iter()
        .enumerate()
        .map(|(k, (name, id))| {
            let ident = format_ident!("{name}");
            let value = printer.definition(*id, &none);
            let doc = (k == 0).then(|| {
                quote! {
                    /// The inertial parameters the dynamics use: each link's mass, first
                    /// moment along its joint axis and inertia about that axis moved to
                    /// the link before it (same torques, fewer terms; see
                    /// docs/generated-code.md).
                }
            });
            quote! { #doc pub const #ident: f64 = #value; }
        });
    quote! { #(#items)* }
}
