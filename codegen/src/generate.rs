//! From a validated description to the text of its generated Rust file.
//!
//! `generate` is pure: it returns the file contents. Symbolica derives the
//! rigid-body torque polynomials (`lagrangian.rs`); everything after that
//! (mass matrix, gravity, Coriolis, regressor, joint effects) is read off those
//! polynomials, turned into shared-subexpression programs and emitted.

use std::time::Instant;

use proc_macro2::TokenStream;
use quote::quote;

use crate::description::Description;
use crate::emit::{Argument, Function, Input, Shape, int, literal};
use crate::fingerprint::{FINGERPRINT_PREFIX, fingerprint, generator_version};
use crate::lagrangian::{self, RigidBodyTorque};
use crate::program::{Dag, NodeId, Poly};
use crate::recursive::{self, Traced};
use crate::reduce::Chain;

/// Names of the ten inertial parameters of body i, Pinocchio's order.
pub const INERTIAL_NAMES: [&str; 10] = [
    "m", "mx", "my", "mz", "ixx", "ixy", "iyy", "ixz", "iyz", "izz",
];
/// Chains up to this many joints also get the expanded Lagrangian, and each
/// function keeps whichever form needs fewer operations. Beyond it the
/// expansion swells (terms grow roughly tenfold per joint) and only the
/// structured form (`recursive.rs`) is derived.
pub const LAGRANGIAN_MAX_DOF: usize = 4;
/// Names of the joint-effect parameters of joint i.
pub const EFFECT_NAMES: [&str; 4] = ["armature", "viscous", "coulomb", "offset"];

/// A generated model file and what it cost.
#[derive(Debug, Clone)]
pub struct Generated {
    pub name: String,
    pub code: String,
    /// Arithmetic operations per generated function, in emission order.
    pub operations: Vec<Cost>,
    pub seconds: f64,
}

/// What one generated function costs and which form was kept.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Cost {
    pub function: String,
    pub operations: usize,
    /// "expanded" (Lagrangian polynomials) or "structured" (`recursive.rs`).
    pub form: &'static str,
}

