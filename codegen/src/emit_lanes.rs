//! Rust emission of a two-lane tangent program (`lanes.rs`): the primal
//! values its coefficients need, as `Function` emits them (`t0, t1, ...`),
//! then one `let dK: Lanes` per tangent, read like the scalar sums
//! (`d3.add_mul(c2, d1).sub_mul(t5, d2) + d4`), then the roots' lanes as
//! the two matrices. `Lanes` is the generated file's two-lane type.

use std::collections::HashMap;

use proc_macro2::{Ident, TokenStream};
use quote::{format_ident, quote};

use crate::emit::{Function, Input, Shape};
use crate::lanes::{LANES, LaneProgram, Ref, Tangent, Term};
use crate::program::NodeId;
use crate::recursive::Direction;

/// A two-lane function: `primal` carries the signature, the inputs and the
/// DAG (its `roots` are ignored), `pairs` says which derivative each lane
/// of each group is; the result is `Shape::Pair(dof, dof)` (by angle, by
/// speed): d tau, or with `through` d qdd of forward dynamics.
pub struct LaneFunction<'a> {
    pub primal: Function<'a>,
    pub program: &'a LaneProgram,
    pub pairs: &'a [[Direction; 2]],
    pub through: Option<Forward<'a>>,
}

/// Forward dynamics' derivatives in one function: `mass_factor` and `bias`
/// traced beside the derivatives (they share sines, rotations and
/// velocities), qdd solved from them, then d qdd / d x = -M^-1 d tau / d x
/// at that qdd.
#[derive(Clone, Copy)]
pub struct Forward<'a> {
    pub factor: &'a [NodeId],
    pub bias: &'a [NodeId],
}

impl LaneFunction<'_> {
    pub fn tokens(&self) -> TokenStream {
        let mut uses = self.program.primal_uses();
        if let Some(forward) = self.through {
            uses.extend(forward.factor.iter().chain(forward.bias));
        }
        let primal = Function {
            roots: &uses,
            ..self.primal
        };
        let mut body = primal.prologue(&primal.used_inputs());
        let (lets, names) = primal.intermediates();
        let n = self.primal.dof;
        let Some(forward) = self.through else {
            body.extend(lets.into_iter().map(|(_, statement)| statement));
            body.extend(self.tangents(&primal, &names));
            return primal.signature(body, Shape::Pair(n, n).value(&self.roots()));
        };
        // What does not need qdd first: the factor and the bias.
        let late = needs_qdd(&primal);
        let (after, before): (Vec<_>, Vec<_>) = lets.into_iter().partition(|(id, _)| late[*id]);
        body.extend(before.into_iter().map(|(_, statement)| statement));
        let printer = primal.printer();
        let exprs = |roots: &[NodeId]| -> Vec<TokenStream> {
            roots.iter().map(|&r| printer.expr(r, &names)).collect()
        };
        let factor = Shape::Matrix(n, n).value(&exprs(forward.factor));
        let bias = Shape::Vector(n).value(&exprs(forward.bias));
        body.push(quote! {
            let factor = #factor;
            let bias = #bias;
            let qdd = solve_factored(&factor, core::array::from_fn(|i| tau[i] - bias[i]));
        });
        for input in primal.used_inputs() {
            if let Input::Qdd(i) = input {
                let (ident, index) = (input.ident(), crate::emit::int(i));
                body.push(quote! { let #ident = qdd[#index]; });
            }
        }
        body.extend(after.into_iter().map(|(_, statement)| statement));
        body.extend(self.tangents(&primal, &names));
        // Each pair's two columns of -M^-1 d tau solved at once, a lane each.
        let mut values = vec![quote! { 0.0 }; 2 * n * n];
        for (g, (pair, group)) in self.pairs.iter().zip(&self.program.roots).enumerate() {
            let x = format_ident!("x{}", g + 1);
            let columns = group.iter().map(|root| match root {
                Some(Ref { tangent, negated }) => {
                    let d = tangent_ident(*tangent);
                    if *negated {
                        quote! { -#d }
                    } else {
                        quote! { #d }
                    }
                }
                None => quote! { Lanes::new(0.0, 0.0) },
            });
            body.push(quote! { let #x = solve_factored_lanes_negated(&factor, [#(#columns),*]); });
            for (lane, direction) in pair.iter().enumerate() {
                let (offset, j) = match *direction {
                    Direction::Angle(j) => (0, j),
                    Direction::Speed(j) => (n * n, j),
                };
                let lane = crate::emit::int(lane);
                for i in 0..n {
                    let row = crate::emit::int(i);
                    values[offset + i * n + j] = quote! { #x[#row].lanes()[#lane] };
                }
            }
        }
        let result = Shape::Pair(n, n).value(&values);
        primal.signature(body, result)
    }

    /// The roots' lanes as the two matrices (by angle, then by speed),
    /// row-major.
    fn roots(&self) -> Vec<TokenStream> {
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
        values
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

/// Per DAG node, whether it reads a joint acceleration.
fn needs_qdd(function: &Function) -> Vec<bool> {
    let mut late = vec![false; function.dag.nodes.len()];
    for (id, node) in function.dag.nodes.iter().enumerate() {
        late[id] = match node {
            crate::program::Node::Input(i) => matches!(function.inputs[*i], Input::Qdd(_)),
            node => node.operands().iter().any(|&o| late[o]),
        };
    }
    late
}
