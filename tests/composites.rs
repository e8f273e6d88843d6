//! Subgraphs as node types: plain, iterating (Newton to convergence), stepped.

mod common;
use common::*;
use weft::graph::Context;

/// Newton's method for √c: x ← x − (x² − c)/(2x), until |x² − c| < tol. `twice` depends only
/// on c, so it must run once per solve, not once per iteration.
fn sqrt_graph(max_iterations: u32, on_limit: &str) -> String {
    format!(
        r#"{{"format": "weft-graph", "version": 1,
  "subgraphs": {{"newton_sqrt": {{
      "inputs": {{"c": "float", "x": {{"type": "float", "default": 1.0}}}},
      "nodes": {{
        "twice":    {{"type": "math.scale", "params": {{"factor": 2.0}}, "inputs": {{"x": "in.c"}}}},
        "residual": {{"type": "math.expr", "params": {{"expr": "x^2 - c"}}, "inputs": {{"x": "in.x", "c": "in.c"}}}},
        "update":   {{"type": "math.expr", "params": {{"expr": "x - y/(2*x) + 0*z"}}, "inputs": {{"x": "in.x", "y": "residual.out", "z": "twice.out"}}}},
        "check":    {{"type": "math.below", "params": {{"tolerance": 1e-13}}, "inputs": {{"x": "residual.out"}}}}
      }},
      "outputs": {{"root": "in.x", "residual": "residual.out"}},
      "iterate": {{"feedback": {{"x": "update.out"}}, "until": "check.out", "residual": "residual.out",
                  "max_iterations": {max_iterations}, "on_limit": "{on_limit}"}}
  }}}},
  "nodes": {{
    "c":     {{"type": "value.float", "params": {{"value": 2.0}}}},
    "solve": {{"type": "newton_sqrt", "inputs": {{"c": "c.out"}}}}
  }},
  "outputs": {{"root": "solve.root", "residual": "solve.residual"}}}}"#
    )
}

fn frames_report(g: &weft::graph::Graph, node: &str) -> serde_json::Value {
    g.node_report(node).unwrap()["frames"].clone()
}

#[test]
fn newton_converges_quadratically_to_the_known_root() {
    let mut g = graph(&sqrt_graph(50, "error"));
    let root = f64_at(&mut g, "root", 0);
    assert!((root - 2f64.sqrt()).abs() <= 2.0 * f64::EPSILON, "{root}");
    let frames = frames_report(&g, "solve");
    let its = frames[0]["iterations"].as_array().unwrap();
    let r: Vec<f64> = its
        .iter()
        .map(|i| i["residual"].as_f64().unwrap().abs())
        .collect();
    // From x = 1: residuals 1, 0.25, 6.9e-3, 6.0e-6, 4.5e-12, then below 1e-13.
    assert!(frames[0]["converged"].as_bool().unwrap());
    assert!((5..=7).contains(&r.len()), "{r:?}");
    // Quadratic convergence: r_{k+1} ≈ r_k² / (4c) once close (here within a factor 2).
    for w in r.windows(2).skip(1).take(3) {
        let predicted = w[0] * w[0] / 8.0;
        assert!(
            w[1] < 2.0 * predicted && w[1] > 0.5 * predicted,
            "{} after {}",
            w[1],
            w[0]
        );
    }
    // Stages that do not depend on the iterate run once; those that do, once per iteration.
    let inner = &g.node_report("solve").unwrap()["inner"];
    let count = |id: &str| {
        inner
            .as_array()
            .unwrap()
            .iter()
            .find(|n| n["node"] == id)
            .unwrap()["evaluations"]
            .as_u64()
            .unwrap()
    };
    assert_eq!(count("twice"), 1);
    assert_eq!(count("residual"), r.len() as u64);
    assert_eq!(count("update"), r.len() as u64 - 1);
    // Every iteration is timed per stage.
    assert!(
        its.iter()
            .all(|i| i["seconds"].as_f64().unwrap() >= 0.0 && i["stages"].is_object())
    );
}

