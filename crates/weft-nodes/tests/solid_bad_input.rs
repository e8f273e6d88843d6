//! Bad input to cloth and hair graphs: each is a clear error (or one warning) naming the node,
//! the parameter or element, and the vertex or triangle; nothing panics.

mod common;
use common::*;
use weft_graph::{Context, Graph};

/// A cloth graph over `mesh_node`, with extra nodes and SEC parameters spliced in.
fn cloth_graph(mesh_node: &str, shell_params: &str, pins: &str, extra: &str) -> String {
    file(
        &format!(
            r#"{mesh_node},
            "cloth":  {{"type": "convert.cloth", "inputs": {{"mesh": "mesh.mesh"{extra}}}}},
            "shell":  {{"type": "sec.discrete_shell", "inputs": {{"element": "cloth.element"}}, "params": {{{shell_params}}}}},
            "pins":   {{"type": "convert.attachment", "inputs": {{"target": "shell.element"}}, "params": {{"vertices": [{pins}]}}}},
            "mat":    {{"type": "behavior.discrete_shell"}},
            "grav":   {{"type": "behavior.gravity"}},
            "att":    {{"type": "behavior.attachment"}},
            "tree":   {{"type": "behavior.tree", "inputs": {{"behaviors": ["mat.behavior", "grav.behavior", "att.behavior"]}}}},
            "solve":  {{"type": "solver.solid", "inputs": {{"elements": ["shell.element", "pins.element"], "tree": "tree.tree"}}}}"#
        ),
        r#""scene": "solve.scene""#,
    )
}

const GRID: &str = r#""mesh": {"type": "geo.grid", "params": {"nx": 5, "ny": 5}}"#;

fn run_error(g: &mut Graph, frame: i64) -> String {
    g.pull("scene", Context::new(frame))
        .unwrap_err()
        .to_string()
}

fn obj_mesh(text: &str) -> (tempfile::TempDir, String) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.obj");
    std::fs::write(&path, text).unwrap();
    let node = format!(
        r#""mesh": {{"type": "geo.obj", "params": {{"path": {:?}}}}}"#,
        path.to_str().unwrap()
    );
    (dir, node)
}

#[test]
fn negative_stiffness_and_poisson_ratio_of_a_half_are_load_errors() {
    let e = load_error(&cloth_graph(
        GRID,
        r#""youngs_modulus": -5.0, "poisson_ratio": 0.5"#,
        "0",
        "",
    ));
    assert!(
        e.contains("node 'shell': param 'youngs_modulus': must be > 0, got -5"),
        "{e}"
    );
    assert!(
        e.contains("node 'shell': param 'poisson_ratio': must be >= 0 and < 0.5, got 0.5"),
        "{e}"
    );
}

#[test]
fn attachment_indices_out_of_range_name_the_vertex() {
    let mut g = graph(&cloth_graph(GRID, "", "0, 25", ""));
    let e = run_error(&mut g, 0);
    assert_eq!(
        e,
        "node 'pins': param 'vertices': vertex 25 is out of range ('cloth' has 25 vertices)"
    );
}

#[test]
fn a_rest_shape_with_another_vertex_count_is_refused() {
    let text = cloth_graph(GRID, "", "0", r#", "rest": "small.mesh""#).replace(
        r#""cloth":"#,
        r#""small": {"type": "geo.grid", "params": {"nx": 4, "ny": 4}}, "cloth":"#,
    );
    let mut g = graph(&text);
    assert_eq!(
        run_error(&mut g, 0),
        "node 'cloth': input 'rest': has 16 vertices but the element has 25"
    );
}

#[test]
fn nan_positions_in_a_file_are_reported_with_the_line() {
    let (_dir, node) = obj_mesh("v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n");
    let mut g = graph(&cloth_graph(&node, "", "0", ""));
    let e = run_error(&mut g, 0);
    assert!(
        e.starts_with("node 'mesh': ") && e.contains("line 3"),
        "{e}"
    );
}

#[test]
fn a_zero_area_triangle_stops_the_solver_with_its_index() {
    let (_dir, node) = obj_mesh("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 4\n");
    let mut g = graph(&cloth_graph(&node, "", "0", ""));
    let e = run_error(&mut g, 0);
    assert_eq!(
        e,
        "node 'solve' at frame 0: element 'cloth': triangle 1 [0, 1, 3] has zero rest area (0e0 m²)"
    );
}

#[test]
fn a_non_manifold_edge_is_one_warning_and_the_cloth_still_runs() {
    // Three triangles share the edge (1, 2).
    let (_dir, node) =
        obj_mesh("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 2 0.5 0\nv 1 0.5 1\nf 1 2 3\nf 2 4 3\nf 2 5 3\n");
    let mut g = graph(&cloth_graph(&node, "", "0", ""));
    for f in 0..3 {
        g.pull("scene", Context::new(f)).unwrap();
    }
    let w = g.take_warnings();
    assert_eq!(w.len(), 1, "{w:?}");
    assert_eq!(w[0].node, "solve");
    assert!(w[0].message.contains("1 non-manifold edge(s)"), "{w:?}");
}

