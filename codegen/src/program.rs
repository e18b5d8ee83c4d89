//! Straight-line programs: a hash-consed expression DAG over the generated
//! function's inputs and the description's named constants.
//!
//! Named constants (`Node::Param`) are leaves like the inputs, so a program's
//! shape depends on which constants are zero, never on their values: editing
//! a number in the description changes the constant's line, not the code
//! that uses it. Subexpressions of constants alone are free at run time (the
//! compiler folds them) and are not counted as operations.
//!
//! This part is plain Rust; Symbolica only produces the polynomials of the
//! cross-check (see `lagrangian.rs`).

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

    /// The value at input values `x`.
    pub fn evaluate(&self, x: &[f64]) -> f64 {
        self.terms
            .iter()
            .map(|(e, c)| {
                let monomial: f64 = e.iter().zip(x).map(|(&k, v)| v.powi(k as i32)).product();
                c * monomial
            })
            .sum()
    }
}

/// A node of the expression DAG.
#[derive(Debug, Clone, PartialEq)]
pub enum Node {
    Input(usize),
    /// A literal: only structural numbers (0, 1, -1, 2, 1/2) and folds of them.
    Const(f64),
    /// A named constant of the description (index into `Dag::params`).
    Param(usize),
    Add(Vec<NodeId>),
    Mul(Vec<NodeId>),
    Neg(NodeId),
    /// 1 / x: the pivots of a factorized mass matrix.
    Recip(NodeId),
}

impl Node {
    /// The nodes this one is computed from.
    pub fn operands(&self) -> &[NodeId] {
        match self {
            Node::Add(ops) | Node::Mul(ops) => ops,
            Node::Neg(x) | Node::Recip(x) => std::slice::from_ref(x),
            Node::Input(_) | Node::Const(_) | Node::Param(_) => &[],
        }
    }

    /// Whether the node computes something (not a leaf).
    pub fn is_compound(&self) -> bool {
        !self.operands().is_empty()
    }
}

pub type NodeId = usize;

/// A named constant: its Rust name and value.
#[derive(Debug, Clone, PartialEq)]
pub struct Param {
    pub name: String,
    pub value: f64,
}

#[derive(Debug, Clone, PartialEq, Eq, Hash)]
enum Key {
    Input(usize),
    Const(u64),
    Param(usize),
    Add(Vec<NodeId>),
    Mul(Vec<NodeId>),
    Neg(NodeId),
    Recip(NodeId),
}

/// A hash-consed expression DAG: equal subexpressions get one node.
#[derive(Debug, Default)]
pub struct Dag {
    pub nodes: Vec<Node>,
    /// The leaves' names and values, in the order they were first used.
    pub params: Vec<Param>,
    /// Names given to compound constant nodes (derived constants, emitted as
    /// `const NAME: f64 = expression;` and used by name), in naming order.
    pub derived: Vec<(String, NodeId)>,
    derived_names: HashMap<NodeId, usize>,
    constant: Vec<bool>,
    index: HashMap<Key, NodeId>,
    param_index: HashMap<String, usize>,
}

impl Dag {
    fn intern(&mut self, node: Node) -> NodeId {
        let key = match &node {
            Node::Input(i) => Key::Input(*i),
            Node::Const(c) => Key::Const(c.to_bits()),
            Node::Param(p) => Key::Param(*p),
            Node::Add(a) => Key::Add(a.clone()),
            Node::Mul(m) => Key::Mul(m.clone()),
            Node::Neg(n) => Key::Neg(*n),
            Node::Recip(n) => Key::Recip(*n),
        };
        if let Some(&id) = self.index.get(&key) {
            return id;
        }
        let constant = match &node {
            Node::Input(_) => false,
            Node::Const(_) | Node::Param(_) => true,
            compound => compound.operands().iter().all(|&o| self.constant[o]),
        };
        self.nodes.push(node);
        self.constant.push(constant);
        self.index.insert(key, self.nodes.len() - 1);
        self.nodes.len() - 1
    }

    pub fn input(&mut self, i: usize) -> NodeId {
        self.intern(Node::Input(i))
    }

    pub fn constant(&mut self, c: f64) -> NodeId {
        self.intern(Node::Const(c))
    }

    /// The named constant `name` (a Rust identifier) with `value`; the first
    /// value given for a name is kept.
    pub fn param(&mut self, name: &str, value: f64) -> NodeId {
        let index = match self.param_index.get(name) {
            Some(&index) => index,
            None => {
                self.params.push(Param {
                    name: name.to_string(),
                    value,
                });
                self.param_index
                    .insert(name.to_string(), self.params.len() - 1);
                self.params.len() - 1
            }
        };
        self.intern(Node::Param(index))
    }

    /// `1 / a`, folding literals and double reciprocals.
    pub fn reciprocal(&mut self, a: NodeId) -> NodeId {
        match self.nodes[a] {
            Node::Const(c) => self.constant(1.0 / c),
            Node::Recip(x) => x,
            _ => self.intern(Node::Recip(a)),
        }
    }

    /// Names a compound constant node (a derived constant); leaves and
    /// nodes already named keep their name.
    pub fn name(&mut self, id: NodeId, name: &str) -> NodeId {
        let compound = self.nodes[id].is_compound();
        if self.constant[id] && compound && !self.derived_names.contains_key(&id) {
            self.derived_names.insert(id, self.derived.len());
            self.derived.push((name.to_string(), id));
        }
        id
    }

