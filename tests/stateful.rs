//! Stateful nodes: per-frame checkpoints, resume, invalidation, start frame.
//!
//! The graph is an oscillator driven by an animated input (a sine of time), so every step
//! reads an upstream value at its own frame: resuming must re-read the same inputs.

mod common;
use common::*;
use weft::graph::{Context, Graph};

fn driven() -> Graph {
    graph(&file(
        r#""clock": {"type": "time.frame"},
           "drive": {"type": "math.expr", "params": {"expr": "3 * sin(5 * x)"}, "inputs": {"x": "clock.time"}},
           "osc":   {"type": "ode.oscillator", "inputs": {"drive": "drive.out"},
                     "params": {"omega": 4.0, "zeta": 0.05, "method": "rk4", "substeps": 3}},
           "other": {"type": "value.float", "params": {"value": 1.0}}"#,
        r#""x": "osc.x", "v": "osc.v", "other": "other.out""#,
    ))
}

fn bits(g: &mut Graph, frame: i64) -> (u64, u64) {
    (
        f64_at(g, "x", frame).to_bits(),
        f64_at(g, "v", frame).to_bits(),
    )
}

#[test]
fn resuming_from_a_checkpoint_is_bit_identical_to_running_from_frame_zero() {
    let mut sequential = driven();
    let reference: Vec<(u64, u64)> = (0..=40).map(|f| bits(&mut sequential, f)).collect();
    assert_eq!(sequential.node_stats("osc").unwrap().steps, 40);

    // Jump straight to 40: one run of 40 steps, the same bits.
    let mut direct = driven();
    assert_eq!(bits(&mut direct, 40), reference[40]);
    assert_eq!(direct.node_stats("osc").unwrap().steps, 40);

    // 30 first, then 40: resumes at 30 (10 more steps), the same bits.
    let mut resumed = driven();
    assert_eq!(bits(&mut resumed, 30), reference[30]);
    assert_eq!(resumed.node_stats("osc").unwrap().steps, 30);
    assert_eq!(bits(&mut resumed, 40), reference[40]);
    assert_eq!(resumed.node_stats("osc").unwrap().steps, 40);

    // Going back costs no steps: every frame is checkpointed.
    assert_eq!(bits(&mut resumed, 12), reference[12]);
    assert_eq!(resumed.node_stats("osc").unwrap().steps, 40);
    assert_eq!(
        resumed.checkpoint_frames("osc"),
        (0..=40).collect::<Vec<_>>()
    );

    // With checkpoints only up to 25 kept, asking for 33 resumes at 25.
    resumed.drop_checkpoints_after("osc", 25);
    assert_eq!(bits(&mut resumed, 33), reference[33]);
    assert_eq!(resumed.node_stats("osc").unwrap().steps, 48);
}

#[test]
fn an_upstream_change_drops_the_checkpoints_and_an_unrelated_one_does_not() {
    let mut g = driven();
    let before = bits(&mut g, 20);
    g.set_param("other", "value", serde_json::json!(2.0))
        .unwrap();
    assert_eq!(
        g.checkpoint_frames("osc").len(),
        21,
        "an unrelated branch keeps the checkpoints"
    );
    assert_eq!(bits(&mut g, 20), before);
    assert_eq!(g.node_stats("osc").unwrap().steps, 20);

    g.set_param("drive", "expr", serde_json::json!("2 * sin(5 * x)"))
        .unwrap();
    // The drive feeds the oscillator: every state it changed is dropped. Both drives are 0 at
    // frame 0 (sin 0), so the start state, computed from it, stays.
    assert_eq!(
        g.checkpoint_frames("osc"),
        vec![0],
        "the drive feeds the oscillator from frame 1"
    );
    let after = bits(&mut g, 20);
    assert_ne!(after, before);
    assert_eq!(
        g.node_stats("osc").unwrap().steps,
        40,
        "re-simulated from the start"
    );
    // And the result is what a fresh graph with the new drive computes.
    let mut fresh = driven();
    fresh
        .set_param("drive", "expr", serde_json::json!("2 * sin(5 * x)"))
        .unwrap();
    assert_eq!(bits(&mut fresh, 20), after);

    // Changing the node's own parameter drops its checkpoints too.
    g.set_param("osc", "zeta", serde_json::json!(0.2)).unwrap();
    assert!(g.checkpoint_frames("osc").is_empty());
}

#[test]
fn frames_before_the_start_hold_the_initial_state() {
    let mut g = driven();
    g.set_param("osc", "start_frame", serde_json::json!(10))
        .unwrap();
    for f in [-5, 0, 9, 10] {
        assert_eq!(f64_at(&mut g, "x", f), 1.0, "frame {f}");
        assert_eq!(f64_at(&mut g, "v", f), 0.0, "frame {f}");
    }
    assert_eq!(g.node_stats("osc").unwrap().steps, 0);
    assert_ne!(f64_at(&mut g, "x", 11), 1.0);
    assert_eq!(g.node_stats("osc").unwrap().steps, 1);
}

#[test]
fn a_different_frame_rate_is_a_different_simulation() {
    let mut g = driven();
    // Without the drive (which is sampled once per frame, a first-order effect), both runs
    // are RK4 to t = 1 s with h = 1/72 vs 1/144 s: close, but not bit for bit.
    g.set_param("drive", "expr", serde_json::json!("0"))
        .unwrap();
    let at24 = f64_at_fps(&mut g, "x", 24, 24.0);
    let at48 = f64_at_fps(&mut g, "x", 48, 48.0);
    assert!((at24 - at48).abs() < 1e-5, "{at24} vs {at48}");
    assert_ne!(at24.to_bits(), at48.to_bits());
    assert_eq!(f64_at_fps(&mut g, "x", 24, 24.0).to_bits(), at24.to_bits());
}

#[test]
fn animated_nodes_recompute_per_frame_and_static_ones_do_not() {
    let mut g = driven();
    for f in 0..5 {
        f64_at(&mut g, "x", f);
        f64_at(&mut g, "other", f);
    }
    // Frame 0 is the initial state, which does not read the drive: frames 1..4 do.
    assert_eq!(
        g.evaluations("drive"),
        4,
        "one evaluation per stepped frame"
    );
    assert_eq!(g.evaluations("other"), 1, "static: evaluated once");
    let _ = g.pull("x", Context::new(4)).unwrap();
    assert_eq!(g.evaluations("drive"), 4, "same frame again: cached");
}
