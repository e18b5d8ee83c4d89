//! Straight-line programs: polynomials in the generated function's inputs
//! turned into a shared expression DAG (greedy multivariate Horner scheme,
//! then common subexpressions computed once).
//!
//! This part is plain Rust on `f64` coefficients; Symbolica only produces the
//! polynomials (see `lagrangian.rs`).

use std::collections::HashMap;

/// A polynomial in the program inputs: exponent vector -> coefficient.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Poly {
    terms: Vec<(Vec<u32>, f64)>,
}

impl Poly {
    /// Builds a polynomial from terms; equal monomials are merged and zero
    /// coefficients dropped. Terms are kept sorted so output is deterministic.
    pub fn from_terms(terms: impl IntoIterator<Item = (Vec<u32>, f64)>) -> Poly {
        let mut merged: Vec<(Vec<u32>, f64)> = Vec::new();
        let mut sorted: Vec<_> = terms.into_iter().collect();
        sorted.sort_by(|a, b| a.0.cmp(&b.0));
        for (exponents, coefficient) in sorted {
            match merged.last_mut() {
                Some((last, c)) if *last == exponents => *c += coefficient,
                _ => merged.push((exponents, coefficient)),
            }
        }
        merged.retain(|(_, c)| *c != 0.0);
        Poly { terms: merged }
    }

    pub fn terms(&self) -> &[(Vec<u32>, f64)] {
        &self.terms
    }

    pub fn is_zero(&self) -> bool {
        self.terms.is_empty()
    }

    /// Rewrites `c^2` as `1 - s^2` for each (sine, cosine) input pair until
    /// every cosine has degree <= 1: a canonical form modulo s^2 + c^2 = 1
    /// that merges terms the plain expansion keeps apart.
    pub fn reduce_trig(&self, pairs: &[(usize, usize)]) -> Poly {
        let mut pending: Vec<(Vec<u32>, f64)> = self.terms.clone();
        let mut done = Vec::new();
        while let Some((exponents, coefficient)) = pending.pop() {
            match pairs.iter().find(|&&(_, c)| exponents[c] >= 2) {
                Some(&(s, c)) => {
                    let mut one = exponents.clone();
                    one[c] -= 2;
                    let mut minus_s2 = one.clone();
                    minus_s2[s] += 2;
                    pending.push((one, coefficient));
                    pending.push((minus_s2, -coefficient));
                }
                None => done.push((exponents, coefficient)),
            }
        }
        Poly::from_terms(done)
    }
}

/// A node of the expression DAG.
#[derive(Debug, Clone, PartialEq)]
pub enum Node {
    Input(usize),
    Const(f64),
    Add(Vec<NodeId>),
    Mul(Vec<NodeId>),
    Neg(NodeId),
}

pub type NodeId = usize;

#[derive(Debug, Clone, PartialEq, Eq, Hash)]
enum Key {
    Input(usize),
    Const(u64),
    Add(Vec<NodeId>),
    Mul(Vec<NodeId>),
    Neg(NodeId),
}

/// A hash-consed expression DAG: equal subexpressions get one node.
#[derive(Debug, Default)]
pub struct Dag {
    pub nodes: Vec<Node>,
    index: HashMap<Key, NodeId>,
}

impl Dag {
    fn intern(&mut self, node: Node) -> NodeId {
        let key = match &node {
            Node::Input(i) => Key::Input(*i),
            Node::Const(c) => Key::Const(c.to_bits()),
            Node::Add(a) => Key::Add(a.clone()),
            Node::Mul(m) => Key::Mul(m.clone()),
            Node::Neg(n) => Key::Neg(*n),
        };
        if let Some(&id) = self.index.get(&key) {
            return id;
        }
        self.nodes.push(node);
        self.index.insert(key, self.nodes.len() - 1);
        self.nodes.len() - 1
    }

    pub fn input(&mut self, i: usize) -> NodeId {
        self.intern(Node::Input(i))
    }

    pub fn constant(&mut self, c: f64) -> NodeId {
        self.intern(Node::Const(c))
    }

