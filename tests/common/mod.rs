//! Helpers shared by the graph-level tests.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::Arc;
use weft::graph::{Context, Graph, Registry, load_path, load_str};

pub fn registry() -> Arc<Registry> {
    weft::nodes::registry()
}

pub fn graphs_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs")
}

/// Loads `graphs/NAME`.
pub fn example(name: &str) -> Graph {
    let path = graphs_dir().join(name);
    load_path(&registry(), &path).unwrap_or_else(|e| panic!("{e}"))
}

/// Loads graph text, panicking with the full error list.
pub fn graph(text: &str) -> Graph {
    load_str(&registry(), text, "<test>").unwrap_or_else(|e| panic!("{e}"))
}

/// The error text of a graph that must not load.
pub fn load_error(text: &str) -> String {
    match load_str(&registry(), text, "t.json") {
        Ok(_) => panic!("graph loaded but should not have"),
        Err(e) => e.to_string(),
    }
}

/// Float output at a frame (fps 24 unless given).
pub fn f64_at(g: &mut Graph, output: &str, frame: i64) -> f64 {
    f64_at_fps(g, output, frame, 24.0)
}

pub fn f64_at_fps(g: &mut Graph, output: &str, frame: i64, fps: f64) -> f64 {
    let v = g
        .pull(output, Context::at(frame, fps))
        .unwrap_or_else(|e| panic!("{e}"));
    *v.get::<f64>()
        .unwrap_or_else(|| panic!("output '{output}' is not a float"))
}

/// Wraps node declarations into a graph file.
pub fn file(nodes: &str, outputs: &str) -> String {
    format!(
        r#"{{"format": "weft-graph", "version": 1, "nodes": {{{nodes}}}, "outputs": {{{outputs}}}}}"#
    )
}

/// Vec3 output at a frame (fps 24).
pub fn vec3_at(g: &mut Graph, output: &str, frame: i64) -> [f64; 3] {
    let v = g
        .pull(output, Context::new(frame))
        .unwrap_or_else(|e| panic!("{e}"));
    *v.get::<[f64; 3]>().expect("a vec3 output")
}

/// Distance between two points.
pub fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Graph-file text for `scene.vertex` probes `v0` … `v{count-1}` of element `element` in the
/// scene `scene` ("node.port"): (their node declarations, their output declarations).
pub fn vertex_probes(scene: &str, element: &str, count: usize) -> (String, String) {
    let nodes: Vec<String> = (0..count)
        .map(|i| {
            format!(
                r#""v{i}": {{"type": "scene.vertex", "inputs": {{"scene": "{scene}"}}, "params": {{"element": "{element}", "index": {i}}}}}"#
            )
        })
        .collect();
    let outputs: Vec<String> = (0..count)
        .map(|i| format!(r#""v{i}": "v{i}.position""#))
        .collect();
    (nodes.join(",\n"), outputs.join(", "))
}

/// The positions of probes `v0` … `v{count-1}` (see [`vertex_probes`]) at `frame`.
pub fn probed_positions(g: &mut Graph, count: usize, frame: i64) -> Vec<[f64; 3]> {
    (0..count)
        .map(|i| vec3_at(g, &format!("v{i}"), frame))
        .collect()
}
