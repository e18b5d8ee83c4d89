//! Vector forward mode: the derivatives of a straight-line program with
//! respect to two variables at once, as a program over two-lane tangents.
//!
//! Every tangent is a linear combination of earlier tangents whose
//! coefficients are primal values (d(a b) = b da + a db), so the tangents
//! of two directions are the same operations on two lanes with the primal
//! coefficient broadcast: one packed multiply and add (SSE2, NEON) does the
//! work of two scalar ones. A lane that is structurally zero where the other
//! is not costs nothing beyond the scalar program. Coefficients are nodes
//! of the primal DAG (hash-consed there, so a cofactor product is computed
//! once for all directions); tangents form a separate list.

use crate::program::{Dag, Node, NodeId};

/// Lanes per tangent: what one SSE2 or NEON register holds.
pub const LANES: usize = 2;

/// A reference to a tangent, possibly negated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Ref {
    pub tangent: usize,
    pub negated: bool,
}

/// One term of a tangent's sum: `factor * tangent` (`None`: factor 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Term {
    pub factor: Option<NodeId>,
    pub of: Ref,
}

/// How a tangent is computed.
#[derive(Debug, Clone, PartialEq)]
pub enum Tangent {
    /// An input's derivative per lane (`None`: 0), primal nodes.
    Seed([Option<NodeId>; LANES]),
    /// A sum of scaled earlier tangents (at least two terms, or one scaled).
    Sum(Vec<Term>),
}

/// The tangents of a program's roots for groups of `LANES` directions.
#[derive(Debug, Default)]
pub struct LaneProgram {
    pub tangents: Vec<Tangent>,
    /// Per group, the roots' tangents (`None`: identically zero).
    pub roots: Vec<Vec<Option<Ref>>>,
}

impl LaneProgram {
    /// Adds one group: the tangents of `roots` for `LANES` directions, given
    /// each direction's derivative of every program input (`seeds[lane][i]`).
    pub fn push_group(
        &mut self,
        dag: &mut Dag,
        roots: &[NodeId],
        seeds: &[Vec<Option<NodeId>>; LANES],
    ) {
        let reachable = dag.reachable(roots);
        let mut of: Vec<Option<Ref>> = vec![None; reachable.len()];
        // Operands precede the nodes built from them.
        for id in (0..reachable.len()).filter(|&id| reachable[id]) {
            let node = dag.nodes[id].clone();
            of[id] = match node {
                Node::Input(i) => {
                    let lanes = [seeds[0][i], seeds[1][i]];
                    lanes
                        .iter()
                        .any(Option::is_some)
                        .then(|| self.push(Tangent::Seed(lanes)))
                }
                Node::Const(_) | Node::Param(_) => None,
                Node::Add(ops) => {
                    let terms = ops
                        .iter()
                        .filter_map(|&o| {
                            of[o].map(|r| Term {
                                factor: None,
                                of: r,
                            })
                        })
                        .collect();
                    self.sum(dag, terms)
                }
                Node::Mul(ops) => {
                    let terms = product_terms(dag, &ops, &of);
                    self.sum(dag, terms)
                }
                Node::Neg(x) => of[x].map(flip),
                Node::Recip(x) => of[x].map(|r| {
                    // d(1/x) = -(1/x)^2 dx.
                    let square = dag.product2(id, id);
                    let term = Term {
                        factor: Some(square),
                        of: flip(r),
                    };
                    self.push(Tangent::Sum(vec![term]))
                }),
            };
        }
        self.roots.push(roots.iter().map(|&r| of[r]).collect());
    }

    /// A sum: one unscaled term is that tangent itself (no operation); a
    /// sum of negated terms is stored positive and referred to negated, so
    /// every emitted sum leads with a positive term (no run-time negation).
    fn sum(&mut self, dag: &mut Dag, terms: Vec<Term>) -> Option<Ref> {
        let mut terms = combine(dag, terms);
        match terms.as_slice() {
            [] => None,
            [Term { factor: None, of }] => Some(*of),
            _ if terms.iter().all(|t| t.of.negated) => {
                terms.iter_mut().for_each(|t| t.of = flip(t.of));
                Some(flip(self.push(Tangent::Sum(terms))))
            }
            _ => Some(self.push(Tangent::Sum(terms))),
        }
    }

    fn push(&mut self, tangent: Tangent) -> Ref {
        self.tangents.push(tangent);
        Ref {
            tangent: self.tangents.len() - 1,
            negated: false,
        }
    }

    /// Run-time lane operations: a scaled term is a multiply (and an add
    /// unless it leads), an unscaled one an add; seeds are free (loads).
    pub fn operation_count(&self) -> usize {
        self.tangents
            .iter()
            .map(|t| match t {
                Tangent::Seed(_) => 0,
                Tangent::Sum(terms) => {
                    let products = terms.iter().filter(|t| t.factor.is_some()).count();
                    products + terms.len() - 1
                }
            })
            .sum()
    }

    /// The primal nodes the tangents read, once per use.
    pub fn primal_uses(&self) -> Vec<NodeId> {
        let mut uses = Vec::new();
        for t in &self.tangents {
            match t {
                Tangent::Seed(lanes) => uses.extend(lanes.iter().flatten()),
                Tangent::Sum(terms) => uses.extend(terms.iter().filter_map(|t| t.factor)),
            }
        }
        uses
    }

