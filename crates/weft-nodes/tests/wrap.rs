//! Wrap (issue 17, item 5) through a graph: a render mesh twice as fine as a hanging cloth,
//! bound at rest, follows the simulated cloth: its vertices on the cloth's vertices exactly,
//! those between on the cloth's triangles, and the output writes it.

mod common;
use common::*;

#[test]
fn a_finer_render_mesh_follows_the_simulated_cloth() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("obj");
    let nodes = format!(
        r#""grid": {{"type": "geo.grid", "params": {{"width": 1.0, "height": 1.0, "nx": 9, "ny": 9, "plane": "xz", "center": [0, 1.5, 0]}}}},
        "fine": {{"type": "geo.grid", "params": {{"width": 1.0, "height": 1.0, "nx": 17, "ny": 17, "plane": "xz", "center": [0, 1.5, 0]}}}},
        "cloth": {{"type": "convert.cloth", "inputs": {{"mesh": "grid.mesh"}}, "params": {{"name": "cloth"}}}},
        "pins": {{"type": "convert.attachment", "inputs": {{"target": "cloth.element"}}, "params": {{"name": "pins", "vertices": [0, 8]}}}},
        "material": {{"type": "behavior.discrete_shell"}},
        "gravity": {{"type": "behavior.gravity"}},
        "attach": {{"type": "behavior.attachment"}},
        "tree": {{"type": "behavior.tree", "inputs": {{"behaviors": ["material.behavior", "gravity.behavior", "attach.behavior"]}}}},
        "solve": {{"type": "solver.solid", "inputs": {{"elements": ["cloth.element", "pins.element"], "tree": "tree.tree"}},
                   "params": {{"substeps": 2, "tolerance": 1e-4}}}},
        "wrap": {{"type": "scene.wrap", "inputs": {{"scene": "solve.scene", "render": "fine.mesh"}}, "params": {{"proxy": "cloth", "name": "render"}}}},
        "obj": {{"type": "output.obj", "inputs": {{"scene": "wrap.scene"}}, "params": {{"directory": {:?}}}}},
        "corner": {{"type": "scene.vertex", "inputs": {{"scene": "wrap.scene"}}, "params": {{"element": "cloth", "index": 80}}}},
        "rcorner": {{"type": "scene.vertex", "inputs": {{"scene": "wrap.scene"}}, "params": {{"element": "render", "index": 288}}}},
        "a": {{"type": "scene.vertex", "inputs": {{"scene": "wrap.scene"}}, "params": {{"element": "cloth", "index": 40}}}},
        "b": {{"type": "scene.vertex", "inputs": {{"scene": "wrap.scene"}}, "params": {{"element": "cloth", "index": 41}}}},
        "mid": {{"type": "scene.vertex", "inputs": {{"scene": "wrap.scene"}}, "params": {{"element": "render", "index": 145}}}}"#,
        obj.to_str().unwrap()
    );
    let mut g = graph(&file(
        &nodes,
        r#""corner": "corner.position", "rcorner": "rcorner.position", "a": "a.position",
           "b": "b.position", "mid": "mid.position", "obj": "obj.path""#,
    ));
    for frame in [0i64, 6, 12] {
        // Render vertex (16, 16) = 288 sits on cloth vertex (8, 8) = 80: weights (1, 0, 0),
        // no offset, so it is that vertex exactly.
        assert_eq!(
            vec3_at(&mut g, "rcorner", frame),
            vec3_at(&mut g, "corner", frame)
        );
        // Render vertex (9, 8) = 145 is the midpoint of cloth edge (4, 4)–(5, 4) = 40–41,
        // on the surface: the midpoint of the simulated edge (to rounding).
        let (a, b) = (vec3_at(&mut g, "a", frame), vec3_at(&mut g, "b", frame));
        let m = vec3_at(&mut g, "mid", frame);
        let want = [0, 1, 2].map(|k| 0.5 * (a[k] + b[k]));
        assert!(dist(m, want) < 1e-12, "frame {frame}: {m:?} vs {want:?}");
        g.pull("obj", weft_graph::Context::new(frame)).unwrap();
        assert!(obj.join(format!("render.{frame:04}.obj")).exists());
    }
    // The cloth fell: the wrap is not the rest pose.
    assert!(vec3_at(&mut g, "corner", 12)[1] < 1.3);
}

