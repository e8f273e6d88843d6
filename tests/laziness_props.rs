//! Property tests over random DAGs of `value.float` → `math.sum` nodes.
//!
//! Node i is a constant `c{i}` feeding a sum `s{i}` that also sums a random subset of earlier
//! sums, so every value has an eager reference computed here in topological order.

mod common;
use common::*;
use proptest::prelude::*;
use std::collections::BTreeSet;
use weft::graph::{Context, Graph};

struct Dag {
    consts: Vec<f64>,
    /// inputs[i]: the earlier sums that s{i} reads.
    inputs: Vec<Vec<usize>>,
}

impl Dag {
    fn from_masks(masks: &[u64]) -> Dag {
        let n = masks.len();
        let inputs = (0..n)
            .map(|i| (0..i).filter(|j| masks[i] >> (j % 64) & 1 == 1).collect())
            .collect();
        let consts = (0..n).map(|i| 0.5 * (i as f64 + 1.0)).collect();
        Dag { consts, inputs }
    }
    fn text(&self, extra_edge: Option<(usize, usize)>) -> String {
        let mut nodes = Vec::new();
        for i in 0..self.consts.len() {
            nodes.push(format!(
                r#""c{i}": {{"type": "value.float", "params": {{"value": {:?}}}}}"#,
                self.consts[i]
            ));
            let mut terms = vec![format!("\"c{i}.out\"")];
            terms.extend(self.inputs[i].iter().map(|j| format!("\"s{j}.out\"")));
            if let Some((from, to)) = extra_edge
                && to == i
            {
                terms.push(format!("\"s{from}.out\""));
            }
            nodes.push(format!(
                r#""s{i}": {{"type": "math.sum", "inputs": {{"terms": [{}]}}}}"#,
                terms.join(", ")
            ));
        }
        let outs: Vec<String> = (0..self.consts.len())
            .map(|i| format!(r#""o{i}": "s{i}.out""#))
            .collect();
        file(&nodes.join(",\n"), &outs.join(", "))
    }
    fn eager(&self) -> Vec<f64> {
        let mut v = vec![0.0; self.consts.len()];
        for i in 0..v.len() {
            // Same summation order as math.sum: its own constant first, then inputs in order.
            let mut s = 0.0 + self.consts[i];
            for &j in &self.inputs[i] {
                s += v[j];
            }
            v[i] = s;
        }
        v
    }
    /// Sums that `t` depends on, itself included.
    fn ancestors(&self, t: usize) -> BTreeSet<usize> {
        let mut seen = BTreeSet::new();
        let mut stack = vec![t];
        while let Some(n) = stack.pop() {
            if seen.insert(n) {
                stack.extend(&self.inputs[n]);
            }
        }
        seen
    }
    /// Sums downstream of sum `k`, itself included.
    fn descendants(&self, k: usize) -> BTreeSet<usize> {
        (k..self.consts.len())
            .filter(|&i| self.ancestors(i).contains(&k))
            .collect()
    }
}

fn evals(g: &Graph, n: usize) -> Vec<(u64, u64)> {
    (0..n)
        .map(|i| {
            (
                g.evaluations(&format!("c{i}")),
                g.evaluations(&format!("s{i}")),
            )
        })
        .collect()
}

fn dag_strategy() -> impl Strategy<Value = (Vec<u64>, usize, usize)> {
    (2usize..40).prop_flat_map(|n| (prop::collection::vec(any::<u64>(), n), 0..n, 0..n))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, ..ProptestConfig::default() })]

    #[test]
    fn lazy_pull_equals_eager_and_touches_only_what_it_needs((masks, target, changed) in dag_strategy()) {
        let mut dag = Dag::from_masks(&masks);
        let n = masks.len();
        let mut g = graph(&dag.text(None));
        let ctx = Context::new(0);

        // 1. Lazy pull gives the eager value, and evaluates exactly the target's ancestors.
        let v = *g.pull(&format!("o{target}"), ctx).unwrap().get::<f64>().unwrap();
        prop_assert_eq!(v.to_bits(), dag.eager()[target].to_bits());
        let need = dag.ancestors(target);
        for (i, (c, s)) in evals(&g, n).into_iter().enumerate() {
            let want = u64::from(need.contains(&i));
            prop_assert_eq!((c, s), (want, want), "node {} (needed: {})", i, need.contains(&i));
        }

        // 2. A second pull is all cache hits: nothing evaluates again.
        let before = evals(&g, n);
        let hits = g.node_stats(&format!("s{target}")).unwrap().cache_hits;
        let v2 = *g.pull(&format!("o{target}"), ctx).unwrap().get::<f64>().unwrap();
        prop_assert_eq!(v2.to_bits(), v.to_bits());
        prop_assert_eq!(evals(&g, n), before.clone());
        prop_assert_eq!(g.node_stats(&format!("s{target}")).unwrap().cache_hits, hits + 1);

        // 3. Changing one constant re-runs exactly (its downstream) ∩ (what the target needs).
        dag.consts[changed] += 1.25;
        g.set_param(&format!("c{changed}"), "value", serde_json::json!(dag.consts[changed])).unwrap();
        let v3 = *g.pull(&format!("o{target}"), ctx).unwrap().get::<f64>().unwrap();
        prop_assert_eq!(v3.to_bits(), dag.eager()[target].to_bits());
        let dirty = dag.descendants(changed);
        for (i, ((c0, s0), (c1, s1))) in before.iter().zip(evals(&g, n)).enumerate() {
            let rerun_s = u64::from(dirty.contains(&i) && need.contains(&i));
            let rerun_c = u64::from(i == changed && need.contains(&i));
            prop_assert_eq!((c1 - c0, s1 - s0), (rerun_c, rerun_s), "node {}", i);
        }
    }

    #[test]
    fn every_cycle_is_rejected_with_its_path((masks, a, b) in dag_strategy()) {
        let dag = Dag::from_masks(&masks);
        // Add an edge s{late} → s{early} where s{early} is an ancestor of s{late}: a cycle.
        let (early, late) = (a.min(b), a.max(b));
        prop_assume!(dag.ancestors(late).contains(&early));
        let err = load_error(&dag.text(Some((late, early))));
        let line = err.lines().find(|l| l.contains("cycle: ")).expect("a cycle error");
        let path: Vec<&str> = line.split("cycle: ").nth(1).unwrap().split(" -> ").collect();
        prop_assert!(path.len() >= 2 && path.first() == path.last(), "{}", line);
        // Every consecutive pair is a real edge (x feeds y).
        for w in path.windows(2) {
            let (x, y): (usize, usize) = (w[0][1..].parse().unwrap(), w[1][1..].parse().unwrap());
            let edge = dag.inputs[y].contains(&x) || (x, y) == (late, early);
            prop_assert!(edge, "{} -> {} is not an edge in {}", w[0], w[1], line);
        }
    }
}

#[test]
fn ten_thousand_node_chain_evaluates_without_deep_recursion() {
    // Evaluation is iterative: a chain much deeper than any call stack allows still works,
    // on a test thread's default stack.
    let n = 10_000;
    let mut nodes = vec![r#""n0": {"type": "value.float", "params": {"value": 1.0}}"#.to_string()];
    for i in 1..n {
        nodes.push(format!(
            r#""n{i}": {{"type": "math.add", "inputs": {{"a": "n{}.out"}}, "params": {{}}}}"#,
            i - 1
        ));
    }
    let mut g = graph(&file(
        &nodes.join(",\n"),
        &format!(r#""out": "n{}.out""#, n - 1),
    ));
    assert_eq!(
        *g.pull("out", Context::new(0))
            .unwrap()
            .get::<f64>()
            .unwrap(),
        1.0
    );
    g.set_param("n0", "value", serde_json::json!(2.0)).unwrap();
    assert_eq!(
        *g.pull("out", Context::new(0))
            .unwrap()
            .get::<f64>()
            .unwrap(),
        2.0
    );
    assert_eq!(g.evaluations(&format!("n{}", n - 1)), 2);
}