#[test]
fn hitting_the_iteration_limit_is_an_error_or_a_warning_as_asked() {
    let mut g = graph(&sqrt_graph(3, "error"));
    let e = g.pull("root", Context::new(0)).unwrap_err().to_string();
    assert!(
        e.starts_with("node 'solve': did not converge after 3 iterations (residual 6.9"),
        "{e}"
    );

    let mut g = graph(&sqrt_graph(3, "warn"));
    let root = f64_at(&mut g, "root", 0);
    // x: 1 → 3/2 → 17/12. The outputs are those of the last iterate checked (17/12, whose
    // residual was reported), not of an update never checked.
    assert_eq!(root, 17.0 / 12.0);
    let w = g.take_warnings();
    assert_eq!(w.len(), 1);
    assert!(
        w[0].message
            .starts_with("did not converge after 3 iterations"),
        "{:?}",
        w
    );
}

#[test]
fn inner_parameters_are_settable_on_the_instance() {
    let mut g = graph(&sqrt_graph(50, "error"));
    f64_at(&mut g, "root", 0);
    let tight = frames_report(&g, "solve")[0]["iterations"]
        .as_array()
        .unwrap()
        .len();
    g.set_param("solve", "check.tolerance", serde_json::json!(1e-3))
        .unwrap();
    let loose_root = f64_at(&mut g, "root", 0);
    let loose = frames_report(&g, "solve")[0]["iterations"]
        .as_array()
        .unwrap()
        .len();
    assert!(loose < tight, "{loose} vs {tight}");
    assert!((loose_root - 2f64.sqrt()).abs() < 1e-3);
    g.set_param("solve", "max_iterations", serde_json::json!(2))
        .unwrap();
    assert!(g.pull("root", Context::new(0)).is_err());
    let e = g
        .set_param("solve", "check.tolerance", serde_json::json!(-1.0))
        .unwrap_err();
    assert_eq!(
        e.describe(),
        "node 'solve': param 'check.tolerance': must be > 0, got -1"
    );
    // An upstream change re-solves.
    g.set_param("solve", "max_iterations", serde_json::json!(50))
        .unwrap();
    g.set_param("c", "value", serde_json::json!(9.0)).unwrap();
    assert!((f64_at(&mut g, "root", 0) - 3.0).abs() < 1e-3);
}

