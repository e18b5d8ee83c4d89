//! Rust emission: a function's expression DAG becomes flat straight-line
//! Rust (one `let` per shared intermediate), built with quote and checked by
//! parsing it with syn.

use std::collections::HashMap;

use proc_macro2::{Ident, Span, TokenStream};
use quote::{format_ident, quote};

use crate::program::{Dag, Node, NodeId};

/// What a generated function takes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Argument {
    Q,
    Qd,
    Qdd,
}

impl Argument {
    fn ident(self) -> Ident {
        match self {
            Argument::Q => format_ident!("q"),
            Argument::Qd => format_ident!("qd"),
            Argument::Qdd => format_ident!("qdd"),
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
    fn value(self, values: &[TokenStream]) -> TokenStream {
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
        let name = format_ident!("{}", self.name);
        let doc = self.doc;
        let n = int(self.dof);
        let used = self.used_inputs();
        let params = self.arguments.iter().map(|&a| {
            let used_here = used.iter().any(|input| argument_of(*input) == a);
            let ident = if used_here {
                a.ident()
            } else {
                format_ident!("_{}", a.ident())
            };
            quote! { #ident: &[f64; #n] }
        });
        let ret = self.shape.rust_type();
        let prologue = self.prologue(&used);
        let (lets, names) = self.intermediates();
        let printer = self.printer();
        let values: Vec<TokenStream> = self
            .roots
            .iter()
            .map(|&r| printer.expr(r, &names))
            .collect();
        let result = self.shape.value(&values);
        quote! {
            #[doc = #doc]
            #[inline]
            #[must_use]
            pub fn #name(#(#params),*) -> #ret {
                #(#prologue)*
                #(#lets)*
                #result
            }
        }
    }

    fn printer(&self) -> Printer<'_> {
        Printer {
            dag: self.dag,
            inputs: self.inputs,
        }
    }

    fn used_inputs(&self) -> Vec<Input> {
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
    fn prologue(&self, used: &[Input]) -> Vec<TokenStream> {
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
            if has(Input::Qdd(i)) {
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
    fn intermediates(&self) -> (Vec<TokenStream>, HashMap<NodeId, Ident>) {
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
                lets.push(quote! { let #name = #expr; });
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

/// Prints expressions of a DAG: inputs by name, named constants by name,
/// shared intermediates by their `let` names, constant subexpressions in
/// plain arithmetic (the compiler folds them).
pub struct Printer<'a> {
    pub dag: &'a Dag,
    pub inputs: &'a [Input],
}

impl Printer<'_> {
    fn expr(&self, id: NodeId, names: &HashMap<NodeId, Ident>) -> TokenStream {
        if let Some(name) = names.get(&id) {
            return quote! { #name };
        }
        if let Some(name) = self.dag.derived_name(id) {
            let ident = format_ident!("{name}");
            return quote! { #ident };
        }
        self.definition(id, names)
    }

    /// The expression of `id` itself, even where it has a name.
    pub fn definition(&self, id: NodeId, names: &HashMap<NodeId, Ident>) -> TokenStream {
        match &self.dag.nodes[id] {
            Node::Input(i) => {
                let ident = self.inputs[*i].ident();
                quote! { #ident }
            }
            Node::Param(p) => {
                let ident = format_ident!("{}", self.dag.params[*p].name);
                quote! { #ident }
            }
            Node::Const(c) => literal(*c),
            Node::Add(ops) => self.sum(ops, names),
            Node::Mul(ops) => self.product(ops, names),
            Node::Neg(x) => {
                let inner = self.factor(*x, names);
                quote! { -#inner }
            }
            Node::Recip(x) => {
                // A divisor in parentheses unless it is one name: `1 / a * b`
                // would read as b / a.
                let inner = self.expr(*x, names);
                if self.is_name(*x, names) {
                    quote! { 1.0 / #inner }
                } else {
                    quote! { 1.0 / (#inner) }
                }
            }
        }
    }

    /// Whether `id` prints as a bare identifier.
    fn is_name(&self, id: NodeId, names: &HashMap<NodeId, Ident>) -> bool {
        names.contains_key(&id)
            || self.dag.derived_name(id).is_some()
            || matches!(self.dag.nodes[id], Node::Input(_) | Node::Param(_))
    }

    /// `a + b * c - d * e` as `a.add_mul(b, c).sub_mul(d, e)`: each product
    /// term is a fused multiply-add where the target has FMA (see the
    /// generated `AddMul`), read left to right like the sum it is.
    /// Constant terms never fuse, so the compiler folds their products.
    fn sum(&self, ops: &[NodeId], names: &HashMap<NodeId, Ident>) -> TokenStream {
        let terms = self.ordered_terms(ops, names);
        let mut tokens = self.expr(terms[0], names);
        // Whether `tokens` can take a method call without parentheses.
        let mut postfix = self.is_postfix(terms[0], names);
        for (i, &term) in terms.iter().enumerate().skip(1) {
            if let Some((subtract, a, b)) = self.product_term(term, names) {
                let receiver = if postfix {
                    tokens
                } else if let (1, Node::Const(c)) = (i, &self.dag.nodes[terms[0]]) {
                    typed_literal(*c)
                } else {
                    quote! { (#tokens) }
                };
                tokens = if subtract {
                    quote! { #receiver.sub_mul(#a, #b) }
                } else {
                    quote! { #receiver.add_mul(#a, #b) }
                };
                postfix = true;
                continue;
            }
            tokens = match self.negated(term, names) {
                Some(magnitude) => quote! { #tokens - #magnitude },
                None => {
                    let expr = self.expr(term, names);
                    quote! { #tokens + #expr }
                }
            };
            postfix = false;
        }
        tokens
    }

    /// The terms of a sum in emission order, unnamed inner sums spliced in.
    /// A constant leads (then the first product fuses too); otherwise the
    /// order stays: the tracer puts the latest-computed term (a child's
    /// wrench) last, off the chain of the others.
    fn ordered_terms(&self, ops: &[NodeId], names: &HashMap<NodeId, Ident>) -> Vec<NodeId> {
        let mut terms = Vec::new();
        let constant = ops.iter().all(|&op| self.dag.is_constant(op));
        self.splice_terms(ops, names, constant, &mut terms);
        let all_constant = terms.iter().all(|&t| self.dag.is_constant(t));
        if !all_constant && let Some(at) = terms.iter().position(|&t| self.dag.is_constant(t)) {
            let constant = terms.remove(at);
            terms.insert(0, constant);
        }
        terms
    }

    /// The terms of a sum, unnamed inner sums replaced by their terms; a
    /// constant inner sum stays whole, so it folds.
    fn splice_terms(
        &self,
        ops: &[NodeId],
        names: &HashMap<NodeId, Ident>,
        constant: bool,
        out: &mut Vec<NodeId>,
    ) {
        for &op in ops {
            match &self.dag.nodes[op] {
                Node::Add(inner)
                    if !self.is_name(op, names) && (constant || !self.dag.is_constant(op)) =>
                {
                    self.splice_terms(inner, names, constant, out)
                }
                _ => out.push(op),
            }
        }
    }

    /// Whether the expression of `id` is a name or ends in a method call.
    fn is_postfix(&self, id: NodeId, names: &HashMap<NodeId, Ident>) -> bool {
        self.is_name(id, names)
            || match &self.dag.nodes[id] {
                Node::Add(ops) => {
                    let terms = self.ordered_terms(ops, names);
                    terms.len() > 1 && self.fuses(terms[terms.len() - 1], names)
                }
                _ => false,
            }
    }

    /// Whether `id`, as a sum's term, is an unnamed run-time `±(a * b)`
    /// that fuses.
    fn fuses(&self, id: NodeId, names: &HashMap<NodeId, Ident>) -> bool {
        !self.is_name(id, names)
            && !self.dag.is_constant(id)
            && match &self.dag.nodes[id] {
                Node::Mul(_) => true,
                Node::Neg(x) => self.fuses(*x, names),
                _ => false,
            }
    }

    /// The magnitude of a leading factor that reads best subtracted: a
    /// negative literal or the negation of a constant; as a factor, or
    /// `alone` (a whole argument, no parentheses needed).
    fn negative_lead(
        &self,
        id: NodeId,
        names: &HashMap<NodeId, Ident>,
        alone: bool,
    ) -> Option<TokenStream> {
        if self.is_name(id, names) {
            return None;
        }
        match self.dag.nodes[id] {
            Node::Const(c) if c < 0.0 => Some(literal(-c)),
            Node::Neg(x) if self.dag.is_constant(x) && alone => Some(self.expr(x, names)),
            Node::Neg(x) if self.dag.is_constant(x) => Some(self.factor(x, names)),
            _ => None,
        }
    }

    /// A sum's term `±(a * b)` that fuses into the sum: whether it is
    /// subtracted, then `a` (all factors but the last, a leading negative
    /// constant by magnitude) and `b`.
    fn product_term(
        &self,
        id: NodeId,
        names: &HashMap<NodeId, Ident>,
    ) -> Option<(bool, TokenStream, TokenStream)> {
        if !self.fuses(id, names) {
            return None;
        }
        match &self.dag.nodes[id] {
            Node::Neg(x) => self
                .product_term(*x, names)
                .map(|(subtract, a, b)| (!subtract, a, b)),
            Node::Mul(ops) => {
                let (last, head) = ops.split_last()?;
                let b = self.expr(*last, names);
                let (subtract, a) = match self.negative_lead(head[0], names, head.len() == 1) {
                    Some(magnitude) => (true, self.times(magnitude, &head[1..], names)),
                    None if head.len() == 1 => (false, self.expr(head[0], names)),
                    None => (false, self.product(head, names)),
                };
                Some((subtract, a, b))
            }
            _ => None,
        }
    }

    /// `a * b * c`, a leading literal or name first and unparenthesized.
    fn product(&self, ops: &[NodeId], names: &HashMap<NodeId, Ident>) -> TokenStream {
        let lead = match self.dag.nodes[ops[0]] {
            Node::Const(c) if !names.contains_key(&ops[0]) => literal(c),
            _ => self.factor(ops[0], names),
        };
        self.times(lead, &ops[1..], names)
    }

    /// `lead * f1 * f2 ...`.
    fn times(
        &self,
        lead: TokenStream,
        factors: &[NodeId],
        names: &HashMap<NodeId, Ident>,
    ) -> TokenStream {
        factors.iter().fold(lead, |tokens, &op| {
            let factor = self.factor(op, names);
            quote! { #tokens * #factor }
        })
    }

    /// For a term that reads best subtracted (`-x`, `-k * x`, `-k`), the
    /// tokens of its magnitude.
    fn negated(&self, id: NodeId, names: &HashMap<NodeId, Ident>) -> Option<TokenStream> {
        if self.is_name(id, names) {
            return None;
        }
        match &self.dag.nodes[id] {
            Node::Neg(x) => Some(self.factor(*x, names)),
            Node::Const(c) if *c < 0.0 => Some(literal(-c)),
            Node::Mul(ops) => self
                .negative_lead(ops[0], names, false)
                .map(|magnitude| self.times(magnitude, &ops[1..], names)),
            _ => None,
        }
    }

    /// An operand of `*`, `-` or unary `-`: sums, negations and negative
    /// leads in parentheses.
    fn factor(&self, id: NodeId, names: &HashMap<NodeId, Ident>) -> TokenStream {
        let inner = self.expr(id, names);
        let needs_parens = !self.is_name(id, names)
            && match &self.dag.nodes[id] {
                Node::Add(_) => !self.is_postfix(id, names),
                Node::Neg(_) | Node::Recip(_) => true,
                Node::Const(c) => *c < 0.0,
                Node::Mul(ops) => self.negative_lead(ops[0], names, false).is_some(),
                Node::Input(_) | Node::Param(_) => false,
            };
        if needs_parens {
            quote! { (#inner) }
        } else {
            inner
        }
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

/// An integer literal without a type suffix.
pub fn int(value: usize) -> proc_macro2::Literal {
    proc_macro2::Literal::usize_unsuffixed(value)
}

/// A float literal with an `f64` suffix, parenthesized if negative: a
/// receiver of a method call (`1.0f64.add_mul(..)`).
fn typed_literal(value: f64) -> TokenStream {
    if value.is_infinite() {
        let inner = literal(value);
        return quote! { (#inner) };
    }
    let lit = syn::LitFloat::new(&format!("{:?}f64", value.abs()), Span::call_site());
    if value.is_sign_negative() && value != 0.0 {
        quote! { (-#lit) }
    } else {
        quote! { #lit }
    }
}

/// A float literal with the shortest representation that round-trips
/// (infinities by name: the reciprocal pivot of a joint that moves nothing).
pub fn literal(value: f64) -> TokenStream {
    if value.is_infinite() {
        let sign = (value < 0.0).then(|| quote! { - });
        return quote! { #sign f64::INFINITY };
    }
    let text = format!("{:?}", value.abs());
    let lit = syn::LitFloat::new(&text, Span::call_site());
    if value.is_sign_negative() && value != 0.0 {
        quote! { -#lit }
    } else {
        quote! { #lit }
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