#[test]
fn an_sec_no_behavior_reads_is_a_warning() {
    let text = cloth_graph(GRID, "", "0", "").replace(
        r#""shell":  {"type": "sec.discrete_shell", "inputs": {"element": "cloth.element"}"#,
        r#""rodsec": {"type": "sec.rod", "inputs": {"element": "cloth.element"}}, "shell":  {"type": "sec.discrete_shell", "inputs": {"element": "rodsec.element"}"#,
    );
    let mut g = graph(&text);
    g.pull("scene", Context::new(1)).unwrap();
    let w = g.take_warnings();
    assert!(
        w.iter().any(|w| w.message
            == "element 'cloth' carries a 'rod' SEC that no Behavior in the tree reads for it"),
        "{w:?}"
    );
}

#[test]
fn a_duplicated_face_is_refused_by_name() {
    // Double-sided exports list a face twice; it would double mass and stiffness.
    let (_dir, node) = obj_mesh("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\nf 3 2 1\n");
    let mut g = graph(&cloth_graph(&node, "", "0", ""));
    let e = run_error(&mut g, 0);
    assert_eq!(
        e,
        "node 'solve' at frame 0: element 'cloth': triangles 0 and 2 use the same vertices [0, 1, 2] (a duplicated face, e.g. from a double-sided export)"
    );
}

#[test]
fn a_vertex_in_no_triangle_is_named_as_such() {
    let (_dir, node) = obj_mesh("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 5 5\nf 1 2 3\n");
    let mut g = graph(&cloth_graph(&node, "", "0", ""));
    let e = run_error(&mut g, 0);
    assert_eq!(
        e,
        "node 'solve' at frame 0: element 'cloth': vertex 3 is in no triangle, so it has no mass (unused vertices cannot be simulated: remove or pin it)"
    );
}

#[test]
fn element_names_cannot_leave_the_output_directory() {
    let text = cloth_graph(GRID, "", "0", "").replace(
        r#""inputs": {"mesh": "mesh.mesh"}}"#,
        r#""inputs": {"mesh": "mesh.mesh"}, "params": {"name": "../escape"}}"#,
    );
    let e = load_error(&text);
    assert!(e.contains("node 'cloth': params: param 'name': must be a non-empty printable name without '/', '\\' or '..', got \"../escape\""), "{e}");
}

/// The small cloth graph with an `output.usd` node writing to `usd`.
fn usd_graph(usd: &std::path::Path) -> String {
    let text = cloth_graph(GRID, "", "0", "").replace(
        r#""scene": "solve.scene""#,
        r#""scene": "solve.scene", "usd": "usd.path""#,
    );
    text.replace(
        r#""solve":  {"type": "solver.solid""#,
        &format!(r#""usd": {{"type": "output.usd", "inputs": {{"scene": "solve.scene"}}, "params": {{"path": {:?}}}}}, "solve":  {{"type": "solver.solid""#, usd.to_str().unwrap()),
    )
}

/// The clips are named after the USD file and listed between `@`s in its root: a name that
/// would break that is refused with the parameter named, before anything is written.
#[test]
fn a_usd_file_name_with_an_at_sign_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let usd = dir.path().join("s@1.usda");
    let mut g = graph(&usd_graph(&usd));
    let e = g.pull("usd", Context::new(0)).unwrap_err().to_string();
    assert!(
        e.contains("node 'usd'") && e.contains("param 'path'") && e.contains("'@'"),
        "{e}"
    );
    assert!(!usd.exists() && !dir.path().join("s@1.clips").exists());
}

#[test]
fn a_usd_file_forgets_frames_from_before_an_upstream_change_and_their_clips() {
    let dir = tempfile::tempdir().unwrap();
    let usd = dir.path().join("s.usda");
    let mut g = graph(&usd_graph(&usd));
    for f in 0..=4 {
        g.pull("usd", Context::new(f)).unwrap();
    }
    assert!(
        std::fs::read_to_string(&usd)
            .unwrap()
            .contains("endTimeCode = 4")
    );
    g.set_param("grav", "acceleration", serde_json::json!([0.0, 0.0, 0.0]))
        .unwrap();
    for f in 0..=2 {
        g.pull("usd", Context::new(f)).unwrap();
    }
    let t = std::fs::read_to_string(&usd).unwrap();
    assert!(
        t.contains("endTimeCode = 2"),
        "stale frames 3 and 4 were kept"
    );
    // Each frame's points are a clip beside the root; the stale frames' clips are gone.
    assert!(
        t.contains("double2[] active = [(0, 0), (1, 1), (2, 2)]\n"),
        "{t}"
    );
    let clips = dir.path().join("s.clips");
    for f in 0..=4 {
        let clip = clips.join(format!("s.{f:04}.usda"));
        assert_eq!(clip.exists(), f <= 2, "{}", clip.display());
    }
    assert!(clips.join("manifest.usda").exists());
}
