//! Freeze (issue 17, item 4) through graphs as a user writes them: weight 1 follows the
//! animated input exactly, releasing it keeps the input's velocity, a partial weight pulls
//! with its documented stiffness, per-vertex weights lock a region as hard attachments do,
//! and the coupled solver does the same.

mod common;
use common::*;
use weft_graph::Graph;

/// The input's x offset at frame f: 0.2 sin(2π · 0.5 Hz · f/24) (xform.animate).
fn input_offset(f: i64) -> f64 {
    0.2 * (std::f64::consts::TAU * 0.5 * f as f64 / 24.0).sin()
}

/// The weight: 1 up to frame 11, 0 from frame 12 on (a keyed step).
const RELEASE_AT_12: &str = r#"{"type": "anim.curve", "params": {"frames": [11, 12], "values": [1, 0], "interpolation": "step"}}"#;

/// `solver.solid`, 4 substeps: its nodes and its scene output.
fn solid() -> (&'static str, &'static str) {
    (
        r#""solve": {"type": "solver.solid", "inputs": {"elements": ["density.element", "freeze.element"], "tree": "tree.tree"},
                     "params": {"substeps": 4, "tolerance": 1e-10}}"#,
        "solve.scene",
    )
}

/// `solver.coupled` without a fluid (one step a frame): its nodes and its scene output.
fn coupled() -> (&'static str, &'static str) {
    (
        r#""scene": {"type": "scene.gather", "inputs": {"elements": ["density.element", "freeze.element"]}},
        "setup": {"type": "coupled.setup", "inputs": {"scene": "scene.scene", "tree": "tree.tree"}},
        "solve": {"type": "solver.coupled", "inputs": {"scene": "scene.scene", "state": "setup.state", "iterate": "setup.state"},
                  "params": {"solid.tolerance": 1.0e-10}},
        "result": {"type": "coupled.scene", "inputs": {"state": "solve.state"}}"#,
        "result.scene",
    )
}

/// A 0.5 m cloth (6 × 6 vertices) whose input swings along x (`input_offset`), every vertex
/// frozen with the weight the node `weight` gives; no gravity, so the cloth is never
/// strained. Outputs: `sim` and `input` (vertex 0 simulated and as input), `corner` (35).
fn swinging(weight: &str, (solver, scene): (&str, &str)) -> Graph {
    let all: Vec<String> = (0..36).map(|i| i.to_string()).collect();
    let nodes = format!(
        r#""grid": {{"type": "geo.grid", "params": {{"width": 0.5, "height": 0.5, "nx": 6, "ny": 6, "plane": "xz", "center": [0, 1, 0]}}}},
        "move": {{"type": "xform.animate", "params": {{"oscillate": [0.2, 0, 0], "frequency": 0.5}}}},
        "moved": {{"type": "geo.transform", "inputs": {{"mesh": "grid.mesh", "transform": "move.transform"}}}},
        "cloth": {{"type": "convert.cloth", "inputs": {{"mesh": "moved.mesh"}}, "params": {{"name": "cloth"}}}},
        "shell": {{"type": "sec.discrete_shell", "inputs": {{"element": "cloth.element"}}, "params": {{"youngs_modulus": 1e5, "thickness": 5e-4}}}},
        "density": {{"type": "sec.density", "inputs": {{"element": "shell.element"}}, "params": {{"area_density": 0.15}}}},
        "weight": {weight},
        "freeze": {{"type": "convert.attachment", "inputs": {{"target": "density.element", "weight": "weight.out"}},
                    "params": {{"name": "freeze", "mode": "freeze", "vertices": [{all}]}}}},
        "material": {{"type": "behavior.discrete_shell"}},
        "attach": {{"type": "behavior.attachment"}},
        "tree": {{"type": "behavior.tree", "inputs": {{"behaviors": ["material.behavior", "attach.behavior"]}}}},
        "inputs": {{"type": "scene.gather", "inputs": {{"elements": ["density.element"]}}}},
        {solver},
        "sim": {{"type": "scene.vertex", "inputs": {{"scene": "{scene}"}}, "params": {{"element": "cloth", "index": 0}}}},
        "corner": {{"type": "scene.vertex", "inputs": {{"scene": "{scene}"}}, "params": {{"element": "cloth", "index": 35}}}},
        "input": {{"type": "scene.vertex", "inputs": {{"scene": "inputs.scene"}}, "params": {{"element": "cloth", "index": 0}}}}"#,
        all = all.join(", ")
    );
    graph(&file(
        &nodes,
        r#""sim": "sim.position", "corner": "corner.position", "input": "input.position""#,
    ))
}

