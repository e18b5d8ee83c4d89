//! Exact first derivatives of straight-line programs by forward-mode
//! differentiation on the expression DAG: the chain rule applied node by
//! node, in evaluation order, so each derivative is itself a program over
//! the same inputs and named constants. Nodes that do not depend on the
//! variable get no derivative node (zero), which keeps the result as sparse
//! as the dependence: joint j's angle moves only the bodies beyond it.

use crate::program::{Dag, Node, NodeId};

/// The derivatives of `roots` with respect to one variable, given each
/// program input's derivative with respect to it (`None`: zero).
pub fn derivative(
    dag: &mut Dag,
    roots: &[NodeId],
    mut input: impl FnMut(&mut Dag, usize) -> Option<NodeId>,
) -> Vec<NodeId> {
    let reachable = dag.reachable(roots);
    let mut derivatives: Vec<Option<NodeId>> = vec![None; reachable.len()];
    // Operands precede the nodes built from them, so index order is an
    // evaluation order.
    for id in (0..reachable.len()).filter(|&id| reachable[id]) {
        let node = dag.nodes[id].clone();
        let d = |k: NodeId| derivatives[k];
        derivatives[id] = match node {
            Node::Input(i) => input(dag, i),
            Node::Const(_) | Node::Param(_) => None,
            Node::Add(ops) => {
                let terms: Vec<NodeId> = ops.iter().filter_map(|&o| d(o)).collect();
                terms.into_iter().reduce(|a, b| dag.sum2(a, b))
            }
            Node::Mul(ops) => product_rule(dag, &ops, &derivatives),
            Node::Neg(x) => d(x).map(|dx| dag.negate(dx)),
            Node::Recip(x) => d(x).map(|dx| {
                // d(1/x) = -(1/x)^2 dx.
                let square = dag.product2(id, id);
                let scaled = dag.product2(square, dx);
                dag.negate(scaled)
            }),
        };
    }
    let zero = dag.constant(0.0);
    roots
        .iter()
        .map(|&r| derivatives[r].unwrap_or(zero))
        .collect()
}

/// d(a b c ...) = da b c + a db c + ...: one term per factor that varies.
fn product_rule(dag: &mut Dag, ops: &[NodeId], derivatives: &[Option<NodeId>]) -> Option<NodeId> {
    let mut total: Option<NodeId> = None;
    for (k, &op) in ops.iter().enumerate() {
        let Some(mut term) = derivatives[op] else {
            continue;
        };
        for (l, &other) in ops.iter().enumerate() {
            if l != k {
                term = dag.product2(other, term);
            }
        }
        total = Some(match total {
            Some(sum) => dag.sum2(sum, term),
            None => term,
        });
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_chain_rule_holds_node_by_node() {
        // f(x, y) = x^2 y + 1 / (x + y); df/dx = 2 x y - 1 / (x + y)^2.
        let mut dag = Dag::default();
        let (x, y) = (dag.input(0), dag.input(1));
        let xx = dag.product2(x, x);
        let xxy = dag.product2(xx, y);
        let s = dag.sum2(x, y);
        let r = dag.reciprocal(s);
        let f = dag.sum2(xxy, r);
        let one = dag.constant(1.0);
        let df = derivative(&mut dag, &[f], |_, i| (i == 0).then_some(one));
        let (a, b) = (1.5, -0.25);
        let value = dag.evaluate(&df, &[a, b])[0];
        let expected = 2.0 * a * b - 1.0 / ((a + b) * (a + b));
        assert!((value - expected).abs() < 1e-15, "{value} {expected}");
    }

    #[test]
    fn what_does_not_depend_on_the_variable_has_no_derivative_node() {
        let mut dag = Dag::default();
        let y = dag.input(1);
        let yy = dag.product2(y, y);
        let (one, zero) = (dag.constant(1.0), dag.constant(0.0));
        let before = dag.nodes.len();
        let d = derivative(&mut dag, &[yy], |dag, i| {
            (i == 0).then(|| dag.input(0)).map(|_| one)
        });
        assert_eq!(d, [zero]);
        assert_eq!(dag.nodes.len(), before, "no node was added");
    }
}