impl std::fmt::Display for Cost {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} {} ({})", self.function, self.operations, self.form)
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
    let rigid = if chain.bodies.len() <= LAGRANGIAN_MAX_DOF {
        Some(crate::session::run(move || lagrangian::derive(&chain))??)
    } else {
        None
    };
    let model = Model::new(description, rigid);
    let mut operations = Vec::new();
    let mut items = Vec::new();
    for spec in model.functions() {
        let (tokens, ops, form) = spec.emit(&model.inputs, &model.traced.dag);
        operations.push(Cost {
            function: spec.name.to_string(),
            operations: ops,
            form,
        });
        items.push(tokens);
    }
    let constants = model.constants();
    let sin_cos = sin_cos_function();
    let file: TokenStream = quote! {
        #constants
        #(#items)*
        /// Coulomb friction direction: sign(x), with sign(0) = 0.
        #[inline]
        #[must_use]
        pub fn sign(x: f64) -> f64 {
            if x > 0.0 { 1.0 } else if x < 0.0 { -1.0 } else { 0.0 }
        }
        #sin_cos
    };
    let syntax = syn::parse2::<syn::File>(file)
        .map_err(|e| format!("generated code does not parse: {e}"))?;
    let body = prettyplease::unparse(&syntax);
    let header = header(description, toml_source, source_label, &operations);
    Ok(Generated {
        name: description.name.clone(),
        code: format!("{header}{body}"),
        operations,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// sin and cos within about one ulp, several times faster than two libm
/// calls: Cody-Waite reduction by pi/2 (pi/2 split in 33 + 33 + 53 bits, so
/// k * part is exact for |k| < 2^20), then Taylor polynomials on
/// [-pi/4, pi/4] (the first omitted terms are below 1e-16 relative),
/// evaluated by Estrin's scheme.
fn sin_cos_function() -> TokenStream {
    quote! {
        /// sin(x) and cos(x) to about one ulp; std beyond |x| = 1e5.
        #[inline]
        #[must_use]
        #[allow(clippy::excessive_precision, clippy::approx_constant)]
        pub fn sin_cos(x: f64) -> (f64, f64) {
            if !(x.abs() <= 1.0e5) {
                return x.sin_cos();
            }
            // Round to nearest by the 1.5 * 2^52 shift: exact for |x| <= 1e5 and
            // one instruction, where `f64::round` is a libm call on baseline x86-64.
            let k = (x * 0.6366197723675814 + 6755399441055744.0) - 6755399441055744.0;
            let r = ((x - k * 1.5707963267341256) - k * 6.077100506303966e-11) - k * 2.0222662487959506e-21;
            // Estrin's scheme: short dependency chains, both polynomials in parallel.
            let (z, z2) = (r * r, r * r * r * r);
            let z4 = z2 * z2;
            let sp = (-0.16666666666666666 + z * 0.008333333333333333)
                + z2 * (-0.0001984126984126984 + z * 2.7557319223985893e-6)
                + z4 * ((-2.505210838544172e-8 + z * 1.6059043836821613e-10)
                    + z2 * (-7.647163731819816e-13 + z * 2.8114572543455206e-15));
            let cp = (-0.5 + z * 0.041666666666666664)
                + z2 * (-0.001388888888888889 + z * 2.48015873015873e-5)
                + z4 * ((-2.755731922398589e-7 + z * 2.08767569878681e-9)
                    + z2 * (-1.1470745597729725e-11 + z * 4.779477332387385e-14));
            let s = r + r * z * sp;
            let c = 1.0 + z * cp;
            match (k as i64) & 3 {
                0 => (s, c),
                1 => (c, -s),
                2 => (-s, -c),
                _ => (-c, s),
            }
        }
    }
}

fn header(
    description: &Description,
    toml_source: &str,
    source_label: &str,
    operations: &[Cost],
) -> String {
    let ops: Vec<String> = operations.iter().map(Cost::to_string).collect();
    format!(
        "// This file is @generated by sdnn-codegen {version} from {source_label}. Do not edit.\n\
         {FINGERPRINT_PREFIX}{fp} (sha256 of the TOML text and the generator)\n\
         // Refresh: `cargo build` regenerates it when the TOML or the generator changes,\n\
         // or run `cargo run -p sdnn-codegen -- {source_label}`.\n\
         // Robot: {robot}; {dof} moving joints ({joints}).\n\
         // Arithmetic operations: {ops}.\n\
         // tau = M(q) qdd + c(q, qd) + g(q) + effects(qd); M includes armature.\n\n",
        version = generator_version(),
        fp = fingerprint(toml_source),
        robot = description.robot,
        dof = description.dof(),
        joints = description
            .chain()
            .bodies
            .iter()
            .map(|b| b.joint.as_str())
            .collect::<Vec<_>>()
            .join(", "),
        ops = ops.join(", "),
    )
}

/// The polynomials of every generated function.
struct Model {
    dof: usize,
    inputs: Vec<Input>,
    chain: Chain,
    /// The expanded Lagrangian's rigid-body torque with the description's
    /// numeric parameters, and its regressor columns `[joint][parameter]`
    /// (small chains only).
    expanded: Option<Expanded>,
    /// The structured programs of every function.
    traced: Traced,
}

struct Expanded {
    tau_rigid: Vec<Poly>,
    regressor_rigid: Vec<Vec<Poly>>,
}

/// One function to emit.
struct Spec<'a> {
    name: &'a str,
    doc: String,
    arguments: &'a [Argument],
    shape: Shape,
    /// The outputs as polynomials (expanded form), if derived.
    polynomials: Option<Vec<Poly>>,
    /// The outputs' roots in the structured programs, if traced.
    traced: Option<Vec<NodeId>>,
}

impl Spec<'_> {
    /// Emits the cheapest available form: its tokens, operation count and name.
    fn emit(&self, inputs: &[Input], traced_dag: &Dag) -> (TokenStream, usize, &'static str) {
        let expanded = self.polynomials.as_ref().map(|p| horner(p, inputs));
        let structured = self
            .traced
            .as_ref()
            .map(|roots| (roots, traced_dag.negation_aware_count(roots)));
        let (dag, roots, ops, form) = match (&expanded, structured) {
            (Some((dag, roots, ops)), Some((_, traced_ops))) if *ops <= traced_ops => {
                (dag, roots, *ops, "expanded")
            }
            (_, Some((roots, ops))) => (traced_dag, roots, ops, "structured"),
            (Some((dag, roots, ops)), None) => (dag, roots, *ops, "expanded"),
            (None, None) => unreachable!("every function has a form"),
        };
        let function = Function {
            name: self.name,
            doc: &self.doc,
            arguments: self.arguments,
            dof: inputs.len() / 5,
            inputs,
            dag,
            roots,
            shape: self.shape,
        };
        (function.tokens(), ops, form)
    }
}

