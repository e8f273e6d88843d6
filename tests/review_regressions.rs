//! Regressions for defects found in review of the graph engine (each test failed before its fix).

mod common;
use common::*;
use weft::graph::{Context, Kernel, NodeSpec, ParamSpec, Registry, Value, load_str};

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
fn a_disk_cache_notices_an_edit_inside_a_nested_subgraph() {
    let dir = tempfile::tempdir().unwrap();
    let mk = |from: &str| {
        format!(
            r#"{{{H}, "subgraphs": {{
            "B": {{"inputs": {{"x": "float"}},
                   "nodes": {{"s": {{"type": "math.scale", "params": {{"factor": 2.0}}, "inputs": {{"x": "in.x"}}}},
                              "t": {{"type": "math.scale", "params": {{"factor": 3.0}}, "inputs": {{"x": "in.x"}}}}}},
                   "outputs": {{"y": "{from}"}}}},
            "A": {{"inputs": {{"x": "float"}}, "nodes": {{"b": {{"type": "B", "inputs": {{"x": "in.x"}}}}}}, "outputs": {{"y": "b.y"}}}}}},
          "nodes": {{"c": {{"type": "value.float", "params": {{"value": 1.0}}}},
                     "a": {{"type": "A", "inputs": {{"x": "c.out"}}}},
                     "k": {{"type": "cache.disk", "params": {{"path": {:?}}}, "inputs": {{"in": "a.y"}}}}}},
          "outputs": {{"y": "k.out"}}}}"#,
            dir.path().to_str().unwrap()
        )
    };
    assert_eq!(f64_at(&mut graph(&mk("s.out")), "y", 0), 2.0);
    assert_eq!(f64_at(&mut graph(&mk("t.out")), "y", 0), 3.0);
}

#[test]
fn long_non_ascii_parameter_values_do_not_panic() {
    let s = format!("a{}", "é".repeat(80));
    let e = load_error(&format!(
        r#"{{{H}, "nodes": {{"c": {{"type": "value.float", "params": {{"value": "{s}"}}}}}}, "outputs": {{"y": "c.out"}}}}"#
    ));
    assert!(
        e.contains("expected a number, got \"aééé") && e.contains("…"),
        "{e}"
    );
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

#[test]
fn a_parameter_that_types_an_output_cannot_change_after_load() {
    let mut reg = Registry::new();
    weft::nodes::register_all(&mut reg).unwrap();
    reg.register(
        NodeSpec::new("parse", "JSON to a value of the named type")
            .output("out", "param:type", "value")
            .param(ParamSpec::string("type", "float").doc("port type"))
            .param(ParamSpec::json("value", serde_json::json!(1.0)).doc("the value")),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let t = cx.params().str("type")?.to_string();
                let j = cx.params().get("value").cloned().unwrap_or_default();
                let f = cx
                    .registry()
                    .port_type(&t)
                    .and_then(|p| p.from_json)
                    .expect("checked at load");
                let v: Value = f(&j).map_err(weft::graph::NodeError::Failed)?;
                cx.set("out", v);
                Ok(())
            }))
        },
    )
    .unwrap();
    let reg = std::sync::Arc::new(reg);
    let text = format!(
        r#"{{{H}, "nodes": {{"p": {{"type": "parse"}}, "s": {{"type": "math.scale", "inputs": {{"x": "p.out"}}}}}}, "outputs": {{"y": "s.out"}}}}"#
    );
    let mut g = load_str(&reg, &text, "t").unwrap();
    assert_eq!(
        g.pull("y", Context::new(0)).unwrap().get::<f64>(),
        Some(&1.0)
    );
    let e = g
        .set_param("p", "type", serde_json::json!("bool"))
        .unwrap_err();
    assert!(
        e.describe()
            .starts_with("node 'p': param 'type': sets an output's type"),
        "{}",
        e.describe()
    );
    g.set_param("p", "value", serde_json::json!(4.0)).unwrap();
    assert_eq!(
        g.pull("y", Context::new(0)).unwrap().get::<f64>(),
        Some(&4.0)
    );
}