    fn constant_value(&self, id: NodeId) -> Option<f64> {
        match self.nodes[id] {
            Node::Const(c) => Some(c),
            _ => None,
        }
    }

    /// Sum with constants folded and operands in canonical order.
    pub fn add(&mut self, operands: Vec<NodeId>) -> NodeId {
        let mut constant = 0.0;
        let mut rest = Vec::new();
        for id in operands {
            match (self.constant_value(id), &self.nodes[id]) {
                (Some(c), _) => constant += c,
                (_, Node::Add(inner)) => rest.extend(inner.clone()),
                _ => rest.push(id),
            }
        }
        if constant != 0.0 {
            rest.push(self.constant(constant));
        }
        rest.sort_unstable();
        match rest.len() {
            0 => self.constant(0.0),
            1 => rest[0],
            _ => self.intern(Node::Add(rest)),
        }
    }

    /// Product with constants folded; a factor of -1 becomes a negation.
    pub fn mul(&mut self, operands: Vec<NodeId>) -> NodeId {
        let mut constant = 1.0;
        let mut rest = Vec::new();
        for id in operands {
            match (self.constant_value(id), &self.nodes[id]) {
                (Some(c), _) => constant *= c,
                (_, Node::Mul(inner)) => rest.extend(inner.clone()),
                _ => rest.push(id),
            }
        }
        if constant == 0.0 {
            return self.constant(0.0);
        }
        rest.sort_unstable();
        let product = match rest.len() {
            0 => return self.constant(constant),
            1 => rest[0],
            _ => self.intern(Node::Mul(rest)),
        };
        if constant == 1.0 {
            product
        } else if constant == -1.0 {
            self.intern(Node::Neg(product))
        } else {
            let c = self.constant(constant);
            self.intern(Node::Mul(vec![c, product]))
        }
    }

    /// `a + b` without flattening, so a traced recursion keeps its shared
    /// partial sums; zeros and constant pairs fold.
    pub fn sum2(&mut self, a: NodeId, b: NodeId) -> NodeId {
        match (self.constant_value(a), self.constant_value(b)) {
            (Some(x), Some(y)) => self.constant(x + y),
            (Some(0.0), _) => b,
            (_, Some(0.0)) => a,
            _ => self.intern(Node::Add(vec![a.min(b), a.max(b)])),
        }
    }

    /// `a * b` without flattening; zeros, ones and constant pairs fold, a
    /// constant goes first and negations move outwards (emitted as `-`).
    pub fn product2(&mut self, a: NodeId, b: NodeId) -> NodeId {
        match (self.constant_value(a), self.constant_value(b)) {
            (Some(x), Some(y)) => return self.constant(x * y),
            (Some(x), _) | (_, Some(x)) if x == 0.0 => return self.constant(0.0),
            (Some(1.0), _) => return b,
            (_, Some(1.0)) => return a,
            (Some(-1.0), _) => return self.negate(b),
            (_, Some(-1.0)) => return self.negate(a),
            _ => {}
        }
        if let Node::Neg(x) = self.nodes[a] {
            let p = self.product2(x, b);
            return self.negate(p);
        }
        if let Node::Neg(y) = self.nodes[b] {
            let p = self.product2(a, y);
            return self.negate(p);
        }
        let operands = match self.constant_value(b) {
            Some(_) => vec![b, a],
            None if self.constant_value(a).is_some() => vec![a, b],
            None => vec![a.min(b), a.max(b)],
        };
        self.intern(Node::Mul(operands))
    }

    /// `-a`, folding constants and double negations; `-(k * x)` becomes
    /// `(-k) * x`, no separate negation.
    pub fn negate(&mut self, a: NodeId) -> NodeId {
        match &self.nodes[a] {
            Node::Const(c) => self.constant(-c),
            Node::Neg(x) => *x,
            Node::Mul(ops) if ops.len() == 2 && self.constant_value(ops[0]).is_some() => {
                let (c, x) = (ops[0], ops[1]);
                let minus = self.negate(c);
                self.intern(Node::Mul(vec![minus, x]))
            }
            _ => self.intern(Node::Neg(a)),
        }
    }