    /// Every group's root tangents for input values `x`: `[group][root][lane]`
    /// (tests and checks).
    pub fn evaluate(&self, dag: &Dag, x: &[f64]) -> Vec<Vec<[f64; LANES]>> {
        let primal = self.primal_uses();
        let values = dag.evaluate(&primal, x);
        let value_of: std::collections::HashMap<NodeId, f64> =
            primal.iter().copied().zip(values).collect();
        let mut lanes: Vec<[f64; LANES]> = Vec::with_capacity(self.tangents.len());
        let read = |lanes: &[[f64; LANES]], r: Ref| {
            let v = lanes[r.tangent];
            if r.negated { v.map(|x| -x) } else { v }
        };
        for t in &self.tangents {
            let v = match t {
                Tangent::Seed(seed) => seed.map(|s| s.map_or(0.0, |s| value_of[&s])),
                Tangent::Sum(terms) => terms.iter().fold([0.0; LANES], |acc, term| {
                    let k = term.factor.map_or(1.0, |f| value_of[&f]);
                    let d = read(&lanes, term.of);
                    [acc[0] + k * d[0], acc[1] + k * d[1]]
                }),
            };
            lanes.push(v);
        }
        self.roots
            .iter()
            .map(|group| {
                group
                    .iter()
                    .map(|r| r.map_or([0.0; LANES], |r| read(&lanes, r)))
                    .collect()
            })
            .collect()
    }
}

/// Terms of one tangent with one factor combine: `d - d` cancels (two
/// primal paths whose tangents coincide), `d + d` is `2 d`, and a square's
/// d(a a) = (2 a) da, its factor a primal node shared by every direction.
fn combine(dag: &mut Dag, terms: Vec<Term>) -> Vec<Term> {
    let mut out: Vec<(Term, i32)> = Vec::new();
    for term in terms {
        let sign = if term.of.negated { -1 } else { 1 };
        let same =
            |(t, _): &(Term, i32)| t.factor == term.factor && t.of.tangent == term.of.tangent;
        match out.iter_mut().find(|entry| same(entry)) {
            Some((_, count)) => *count += sign,
            None => out.push((term, sign)),
        }
    }
    out.into_iter()
        .filter(|&(_, count)| count != 0)
        .map(|(term, count)| {
            let of = Ref {
                negated: count < 0,
                ..term.of
            };
            if count.abs() == 1 {
                return Term { of, ..term };
            }
            let times = dag.constant(f64::from(count.abs()));
            let factor = Some(term.factor.map_or(times, |f| dag.product2(times, f)));
            Term { factor, of }
        })
        .collect()
}

fn flip(r: Ref) -> Ref {
    Ref {
        negated: !r.negated,
        ..r
    }
}

/// d(a b c ...) = (b c ...) da + (a c ...) db + ...: one term per factor
/// that varies, its cofactor a primal node (shared by every direction).
fn product_terms(dag: &mut Dag, ops: &[NodeId], of: &[Option<Ref>]) -> Vec<Term> {
    let mut terms = Vec::new();
    for (k, &op) in ops.iter().enumerate() {
        let Some(mut r) = of[op] else {
            continue;
        };
        let mut cofactor: Option<NodeId> = None;
        for (l, &other) in ops.iter().enumerate() {
            if l != k {
                cofactor = Some(match cofactor {
                    Some(c) => dag.product2(c, other),
                    None => other,
                });
            }
        }
        // A negated cofactor (or -1) becomes a negated tangent, so the
        // emitted term is a subtraction, not a negation.
        let mut factor = cofactor;
        if let Some(c) = factor
            && let Node::Neg(x) = dag.nodes[c]
        {
            factor = Some(x);
            r = flip(r);
        }
        match factor.map(|c| dag.nodes[c].clone()) {
            Some(Node::Const(1.0)) => factor = None,
            Some(Node::Const(-1.0)) => {
                factor = None;
                r = flip(r);
            }
            _ => {}
        }
        terms.push(Term { factor, of: r });
    }
    terms
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::derivative::derivative;

    /// f(x, y) = x^2 y + 1 / (x + y) - x y, both directions at once, equal
    /// to the scalar forward mode's.
    #[test]
    fn two_lanes_equal_two_scalar_passes() {
        let mut dag = Dag::default();
        let (x, y) = (dag.input(0), dag.input(1));
        let xx = dag.product2(x, x);
        let xxy = dag.product2(xx, y);
        let s = dag.sum2(x, y);
        let r = dag.reciprocal(s);
        let xy = dag.product2(x, y);
        let minus = dag.negate(xy);
        let f0 = dag.sum2(xxy, r);
        let f = dag.sum2(f0, minus);
        let one = dag.constant(1.0);
        let seeds = [vec![Some(one), None], vec![None, Some(one)]];
        let mut lanes = LaneProgram::default();
        lanes.push_group(&mut dag, &[f, xx], &seeds);
        let point = [1.5, -0.25];
        let got = lanes.evaluate(&dag, &point);
        for lane in 0..LANES {
            let scalar = derivative(&mut dag, &[f, xx], |_, i| seeds[lane][i]);
            let expected = dag.evaluate(&scalar, &point);
            for (root, e) in expected.iter().enumerate() {
                let g = got[0][root][lane];
                assert!((g - e).abs() < 1e-14, "lane {lane} root {root}: {g} {e}");
            }
        }
        // d(xx)/dy is structurally zero in lane 1 but lane 0 carries it.
        assert_eq!(got[0][1][1], 0.0);
    }

    #[test]
    fn an_unscaled_single_term_is_no_operation() {
        let mut dag = Dag::default();
        let (x, y) = (dag.input(0), dag.input(1));
        let s = dag.sum2(x, y);
        let n = dag.negate(s);
        let one = dag.constant(1.0);
        let mut lanes = LaneProgram::default();
        lanes.push_group(
            &mut dag,
            &[n],
            &[vec![Some(one), None], vec![Some(one), None]],
        );
        assert_eq!(lanes.tangents.len(), 1, "only the seed");
        assert_eq!(lanes.operation_count(), 0);
        assert!(lanes.roots[0][0].unwrap().negated);
    }
}