/// Held to frame 11 and released at 12: while held, bit for bit at the input; released,
/// unstrained and without gravity, it keeps the velocity the input had over the last held
/// frame, (input(11) − input(10))·24, exactly as implicit Euler does (x = x⁰ + h v⁰).
fn held_then_released(g: &mut Graph, what: &str) {
    let x0 = vec3_at(g, "input", 0);
    for f in 1..=11 {
        let (sim, input) = (vec3_at(g, "sim", f), vec3_at(g, "input", f));
        assert_eq!(sim, input, "{what}: frame {f}: held, not at its input");
        // The input is the animated mesh (checked against the transform's formula).
        assert!((input[0] - x0[0] - input_offset(f)).abs() < 1e-15);
    }
    let (a, b) = (vec3_at(g, "input", 10), vec3_at(g, "input", 11));
    let v = (b[0] - a[0]) * 24.0;
    let mut last = b[0];
    for f in 12..=20 {
        let sim = vec3_at(g, "sim", f);
        let vf = (sim[0] - last) * 24.0;
        // Continuous: the released cloth moves on at the held frame's velocity (to the
        // solve's tolerance of 1e-10 m/s; the input itself turns: 0.4 m/s less by frame 20).
        assert!(
            (vf - v).abs() < 1e-8,
            "{what}: frame {f}: {vf} m/s after release, {v} m/s before"
        );
        assert!((sim[1] - b[1]).abs() < 1e-12 && (sim[2] - b[2]).abs() < 1e-12);
        last = sim[0];
    }
    // Free: no longer following its input (which has slowed and turned back by now).
    let gap = (vec3_at(g, "sim", 20)[0] - vec3_at(g, "input", 20)[0]).abs();
    assert!(gap > 0.05, "{what}: {gap} m from its input at frame 20");
    // The whole cloth moved as one (no strain, no gravity).
    let c = vec3_at(g, "corner", 20);
    let s = vec3_at(g, "sim", 20);
    let c0 = vec3_at(g, "corner", 0);
    assert!(((c[0] - s[0]) - (c0[0] - x0[0])).abs() < 1e-9);
}

#[test]
fn weight_one_follows_the_input_exactly_and_released_keeps_its_velocity() {
    let mut g = swinging(RELEASE_AT_12, solid());
    held_then_released(&mut g, "solver.solid");
}

#[test]
fn the_coupled_solver_holds_and_releases_frozen_vertices_alike() {
    let mut g = swinging(RELEASE_AT_12, coupled());
    held_then_released(&mut g, "solver.coupled");
}