    /// The name of a derived constant node.
    pub fn derived_name(&self, id: NodeId) -> Option<&str> {
        self.derived_names
            .get(&id)
            .map(|&k| self.derived[k].0.as_str())
    }

    /// Whether `id` is the literal 0.
    pub fn is_literal_zero(&self, id: NodeId) -> bool {
        self.constant_value(id) == Some(0.0)
    }

    /// Whether `id` depends on constants only (folded at compile time).
    pub fn is_constant(&self, id: NodeId) -> bool {
        self.constant[id]
    }

    fn constant_value(&self, id: NodeId) -> Option<f64> {
        match self.nodes[id] {
            Node::Const(c) => Some(c),
            _ => None,
        }
    }

    /// `a + b` without flattening, so a traced recursion keeps its shared
    /// partial sums; zeros, literal pairs and `x + (-x)` fold.
    pub fn sum2(&mut self, a: NodeId, b: NodeId) -> NodeId {
        match (self.constant_value(a), self.constant_value(b)) {
            (Some(x), Some(y)) => return self.constant(x + y),
            (Some(0.0), _) => return b,
            (_, Some(0.0)) => return a,
            _ => {}
        }
        if self.nodes[a] == Node::Neg(b) || self.nodes[b] == Node::Neg(a) {
            return self.constant(0.0);
        }
        self.intern(Node::Add(vec![a.min(b), a.max(b)]))
    }

    /// `a * b` without flattening; zeros, ones and literal pairs fold, a
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
        let operands = match (self.constant[a], self.constant[b]) {
            (false, true) => vec![b, a],
            (true, false) => vec![a, b],
            _ => vec![a.min(b), a.max(b)],
        };
        self.intern(Node::Mul(operands))
    }

    /// `-a`, folding literals and double negations; `-(k * x)` with a
    /// constant k becomes `(-k) * x`, no separate negation.
    pub fn negate(&mut self, a: NodeId) -> NodeId {
        match &self.nodes[a] {
            Node::Const(c) => self.constant(-c),
            Node::Neg(x) => *x,
            Node::Mul(ops) if ops.len() == 2 && self.constant[ops[0]] && !self.constant[a] => {
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
                Node::Param(p) => self.params[*p].value,
                Node::Add(ops) => ops.iter().map(|&o| values[o]).sum(),
                Node::Mul(ops) => ops.iter().map(|&o| values[o]).product(),
                Node::Neg(n) => -values[*n],
                Node::Recip(n) => 1.0 / values[*n],
            };
            values.push(v);
        }
        roots.iter().map(|&r| values[r]).collect()
    }

    /// Run-time arithmetic operations of `roots` (each shared node once;
    /// constant subexpressions are free).
    pub fn operation_count(&self, roots: &[NodeId]) -> usize {
        let reachable = self.reachable(roots);
        (0..self.nodes.len())
            .filter(|&id| reachable[id] && !self.constant[id])
            .map(|id| match &self.nodes[id] {
                Node::Add(ops) | Node::Mul(ops) => ops.len() - 1,
                Node::Neg(_) | Node::Recip(_) => 1,
                _ => 0,
            })
            .sum()
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
                Node::Neg(x) | Node::Recip(x) => free[*x] = false,
                _ => {}
            }
        }
        let free_negations = (0..self.nodes.len())
            .filter(|&id| {
                reachable[id]
                    && free[id]
                    && !self.constant[id]
                    && matches!(self.nodes[id], Node::Neg(_))
            })
            .count();
        self.operation_count(roots) - free_negations
    }

    /// The nodes `roots` depend on.
    pub fn reachable(&self, roots: &[NodeId]) -> Vec<bool> {
        let mut seen = vec![false; self.nodes.len()];
        let mut stack: Vec<NodeId> = roots.to_vec();
        while let Some(id) = stack.pop() {
            if std::mem::replace(&mut seen[id], true) {
                continue;
            }
            stack.extend(self.nodes[id].operands());
        }
        seen
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let first = dag.product2(a, b);
        let second = dag.product2(b, a);
        assert_eq!(first, second);
        assert_eq!(dag.operation_count(&[first, second]), 1);
    }

    #[test]
    fn constants_are_free_and_their_values_never_shape_the_program() {
        let shape = |mass: f64, length: f64| {
            let mut dag = Dag::default();
            let x = dag.input(0);
            let (m, l) = (dag.param("MASS", mass), dag.param("LENGTH", length));
            let ml = dag.product2(m, l);
            let minus = dag.negate(ml);
            let root = dag.product2(minus, x);
            let ops = dag.operation_count(&[root]);
            let value = dag.evaluate(&[root], &[2.0])[0];
            (dag.nodes, ops, value)
        };
        let (first, ops, value) = shape(1.5, 0.25);
        let (second, _, other) = shape(1.0, -3.0);
        assert_eq!(first, second);
        assert_eq!(ops, 1, "only the multiply by x runs");
        assert_eq!(value, -0.75);
        assert_eq!(other, 6.0);
    }

    #[test]
    fn a_constant_minus_itself_is_zero() {
        let mut dag = Dag::default();
        let m = dag.param("MASS", 2.0);
        let minus = dag.negate(m);
        let zero = dag.constant(0.0);
        assert_eq!(dag.sum2(m, minus), zero);
    }
}