    /// Values of `roots` for input values `x` (tests and checks).
    pub fn evaluate(&self, roots: &[NodeId], x: &[f64]) -> Vec<f64> {
        let mut values: Vec<f64> = Vec::with_capacity(self.nodes.len());
        for node in &self.nodes {
            let v = match node {
                Node::Input(i) => x[*i],
                Node::Const(c) => *c,
                Node::Add(ops) => ops.iter().map(|&o| values[o]).sum(),
                Node::Mul(ops) => ops.iter().map(|&o| values[o]).product(),
                Node::Neg(n) => -values[*n],
            };
            values.push(v);
        }
        roots.iter().map(|&r| values[r]).collect()
    }

    /// A polynomial by a greedy multivariate Horner scheme: factor out the
    /// input of highest `priority` that occurs in the most terms, recurse on
    /// both parts. Equal priorities everywhere give the plain greedy scheme.
    pub fn horner(&mut self, poly: &Poly, priority: &[u8]) -> NodeId {
        self.horner_terms(poly.terms().to_vec(), priority)
    }

    fn horner_terms(&mut self, terms: Vec<(Vec<u32>, f64)>, priority: &[u8]) -> NodeId {
        let Some(width) = terms.first().map(|t| t.0.len()) else {
            return self.constant(0.0);
        };
        let counts: Vec<usize> = (0..width)
            .map(|v| terms.iter().filter(|t| t.0[v] > 0).count())
            .collect();
        let best = (0..width)
            .filter(|&v| counts[v] > 0)
            .max_by_key(|&v| (priority[v], counts[v], std::cmp::Reverse(v)));
        let Some(v) = best.filter(|&v| counts[v] > 0) else {
            let sum = terms.iter().map(|t| t.1).sum();
            return self.constant(sum);
        };
        if counts[v] == 1 && terms.len() == 1 {
            return self.monomial(&terms[0]);
        }
        let (mut with, without): (Vec<_>, Vec<_>) = terms.into_iter().partition(|t| t.0[v] > 0);
        for t in &mut with {
            t.0[v] -= 1;
        }
        let x = self.input(v);
        let inner = self.horner_terms(with, priority);
        let factored = self.mul(vec![x, inner]);
        if without.is_empty() {
            return factored;
        }
        let rest = self.horner_terms(without, priority);
        self.add(vec![factored, rest])
    }

    fn monomial(&mut self, (exponents, coefficient): &(Vec<u32>, f64)) -> NodeId {
        let mut factors = vec![self.constant(*coefficient)];
        for (v, &e) in exponents.iter().enumerate() {
            let x = self.input(v);
            factors.extend(std::iter::repeat_n(x, e as usize));
        }
        self.mul(factors)
    }

    /// Arithmetic operations needed to evaluate `roots` (each shared node once).
    pub fn operation_count(&self, roots: &[NodeId]) -> usize {
        let mut seen = vec![false; self.nodes.len()];
        let mut stack: Vec<NodeId> = roots.to_vec();
        let mut count = 0;
        while let Some(id) = stack.pop() {
            if std::mem::replace(&mut seen[id], true) {
                continue;
            }
            match &self.nodes[id] {
                Node::Add(ops) | Node::Mul(ops) => {
                    count += ops.len() - 1;
                    stack.extend(ops);
                }
                Node::Neg(n) => {
                    count += 1;
                    stack.push(*n);
                }
                Node::Input(_) | Node::Const(_) => {}
            }
        }
        count
    }

    /// `operation_count` with negations that only feed sums left out: the
    /// emitter writes `a + (-b)` as `a - b`.
    pub fn negation_aware_count(&self, roots: &[NodeId]) -> usize {
        let reachable = self.reachable(roots);
        let mut free = vec![true; self.nodes.len()];
        for &r in roots {
            free[r] = false;
        }
        for id in (0..self.nodes.len()).filter(|&id| reachable[id]) {
            match &self.nodes[id] {
                Node::Mul(ops) => ops.iter().for_each(|&o| free[o] = false),
                Node::Neg(x) => free[*x] = false,
                _ => {}
            }
        }
        let free_negations = (0..self.nodes.len())
            .filter(|&id| reachable[id] && free[id] && matches!(self.nodes[id], Node::Neg(_)))
            .count();
        self.operation_count(roots) - free_negations
    }