/// A 0.5 m cloth (6 × 6) under gravity, `extra` nodes beside it (an attachment named
/// `freeze` among them), solved by `params`; its vertex positions at `frame`.
fn hanging(extra: &str, params: &str, frames: &[i64]) -> Vec<Vec<[f64; 3]>> {
    let (probes, outputs) = vertex_probes("solve.scene", "cloth", 36);
    let nodes = format!(
        r#""grid": {{"type": "geo.grid", "params": {{"width": 0.5, "height": 0.5, "nx": 6, "ny": 6, "plane": "xz", "center": [0, 1, 0]}}}},
        "cloth": {{"type": "convert.cloth", "inputs": {{"mesh": "grid.mesh"}}, "params": {{"name": "cloth"}}}},
        "shell": {{"type": "sec.discrete_shell", "inputs": {{"element": "cloth.element"}}, "params": {{"youngs_modulus": 1e5, "thickness": 5e-4}}}},
        "density": {{"type": "sec.density", "inputs": {{"element": "shell.element"}}, "params": {{"area_density": 0.15}}}},
        {extra},
        "material": {{"type": "behavior.discrete_shell"}},
        "gravity": {{"type": "behavior.gravity"}},
        "attach": {{"type": "behavior.attachment"}},
        "tree": {{"type": "behavior.tree", "inputs": {{"behaviors": ["material.behavior", "gravity.behavior", "attach.behavior"]}}}},
        "solve": {{"type": "solver.solid", "inputs": {{"elements": ["density.element", "freeze.element"], "tree": "tree.tree"}},
                   "params": {params}}},
        {}"#,
        probes
    );
    let mut g = graph(&file(&nodes, &outputs));
    frames
        .iter()
        .map(|&f| probed_positions(&mut g, 36, f))
        .collect()
}

#[test]
fn a_partial_weight_pulls_with_its_stated_stiffness() {
    // Every vertex frozen at w = 0.5 to a still input: the springs k = w/(1 − w)·m/Δt² carry
    // each vertex's weight, so the cloth hangs unstrained, g Δt² (1 − w)/w = 9.81/576 m below
    // its input (a static solve: the equilibrium itself, to its tolerance).
    let all: Vec<String> = (0..36).map(|i| i.to_string()).collect();
    let extra = format!(
        r#""freeze": {{"type": "convert.attachment", "inputs": {{"target": "density.element"}},
                    "params": {{"name": "freeze", "mode": "freeze", "vertices": [{}]}}}},
        "half": {{"type": "value.float", "params": {{"value": 0.5}}}}"#,
        all.join(", ")
    )
    .replace(
        r#""target": "density.element"}"#,
        r#""target": "density.element", "weight": "half.out"}"#,
    );
    let at = hanging(
        &extra,
        r#"{"method": "static", "substeps": 1, "tolerance": 1e-13}"#,
        &[0, 1],
    );
    let sag = 9.81 / (24.0 * 24.0);
    for (i, (a, b)) in at[0].iter().zip(&at[1]).enumerate() {
        let d = a[1] - b[1];
        assert!(
            (d - sag).abs() < 1e-12,
            "vertex {i}: {d} m below its input, want {sag}"
        );
        assert!((a[0] - b[0]).abs() < 1e-12 && (a[2] - b[2]).abs() < 1e-12);
    }
}

#[test]
fn per_vertex_weights_lock_a_region_as_hard_attachments_do() {
    // Weight 1 with per-vertex factors 1 on the first row and 0 elsewhere: the row is held
    // at its (still) input and the rest is free, the same system as the row attached hard.
    // Held through the sliders' machinery instead of eliminated: equal to the solve's
    // tolerance (1e-10 m/s a step; measured 6.5e-16 m over 12 frames).
    let all: Vec<String> = (0..36).map(|i| i.to_string()).collect();
    let factors: Vec<&str> = (0..36).map(|i| if i < 6 { "1" } else { "0" }).collect();
    let frozen = format!(
        r#""freeze": {{"type": "convert.attachment", "inputs": {{"target": "density.element"}},
                    "params": {{"name": "freeze", "mode": "freeze", "vertices": [{}], "vertex_weights": [{}]}}}}"#,
        all.join(", "),
        factors.join(", ")
    );
    let hard = r#""freeze": {"type": "convert.attachment", "inputs": {"target": "density.element"},
                    "params": {"name": "freeze", "vertices": [0, 1, 2, 3, 4, 5]}}"#;
    let params = r#"{"substeps": 2, "tolerance": 1e-10}"#;
    let frames: Vec<i64> = (0..=12).collect();
    let (a, b) = (
        hanging(&frozen, params, &frames),
        hanging(hard, params, &frames),
    );
    let mut worst = 0.0f64;
    for (f, (pa, pb)) in a.iter().zip(&b).enumerate() {
        for (i, (x, y)) in pa.iter().zip(pb).enumerate() {
            if i < 6 {
                assert_eq!(x, y, "frame {f}: held vertex {i} moved");
            }
            worst = worst.max(dist(*x, *y));
        }
    }
    assert!(worst < 1e-9, "frozen and hard rows differ by {worst:e} m");
    // And it did swing: the free corner fell.
    assert!(a[12][35][1] < 0.9, "{:?}", a[12][35]);
}

