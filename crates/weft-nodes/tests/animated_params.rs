//! Animated parameters (issue 17, item 6) at the graph level: a float or integer parameter
//! connected like an input takes its connection's value at every frame, checked as the file
//! would be; editing a keyed curve re-steps only the frames from its first change.

mod common;
use common::*;
use weft_graph::{Context, Graph};

/// y' = −k(t) y from y(0) = 1 by ode.decay's exact step (exact for a rate constant over each
/// frame: the rate at frame f holds over the step to it), k keyed by `keys`.
fn decay(keys: &str) -> Graph {
    graph(&file(
        &format!(
            r#""k": {{"type": "anim.curve", "params": {keys}}},
               "y": {{"type": "ode.decay", "inputs": {{"rate": "k.out"}}, "params": {{"y0": 1.0, "method": "exact"}}}}"#
        ),
        r#""y": "y.y""#,
    ))
}

#[test]
fn a_connected_parameter_takes_its_value_at_every_frame() {
    // math.scale's factor driven by the time: x · t at every frame.
    let mut g = graph(&file(
        r#""one": {"type": "value.float", "params": {"value": 2.0}},
           "t": {"type": "time.frame"},
           "s": {"type": "math.scale", "inputs": {"x": "one.out", "factor": "t.time"}}"#,
        r#""s": "s.out""#,
    ));
    for f in [0, 6, 12, 24] {
        assert_eq!(f64_at(&mut g, "s", f), 2.0 * f as f64 / 24.0, "frame {f}");
    }
    assert_eq!(g.output_is_time_dependent("s"), Some(true));
}

