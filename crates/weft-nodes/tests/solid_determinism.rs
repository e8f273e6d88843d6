//! The cloth solver is a stateful node: resuming from any checkpoint, jumping straight to a
//! frame, or running again from scratch must give bit-identical positions.

mod common;
use common::*;
use weft_graph::{Context, Graph};
use weft_nodes::physics::Scene;

fn cloth_with(integrator: &str) -> Graph {
    graph(&file(
        &r#""mesh":  {"type": "geo.grid", "params": {"nx": 8, "ny": 8, "center": [0.0, 1.0, 0.0]}},
           "cloth": {"type": "convert.cloth", "inputs": {"mesh": "mesh.mesh"}},
           "pins":  {"type": "convert.attachment", "inputs": {"target": "cloth.element"}, "params": {"vertices": [0, 7]}},
           "mat":   {"type": "behavior.discrete_shell"},
           "grav":  {"type": "behavior.gravity"},
           "att":   {"type": "behavior.attachment"},
           "tree":  {"type": "behavior.tree", "inputs": {"behaviors": ["mat.behavior", "grav.behavior", "att.behavior"]}},
           "solve": {"type": "solver.solid", "inputs": {"elements": ["cloth.element", "pins.element"], "tree": "tree.tree"}, "params": {"substeps": 2, "integrator": "INTEGRATOR"}}"#
            .replace("INTEGRATOR", integrator),
        r#""scene": "solve.scene""#,
    ))
}

fn bits(g: &mut Graph, frame: i64) -> Vec<u64> {
    let v = g.pull("scene", Context::new(frame)).unwrap();
    let scene = v.get::<Scene>().unwrap();
    scene[0]
        .geometry
        .positions()
        .iter()
        .flat_map(|p| p.map(f64::to_bits))
        .collect()
}

#[test]
fn resume_jump_and_rerun_are_bit_identical() {
    resume_jump_and_rerun("euler");
}

/// BDF2 steps from the last two states: its history travels with the checkpoints, so a
/// resumed run takes the same BDF2 steps as the sequential one, not an Euler restart.
#[test]
fn bdf2_resume_jump_and_rerun_are_bit_identical() {
    resume_jump_and_rerun("bdf2");
    // And it is not implicit Euler under another name.
    assert_ne!(
        bits(&mut cloth_with("bdf2"), 8),
        bits(&mut cloth_with("euler"), 8)
    );
}

fn resume_jump_and_rerun(integrator: &str) {
    let cloth = || cloth_with(integrator);
    let mut seq = cloth();
    let reference: Vec<Vec<u64>> = (0..=8).map(|f| bits(&mut seq, f)).collect();
    assert_ne!(reference[0], reference[8], "the cloth moved");

    let mut jump = cloth();
    assert_eq!(bits(&mut jump, 8), reference[8]);

    let mut resumed = cloth();
    bits(&mut resumed, 5);
    resumed.drop_checkpoints_after("solve", 3);
    assert_eq!(bits(&mut resumed, 8), reference[8], "resumed from frame 3");
    assert_eq!(bits(&mut resumed, 2), reference[2], "an earlier checkpoint");

    // An upstream change re-simulates, and changing it back returns exactly the original.
    resumed
        .set_param("grav", "acceleration", serde_json::json!([0.0, -5.0, 0.0]))
        .unwrap();
    assert_ne!(bits(&mut resumed, 8), reference[8]);
    resumed
        .set_param("grav", "acceleration", serde_json::json!([0.0, -9.81, 0.0]))
        .unwrap();
    assert_eq!(bits(&mut resumed, 8), reference[8]);
}
