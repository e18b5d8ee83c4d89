//! Rust expressions of a DAG's nodes: the straight-line code's right-hand
//! sides, with sums of products as fused multiply-adds read left to right
//! and parentheses only where precedence needs them.

use std::collections::HashMap;

use proc_macro2::{Ident, Span, TokenStream};
use quote::{format_ident, quote};

use crate::emit::Input;
use crate::program::{Dag, Node, NodeId};

/// Prints expressions of a DAG: inputs by name, named constants by name,
/// shared intermediates by their `let` names, constant subexpressions in
/// plain arithmetic (the compiler folds them).
pub struct Printer<'a> {
    pub dag: &'a Dag,
    pub inputs: &'a [Input],
}

impl Printer<'_> {
    pub fn expr(&self, id: NodeId, names: &HashMap<NodeId, Ident>) -> TokenStream {
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