/// Polynomials as a shared-subexpression program: two factoring orders, the
/// cheaper kept.
fn horner(outputs: &[Poly], inputs: &[Input]) -> (Dag, Vec<NodeId>, usize) {
    let pairs = trig_pairs(inputs);
    let reduced: Vec<Poly> = outputs.iter().map(|p| p.reduce_trig(&pairs)).collect();
    let greedy = vec![0; inputs.len()];
    let motion_first: Vec<u8> = inputs
        .iter()
        .map(|i| u8::from(!matches!(i, Input::Sin(_) | Input::Cos(_))))
        .collect();
    [greedy, motion_first]
        .iter()
        .map(|priority| {
            let mut dag = Dag::default();
            let roots: Vec<NodeId> = reduced.iter().map(|p| dag.horner(p, priority)).collect();
            let ops = dag.negation_aware_count(&roots);
            (dag, roots, ops)
        })
        .min_by_key(|(_, _, ops)| *ops)
        .expect("two candidates")
}

fn trig_pairs(inputs: &[Input]) -> Vec<(usize, usize)> {
    let position = |wanted: Input| inputs.iter().position(|&i| i == wanted);
    inputs
        .iter()
        .filter_map(|&input| match input {
            Input::Sin(j) => Some((position(Input::Sin(j))?, position(Input::Cos(j))?)),
            _ => None,
        })
        .collect()
}

impl Model {
    fn new(description: &Description, rigid: Option<RigidBodyTorque>) -> Model {
        let chain = description.chain().clone();
        let dof = chain.bodies.len();
        let parameters: Vec<f64> = chain
            .bodies
            .iter()
            .flat_map(|b| b.inertial.standard_parameters())
            .collect();
        let expanded = rigid.map(|rigid| Expanded {
            tau_rigid: rigid
                .regressor
                .iter()
                .map(|row| {
                    let scaled = row.iter().zip(&parameters).flat_map(|(column, &p)| {
                        column.terms().iter().map(move |(e, c)| (e.clone(), c * p))
                    });
                    Poly::from_terms(scaled.collect::<Vec<_>>())
                })
                .collect(),
            regressor_rigid: rigid.regressor,
        });
        Model {
            dof,
            inputs: lagrangian::inputs(dof),
            traced: recursive::trace(&chain),
            chain,
            expanded,
        }
    }

    fn position(&self, input: Input) -> usize {
        self.inputs.iter().position(|&i| i == input).unwrap_or(0)
    }

    fn variable(&self, input: Input, coefficient: f64) -> Poly {
        let mut exponents = vec![0; self.inputs.len()];
        exponents[self.position(input)] = 1;
        Poly::from_terms([(exponents, coefficient)])
    }

    fn constant(&self, value: f64) -> Poly {
        Poly::from_terms([(vec![0; self.inputs.len()], value)])
    }