#[test]
fn errors_inside_a_composite_name_the_inner_node() {
    let text = sqrt_graph(50, "error")
        .replace(r#""value": 2.0"#, r#""value": 0.0"#)
        .replace("x - y/(2*x)", "x - y/(0*x)");
    let mut g = graph(&text);
    let e = g.pull("root", Context::new(0)).unwrap_err().to_string();
    assert!(e.starts_with("node 'solve/update': formula gave"), "{e}");
}

#[test]
fn a_plain_subgraph_is_evaluated_lazily_inside() {
    let mut g = example("hypot_static.json");
    assert_eq!(f64_at(&mut g, "hyp2", 0), 13.0);
    assert_eq!(g.evaluations("hyp1"), 1);
    g.set_param("twelve", "value", serde_json::json!(5.0))
        .unwrap();
    // hyp1 does not depend on "twelve": it is not re-run.
    assert!((f64_at(&mut g, "hyp2", 0) - 50f64.sqrt()).abs() < 1e-14);
    assert_eq!(g.evaluations("hyp1"), 1);
    assert_eq!(g.evaluations("hyp2"), 2);
}

#[test]
fn subgraph_mistakes_are_reported_at_load() {
    let bad = sqrt_graph(50, "error")
        .replace(
            r#""feedback": {"x": "update.out"}"#,
            r#""feedback": {"q": "update.out"}"#,
        )
        .replace(r#""until": "check.out""#, r#""until": "residual.out""#);
    let e = load_error(&bad);
    assert!(
        e.contains("feedback names 'q', which is not an input of the subgraph"),
        "{e}"
    );
    assert!(
        e.contains("'until' 'residual.out' is float, must be bool"),
        "{e}"
    );

    let stateful_inside = sqrt_graph(50, "error").replace(
        r#""twice":    {"type": "math.scale""#,
        r#""osc": {"type": "ode.decay"}, "twice":    {"type": "math.scale""#,
    );
    let e = load_error(&stateful_inside);
    assert!(
        e.contains(
            "node 'newton_sqrt/osc': stateful node type 'ode.decay' cannot run inside a subgraph"
        ),
        "{e}"
    );

    let recursive = r#"{"format": "weft-graph", "version": 1,
      "subgraphs": {
        "a": {"nodes": {"x": {"type": "b"}}, "outputs": {"o": "x.o"}},
        "b": {"nodes": {"y": {"type": "a"}}, "outputs": {"o": "y.o"}}},
      "nodes": {"n": {"type": "a"}}, "outputs": {"o": "n.o"}}"#;
    let e = load_error(recursive);
    assert!(
        e.contains("subgraphs instance each other in a cycle: a -> b -> a"),
        "{e}"
    );
}

#[test]
fn a_stepped_output_that_feeds_nothing_needs_an_initial_value() {
    let text = std::fs::read_to_string(graphs_dir().join("stiff_newton.json")).unwrap();
    let e = load_error(&text.replace(r#""initial": 0.0, "#, ""));
    assert!(e.contains("output 'residual' of stepped subgraph 'cubic_decay_step' feeds no input, so it needs an 'initial' value"), "{e}");
}

#[test]
fn an_optional_subgraph_input_left_unconnected_reads_as_unconnected_inside() {
    // "offset" is declared with a null default: unconnected outside, the inner math.add
    // reads its own default (0) for it; connected, it takes the value.
    let text = |outer: &str| {
        format!(
            r#"{{"format": "weft-graph", "version": 1,
              "subgraphs": {{"shift": {{
                "inputs": {{"x": {{"type": "float"}}, "offset": {{"type": "float", "doc": "optional", "default": null}}}},
                "nodes": {{"add": {{"type": "math.add", "inputs": {{"a": "in.x", "b": "in.offset"}}}}}},
                "outputs": {{"y": {{"from": "add.out"}}}}}}}},
              "nodes": {{"x": {{"type": "value.float", "params": {{"value": 2.0}}}},
                        "three": {{"type": "value.float", "params": {{"value": 3.0}}}},
                        "s": {{"type": "shift", "inputs": {{"x": "x.out"{outer}}}}}}},
              "outputs": {{"y": "s.y"}}}}"#
        )
    };
    assert_eq!(f64_at(&mut graph(&text("")), "y", 0), 2.0);
    assert_eq!(
        f64_at(&mut graph(&text(r#", "offset": "three.out""#)), "y", 0),
        5.0
    );
}

/// The header every graph file starts with.
const H: &str = r#""format": "weft-graph", "version": 1"#;

#[test]
fn stateful_nodes_are_refused_inside_subgraphs_at_any_depth() {
    // Inside a plain subgraph the oscillator would restart whenever its input changed.
    let plain = format!(
        r#"{{{H}, "subgraphs": {{"wrap": {{"inputs": {{"d": "float"}},
          "nodes": {{"o": {{"type": "ode.oscillator", "inputs": {{"drive": "in.d"}}}}}}, "outputs": {{"x": "o.x"}}}}}},
          "nodes": {{"t": {{"type": "time.frame"}}, "w": {{"type": "wrap", "inputs": {{"d": "t.time"}}}}}},
          "outputs": {{"x": "w.x"}}}}"#
    );
    let e = load_error(&plain);
    assert!(
        e.contains(
            "node 'wrap/o': stateful node type 'ode.oscillator' cannot run inside a subgraph"
        ),
        "{e}"
    );
    // Nor through a plain wrapper inside an iterating subgraph.
    let nested = format!(
        r#"{{{H}, "subgraphs": {{
            "W": {{"nodes": {{"d": {{"type": "ode.decay"}}}}, "outputs": {{"y": "d.y"}}}},
            "L": {{"inputs": {{"x": {{"type": "float", "default": 0.0}}}},
                   "nodes": {{"w": {{"type": "W"}}, "b": {{"type": "math.below", "params": {{"tolerance": 10.0}}, "inputs": {{"x": "w.y"}}}}}},
                   "outputs": {{"y": "w.y"}}, "iterate": {{"feedback": {{}}, "until": "b.out"}}}}}},
          "nodes": {{"l": {{"type": "L"}}}}, "outputs": {{"y": "l.y"}}}}"#
    );
    let e = load_error(&nested);
    assert!(
        e.contains("node 'W/d': stateful node type 'ode.decay' cannot run inside a subgraph"),
        "{e}"
    );
}

