//! The physics examples checked against stated invariants through their graph files: pinned
//! vertices stay exactly on their targets, cloth and strands keep their lengths within the
//! stretch their stiffness allows, and the cloth hangs.

mod common;
use common::*;
use weft::graph::{Context, Graph};

/// Loads `graphs/NAME` with extra measuring nodes and outputs, and without the file outputs.
fn instrumented(name: &str, nodes: serde_json::Value, outputs: serde_json::Value) -> Graph {
    let text = std::fs::read_to_string(graphs_dir().join(name)).unwrap();
    let mut doc: serde_json::Value = serde_json::from_str(&text).unwrap();
    for (k, v) in nodes.as_object().unwrap() {
        doc["nodes"][k] = v.clone();
    }
    doc["outputs"] = outputs;
    graph(&doc.to_string())
}

fn vec3_at(g: &mut Graph, output: &str, frame: i64) -> [f64; 3] {
    let v = g
        .pull(output, Context::new(frame))
        .unwrap_or_else(|e| panic!("{e}"));
    *v.get::<[f64; 3]>().expect("a vec3 output")
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

#[test]
fn cloth_hang_keeps_its_pins_and_its_size_and_hangs() {
    let vertex = |i: u32| {
        serde_json::json!({"type": "scene.vertex", "inputs": {"scene": "solve.scene"},
                           "params": {"element": "cloth", "index": i}})
    };
    let mut g = instrumented(
        "cloth_hang.json",
        serde_json::json!({"pin0": vertex(0), "pin1": vertex(23), "free": vertex(575)}),
        serde_json::json!({"pin0": "pin0.position", "pin1": "pin1.position",
                           "free": "free.position", "center": "center.centroid"}),
    );
    // The 1 m grid at height 1.5: its first row holds the pins.
    let (p0, p1) = (vec3_at(&mut g, "pin0", 0), vec3_at(&mut g, "pin1", 0));
    assert_eq!(p0, [-0.5, 1.5, -0.5]);
    assert_eq!(p1, [0.5, 1.5, -0.5]);
    let c0 = vec3_at(&mut g, "center", 0);
    let mut lowest: f64 = c0[1];
    for frame in 1..=24 {
        // Hard attachments: exactly on target, every frame.
        assert_eq!(vec3_at(&mut g, "pin0", frame), p0, "frame {frame}");
        assert_eq!(vec3_at(&mut g, "pin1", frame), p1, "frame {frame}");
        // The free corner is at most the diagonal (√2 m) from a pin, plus the stretch this
        // membrane allows under its own weight (E t = 1000 N/m against ~1.5 N: well below 1 %).
        let d = dist(vec3_at(&mut g, "free", frame), p0);
        assert!(
            d < 2f64.sqrt() * 1.01,
            "frame {frame}: corner {d} m from the pin"
        );
        lowest = lowest.min(vec3_at(&mut g, "center", frame)[1]);
    }
    // Hanging from one edge's ends, the centroid drops; it cannot drop below the pins by more
    // than the cloth's half-diagonal (0.71 m).
    assert!(
        lowest < c0[1] - 0.2,
        "centroid only reached {lowest} from {}",
        c0[1]
    );
    assert!(lowest > 1.5 - 0.72, "centroid fell to {lowest}");
}

#[test]
fn hair_swing_keeps_its_segment_lengths() {
    // Strand 0 has 11 vertices (10 segments of 0.025 m); the first two are the clamped root.
    let vertex = |i: u32| {
        serde_json::json!({"type": "scene.vertex", "inputs": {"scene": "solve.scene"},
                           "params": {"element": "hair", "index": i}})
    };
    let mut g = instrumented(
        "hair_swing.json",
        serde_json::json!({"a": vertex(5), "b": vertex(6), "tip": vertex(10), "root": vertex(0)}),
        serde_json::json!({"a": "a.position", "b": "b.position", "tip": "tip.position",
                           "root": "root.position"}),
    );
    let rest = dist(vec3_at(&mut g, "a", 0), vec3_at(&mut g, "b", 0));
    assert!((rest - 0.025).abs() < 1e-12, "rest segment {rest}");
    for frame in 1..=24 {
        // Stretch stiffness E·πr² against the strand's weight and swing: under 0.1 %.
        let l = dist(vec3_at(&mut g, "a", frame), vec3_at(&mut g, "b", frame));
        assert!(
            (l / rest - 1.0).abs() < 1e-3,
            "frame {frame}: segment {l} m"
        );
        // Polyline: the tip is never farther from the root than the strand's length.
        let reach = dist(
            vec3_at(&mut g, "tip", frame),
            vec3_at(&mut g, "root", frame),
        );
        assert!(
            reach <= 0.25 * 1.001,
            "frame {frame}: tip {reach} m from the root"
        );
    }
}