    /// Terms of `p` whose qd and qdd degrees satisfy the filter.
    fn select(&self, p: &Poly, keep: impl Fn(u32, u32) -> bool) -> Poly {
        let qd: Vec<usize> = (0..self.dof).map(|i| self.position(Input::Qd(i))).collect();
        let qdd: Vec<usize> = (0..self.dof)
            .map(|i| self.position(Input::Qdd(i)))
            .collect();
        let degree = |e: &[u32], idx: &[usize]| idx.iter().map(|&k| e[k]).sum::<u32>();
        Poly::from_terms(
            p.terms()
                .iter()
                .filter(|(e, _)| keep(degree(e, &qd), degree(e, &qdd)))
                .cloned()
                .collect::<Vec<_>>(),
        )
    }

    /// d p / d qdd_j for p linear in qdd.
    fn qdd_coefficient(&self, p: &Poly, j: usize) -> Poly {
        let k = self.position(Input::Qdd(j));
        Poly::from_terms(
            p.terms()
                .iter()
                .filter(|(e, _)| e[k] == 1)
                .map(|(e, c)| {
                    let mut e = e.clone();
                    e[k] = 0;
                    (e, *c)
                })
                .collect::<Vec<_>>(),
        )
    }

    fn effects(&self, i: usize, with_armature: bool) -> Poly {
        let e = self.chain.bodies[i].effects;
        let mut terms = Vec::new();
        for (input, value) in [
            (Input::Qd(i), e.viscous),
            (Input::Sign(i), e.coulomb),
            (Input::Qdd(i), if with_armature { e.armature } else { 0.0 }),
        ] {
            terms.extend(self.variable(input, value).terms().to_vec());
        }
        terms.extend(self.constant(e.offset).terms().to_vec());
        Poly::from_terms(terms)
    }

    fn sum(a: &Poly, b: &Poly) -> Poly {
        Poly::from_terms(
            a.terms()
                .iter()
                .chain(b.terms())
                .cloned()
                .collect::<Vec<_>>(),
        )
    }