    fn reachable(&self, roots: &[NodeId]) -> Vec<bool> {
        let mut seen = vec![false; self.nodes.len()];
        let mut stack: Vec<NodeId> = roots.to_vec();
        while let Some(id) = stack.pop() {
            if std::mem::replace(&mut seen[id], true) {
                continue;
            }
            match &self.nodes[id] {
                Node::Add(ops) | Node::Mul(ops) => stack.extend(ops),
                Node::Neg(n) => stack.push(*n),
                Node::Input(_) | Node::Const(_) => {}
            }
        }
        seen
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn eval(dag: &Dag, id: NodeId, x: &[f64]) -> f64 {
        match &dag.nodes[id] {
            Node::Input(i) => x[*i],
            Node::Const(c) => *c,
            Node::Add(ops) => ops.iter().map(|&o| eval(dag, o, x)).sum(),
            Node::Mul(ops) => ops.iter().map(|&o| eval(dag, o, x)).product(),
            Node::Neg(n) => -eval(dag, *n, x),
        }
    }

    fn eval_poly(p: &Poly, x: &[f64]) -> f64 {
        p.terms()
            .iter()
            .map(|(e, c)| {
                c * e
                    .iter()
                    .zip(x)
                    .map(|(&k, v)| v.powi(k as i32))
                    .product::<f64>()
            })
            .sum()
    }

    #[test]
    fn horner_evaluates_like_the_polynomial() {
        let p = Poly::from_terms([
            (vec![2, 0, 1], 3.0),
            (vec![1, 1, 0], -2.0),
            (vec![0, 0, 0], 0.5),
            (vec![1, 0, 1], 4.0),
            (vec![0, 3, 0], -1.0),
        ]);
        let mut dag = Dag::default();
        let root = dag.horner(&p, &[0, 0, 0]);
        for x in [[0.3, -1.2, 2.0], [1.5, 0.1, -0.7]] {
            assert!((eval(&dag, root, &x) - eval_poly(&p, &x)).abs() < 1e-12);
        }
    }

    #[test]
    fn negations_fold_into_constants_and_subtractions_are_free() {
        let mut dag = Dag::default();
        let (a, b) = (dag.input(0), dag.input(1));
        let k = dag.constant(2.5);
        let scaled = dag.product2(k, b);
        let minus = dag.negate(scaled);
        let minus_k = dag.constant(-2.5);
        assert_eq!(dag.nodes[minus], Node::Mul(vec![minus_k, b]));
        let nb = dag.negate(b);
        let difference = dag.sum2(a, nb);
        assert_eq!(dag.operation_count(&[difference]), 2);
        assert_eq!(dag.negation_aware_count(&[difference]), 1);
        assert_eq!(dag.negation_aware_count(&[nb]), 1);
    }

    #[test]
    fn equal_subexpressions_share_one_node() {
        let mut dag = Dag::default();
        let a = dag.input(0);
        let b = dag.input(1);
        let first = dag.mul(vec![a, b]);
        let second = dag.mul(vec![b, a]);
        assert_eq!(first, second);
        assert_eq!(dag.operation_count(&[first, second]), 1);
    }

    #[test]
    fn trig_reduction_keeps_value_and_lowers_cosine_degree() {
        // inputs: s = 0, c = 1, x = 2
        let p = Poly::from_terms([
            (vec![0, 3, 1], 2.0),
            (vec![2, 2, 0], 1.0),
            (vec![0, 2, 0], 1.0),
        ]);
        let r = p.reduce_trig(&[(0, 1)]);
        assert!(r.terms().iter().all(|(e, _)| e[1] <= 1));
        for angle in [0.3_f64, -2.1] {
            let x = [angle.sin(), angle.cos(), 0.7];
            assert!((eval_poly(&p, &x) - eval_poly(&r, &x)).abs() < 1e-12);
        }
    }
}