#[test]
fn bad_freeze_input_is_a_clear_error_naming_the_node() {
    // A negative weight on the port: the node and the port.
    let mut g = swinging(
        r#"{"type": "value.float", "params": {"value": -0.5}}"#,
        solid(),
    );
    let e = match g.pull("sim", weft_graph::Context::new(1)) {
        Ok(_) => panic!("a negative weight was taken"),
        Err(e) => e.to_string(),
    };
    assert!(
        e.contains("'freeze'") && e.contains("'weight'") && e.contains("≥ 0, got -0.5"),
        "{e}"
    );
    // Weights for another mode, of the wrong count, negative; a clamp on frozen vertices;
    // keys that do not increase: refused when the file loads.
    let e = load_error(&file(
        r#""a": {"type": "convert.attachment", "params": {"mode": "hard", "vertices": [0], "vertex_weights": [1]}},
           "b": {"type": "convert.attachment", "params": {"mode": "freeze", "vertices": [0, 1], "vertex_weights": [1]}},
           "c": {"type": "convert.attachment", "params": {"mode": "freeze", "vertices": [0], "vertex_weights": [-1]}},
           "d": {"type": "convert.attachment", "params": {"mode": "freeze", "clamp": true}},
           "e": {"type": "anim.curve", "params": {"frames": [1, 1], "values": [0, 1]}},
           "f": {"type": "anim.curve", "params": {"frames": [1, 2], "values": [0]}}"#,
        r#""e": "e.out""#,
    ));
    for want in [
        "node 'a': params: param 'vertex_weights': only mode freeze reads weights (mode is hard)",
        "node 'b': params: param 'vertex_weights': 1 weights for 2 listed vertices",
        "node 'c': params: param 'vertex_weights': -1 is not a weight",
        "node 'd': params: param 'clamp': a clamp holds the direction at held vertices; with mode freeze",
        "node 'e': params: param 'frames': key frames must increase (1 then 1)",
        "node 'f': params: param 'values': 1 values for 2 key frames",
    ] {
        assert!(e.contains(want), "missing {want:?} in {e}");
    }
    // A vertex frozen and held by another attachment.
    let extra = r#""freeze": {"type": "convert.attachment", "inputs": {"target": "density.element"},
                    "params": {"name": "freeze", "mode": "freeze", "vertices": [0, 1]}},
        "pins": {"type": "convert.attachment", "inputs": {"target": "density.element"},
                    "params": {"name": "pins", "vertices": [1]}}"#;
    let text = file(
        &format!(
            r#""grid": {{"type": "geo.grid", "params": {{"nx": 4, "ny": 4}}}},
        "cloth": {{"type": "convert.cloth", "inputs": {{"mesh": "grid.mesh"}}, "params": {{"name": "cloth"}}}},
        "density": {{"type": "sec.density", "inputs": {{"element": "cloth.element"}}}},
        {extra},
        "material": {{"type": "behavior.discrete_shell"}},
        "attach": {{"type": "behavior.attachment"}},
        "tree": {{"type": "behavior.tree", "inputs": {{"behaviors": ["material.behavior", "attach.behavior"]}}}},
        "solve": {{"type": "solver.solid", "inputs": {{"elements": ["density.element", "freeze.element", "pins.element"], "tree": "tree.tree"}}}}"#
        ),
        r#""scene": "solve.scene""#,
    );
    let mut g = graph(&text);
    let e = match g.pull("scene", weft_graph::Context::new(1)) {
        Ok(_) => panic!("a vertex frozen and held was taken"),
        Err(e) => e.to_string(),
    };
    assert!(
        e.contains("'pins'") && e.contains("vertex 1 of 'cloth'") && e.contains("frozen"),
        "{e}"
    );
}

