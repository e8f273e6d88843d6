//! `solver.coupled` at graph level: with no fluid in the scene it makes no grid and steps the
//! solids exactly as `solver.solid` does; its stages are reported per iteration; bad fluid
//! input is named.

mod common;
use common::*;
use weft_graph::Context;

/// A hanging strand, stepped by the given solver node.
fn strand_graph(solver: &str, extra: &str) -> String {
    let solve = match solver {
        "solid" => r#""solve": {"type": "solver.solid", "inputs": {"elements": ["hair.element", "root.element"], "tree": "tree.tree"},
                     "params": {"substeps": 1, "tolerance": 1e-7, "max_iterations": 500, "max_retries": 0}},
           "result": {"type": "scene.gather", "inputs": {"elements": []}},
           "tip": {"type": "scene.vertex", "inputs": {"scene": "solve.scene"}, "params": {"element": "hair", "index": 8}}"#
            .to_string(),
        _ => r#""scene": {"type": "scene.gather", "inputs": {"elements": ["hair.element", "root.element"EXTRA]}},
           "setup": {"type": "coupled.setup", "inputs": {"scene": "scene.scene", "tree": "tree.tree"}},
           "solve": {"type": "solver.coupled", "inputs": {"scene": "scene.scene", "state": "setup.state", "iterate": "setup.state"},
                     "params": {"solid.tolerance": 1e-7, "solid.max_iterations": 500}},
           "result": {"type": "coupled.scene", "inputs": {"state": "solve.state"}},
           "tip": {"type": "scene.vertex", "inputs": {"scene": "result.scene"}, "params": {"element": "hair", "index": 8}}"#
            .replace("EXTRA", extra),
    };
    format!(
        r#"{{"format": "weft-graph", "version": 1, "nodes": {{
           "curves": {{"type": "geo.strands", "params": {{"center": [0, 1, 0], "radius": 0.05, "count": 1, "segments": 8, "length": 0.2, "cap_degrees": 60}}}},
           "hair": {{"type": "convert.hair", "inputs": {{"curves": "curves.curves"}}, "params": {{"name": "hair"}}}},
           "root": {{"type": "convert.attachment", "inputs": {{"target": "hair.element"}}, "params": {{"name": "root", "vertices": [0]}}}},
           "water": {{"type": "convert.fluid_domain", "params": {{"name": "water", "cell_size": 0.02}}}},
           "rod": {{"type": "behavior.rod"}}, "gravity": {{"type": "behavior.gravity"}},
           "attach": {{"type": "behavior.attachment"}}, "drag": {{"type": "behavior.fluid_drag"}},
           "tree": {{"type": "behavior.tree", "inputs": {{"behaviors": ["rod.behavior", "gravity.behavior", "attach.behavior", "drag.behavior"]}}}},
           {solve}
        }}, "outputs": {{"tip": "tip.position"}}}}"#
    )
}

fn tip(g: &mut weft_graph::Graph, frame: i64) -> [f64; 3] {
    *g.pull("tip", Context::new(frame))
        .unwrap_or_else(|e| panic!("{e}"))
        .get::<[f64; 3]>()
        .unwrap()
}

/// No fluid-domain element: no grid (the setup's stats say so), one coupling iteration per
/// frame, and the strand's tip bit-identical to `solver.solid` with one substep (the same
/// implicit step with zero fluid forces).
#[test]
fn without_a_fluid_there_is_no_grid_and_the_solids_step_as_alone() {
    let mut solid = graph(&strand_graph("solid", ""));
    let mut coupled = graph(&strand_graph("coupled", ""));
    for frame in 0..=6 {
        assert_eq!(
            tip(&mut solid, frame),
            tip(&mut coupled, frame),
            "frame {frame}"
        );
    }
    assert!(
        tip(&mut coupled, 6)[1] < tip(&mut coupled, 0)[1],
        "the strand swings down"
    );
    let setup = coupled.node_report("setup").expect("setup report");
    assert!(setup["iterations"][0]["grid"].is_null(), "{setup}");
    // One iteration per frame: nothing couples.
    let report = coupled.node_report("solve").expect("solve report");
    let frames = report["frames"].as_array().expect("per-frame reports");
    assert_eq!(frames.len(), 6);
    assert!(
        frames
            .iter()
            .all(|f| f["iterations"].as_array().unwrap().len() == 1)
    );
}