    fn functions(&self) -> Vec<Spec<'static>> {
        let n = self.dof;
        let expanded = self.expanded.as_ref().map(|x| self.expanded_functions(x));
        let [tau, mass, gravity, coriolis, regressor] = match expanded {
            Some(polynomials) => polynomials.map(Some),
            None => [None, None, None, None, None],
        };
        let traced = &self.traced;
        let effects = (0..n).map(|i| self.effects(i, false)).collect();
        vec![
            Spec {
                name: "tau",
                doc: " Joint torques tau = M(q) qdd + c(q, qd) + g(q) + effects(qd), N m.".into(),
                arguments: &[Argument::Q, Argument::Qd, Argument::Qdd],
                shape: Shape::Vector(n),
                polynomials: tau,
                traced: Some(traced.tau.clone()),
            },
            Spec {
                name: "mass_matrix",
                doc: " Joint-space inertia matrix M(q), armature on the diagonal, kg m^2.".into(),
                arguments: &[Argument::Q],
                shape: Shape::Matrix(n, n),
                polynomials: mass,
                traced: Some(traced.mass_matrix.clone()),
            },
            Spec {
                name: "gravity",
                doc: " Generalized gravity g(q) = dU/dq, N m.".into(),
                arguments: &[Argument::Q],
                shape: Shape::Vector(n),
                polynomials: gravity,
                traced: Some(traced.gravity.clone()),
            },
            Spec {
                name: "coriolis",
                doc: " Coriolis and centrifugal torques c(q, qd), N m.".into(),
                arguments: &[Argument::Q, Argument::Qd],
                shape: Shape::Vector(n),
                polynomials: coriolis,
                traced: Some(traced.coriolis.clone()),
            },
            Spec {
                name: "effects",
                doc:
                    " Joint effects without armature: viscous*qd + coulomb*sign(qd) + offset, N m."
                        .into(),
                arguments: &[Argument::Qd],
                shape: Shape::Vector(n),
                polynomials: Some(effects),
                traced: None,
            },
            Spec {
                name: "regressor",
                doc: " Regressor Y(q, qd, qdd) with tau = Y * PARAMETERS (see PARAMETER_NAMES)."
                    .into(),
                arguments: &[Argument::Q, Argument::Qd, Argument::Qdd],
                shape: Shape::Matrix(n, 14 * n),
                polynomials: regressor,
                traced: Some(traced.regressor.clone()),
            },
        ]
    }

    /// tau, M, g, c and the regressor read off the expanded Lagrangian.
    fn expanded_functions(&self, expanded: &Expanded) -> [Vec<Poly>; 5] {
        let n = self.dof;
        let tau_rigid = &expanded.tau_rigid;
        let tau = (0..n)
            .map(|i| Model::sum(&tau_rigid[i], &self.effects(i, true)))
            .collect();
        let mut mass: Vec<Poly> = Vec::with_capacity(n * n);
        for i in 0..n {
            for j in 0..n {
                // Mirror the upper triangle: M is symmetric bit for bit.
                let m = if j < i {
                    mass[j * n + i].clone()
                } else if i == j {
                    let armature = self.constant(self.chain.bodies[i].effects.armature);
                    Model::sum(&self.qdd_coefficient(&tau_rigid[i], j), &armature)
                } else {
                    self.qdd_coefficient(&tau_rigid[i], j)
                };
                mass.push(m);
            }
        }
        let gravity = tau_rigid
            .iter()
            .map(|p| self.select(p, |d, a| d == 0 && a == 0))
            .collect();
        let coriolis = tau_rigid
            .iter()
            .map(|p| self.select(p, |d, a| d > 0 && a == 0))
            .collect();
        let regressor = self.regressor(&expanded.regressor_rigid);
        [tau, mass, gravity, coriolis, regressor]
    }

    fn regressor(&self, rigid: &[Vec<Poly>]) -> Vec<Poly> {
        let n = self.dof;
        let mut rows = Vec::with_capacity(n * 14 * n);
        for (i, rigid_row) in rigid.iter().enumerate() {
            rows.extend(rigid_row.iter().cloned());
            for j in 0..n {
                let own = |input, value| {
                    if i == j {
                        self.variable(input, value)
                    } else {
                        Poly::default()
                    }
                };
                rows.push(own(Input::Qdd(j), 1.0));
                rows.push(own(Input::Qd(j), 1.0));
                rows.push(own(Input::Sign(j), 1.0));
                rows.push(if i == j {
                    self.constant(1.0)
                } else {
                    Poly::default()
                });
            }
        }
        rows
    }

    fn constants(&self) -> TokenStream {
        let n = int(self.dof);
        let count = int(14 * self.dof);
        let mut values = Vec::new();
        let mut names = Vec::new();
        for (i, body) in self.chain.bodies.iter().enumerate() {
            for (name, value) in INERTIAL_NAMES
                .iter()
                .zip(body.inertial.standard_parameters())
            {
                names.push(format!("{name}{}", i + 1));
                values.push(literal(value));
            }
        }
        for (i, body) in self.chain.bodies.iter().enumerate() {
            let e = body.effects;
            for (name, value) in EFFECT_NAMES
                .iter()
                .zip([e.armature, e.viscous, e.coulomb, e.offset])
            {
                names.push(format!("{name}{}", i + 1));
                values.push(literal(value));
            }
        }
        let joints = self.chain.bodies.iter().map(|b| b.joint.as_str());
        quote! {
            /// Number of moving joints.
            pub const DOF: usize = #n;
            /// Number of regressor parameters: 10 inertial per link, 4 effects per joint.
            pub const NUM_PARAMETERS: usize = #count;
            /// Names of the moving joints, base first.
            pub const JOINT_NAMES: [&str; #n] = [#(#joints),*];
            /// Parameter values of this description, in regressor column order:
            /// per link m, m*c (x, y, z), inertia about the link origin (xx, xy, yy,
            /// xz, yz, zz); then per joint armature, viscous, coulomb, offset.
            #[allow(clippy::excessive_precision)]
            pub const PARAMETERS: [f64; #count] = [#(#values),*];
            /// Names of PARAMETERS, suffixed by the 1-based link or joint.
            pub const PARAMETER_NAMES: [&str; #count] = [#(#names),*];
        }
    }
}
