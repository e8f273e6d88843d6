//! Malformed graph files: each problem is a clear error naming the node, the port or parameter
//! and the line; all problems of a file are reported at once; nothing panics. And the
//! examples with a contact band too wide for their elements: refused before a step, or
//! reported with their numbers.

mod common;
use common::*;
use expect_test::expect;
use proptest::prelude::*;

#[test]
fn invalid_json_gives_line_and_column() {
    let e = load_error("{\"format\": \"weft-graph\",\n \"version\": 1,\n \"nodes\": {\"a\": }\n}");
    expect![[r#"
        t.json: 1 error in graph file
          t.json: line 3, column 17: error: invalid JSON: expected value
    "#]]
    .assert_eq(&e);
}

#[test]
fn wrong_format_and_unsupported_version() {
    let e = load_error(r#"{"format": "weft", "version": 2, "nodes": {}, "outputs": {}}"#);
    assert!(
        e.contains(r#"line 1, column 2: error: 'format' must be "weft-graph", got "weft""#),
        "{e}"
    );
    assert!(
        e.contains("unsupported version 2; this build reads version [1]"),
        "{e}"
    );
}

#[test]
fn unknown_node_type_suggests_the_nearest() {
    let e = load_error(&file(r#""a": {"type": "math.ad"}"#, r#""x": "a.out""#));
    assert!(
        e.contains("node 'a': unknown node type 'math.ad' (did you mean 'math.add'?)"),
        "{e}"
    );
}

#[test]
fn unknown_port_type_mismatch_and_missing_input() {
    let e = load_error(&file(
        r#""x": {"type": "value.float"},
           "a": {"type": "math.add", "inputs": {"c": "x.out"}},
           "l": {"type": "vec3.length", "inputs": {"v": "x.out"}},
           "m": {"type": "vec3.length"},
           "n": {"type": "math.add", "inputs": {"a": "x.value"}},
           "o": {"type": "math.add", "inputs": {"a": "nope.out"}}"#,
        r#""y": "a.out""#,
    ));
    assert!(
        e.contains("node 'a': input 'c': 'math.add' has no input 'c' (inputs: a, b)"),
        "{e}"
    );
    assert!(
        e.contains("node 'l': input 'v': type mismatch: 'x.out' is float, this input takes vec3"),
        "{e}"
    );
    assert!(
        e.contains("node 'm': input 'v': missing required input (vec3: vector)"),
        "{e}"
    );
    assert!(
        e.contains(
            "node 'n': input 'a': node 'x' (value.float) has no output 'value' (outputs: out)"
        ),
        "{e}"
    );
    assert!(
        e.contains("node 'o': input 'a': connection to unknown node 'nope'"),
        "{e}"
    );
}

#[test]
fn duplicate_ids_and_cycles() {
    let e = load_error(
        "{\"format\": \"weft-graph\", \"version\": 1, \"nodes\": {\n\"a\": {\"type\": \"value.float\"},\n\"a\": {\"type\": \"value.int\"}}, \"outputs\": {}}",
    );
    assert!(
        e.contains("line 3, column 1: error: node 'a': duplicate node id 'a'"),
        "{e}"
    );
    let e = load_error(&file(
        r#""s": {"type": "math.sum", "inputs": {"terms": ["s.out"]}}"#,
        r#""y": "s.out""#,
    ));
    assert!(e.contains("node 's': cycle: s -> s"), "{e}");
    let e = load_error(&file(
        r#""a": {"type": "math.add", "inputs": {"a": "c.out"}},
           "b": {"type": "math.add", "inputs": {"a": "a.out"}},
           "c": {"type": "math.add", "inputs": {"a": "b.out"}}"#,
        r#""y": "c.out""#,
    ));
    assert!(e.contains("node 'a': cycle: a -> b -> c -> a"), "{e}");
}

#[test]
fn parameters_of_the_wrong_type_or_out_of_range() {
    let e = load_error(&file(
        r#""a": {"type": "value.float", "params": {"value": "abc"}},
           "d": {"type": "ode.decay", "params": {"rate": -1, "method": "euler", "substeps": 0, "y00": 1}}"#,
        r#""y": "d.y""#,
    ));
    assert!(
        e.contains(r#"node 'a': param 'value': expected a number, got "abc""#),
        "{e}"
    );
    assert!(
        e.contains("node 'd': param 'rate': must be > 0, got -1"),
        "{e}"
    );
    assert!(e.contains(r#"node 'd': param 'method': expected one of ["explicit_euler", "implicit_euler", "rk4", "exact"], got "euler""#), "{e}");
    assert!(
        e.contains("node 'd': param 'substeps': must be >= 1, got 0"),
        "{e}"
    );
    assert!(
        e.contains("node 'd': param 'y00': 'ode.decay' has no such parameter (did you mean 'y0'?)"),
        "{e}"
    );
}

#[test]
fn unknown_fields_are_errors_with_suggestions() {
    let e = load_error(
        r#"{"format": "weft-graph", "version": 1, "nodes": {"a": {"type": "value.float", "paramz": {}}}, "output": {}, "meta": {"free": true}}"#,
    );
    assert!(e.contains("node 'a': unknown field 'paramz' in node 'a' (allowed: type, inputs, params, meta) (did you mean 'params'?)"), "{e}");
    assert!(
        e.contains("unknown field 'output' in the graph file"),
        "{e}"
    );
    assert!(!e.contains("'meta'"), "meta is free: {e}");
}

#[test]
fn every_error_of_a_file_is_reported_at_once_in_line_order() {
    let text = r#"{
  "format": "weft-graph",
  "version": 1,
  "nodes": {
    "clock": {"type": "time.frame"},
    "osc":   {"type": "ode.oscilator"},
    "sum":   {"type": "math.add", "inputs": {"a": "clock.frame", "q": "clock.time"}},
    "len":   {"type": "vec3.length"},
    "dt":    {"type": "value.float", "params": {"value": [1]}},
    "loop1": {"type": "math.add", "inputs": {"a": "loop2.out"}},
    "loop2": {"type": "math.add", "inputs": {"a": "loop1.out"}}
  },
  "outputs": {"y": "sum.out", "z": "missing.out"}
}"#;
    expect![[r#"
        t.json: 7 errors in graph file
          t.json: line 6, column 15: error: node 'osc': unknown node type 'ode.oscilator' (did you mean 'ode.oscillator'?)
          t.json: line 7, column 46: error: node 'sum': input 'a': type mismatch: 'clock.frame' is int, this input takes float
          t.json: line 7, column 66: error: node 'sum': input 'q': 'math.add' has no input 'q' (inputs: a, b)
          t.json: line 8, column 5: error: node 'len': input 'v': missing required input (vec3: vector)
          t.json: line 9, column 49: error: node 'dt': param 'value': expected a number, got [1]
          t.json: line 10, column 5: error: node 'loop1': cycle: loop1 -> loop2 -> loop1
          t.json: line 13, column 31: error: output 'z': connection to unknown node 'missing'
    "#]]
    .assert_eq(&load_error(text));
}

#[test]
fn a_file_that_cannot_be_read_says_so() {
    let e = weft::graph::load_path(&registry(), std::path::Path::new("/nonexistent/graph.json"))
        .unwrap_err();
    assert!(
        e.to_string()
            .contains("/nonexistent/graph.json: 1 error in graph file"),
        "{e}"
    );
    assert!(e.to_string().contains("cannot read file"), "{e}");
}

#[test]
fn a_non_finite_number_is_reported_where_it_appears() {
    let mut g = graph(&file(
        r#""big": {"type": "value.float", "params": {"value": 1e308}},
           "sum": {"type": "math.add", "inputs": {"a": "big.out", "b": "big.out"}},
           "v":   {"type": "vec3.make", "inputs": {"x": "sum.out"}},
           "len": {"type": "vec3.length", "inputs": {"v": "v.out"}}"#,
        r#""len": "len.out""#,
    ));
    let e = g
        .pull("len", weft::graph::Context::new(0))
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        "node 'sum': produced inf on output 'out'; a non-finite number is reported where it appears, never passed on"
    );
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    /// Damaging a valid file anywhere (deleting a span, or splicing in JSON fragments) gives a
    /// graph or an error, never a panic.
    #[test]
    fn damaged_files_never_panic(cut in 0usize..2000, len in 0usize..40, junk in prop::sample::select(vec![
        "", "null", "1e999", "-1", "[]", "{}", "\"x\"", "\"a.b.c\"", ",", "}", "\"in.y\"", "true", "0.0",
    ])) {
        let text = std::fs::read_to_string(graphs_dir().join("stiff_newton.json")).unwrap();
        let cut = cut.min(text.len());
        let end = (cut + len).min(text.len());
        if text.is_char_boundary(cut) && text.is_char_boundary(end) {
            let damaged = format!("{}{}{}", &text[..cut], junk, &text[end..]);
            if let Ok(mut g) = weft::graph::load_str(&registry(), &damaged, "d") {
                let outs: Vec<String> = g.output_names().map(str::to_string).collect();
                for o in outs {
                    let _ = g.pull(&o, weft::graph::Context::new(3));
                }
            }
        }
    }
}

/// The header every graph file starts with.
const H: &str = r#""format": "weft-graph", "version": 1"#;

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

/// The first pull of the drape example with `thickness` [m] on both Collider SECs (a metre,
/// or worse, where a millimetre was meant): its error, or its warnings.
fn drape_with_thickness(thickness: f64) -> Result<Vec<String>, String> {
    let mut g = example("cloth_drape.json");
    for node in ["contact", "ballsec"] {
        g.set_param(node, "thickness", serde_json::json!(thickness))
            .unwrap();
    }
    g.pull("center", weft_graph::Context::new(0))
        .map_err(|e| e.to_string())?;
    Ok(g.take_warnings().into_iter().map(|w| w.message).collect())
}

/// A contact band wider than its own element cannot describe the scene: refused before a
/// step, naming the element, the parameter and both sizes (issue 70: 1 m in cloth_drape ran
/// frame 1 for two minutes, every vertex in contact with every triangle of the ball).
#[test]
fn a_thickness_wider_than_its_element_is_refused_with_both_sizes() {
    for (t, shown) in [(1.0, "1 m"), (1e9, "1e9 m")] {
        let e = drape_with_thickness(t).unwrap_err();
        assert!(
            e.contains(&format!("element 'cloth': collider.thickness is {shown}, wider than the element itself (its bounding box's largest side is 0.8 m)")),
            "{e}"
        );
    }
}

/// A band that holds most of a member at the start, narrower than the elements: the run
/// goes on, and says at once how many vertices start how deep in it, what the first step
/// does about it, and how many contacts that makes.
#[test]
fn a_start_inside_a_wide_band_is_reported_with_its_numbers() {
    let w = drape_with_thickness(0.2).unwrap().join("\n");
    // The sphere's top is 0.05 m below the cloth and the band 0.4 m: all 576 vertices are
    // in it, the centre 0.35 m deep (0.4 − 0.05, to the sphere's facets' rounding).
    assert!(
        w.contains("'cloth': 576 of its 576 free vertices start inside the 0.4 m contact band of collider 'ball' (up to 0.3485 m deep): the first step pushes them out by 0.1742 m at most (collision_response.strength 0.5 of their depth each step); about "),
        "{w}"
    );
    assert!(w.contains("contacts in the first step"), "{w}");
    // The example's own millimetre: nothing to say.
    let w = drape_with_thickness(1e-3).unwrap();
    assert!(!w.iter().any(|m| m.contains("contact band")), "{w:?}");
}

/// A self-collision band wider than the sheet's own spacing holds every vertex at rest
/// (triangles one edge away are inside it), which no motion can undo: refused, with the
/// spacing and the thickness that would fit.
#[test]
fn a_self_collision_band_wider_than_the_mesh_spacing_is_refused() {
    let mut g = example("cloth_pile.json");
    for node in ["lower_contact", "middle_contact", "upper_contact"] {
        g.set_param(node, "thickness", serde_json::json!(0.1))
            .unwrap();
    }
    let e = g
        .pull("upper_center", weft_graph::Context::new(0))
        .unwrap_err()
        .to_string();
    // 12 × 12 vertices over 0.5 m: edges of 0.0455 m, the nearest triangle that does not
    // hold a vertex 0.0455/√2 = 0.0321 m from it.
    assert!(
        e.contains("element 'lower': collider.thickness gives a self-collision band of 0.2 m (both sides' thickness), but 144 of its 144 free vertices start within that of its own other primitives (the nearest 0.0321 m away)"),
        "{e}"
    );
    assert!(e.contains("smaller than 0.0161 m"), "{e}");
}