/// With a fluid: the composite reports each frame's coupling iterations with their residual and
/// the seconds of every stage that ran (predict once per frame, the others per iteration), and
/// a Newton step iterates until the residual is below the tolerance.
#[test]
fn coupled_iterations_are_reported_per_stage_with_residuals() {
    let mut g = graph(&strand_graph("coupled", r#", "water.element""#));
    tip(&mut g, 3);
    let setup = g.node_report("setup").expect("setup report");
    assert!(
        setup["iterations"][0]["grid"]["cells"].is_array(),
        "{setup}"
    );
    let report = g.node_report("solve").expect("solve report");
    let frames = report["frames"].as_array().unwrap();
    assert_eq!(frames.len(), 3);
    for f in frames {
        let its = f["iterations"].as_array().unwrap();
        assert!(its.len() >= 2, "{f}");
        assert!(f["converged"].as_bool().unwrap());
        let last = its.last().unwrap();
        assert!(last["residual"].as_f64().unwrap() < 1e-6, "{last}");
        for stage in ["forces", "solid", "rasterize", "pressure", "update"] {
            assert!(
                its[1]["stages"].get(stage).is_some(),
                "{stage} in {}",
                its[1]
            );
        }
        assert!(its[0]["stages"].get("predict").is_some());
        assert!(
            its[1]["stages"].get("predict").is_none(),
            "predict runs once per step"
        );
    }
}

/// Bad fluid input: a grid too large is refused at the start frame with its estimate, naming
/// the element and field; a one-sided periodic axis is refused when the graph loads.
#[test]
fn bad_fluid_domains_are_named() {
    let text = strand_graph("coupled", r#", "water.element""#).replace(
        r#""cell_size": 0.02"#,
        r#""cell_size": 1e-5, "padding": 1.0"#,
    );
    let mut g = graph(&text);
    let e = g.pull("tip", Context::new(0)).unwrap_err().to_string();
    assert!(
        e.contains("water") && e.contains("fluid_domain.cell_size") && e.contains("GiB"),
        "{e}"
    );
    let text = strand_graph("coupled", r#", "water.element""#).replace(
        r#""cell_size": 0.02"#,
        r#""cell_size": 0.02, "x_min": "periodic""#,
    );
    let e = load_error(&text);
    assert!(e.contains("water") && e.contains("periodic"), "{e}");
}

/// Solids outside the domain are clipped with a warning naming the frame and the count; a
/// pressure solve that cannot reach its tolerance is an error naming the stage, the frame, the
/// coupling iteration and the residual (the mixture divergence) reached.
#[test]
fn outside_solids_warn_and_a_failed_pressure_solve_names_its_frame() {
    // A domain that covers only the strand's root region (the strand hangs from (0, 1.05, 0)).
    let text = strand_graph("coupled", r#", "water.element""#).replace(
        r#""cell_size": 0.02"#,
        r#""cell_size": 0.02, "auto_bounds": false, "min": [-0.1, 0.95, -0.1], "max": [0.1, 1.15, 0.1]"#,
    );
    let mut g = graph(&text);
    tip(&mut g, 1);
    let w = g.take_warnings();
    assert!(
        w.iter().any(
            |w| w.message.contains("frame 1") && w.message.contains("outside the fluid domain")
        ),
        "{w:?}"
    );
    let mut g = graph(&strand_graph("coupled", r#", "water.element""#));
    g.set_param("solve", "pressure.max_iterations", serde_json::json!(1))
        .unwrap();
    g.set_param("solve", "pressure.tolerance", serde_json::json!(1e-300))
        .unwrap();
    let e = g.pull("tip", Context::new(1)).unwrap_err().to_string();
    assert!(
        e.contains("solve/pressure")
            && e.contains("frame 1")
            && e.contains("coupling iteration 0")
            && e.contains("did not converge")
            && e.contains("divergence"),
        "{e}"
    );
}

/// Optional viscosity at graph level: `predict.viscosity` turns on the implicit diffusion,
/// whose CG iterations the predict stage reports each frame; off (the default) it runs none. Water at 2 cm cells and 1/24 s barely diffuses (hν/Δx² ≈ 1e-4), so the strand's tip
/// moves by less than 1e-4 m between the two runs.
#[test]
fn viscosity_is_an_option_of_the_predict_stage() {
    let text = strand_graph("coupled", r#", "water.element""#);
    let viscous = text.replace(
        r#""solid.tolerance": 1e-7"#,
        r#""solid.tolerance": 1e-7, "predict.viscosity": true"#,
    );
    let mut a = graph(&text);
    let mut b = graph(&viscous);
    let (ta, tb) = (tip(&mut a, 3), tip(&mut b, 3));
    let its = |g: &weft_graph::Graph| {
        let report = g.node_report("solve").expect("solve report");
        let predict = report["inner"]
            .as_array()
            .unwrap()
            .iter()
            .find(|n| n["node"] == "predict")
            .unwrap()["details"]["iterations"]
            .clone();
        predict
            .as_array()
            .unwrap()
            .iter()
            .map(|r| r["viscosity_cg_iterations"].as_u64().unwrap())
            .collect::<Vec<_>>()
    };
    assert_eq!(its(&a), [0, 0, 0]);
    // The water starts at rest: nothing to diffuse at the first step; then the strand has
    // stirred it.
    let on = its(&b);
    assert!(on[0] == 0 && on[1] > 0 && on[2] > 0, "{on:?}");
    let d = (0..3).map(|i| (ta[i] - tb[i]).powi(2)).sum::<f64>().sqrt();
    assert!(d < 1e-4, "{d}");
}