#[test]
fn a_wrap_without_its_proxy_or_under_a_taken_name_is_a_clear_error() {
    let nodes = r#""grid": {"type": "geo.grid", "params": {"nx": 3, "ny": 3}},
        "cloth": {"type": "convert.cloth", "inputs": {"mesh": "grid.mesh"}, "params": {"name": "cloth"}},
        "scene": {"type": "scene.gather", "inputs": {"elements": ["cloth.element"]}},
        "wrap": {"type": "scene.wrap", "inputs": {"scene": "scene.scene", "render": "grid.mesh"}, "params": {"proxy": "shirt"}},
        "ok": {"type": "scene.wrap", "inputs": {"scene": "scene.scene", "render": "grid.mesh"}, "params": {"name": "cloth"}}"#;
    let mut g = graph(&file(nodes, r#""wrap": "wrap.scene", "ok": "ok.scene""#));
    let e = g
        .pull("wrap", weft_graph::Context::new(0))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("'wrap'") && e.contains("has no element 'shirt' to wrap"),
        "{e}"
    );
    let e = g
        .pull("ok", weft_graph::Context::new(0))
        .unwrap_err()
        .to_string();
    assert!(e.contains("already has an element 'cloth'"), "{e}");
}

#[test]
fn render_hairs_follow_their_simulated_guides() {
    // 16 guide strands on a head-like sphere fall under gravity from straight out; 64 render
    // hairs grown the same way are interpolated from them. The guides' roots are held, so
    // every render root stays where it is (its three guide points there do not move: to
    // rounding), while the render tips swing with the guides; at the start frame the render
    // hairs are their own rest shape.
    let strands = |count: u32| {
        format!(
            r#"{{"type": "geo.strands", "params": {{"center": [0, 1, 0], "radius": 0.1, "count": {count}, "segments": 8, "length": 0.2, "cap_degrees": 80}}}}"#
        )
    };
    let nodes = format!(
        r#""guides": {}, "dense": {},
        "hair": {{"type": "convert.hair", "inputs": {{"curves": "guides.curves"}}, "params": {{"name": "hair"}}}},
        "roots": {{"type": "convert.attachment", "inputs": {{"target": "hair.element"}}, "params": {{"name": "roots", "select": "curve_roots", "root_vertices": 2}}}},
        "material": {{"type": "behavior.rod"}},
        "gravity": {{"type": "behavior.gravity"}},
        "attach": {{"type": "behavior.attachment"}},
        "tree": {{"type": "behavior.tree", "inputs": {{"behaviors": ["material.behavior", "gravity.behavior", "attach.behavior"]}}}},
        "solve": {{"type": "solver.solid", "inputs": {{"elements": ["hair.element", "roots.element"], "tree": "tree.tree"}}, "params": {{"substeps": 2, "tolerance": 1e-4}}}},
        "interp": {{"type": "scene.interpolate_hair", "inputs": {{"scene": "solve.scene", "render": "dense.curves"}}, "params": {{"guides": "hair", "name": "fur"}}}},
        "root": {{"type": "scene.vertex", "inputs": {{"scene": "interp.scene"}}, "params": {{"element": "fur", "index": 90}}}},
        "tip": {{"type": "scene.vertex", "inputs": {{"scene": "interp.scene"}}, "params": {{"element": "fur", "index": 98}}}},
        "dense_el": {{"type": "convert.hair", "inputs": {{"curves": "dense.curves"}}, "params": {{"name": "dense"}}}},
        "dscene": {{"type": "scene.gather", "inputs": {{"elements": ["dense_el.element"]}}}},
        "tip_rest": {{"type": "scene.vertex", "inputs": {{"scene": "dscene.scene"}}, "params": {{"element": "dense", "index": 98}}}}"#,
        strands(16),
        strands(64)
    );
    let mut g = graph(&file(
        &nodes,
        r#""root": "root.position", "tip": "tip.position", "tip_rest": "tip_rest.position""#,
    ));
    // Render strand 10 is vertices 90..=98; at the start it is its rest shape.
    let (root0, tip0) = (vec3_at(&mut g, "root", 0), vec3_at(&mut g, "tip", 0));
    assert!(dist(tip0, vec3_at(&mut g, "tip_rest", 0)) < 1e-15);
    for frame in [6i64, 12] {
        assert!(
            dist(vec3_at(&mut g, "root", frame), root0) < 1e-12,
            "frame {frame}"
        );
    }
    assert!(
        dist(vec3_at(&mut g, "tip", 12), tip0) > 0.01,
        "the render tip did not move"
    );
}
