//! Rust emission: a function's expression DAG becomes flat straight-line
//! Rust (one `let` per shared intermediate), built with quote and checked by
//! parsing it with syn.

use std::collections::HashMap;

use proc_macro2::{Ident, TokenStream};
use quote::{format_ident, quote};

pub use crate::printer::{Printer, int, literal};
use crate::program::{Dag, Node, NodeId};

/// What a generated function takes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Argument {
    Q,
    Qd,
    Qdd,
    /// Joint torques, the input of forward dynamics (no program input reads
    /// it: the emitter solves for qdd with it).
    Tau,
}

impl Argument {
    fn ident(self) -> Ident {
        match self {
            Argument::Q => format_ident!("q"),
            Argument::Qd => format_ident!("qd"),
            Argument::Qdd => format_ident!("qdd"),
            Argument::Tau => format_ident!("tau"),
        }
    }
}

/// The program inputs, derived from the arguments: per joint i (1-based in
/// names) sin and cos of q_i, qd_i, qdd_i, sign(qd_i), q_i itself (a
/// joint spring's stretch), the Stribeck shape
/// sign(qd_i) exp(-(qd_i/v_s)^2), and sin and cos of the ripple's angle
/// cycles*q_i.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Input {
    Sin(usize),
    Cos(usize),
    Qd(usize),
    Qdd(usize),
    Sign(usize),
    Q(usize),
    Stribeck(usize),
    RippleSin(usize),
    RippleCos(usize),
    /// Sine and cosine of a coupled body's angle (0-based body index and
    /// the degree of freedom it follows): multiplier * q_dof + offset.
    MimicSin(usize, usize),
    MimicCos(usize, usize),
}

impl Input {
    pub fn ident(self) -> Ident {
        match self {
            Input::Sin(i) => format_ident!("s{}", i + 1),
            Input::Cos(i) => format_ident!("c{}", i + 1),
            Input::Qd(i) => format_ident!("qd{}", i + 1),
            Input::Qdd(i) => format_ident!("qdd{}", i + 1),
            Input::Sign(i) => format_ident!("sign_qd{}", i + 1),
            Input::Q(i) => format_ident!("q{}", i + 1),
            Input::Stribeck(i) => format_ident!("stribeck{}", i + 1),
            Input::RippleSin(i) => format_ident!("ripple_s{}", i + 1),
            Input::RippleCos(i) => format_ident!("ripple_c{}", i + 1),
            Input::MimicSin(b, _) => format_ident!("mimic_s{}", b + 1),
            Input::MimicCos(b, _) => format_ident!("mimic_c{}", b + 1),
        }
    }
}

/// Shape of a function's result.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shape {
    Vector(usize),
    Matrix(usize, usize),
    /// Two matrices of one size, returned as a pair.
    Pair(usize, usize),
    /// `Pose`s (12 roots each: rotation row-major, then position).
    Poses(usize),
    Pose,
    /// A `Pose` and a matrix, as a pair.
    PoseAndMatrix(usize, usize),
}