#[test]
fn a_keyed_rate_integrates_piecewise_and_matches_the_closed_form() {
    // k = 1/s to frame 12, 3/s from frame 13 (a step key): y(f) = exp(−Σ k Δt).
    let mut g = decay(r#"{"frames": [12, 13], "values": [1.0, 3.0], "interpolation": "step"}"#);
    let dt = 1.0 / 24.0;
    for f in [6, 12, 18, 24] {
        let want = if f <= 12 {
            (-(f as f64) * dt).exp()
        } else {
            (-12.0 * dt - 3.0 * (f - 12) as f64 * dt).exp()
        };
        let y = f64_at(&mut g, "y", f);
        assert!(
            (y - want).abs() < 1e-14 * want,
            "frame {f}: {y} want {want}"
        );
    }
}

#[test]
fn editing_a_key_re_steps_only_the_frames_after_its_first_change() {
    let keys = |late: f64| {
        format!(
            r#"{{"frames": [0, 10, 20], "values": [1.0, 1.0, {late}], "interpolation": "linear"}}"#
        )
    };
    let mut g = decay(&keys(2.0));
    for f in 0..=24 {
        f64_at(&mut g, "y", f);
    }
    let steps = g.node_stats("y").unwrap().steps;
    assert_eq!(steps, 24);
    // The last key changes: the curve is unchanged up to frame 10 (its previous key), so the
    // states to frame 10 stay and 14 frames are stepped again.
    g.set_param("k", "values", serde_json::json!([1.0, 1.0, 4.0]))
        .unwrap();
    let y24 = f64_at(&mut g, "y", 24);
    assert_eq!(g.node_stats("y").unwrap().steps - steps, 14);
    // The same answer as a run of the edited curve from the start, bit for bit.
    let mut fresh = decay(&keys(4.0));
    assert_eq!(y24.to_bits(), f64_at(&mut fresh, "y", 24).to_bits());
    // A change from the start (the first key) re-steps everything.
    let steps = g.node_stats("y").unwrap().steps;
    g.set_param("k", "values", serde_json::json!([2.0, 1.0, 4.0]))
        .unwrap();
    f64_at(&mut g, "y", 24);
    assert_eq!(g.node_stats("y").unwrap().steps - steps, 24);
    // An edit that changes nothing re-steps nothing.
    let steps = g.node_stats("y").unwrap().steps;
    g.set_param("k", "interpolation", serde_json::json!("linear"))
        .unwrap();
    f64_at(&mut g, "y", 24);
    assert_eq!(g.node_stats("y").unwrap().steps, steps);
}

#[test]
fn a_connected_parameter_out_of_range_is_an_error_naming_it_and_the_frame() {
    // math.below's tolerance must be > 0: driven to 0 at frame 12.
    let mut g = graph(&file(
        r#""tol": {"type": "anim.curve", "params": {"frames": [0, 12], "values": [1.0, 0.0]}},
           "x": {"type": "value.float", "params": {"value": 0.5}},
           "b": {"type": "math.below", "inputs": {"x": "x.out", "tolerance": "tol.out"}}"#,
        r#""b": "b.out""#,
    ));
    assert!(g.pull("b", Context::new(6)).is_ok());
    let e = g.pull("b", Context::new(12)).unwrap_err().to_string();
    assert!(
        e.contains("node 'b'")
            && e.contains("frame 12")
            && e.contains("param 'tolerance' from its connection")
            && e.contains("> 0"),
        "{e}"
    );
    // Given a value and connected; connected to something that is not a number; a parameter
    // that is not a number: refused when the file loads.
    let e = load_error(&file(
        r#""t": {"type": "time.frame"},
           "v": {"type": "value.vec3"},
           "a": {"type": "math.scale", "inputs": {"x": "t.time", "factor": "t.time"}, "params": {"factor": 2}},
           "b": {"type": "math.scale", "inputs": {"x": "t.time", "factor": "v.out"}},
           "c": {"type": "anim.curve", "inputs": {"interpolation": "t.time"}}"#,
        r#""a": "a.out""#,
    ));
    for want in [
        "node 'a': input 'factor': param 'factor' is both given a value and connected",
        "node 'b': input 'factor': type mismatch: 'v.out' is vec3, this input takes float",
        "node 'c': input 'interpolation': 'anim.curve' has no input 'interpolation'",
    ] {
        assert!(e.contains(want), "missing {want:?} in {e}");
    }
}

/// Implicit Euler's velocity of a vertex falling from rest under gravity with mass-
/// proportional damping c(f) keyed per frame: v ← (v − h g)/(1 + h c) each step (y up).
fn damped_fall(c: impl Fn(i64) -> f64, frames: i64, substeps: i64) -> Vec<f64> {
    let h = 1.0 / (24.0 * substeps as f64);
    let mut v = 0.0;
    let mut out = vec![0.0];
    for f in 1..=frames {
        for _ in 0..substeps {
            v = (v - h * 9.81) / (1.0 + h * c(f));
        }
        out.push(v);
    }
    out
}

/// A free cloth (no attachments) falling as one body, its damping keyed 0 → 4/s at frame 13
/// on the Discrete Shell SEC (`sec`) or on behavior.damping (otherwise), in solver.coupled
/// (`coupled`) or solver.solid: vertex 0's mean vertical velocity over each frame (from its
/// positions).
fn falling_cloth(sec: bool, coupled: bool) -> Vec<f64> {
    let (shell_link, damping) = if sec {
        (
            r#", "damping": "c.out""#,
            r#""damping": {"type": "behavior.damping", "params": {"coefficient": 0.0}}"#,
        )
    } else {
        (
            "",
            r#""damping": {"type": "behavior.damping", "inputs": {"coefficient": "c.out"}}"#,
        )
    };
    let solver = if coupled {
        r#""scene": {"type": "scene.gather", "inputs": {"elements": ["density.element"]}},
        "setup": {"type": "coupled.setup", "inputs": {"scene": "scene.scene", "tree": "tree.tree"}},
        "solve": {"type": "solver.coupled", "inputs": {"scene": "scene.scene", "state": "setup.state", "iterate": "setup.state", "tree": "tree.tree"},
                  "params": {"solid.tolerance": 1.0e-12}},
        "result": {"type": "coupled.scene", "inputs": {"state": "solve.state"}},
        "v": {"type": "scene.vertex", "inputs": {"scene": "result.scene"}, "params": {"element": "cloth", "index": 0}}"#
    } else {
        r#""solve": {"type": "solver.solid", "inputs": {"elements": ["density.element"], "tree": "tree.tree"},
                   "params": {"substeps": 2, "tolerance": 1e-12}},
        "v": {"type": "scene.vertex", "inputs": {"scene": "solve.scene"}, "params": {"element": "cloth", "index": 0}}"#
    };
    let nodes = format!(
        r#""grid": {{"type": "geo.grid", "params": {{"width": 0.3, "height": 0.3, "nx": 4, "ny": 4, "plane": "xz", "center": [0, 1, 0]}}}},
        "cloth": {{"type": "convert.cloth", "inputs": {{"mesh": "grid.mesh"}}, "params": {{"name": "cloth"}}}},
        "c": {{"type": "anim.curve", "params": {{"frames": [12, 13], "values": [0.0, 4.0], "interpolation": "step"}}}},
        "shell": {{"type": "sec.discrete_shell", "inputs": {{"element": "cloth.element"{shell_link}}}}},
        "density": {{"type": "sec.density", "inputs": {{"element": "shell.element"}}, "params": {{"area_density": 0.15}}}},
        "material": {{"type": "behavior.discrete_shell"}},
        "gravity": {{"type": "behavior.gravity"}},
        {damping},
        "tree": {{"type": "behavior.tree", "inputs": {{"behaviors": ["material.behavior", "gravity.behavior", "damping.behavior"]}}}},
        {solver}"#
    );
    let mut g = graph(&file(&nodes, r#""v": "v.position""#));
    let y: Vec<f64> = (0..=20).map(|f| vec3_at(&mut g, "v", f)[1]).collect();
    y.windows(2).map(|w| (w[1] - w[0]) * 24.0).collect()
}

#[test]
fn keyed_damping_on_an_sec_or_a_behavior_changes_the_fall_from_its_key() {
    // The cloth falls unstrained, so each vertex follows implicit Euler's damped fall
    // exactly (to the 1e-12 m/s tolerance); the frame's velocity is read from positions, the
    // mean over its substeps: compare positions' differences with the same mean.
    let c = |f: i64| if f <= 12 { 0.0 } else { 4.0 };
    for (what, sec, coupled, substeps) in [
        ("sec.discrete_shell damping, solver.solid", true, false, 2),
        (
            "behavior.damping coefficient, solver.solid",
            false,
            false,
            2,
        ),
        ("sec.discrete_shell damping, solver.coupled", true, true, 1),
        (
            "behavior.damping coefficient, solver.coupled",
            false,
            true,
            1,
        ),
    ] {
        let got = falling_cloth(sec, coupled);
        // Mean velocity over each frame from the substeps' velocities.
        let h = 1.0 / (24.0 * substeps as f64);
        let mut v = 0.0;
        for (k, g) in got.iter().enumerate() {
            let f = k as i64 + 1;
            let mut dx = 0.0;
            for _ in 0..substeps {
                v = (v - h * 9.81) / (1.0 + h * c(f));
                dx += h * v;
            }
            let want = dx * 24.0;
            assert!(
                (g - want).abs() < 1e-9,
                "{what}: frame {f}: {g} m/s, want {want}"
            );
        }
        // Undamped to frame 12, then slowed: the keyed value took effect at its key.
        let free = damped_fall(|_| 0.0, 20, substeps);
        assert!(
            (got[19] - free[20]).abs() > 0.1,
            "{what}: damping had no effect"
        );
    }
}

#[test]
fn editing_a_keyed_stiffness_re_simulates_only_from_its_first_changed_frame() {
    // A cloth hanging from two corners, its Young's modulus keyed (2e5 Pa to frame 10, 1e6
    // from frame 16); editing the last key keeps the solver's states to frame 10 and steps
    // 10 frames again, to the same bits as a fresh run of the edited graph.
    let text = |late: f64| {
        file(
            &format!(
                r#""grid": {{"type": "geo.grid", "params": {{"width": 0.5, "height": 0.5, "nx": 6, "ny": 6, "plane": "xz", "center": [0, 1, 0]}}}},
        "cloth": {{"type": "convert.cloth", "inputs": {{"mesh": "grid.mesh"}}, "params": {{"name": "cloth"}}}},
        "e": {{"type": "anim.curve", "params": {{"frames": [10, 16], "values": [2e5, {late}], "interpolation": "smooth"}}}},
        "shell": {{"type": "sec.discrete_shell", "inputs": {{"element": "cloth.element", "youngs_modulus": "e.out"}}, "params": {{"thickness": 5e-4}}}},
        "density": {{"type": "sec.density", "inputs": {{"element": "shell.element"}}, "params": {{"area_density": 0.15}}}},
        "pins": {{"type": "convert.attachment", "inputs": {{"target": "density.element"}}, "params": {{"name": "pins", "vertices": [0, 5]}}}},
        "material": {{"type": "behavior.discrete_shell"}},
        "gravity": {{"type": "behavior.gravity"}},
        "attach": {{"type": "behavior.attachment"}},
        "tree": {{"type": "behavior.tree", "inputs": {{"behaviors": ["material.behavior", "gravity.behavior", "attach.behavior"]}}}},
        "solve": {{"type": "solver.solid", "inputs": {{"elements": ["density.element", "pins.element"], "tree": "tree.tree"}},
                   "params": {{"substeps": 2, "tolerance": 1e-8}}}},
        "corner": {{"type": "scene.vertex", "inputs": {{"scene": "solve.scene"}}, "params": {{"element": "cloth", "index": 35}}}}"#
            ),
            r#""corner": "corner.position""#,
        )
    };
    let mut g = graph(&text(1e6));
    for f in 0..=20 {
        vec3_at(&mut g, "corner", f);
    }
    let steps = g.node_stats("solve").unwrap().steps;
    assert_eq!(steps, 20);
    g.set_param("e", "values", serde_json::json!([2e5, 5e6]))
        .unwrap();
    let edited = vec3_at(&mut g, "corner", 20);
    assert_eq!(g.node_stats("solve").unwrap().steps - steps, 10);
    let mut fresh = graph(&text(5e6));
    assert_eq!(edited, vec3_at(&mut fresh, "corner", 20));
    // The stiffer late cloth hangs differently: the edit took effect.
    let mut before = graph(&text(1e6));
    assert_ne!(edited, vec3_at(&mut before, "corner", 20));
}
