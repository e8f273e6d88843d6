//! Helpers shared by the graph-level tests, here and in the workspace's `tests/` (which
//! includes this file): graphs from text with the full registry, outputs at a frame, vertex
//! probes, and the independent distance and intersection checks of `weft_check` applied to
//! a scene's elements.
#![allow(dead_code, unused_imports)] // each test file uses some of these

use std::sync::Arc;
use weft_check::distance::{along, length};
pub use weft_check::vertex_probes;
use weft_check::{distance_to_segment, distance_to_triangle, least_along};
use weft_graph::{Context, Graph, Registry, load_str};
use weft_nodes::physics::Scene;

pub fn registry() -> Arc<Registry> {
    weft_nodes::registry()
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

/// The positions of probes `v0` … `v{count-1}` (see [`vertex_probes`]) at `frame`.
pub fn probed_positions(g: &mut Graph, count: usize, frame: i64) -> Vec<[f64; 3]> {
    (0..count)
        .map(|i| vec3_at(g, &format!("v{i}"), frame))
        .collect()
}

/// What the solver may leave of the distance `distance` kept [m], with Newton and ADMM at
/// `tol` [m/s] and steps of `h` [s] and the default response strength ½: a step may end
/// `tol`·h inside (the ADMM's primal residual), and the next resolves only half of an
/// existing penetration (strength) while adding at most `tol`·h again, so it stays below
/// `tol`·h / ½; plus the exact check's slack on triangles without a contact, a thousandth of
/// the distance.
pub fn allowed(tol: f64, h: f64, distance: f64) -> f64 {
    tol * h / 0.5 + 1e-3 * distance
}

/// The mesh of element `name` in `scene` (the test's collider).
fn mesh_of<'a>(scene: &'a Scene, name: &str) -> &'a weft_scene::Mesh {
    let c = scene.iter().find(|e| e.name == name).unwrap();
    let weft_scene::Geometry::Mesh(m) = &*c.geometry else {
        panic!("'{name}' is a mesh")
    };
    m
}

/// The smallest exact distance from the free vertices of element `member` (skipping the
/// first `skip` of every `per` vertices: a strand's held roots) to the triangles of the mesh
/// element `collider`, in `scene`.
pub fn closest_to_mesh(
    scene: &Scene,
    member: &str,
    per: usize,
    skip: usize,
    collider: &str,
) -> f64 {
    let m = mesh_of(scene, collider);
    let e = scene.iter().find(|e| e.name == member).unwrap();
    let mut closest = f64::INFINITY;
    for (i, p) in e.geometry.positions().iter().enumerate() {
        if i % per < skip {
            continue;
        }
        for t in &m.triangles {
            let tri = t.map(|i| m.positions[i as usize]);
            closest = closest.min(distance_to_triangle(*p, tri));
        }
    }
    closest
}

/// The least distance from the hair `member`'s segments to the `collider`'s mesh,
/// independently of the solver: the distance from a point moving along a segment to a
/// triangle (a convex set) is convex in its parameter, so a golden-section search over it
/// (60 rounds: 3e-13 of the segment) with `distance_to_triangle` finds its minimum; a
/// triangle whose distance to the segment's middle, less half the segment, is already no
/// closer than the best so far is skipped. `per` vertices a strand; segments whose second
/// vertex is below `skip` (both ends held) are left out.
pub fn closest_segment_to_mesh(
    scene: &Scene,
    member: &str,
    per: usize,
    skip: usize,
    collider: &str,
) -> f64 {
    let m = mesh_of(scene, collider);
    let p = positions_of(scene, member);
    let mut closest = f64::INFINITY;
    for i in 0..p.len() - 1 {
        if i % per == per - 1 || i % per + 1 < skip {
            continue;
        }
        let (a, b) = (p[i], p[i + 1]);
        let half = 0.5 * length(a, b);
        for t in &m.triangles {
            let tri = t.map(|i| m.positions[i as usize]);
            if distance_to_triangle(along(a, b, 0.5), tri) - half >= closest {
                continue;
            }
            closest = closest.min(least_along(a, b, |x| distance_to_triangle(x, tri)));
        }
    }
    closest
}

/// The positions of the element `name` in `scene`.
pub fn positions_of<'s>(scene: &'s Scene, name: &str) -> &'s [[f64; 3]] {
    scene
        .iter()
        .find(|e| e.name == name)
        .unwrap()
        .geometry
        .positions()
}

/// Pairs of triangles of the cloth elements `names` in `scene` (between them and within
/// each, skipping pairs that share a vertex) that intersect: an edge of one meets the other
/// (`weft_check`, independent of the solver).
pub fn intersecting_triangles(scene: &Scene, names: &[&str]) -> usize {
    let mut tris: Vec<[[f64; 3]; 3]> = Vec::new();
    let mut ids: Vec<[(usize, u32); 3]> = Vec::new();
    for (k, name) in names.iter().enumerate() {
        let e = scene.iter().find(|e| e.name == *name).unwrap();
        let weft_scene::Geometry::Mesh(m) = &*e.geometry else {
            panic!("'{name}' is a mesh")
        };
        for t in &m.triangles {
            tris.push(t.map(|v| m.positions[v as usize]));
            ids.push(t.map(|v| (k, v)));
        }
    }
    weft_check::intersecting_pairs(&tris, &ids)
}

/// The least distance between two segments of the hair `member` in `scene` that share no
/// vertex (of one strand or of two), independently of the solver: the distance from a point
/// moving along one segment to the other (a convex set) is convex, so `least_along` finds
/// it; pairs whose bounding boxes are already farther apart than the best so far are
/// skipped. `per` vertices a strand; segments with both ends held (below `skip`) are left out.
pub fn closest_hair_pair(scene: &Scene, member: &str, per: usize, skip: usize) -> f64 {
    let p = positions_of(scene, member);
    let segments: Vec<usize> = (0..p.len() - 1)
        .filter(|i| i % per != per - 1 && i % per + 1 >= skip)
        .collect();
    let gap = |i: usize, j: usize| {
        (0..3)
            .map(|k| {
                let (li, hi) = (p[i][k].min(p[i + 1][k]), p[i][k].max(p[i + 1][k]));
                let (lj, hj) = (p[j][k].min(p[j + 1][k]), p[j][k].max(p[j + 1][k]));
                (lj - hi).max(li - hj).max(0.0)
            })
            .fold(0.0f64, f64::max)
    };
    let mut closest = f64::INFINITY;
    for (n, &i) in segments.iter().enumerate() {
        for &j in &segments[n + 1..] {
            if j <= i + 1 || gap(i, j) >= closest {
                continue; // adjacent segments share a vertex
            }
            let d = least_along(p[i], p[i + 1], |x| distance_to_segment(x, p[j], p[j + 1]));
            closest = closest.min(d);
        }
    }
    closest
}