#[test]
fn a_loop_whose_stop_test_reads_time_is_time_dependent() {
    // n counts up from 0 until n ≈ t: the output depends on the frame only through `until`.
    let text = format!(
        r#"{{{H}, "subgraphs": {{"loop": {{"inputs": {{"x": {{"type": "float", "default": 0.0}}}},
          "nodes": {{"one": {{"type": "value.float", "params": {{"value": 1.0}}}},
                     "inc": {{"type": "math.add", "inputs": {{"a": "in.x", "b": "one.out"}}}},
                     "t": {{"type": "time.frame"}},
                     "d": {{"type": "math.expr", "params": {{"expr": "x - y"}}, "inputs": {{"x": "inc.out", "y": "t.time"}}}},
                     "ok": {{"type": "math.below", "params": {{"tolerance": 0.5}}, "inputs": {{"x": "d.out"}}}}}},
          "outputs": {{"n": "inc.out"}},
          "iterate": {{"feedback": {{"x": "inc.out"}}, "until": "ok.out", "max_iterations": 100}}}}}},
          "nodes": {{"l": {{"type": "loop"}}}}, "outputs": {{"n": "l.n"}}}}"#
    );
    let mut g = graph(&text);
    assert_eq!(g.output_is_time_dependent("n"), Some(true));
    assert_eq!(f64_at_fps(&mut g, "n", 3, 1.0), 3.0);
    assert_eq!(f64_at_fps(&mut g, "n", 5, 1.0), 5.0);
}

#[test]
fn loop_tests_must_name_inner_outputs() {
    let text = format!(
        r#"{{{H}, "subgraphs": {{"loop": {{"inputs": {{"x": "float", "stop": {{"type": "bool", "default": true}}}},
          "nodes": {{"s": {{"type": "math.scale", "inputs": {{"x": "in.x"}}}}}},
          "outputs": {{"y": "s.out"}}, "iterate": {{"feedback": {{"x": "s.out"}}, "until": "in.stop"}}}}}},
          "nodes": {{"c": {{"type": "value.float", "params": {{"value": 2.0}}}}, "l": {{"type": "loop", "inputs": {{"x": "c.out"}}}}}},
          "outputs": {{"y": "l.y"}}}}"#
    );
    let e = load_error(&text);
    assert!(
        e.contains("'until' 'in.stop' is not an output of a node in the subgraph"),
        "{e}"
    );
}

#[test]
fn step_feedback_types_must_match() {
    let text = format!(
        r#"{{{H}, "subgraphs": {{"st": {{"inputs": {{"x": "float"}},
          "nodes": {{"m": {{"type": "vec3.make", "inputs": {{"x": "in.x"}}}}}},
          "outputs": {{"v": "m.out"}}, "step": {{"feedback": {{"x": "v"}}}}}}}},
          "nodes": {{"c": {{"type": "value.float", "params": {{"value": 2.0}}}}, "s": {{"type": "st", "inputs": {{"x": "c.out"}}}}}},
          "outputs": {{"v": "s.v"}}}}"#
    );
    let e = load_error(&text);
    assert!(
        e.contains("step feedback: input 'x' is float but output 'v' is vec3"),
        "{e}"
    );
}

#[test]
fn subgraph_input_defaults_are_validated() {
    for (ty, def, want) in [
        (
            "float",
            r#""abc""#,
            "input 'x': bad default: expected a number",
        ),
        (
            "any",
            "1.5",
            "input 'x': bad default: type 'any' has no JSON form",
        ),
    ] {
        let e = load_error(&format!(
            r#"{{{H}, "subgraphs": {{"p": {{"inputs": {{"x": {{"type": "{ty}", "default": {def}}}}}, "nodes": {{}}, "outputs": {{"y": "in.x"}}}}}},
              "nodes": {{"s": {{"type": "p"}}}}, "outputs": {{"y": "s.y"}}}}"#
        ));
        assert!(e.contains(want), "{ty}: {e}");
    }
}