#[test]
fn a_run_resumed_from_disk_checkpoints_across_the_release_is_bit_identical() {
    // The frozen inputs at a frame's end start the next frame's interpolation: they travel in
    // the disk checkpoints of both solvers, so a run resumed at frame 11 (held) or 14
    // (released) continues bit for bit.
    for (what, solver) in [("solver.solid", solid()), ("solver.coupled", coupled())] {
        let mut seq = swinging(RELEASE_AT_12, solver);
        let want: Vec<[f64; 3]> = (0..=16).map(|f| vec3_at(&mut seq, "corner", f)).collect();
        for stop in [11, 14] {
            let dir = tempfile::tempdir().unwrap();
            let mut first = swinging(RELEASE_AT_12, solver);
            first.set_checkpoint_dir(Some(dir.path().to_path_buf()));
            for f in 0..=stop {
                vec3_at(&mut first, "corner", f);
            }
            let mut resumed = swinging(RELEASE_AT_12, solver);
            resumed.set_checkpoint_dir(Some(dir.path().to_path_buf()));
            assert_eq!(
                vec3_at(&mut resumed, "corner", 16),
                want[16],
                "{what}: resumed from frame {stop}"
            );
        }
    }
}

#[test]
fn frozen_hair_follows_its_moved_curves_exactly() {
    // A strand whose curves a spinning transform carries (geo.transform_curves), frozen at
    // weight 1 under gravity: every vertex is its input's, bit for bit, every frame.
    let nodes = r#""line": {"type": "geo.line", "params": {"start": [0, 1, 0], "end": [0.4, 1, 0], "segments": 4}},
        "spin": {"type": "xform.animate", "params": {"spin": 2.0}},
        "moved": {"type": "geo.transform_curves", "inputs": {"curves": "line.curves", "transform": "spin.transform"}},
        "hair": {"type": "convert.hair", "inputs": {"curves": "moved.curves"}, "params": {"name": "hair"}},
        "rod": {"type": "sec.rod", "inputs": {"element": "hair.element"}, "params": {"radius": 0.001}},
        "freeze": {"type": "convert.attachment", "inputs": {"target": "rod.element"},
                   "params": {"name": "freeze", "mode": "freeze", "vertices": [0, 1, 2, 3, 4]}},
        "material": {"type": "behavior.rod"},
        "gravity": {"type": "behavior.gravity"},
        "attach": {"type": "behavior.attachment"},
        "tree": {"type": "behavior.tree", "inputs": {"behaviors": ["material.behavior", "gravity.behavior", "attach.behavior"]}},
        "solve": {"type": "solver.solid", "inputs": {"elements": ["rod.element", "freeze.element"], "tree": "tree.tree"}},
        "inputs": {"type": "scene.gather", "inputs": {"elements": ["rod.element"]}},
        "tip": {"type": "scene.vertex", "inputs": {"scene": "solve.scene"}, "params": {"element": "hair", "index": 4}},
        "input": {"type": "scene.vertex", "inputs": {"scene": "inputs.scene"}, "params": {"element": "hair", "index": 4}}"#;
    let mut g = graph(&file(
        nodes,
        r#""tip": "tip.position", "input": "input.position""#,
    ));
    for f in 0..=12 {
        let (tip, input) = (vec3_at(&mut g, "tip", f), vec3_at(&mut g, "input", f));
        assert_eq!(tip, input, "frame {f}");
        // Spinning about y through the origin at 2 rad/s: the tip at (0.4 cos, 1, −0.4 sin).
        let a = 2.0 * f as f64 / 24.0;
        assert!(
            dist(tip, [0.4 * a.cos(), 1.0, -0.4 * a.sin()]) < 1e-15,
            "frame {f}: {tip:?}"
        );
    }
}