impl Shape {
    /// The Rust type of the result.
    fn rust_type(self) -> TokenStream {
        let matrix = |rows: usize, cols: usize| {
            let (rows, cols) = (int(rows), int(cols));
            quote! { [[f64; #cols]; #rows] }
        };
        match self {
            Shape::Vector(len) => {
                let len = int(len);
                quote! { [f64; #len] }
            }
            Shape::Matrix(rows, cols) => matrix(rows, cols),
            Shape::Pair(rows, cols) => {
                let one = matrix(rows, cols);
                quote! { (#one, #one) }
            }
            Shape::Poses(count) => {
                let count = int(count);
                quote! { [Pose; #count] }
            }
            Shape::Pose => quote! { Pose },
            Shape::PoseAndMatrix(rows, cols) => {
                let m = matrix(rows, cols);
                quote! { (Pose, #m) }
            }
        }
    }

    /// The result expression from the roots' expressions, in order.
    pub(crate) fn value(self, values: &[TokenStream]) -> TokenStream {
        let matrix = |values: &[TokenStream], cols: usize| {
            let rows = values.chunks(cols).map(|row| quote! { [#(#row),*] });
            quote! { [#(#rows),*] }
        };
        let pose = |v: &[TokenStream]| {
            let rotation = matrix(&v[..9], 3);
            let position = &v[9..12];
            quote! { Pose { rotation: #rotation, position: [#(#position),*] } }
        };
        match self {
            Shape::Vector(_) => quote! { [#(#values),*] },
            Shape::Matrix(_, cols) => matrix(values, cols),
            Shape::Pair(rows, cols) => {
                let (first, second) = values.split_at(rows * cols);
                let (first, second) = (matrix(first, cols), matrix(second, cols));
                quote! { (#first, #second) }
            }
            Shape::Poses(_) => {
                let poses = values.chunks(12).map(pose);
                quote! { [#(#poses),*] }
            }
            Shape::Pose => pose(values),
            Shape::PoseAndMatrix(_, cols) => {
                let (first, rest) = values.split_at(12);
                let (first, rest) = (pose(first), matrix(rest, cols));
                quote! { (#first, #rest) }
            }
        }
    }
}

/// One generated function: its DAG, inputs and row-major result roots.
#[derive(Clone, Copy)]
pub struct Function<'a> {
    pub name: &'a str,
    pub doc: &'a str,
    pub arguments: &'a [Argument],
    pub dof: usize,
    pub inputs: &'a [Input],
    pub dag: &'a Dag,
    pub roots: &'a [NodeId],
    pub shape: Shape,
}

impl Function<'_> {
    /// The function as Rust tokens.
    pub fn tokens(&self) -> TokenStream {
        let used = self.used_inputs();
        let mut body = self.prologue(&used);
        let (lets, names) = self.intermediates();
        body.extend(lets.into_iter().map(|(_, statement)| statement));
        let printer = self.printer();
        let values: Vec<TokenStream> = self
            .roots
            .iter()
            .map(|&r| printer.expr(r, &names))
            .collect();
        self.signature(body, self.shape.value(&values))
    }

    /// The function item around `body` (statements) and `result`; an
    /// argument the body does not read is named `_q` (no warning).
    pub(crate) fn signature(&self, body: Vec<TokenStream>, result: TokenStream) -> TokenStream {
        let name = format_ident!("{}", self.name);
        let doc = self.doc;
        let n = int(self.dof);
        let used = self.used_inputs();
        let params = self.arguments.iter().map(|&a| {
            let used_here = a == Argument::Tau || used.iter().any(|input| argument_of(*input) == a);
            let ident = if used_here {
                a.ident()
            } else {
                format_ident!("_{}", a.ident())
            };
            quote! { #ident: &[f64; #n] }
        });
        let ret = self.shape.rust_type();
        quote! {
            #[doc = #doc]
            #[inline]
            #[must_use]
            pub fn #name(#(#params),*) -> #ret {
                #(#body)*
                #result
            }
        }
    }

    pub(crate) fn printer(&self) -> Printer<'_> {
        Printer {
            dag: self.dag,
            inputs: self.inputs,
        }
    }

    pub(crate) fn used_inputs(&self) -> Vec<Input> {
        let mut used = vec![false; self.inputs.len()];
        let mut seen = vec![false; self.dag.nodes.len()];
        let mut stack = self.roots.to_vec();
        while let Some(id) = stack.pop() {
            if std::mem::replace(&mut seen[id], true) {
                continue;
            }
            match &self.dag.nodes[id] {
                Node::Input(i) => used[*i] = true,
                node => stack.extend(node.operands()),
            }
        }
        self.inputs
            .iter()
            .zip(used)
            .filter_map(|(input, u)| u.then_some(*input))
            .collect()
    }

    /// Bindings of the used inputs: the sines and cosines all at once (one
    /// vectorized `sin_cos_n`), then velocities, accelerations and signs.
    pub(crate) fn prologue(&self, used: &[Input]) -> Vec<TokenStream> {
        let has = |input: Input| used.contains(&input);
        let mut lines = Vec::new();
        let angles: Vec<usize> = (0..self.dof)
            .filter(|&i| has(Input::Sin(i)) || has(Input::Cos(i)))
            .collect();
        if !angles.is_empty() {
            let binding = |input: Input| {
                if has(input) {
                    let ident = input.ident();
                    quote! { #ident }
                } else {
                    quote! { _ }
                }
            };
            let sines = angles.iter().map(|&i| binding(Input::Sin(i)));
            let cosines = angles.iter().map(|&i| binding(Input::Cos(i)));
            let qs = angles.iter().map(|&i| {
                let index = int(i);
                quote! { q[#index] }
            });
            lines.push(quote! { let ([#(#sines),*], [#(#cosines),*]) = sin_cos_n([#(#qs),*]); });
        }
        for i in 0..self.dof {
            let index = int(i);
            if has(Input::Q(i)) {
                let angle = Input::Q(i).ident();
                lines.push(quote! { let #angle = q[#index]; });
            }
            if has(Input::Qd(i)) {
                let v = Input::Qd(i).ident();
                lines.push(quote! { let #v = qd[#index]; });
            }
            // Without a qdd argument (forward dynamics' derivatives), the
            // caller binds qdd after solving for it.
            if has(Input::Qdd(i)) && self.arguments.contains(&Argument::Qdd) {
                let a = Input::Qdd(i).ident();
                lines.push(quote! { let #a = qdd[#index]; });
            }
            if has(Input::Sign(i)) {
                let sg = Input::Sign(i).ident();
                lines.push(quote! { let #sg = sign(qd[#index]); });
            }
            if has(Input::Stribeck(i)) {
                let st = Input::Stribeck(i).ident();
                let velocity = format_ident!("{}", crate::recursive::stribeck_velocity(i + 1));
                lines.push(quote! { let #st = stribeck(qd[#index], #velocity); });
            }
            if has(Input::RippleSin(i)) || has(Input::RippleCos(i)) {
                let [s, c] = [Input::RippleSin(i), Input::RippleCos(i)].map(|input| {
                    let ident = input.ident();
                    if has(input) {
                        quote! { #ident }
                    } else {
                        quote! { _ }
                    }
                });
                let cycles = format_ident!("{}", crate::recursive::ripple_cycles(i + 1));
                lines.push(quote! { let (#s, #c) = sin_cos(#cycles * q[#index]); });
            }
        }
        // A coupled body's angle, once for its sine and cosine.
        let mut coupled: Vec<(usize, usize)> = used
            .iter()
            .filter_map(|input| match *input {
                Input::MimicSin(b, d) | Input::MimicCos(b, d) => Some((b, d)),
                _ => None,
            })
            .collect();
        coupled.dedup();
        for (b, d) in coupled {
            let [s, c] = [Input::MimicSin(b, d), Input::MimicCos(b, d)].map(|input| {
                let ident = input.ident();
                if has(input) {
                    quote! { #ident }
                } else {
                    quote! { _ }
                }
            });
            let multiplier = format_ident!("JOINT{}_MIMIC_MULTIPLIER", b + 1);
            let offset = format_ident!("JOINT{}_MIMIC_OFFSET", b + 1);
            let index = int(d);
            lines.push(quote! { let (#s, #c) = sin_cos(#multiplier * q[#index] + #offset); });
        }
        lines
    }

    /// One `let` per node used more than once, in evaluation order.
    #[allow(clippy::type_complexity)]
    pub(crate) fn intermediates(&self) -> (Vec<(NodeId, TokenStream)>, HashMap<NodeId, Ident>) {
        let uses = self.use_counts();
        let mut names = HashMap::new();
        let mut lets = Vec::new();
        for id in self.evaluation_order() {
            let shared = uses[id] > 1;
            let compound = self.dag.nodes[id].is_compound();
            // Constants are folded by the compiler wherever they appear.
            if shared && compound && !self.dag.is_constant(id) {
                let expr = self.printer().expr(id, &names);
                let name = format_ident!("t{}", names.len());
                lets.push((id, quote! { let #name = #expr; }));
                names.insert(id, name);
            }
        }
        (lets, names)
    }

    fn use_counts(&self) -> Vec<usize> {
        let mut uses = vec![0usize; self.dag.nodes.len()];
        let mut seen = vec![false; self.dag.nodes.len()];
        let mut stack = self.roots.to_vec();
        for &r in self.roots {
            uses[r] += 1;
        }
        while let Some(id) = stack.pop() {
            if std::mem::replace(&mut seen[id], true) {
                continue;
            }
            for &c in self.dag.nodes[id].operands() {
                uses[c] += 1;
                stack.push(c);
            }
        }
        uses
    }

    /// Post-order over the roots: every node after its operands.
    fn evaluation_order(&self) -> Vec<NodeId> {
        let mut order = Vec::new();
        let mut state = vec![0u8; self.dag.nodes.len()];
        for &root in self.roots {
            let mut stack = vec![(root, false)];
            while let Some((id, expanded)) = stack.pop() {
                if expanded {
                    state[id] = 2;
                    order.push(id);
                    continue;
                }
                if state[id] != 0 {
                    continue;
                }
                state[id] = 1;
                stack.push((id, true));
                let operands = self.dag.nodes[id].operands();
                stack.extend(operands.iter().rev().map(|&o| (o, false)));
            }
        }
        order
    }
}

fn argument_of(input: Input) -> Argument {
    match input {
        Input::Sin(_)
        | Input::Cos(_)
        | Input::Q(_)
        | Input::RippleSin(_)
        | Input::RippleCos(_)
        | Input::MimicSin(..)
        | Input::MimicCos(..) => Argument::Q,
        Input::Qd(_) | Input::Sign(_) | Input::Stribeck(_) => Argument::Qd,
        Input::Qdd(_) => Argument::Qdd,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn emitted(dag: &Dag, root: NodeId) -> String {
        let inputs = [Input::Qd(0), Input::Qd(1), Input::Qd(2), Input::Qd(3)];
        let function = Function {
            name: "f",
            doc: "",
            arguments: &[Argument::Qd],
            dof: 4,
            inputs: &inputs,
            dag,
            roots: &[root],
            shape: Shape::Vector(1),
        };
        function.tokens().to_string()
    }

    #[test]
    fn products_in_a_sum_fuse_in_order() {
        let mut dag = Dag::default();
        let x: Vec<NodeId> = (0..4).map(|i| dag.input(i)).collect();
        let k = dag.constant(-2.5);
        let scaled = dag.product2(k, x[1]);
        let partial = dag.sum2(x[0], scaled);
        let product = dag.product2(x[2], x[3]);
        let root = dag.sum2(partial, product);
        let code = emitted(&dag, root);
        assert!(
            code.contains("qd1 . sub_mul (2.5 , qd2) . add_mul (qd3 , qd4)"),
            "{code}"
        );
    }

    #[test]
    fn a_reciprocal_of_a_product_keeps_its_parentheses() {
        let mut dag = Dag::default();
        let x: Vec<NodeId> = (0..4).map(|i| dag.input(i)).collect();
        let product = dag.product2(x[0], x[1]);
        let inverse = dag.reciprocal(product);
        let root = dag.product2(inverse, x[2]);
        let code = emitted(&dag, root);
        assert!(code.contains("1.0 / (qd1 * qd2)"), "{code}");
    }

    #[test]
    fn a_leading_product_is_a_plain_multiply_and_a_constant_gets_a_type() {
        let mut dag = Dag::default();
        let x: Vec<NodeId> = (0..4).map(|i| dag.input(i)).collect();
        let first = dag.product2(x[0], x[1]);
        let second = dag.product2(x[2], x[3]);
        let root = dag.sum2(first, second);
        let code = emitted(&dag, root);
        assert!(code.contains("(qd1 * qd2) . add_mul (qd3 , qd4)"), "{code}");
        let one = dag.constant(1.0);
        let root = dag.sum2(one, second);
        let code = emitted(&dag, root);
        assert!(code.contains("1.0f64 . add_mul (qd3 , qd4)"), "{code}");
    }
}
