//! Rust emission of a two-lane tangent program (`lanes.rs`): the primal
//! values its coefficients need, as `Function` emits them (`t0, t1, ...`),
//! then one `let dK: Lanes` per tangent, read like the scalar sums
//! (`d3.add_mul(c2, d1).sub_mul(t5, d2) + d4`), then the roots' lanes as
//! the two matrices. `Lanes` is the generated file's two-lane type.

use std::collections::HashMap;

use proc_macro2::{Ident, TokenStream};
use quote::{format_ident, quote};

use crate::emit::{Function, Shape};
use crate::lanes::{LANES, LaneProgram, Ref, Tangent, Term};
use crate::program::NodeId;
use crate::recursive::Direction;

/// A two-lane function: `primal` carries the signature, the inputs and the
/// DAG (its `roots` are ignored), `pairs` says which derivative each lane
/// of each group is; the result is `Shape::Pair(dof, dof)` (by angle, by
/// speed).
pub struct LaneFunction<'a> {
    pub primal: Function<'a>,
    pub program: &'a LaneProgram,
    pub pairs: &'a [[Direction; 2]],
}

impl LaneFunction<'_> {
    pub fn tokens(&self) -> TokenStream {
        let uses = self.program.primal_uses();
        let primal = Function {
            roots: &uses,
            ..self.primal
        };
        let mut body = primal.prologue(&primal.used_inputs());
        let (lets, names) = primal.intermediates();
        body.extend(lets);
        body.extend(self.tangents(&primal, &names));
        let n = self.primal.dof;
        let mut values = vec![quote! { 0.0 }; 2 * n * n];
        for (pair, group) in self.pairs.iter().zip(&self.program.roots) {
            for (lane, direction) in pair.iter().enumerate() {
                let (offset, j) = match *direction {
                    Direction::Angle(j) => (0, j),
                    Direction::Speed(j) => (n * n, j),
                };
                for (i, root) in group.iter().enumerate() {
                    if let Some(r) = root {
                        values[offset + i * n + j] = lane_value(*r, lane);
                    }
                }
            }
        }
        primal.signature(body, Shape::Pair(n, n).value(&values))
    }

    fn tangents(&self, primal: &Function, names: &HashMap<NodeId, Ident>) -> Vec<TokenStream> {
        let printer = primal.printer();
        let factor = |f: NodeId| printer.expr(f, names);
        self.program
            .tangents
            .iter()
            .enumerate()
            .map(|(k, tangent)| {
                let name = tangent_ident(k);
                let value = match tangent {
                    Tangent::Seed(lanes) => {
                        let lanes = lanes.iter().map(|s| match s {
                            Some(s) => factor(*s),
                            None => quote! { 0.0 },
                        });
                        quote! { Lanes::new(#(#lanes),*) }
                    }
                    Tangent::Sum(terms) => sum(terms, &factor),
                };
                quote! { let #name = #value; }
            })
            .collect()
    }
}

/// `lead.add_mul(k, d).sub_mul(l, e) + f - g`: the lead is a positive term
/// (unscaled if there is one), then the scaled terms as fused multiply-adds,
/// then the unscaled ones (after the calls, so no parentheses are needed).
fn sum(terms: &[Term], factor: &dyn Fn(NodeId) -> TokenStream) -> TokenStream {
    let lead = terms
        .iter()
        .position(|t| !t.of.negated && t.factor.is_none())
        .or_else(|| terms.iter().position(|t| !t.of.negated))
        .expect("a sum has a positive term (lanes.rs)");
    let first = &terms[lead];
    let d = tangent_ident(first.of.tangent);
    let mut out = match first.factor {
        Some(f) => {
            let f = factor(f);
            quote! { #d.times(#f) }
        }
        None => quote! { #d },
    };
    let rest = terms.iter().enumerate().filter(|&(k, _)| k != lead);
    for (_, term) in rest.clone().filter(|(_, t)| t.factor.is_some()) {
        let (f, d) = (
            factor(term.factor.expect("scaled")),
            tangent_ident(term.of.tangent),
        );
        out = if term.of.negated {
            quote! { #out.sub_mul(#f, #d) }
        } else {
            quote! { #out.add_mul(#f, #d) }
        };
    }
    for (_, term) in rest.filter(|(_, t)| t.factor.is_none()) {
        let d = tangent_ident(term.of.tangent);
        out = if term.of.negated {
            quote! { #out - #d }
        } else {
            quote! { #out + #d }
        };
    }
    out
}

fn lane_value(r: Ref, lane: usize) -> TokenStream {
    debug_assert!(lane < LANES);
    let d = tangent_ident(r.tangent);
    let lane = crate::emit::int(lane);
    if r.negated {
        quote! { -#d.lanes()[#lane] }
    } else {
        quote! { #d.lanes()[#lane] }
    }
}

fn tangent_ident(k: usize) -> Ident {
    format_ident!("d{k}")
}
