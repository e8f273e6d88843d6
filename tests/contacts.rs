//! Contacts with colliders, through graphs as a user builds them (issue 13's verification):
//! an incline that sticks exactly or slides by Coulomb, a cloth thrown at a thin plane at
//! 10 m/s, cohesion under a ceiling, and a drape over a sphere whose clearance is checked by
//! an exact distance computed here, independently of the solver.

mod common;
use common::*;
use weft::graph::{Context, Graph};
use weft::nodes::physics::Scene;

/// A 0.1 m cloth patch (3 × 3 vertices, 0.15 kg/m²) at height `y` above (or below) a 4 m
/// square plane collider at height `plane_y`, both with friction `mu`, thickness 1 mm and
/// cohesion `cohesion` [Pa]; gravity `g`, initial velocity `v0`; `substeps` steps a frame,
/// Newton and ADMM to `tol` m/s.
#[allow(clippy::too_many_arguments)]
fn patch(
    y: f64,
    plane_y: f64,
    mu: f64,
    cohesion: f64,
    g: [f64; 3],
    v0: [f64; 3],
    substeps: usize,
    tol: f64,
) -> Graph {
    graph(&file(
        &format!(
            r#""grid":   {{"type": "geo.grid", "params": {{"width": 0.1, "height": 0.1, "nx": 3, "ny": 3, "plane": "xz", "center": [0.0, {y}, 0.0]}}}},
               "cloth":  {{"type": "convert.cloth", "inputs": {{"mesh": "grid.mesh"}}, "params": {{"name": "patch", "velocity": {v0:?}}}}},
               "dens":   {{"type": "sec.density", "inputs": {{"element": "cloth.element"}}, "params": {{"area_density": 0.15}}}},
               "csec":   {{"type": "sec.collider", "inputs": {{"element": "dens.element"}}, "params": {{"friction": {mu}, "thickness": 1e-3, "cohesion": {cohesion}}}}},
               "pmesh":  {{"type": "geo.grid", "params": {{"width": 4.0, "height": 4.0, "nx": 2, "ny": 2, "plane": "xz", "center": [0.0, {plane_y}, 0.0]}}}},
               "plane":  {{"type": "convert.collider", "inputs": {{"mesh": "pmesh.mesh"}}, "params": {{"name": "plane"}}}},
               "psec":   {{"type": "sec.collider", "inputs": {{"element": "plane.element"}}, "params": {{"friction": {mu}, "thickness": 1e-3, "cohesion": {cohesion}}}}},
               "group":  {{"type": "convert.collision_group"}},
               "mat":    {{"type": "behavior.discrete_shell"}},
               "grav":   {{"type": "behavior.gravity", "params": {{"acceleration": {g:?}}}}},
               "col":    {{"type": "behavior.collision"}},
               "tree":   {{"type": "behavior.tree", "inputs": {{"behaviors": ["mat.behavior", "grav.behavior", "col.behavior"]}}}},
               "solve":  {{"type": "solver.solid", "inputs": {{"elements": ["csec.element", "psec.element", "group.element"], "tree": "tree.tree"}},
                           "params": {{"substeps": {substeps}, "tolerance": {tol:e}, "max_iterations": 50, "contact_iterations": 2000}}}}"#
        ),
        r#""scene": "solve.scene""#,
    ))
}

/// The patch's positions and velocities at `frame`.
fn state(g: &mut Graph, frame: i64) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let v = g
        .pull("scene", Context::new(frame))
        .unwrap_or_else(|e| panic!("{e}"));
    let scene = v.get::<Scene>().unwrap();
    let e = scene.iter().find(|e| e.name == "patch").unwrap();
    let vel = e
        .vec3_channel("velocity")
        .map_or_else(Vec::new, <[_]>::to_vec);
    (e.geometry.positions().to_vec(), vel)
}

/// Gravity tilted by θ about z is the plane tilted by θ (the patch lies on the plane y = 0,
/// 2 mm up: both thicknesses). Returns, after 1 s (24 frames, h = 1/96 s): the largest
/// displacement along the slope [m], the mean velocity along it [m/s], the largest distance
/// off the plane's surface [m].
fn incline(theta_deg: f64, mu: f64) -> (f64, f64, f64) {
    let th = theta_deg.to_radians();
    let g = [9.81 * th.sin(), -9.81 * th.cos(), 0.0];
    let mut gr = patch(2e-3, 0.0, mu, 0.0, g, [0.0; 3], 4, 1e-11);
    let (x0, _) = state(&mut gr, 0);
    let (x, v) = state(&mut gr, 24);
    let slide = x
        .iter()
        .zip(&x0)
        .fold(0.0f64, |m, (a, b)| m.max((a[0] - b[0]).abs()));
    let off = x.iter().fold(0.0f64, |m, a| m.max((a[1] - 2e-3).abs()));
    let mean_v = v.iter().map(|v| v[0]).sum::<f64>() / v.len() as f64;
    (slide, mean_v, off)
}

/// VERIFY: with tan θ ≤ μ the patch sticks exactly (below 1e-9 m over 1 s; the ADMM stops at
/// 1e-11 m/s, so creep is at most 1e-11 m); above, it slides with a = g(sin θ − μ cos θ)
/// within 1 % (implicit Euler's velocity under a constant net force is exactly a t); the
/// threshold lies within 0.5° of atan μ (26.57° for μ = 0.5: 26.1° sticks, 27.0° slides).
#[test]
fn a_patch_on_an_incline_sticks_exactly_or_slides_by_coulomb() {
    let mu = 0.5;
    for theta in [20.0, 26.1] {
        let (slide, v, off) = incline(theta, mu);
        assert!(
            slide < 1e-9 && v.abs() < 1e-9,
            "θ = {theta}°: slid {slide} m, v {v}"
        );
        assert!(off < 1e-9, "θ = {theta}°: left the plane by {off} m");
    }
    for theta in [27.0f64, 35.0] {
        let (_, v, off) = incline(theta, mu);
        let th = theta.to_radians();
        let a = 9.81 * (th.sin() - mu * th.cos());
        assert!(
            (v / a - 1.0).abs() < 0.01,
            "θ = {theta}°: v {v} vs a t = {a}"
        );
        assert!(off < 1e-6, "θ = {theta}°: left the plane by {off} m");
    }
}

/// A patch thrown at 10 m/s at a thin (open, one-layer) plane with one step per frame at 24
/// fps (0.42 m a step, 200 times the distance kept) is stopped at it: at every frame every
/// vertex is above the plane by the 2 mm kept, less 1e-6 m (the solver's tolerance, 1e-6
/// m/s, over a step is 4e-8 m).
#[test]
fn a_fast_patch_never_crosses_a_thin_plane() {
    let mut g = patch(
        0.5,
        0.0,
        0.3,
        0.0,
        [0.0, -9.81, 0.0],
        [0.0, -10.0, 0.0],
        1,
        1e-6,
    );
    let mut lowest = f64::INFINITY;
    for f in 0..=12 {
        let (x, _) = state(&mut g, f);
        lowest = lowest.min(x.iter().map(|p| p[1]).fold(f64::INFINITY, f64::min));
    }
    assert!(lowest >= 2e-3 - 1e-6, "lowest vertex at {lowest} m");
    assert!(lowest < 2e-3 + 1e-6, "it reached the plane: {lowest} m");
}

/// Cohesion: a patch touching a ceiling stays when the cohesion exceeds its weight per area
/// (0.15 kg/m² × 9.81 m/s² = 1.4715 Pa) and falls when it does not: the threshold within 5 %
/// (1.05 × stays to 1e-9 m over 1 s, 0.95 × has fallen more than 1 cm).
#[test]
fn cohesion_holds_a_patch_under_a_ceiling_up_to_its_weight() {
    let weight = 0.15 * 9.81;
    let drop = |factor: f64| {
        let mut g = patch(
            1.0 - 2e-3,
            1.0,
            0.5,
            factor * weight,
            [0.0, -9.81, 0.0],
            [0.0; 3],
            4,
            1e-11,
        );
        let (x, _) = state(&mut g, 24);
        x.iter().map(|p| 1.0 - 2e-3 - p[1]).fold(0.0f64, f64::max)
    };
    let stays = drop(1.05);
    assert!(stays.abs() < 1e-9, "{stays}");
    let falls = drop(0.95);
    assert!(falls > 1e-2, "{falls}");
}

/// The exact distance from p to triangle (a, b, c), computed without the solver's code: the
/// projection onto the plane when it falls inside (by edge half-planes), else the nearest of
/// the three edges as clamped segments.
fn distance_to_triangle(p: [f64; 3], t: [[f64; 3]; 3]) -> f64 {
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let n = cross(sub(t[1], t[0]), sub(t[2], t[0]));
    let nn = dot(n, n).sqrt();
    let n = [n[0] / nn, n[1] / nn, n[2] / nn];
    let h = dot(sub(p, t[0]), n);
    let q = [p[0] - h * n[0], p[1] - h * n[1], p[2] - h * n[2]];
    let inside = (0..3).all(|k| dot(cross(sub(t[(k + 1) % 3], t[k]), sub(q, t[k])), n) >= 0.0);
    if inside {
        return h.abs();
    }
    (0..3)
        .map(|k| {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            let ab = sub(b, a);
            let s = (dot(sub(p, a), ab) / dot(ab, ab)).clamp(0.0, 1.0);
            let c = [a[0] + s * ab[0], a[1] + s * ab[1], a[2] + s * ab[2]];
            dot(sub(p, c), sub(p, c)).sqrt()
        })
        .fold(f64::INFINITY, f64::min)
}

/// The example `graphs/NAME` with one output, `scene`, from `from` (its file outputs off).
fn example_scene(name: &str, from: &str) -> Graph {
    let text = std::fs::read_to_string(graphs_dir().join(name)).unwrap();
    let mut doc: serde_json::Value = serde_json::from_str(&text).unwrap();
    doc["outputs"] = serde_json::json!({ "scene": from });
    graph(&doc.to_string())
}

/// What the solver may leave of the distance `distance` kept [m], with Newton and ADMM at
/// `tol` [m/s] and steps of `h` [s] and the default response strength ½: a step may end
/// `tol`·h inside (the ADMM's primal residual), and the next resolves only half of an
/// existing penetration (strength) while adding at most `tol`·h again, so it stays below
/// `tol`·h / ½; plus the exact check's slack on triangles without a contact, a thousandth of
/// the distance.
fn allowed(tol: f64, h: f64, distance: f64) -> f64 {
    tol * h / 0.5 + 1e-3 * distance
}

/// The drape example: at every frame every cloth vertex keeps at least the 2 mm both
/// thicknesses ask from the sphere's mesh, less what the solver is [`allowed`] (1e-4 m/s,
/// 1/96 s steps: 4.1e-6 m), checked against every triangle by the exact distance above
/// (measured: 6.4e-7 m short at worst); and no vertex is inside the sphere.
/// The cloth comes to rest on it: its centre stops between the sphere's equator and top.
#[test]
fn the_drape_never_enters_the_sphere() {
    let mut g = example_scene("cloth_drape.json", "solve.scene");
    let mut closest = f64::INFINITY;
    let mut centre = 0.0;
    for f in 0..=24 {
        let v = g.pull("scene", Context::new(f)).unwrap();
        let scene = v.get::<Scene>().unwrap();
        let cloth = scene.iter().find(|e| e.name == "cloth").unwrap();
        for p in cloth.geometry.positions() {
            let r = ((p[0]).powi(2) + (p[1] - 0.5).powi(2) + p[2].powi(2)).sqrt();
            assert!(r > 0.2, "frame {f}: a vertex is inside the sphere at {p:?}");
        }
        closest = closest.min(closest_to_mesh(scene, "cloth", 1, 0, "ball"));
        centre = cloth.geometry.positions().iter().map(|p| p[1]).sum::<f64>()
            / cloth.vertex_count() as f64;
    }
    assert!(
        closest >= 2e-3 - allowed(1e-4, 1.0 / 96.0, 2e-3),
        "closest approach {closest} m"
    );
    assert!(
        closest < 2e-3 + 1e-4,
        "the cloth never touched: {closest} m"
    );
    assert!((0.5..0.75).contains(&centre), "centre at {centre} m");
}

/// Bad contact parameters are load errors naming the node and parameter; a group naming an
/// element the scene lacks fails at the solver's first frame, naming the group and the name.
#[test]
fn bad_contact_parameters_are_named() {
    for (params, word) in [
        (r#"{"friction": -0.1}"#, "friction"),
        (r#"{"thickness": 0.0}"#, "thickness"),
        (r#"{"cohesion": -1.0}"#, "cohesion"),
    ] {
        let e = load_error(&file(
            &format!(
                r#""g": {{"type": "geo.grid"}}, "c": {{"type": "convert.cloth", "inputs": {{"mesh": "g.mesh"}}}},
                   "s": {{"type": "sec.collider", "inputs": {{"element": "c.element"}}, "params": {params}}}"#
            ),
            r#""e": "s.element""#,
        ));
        assert!(e.contains("'s'") && e.contains(word), "{e}");
    }
    let e = load_error(&file(
        r#""g": {"type": "convert.collision_group", "params": {"members": " , "}}"#,
        r#""e": "g.element""#,
    ));
    assert!(e.contains("members"), "{e}");
    let mut g = graph(&file(
        r#""grid":  {"type": "geo.grid"},
           "cloth": {"type": "convert.cloth", "inputs": {"mesh": "grid.mesh"}, "params": {"name": "cloth"}},
           "group": {"type": "convert.collision_group", "params": {"name": "grp", "members": "cloth, scarf"}},
           "mat":   {"type": "behavior.discrete_shell"},
           "col":   {"type": "behavior.collision"},
           "tree":  {"type": "behavior.tree", "inputs": {"behaviors": ["mat.behavior", "col.behavior"]}},
           "solve": {"type": "solver.solid", "inputs": {"elements": ["cloth.element", "group.element"], "tree": "tree.tree"}}"#,
        r#""scene": "solve.scene""#,
    ));
    let e = match g.pull("scene", Context::new(0)) {
        Ok(_) => panic!("a group naming an unknown member ran"),
        Err(e) => e.to_string(),
    };
    assert!(
        e.contains("grp") && e.contains("scarf") && e.contains("members"),
        "{e}"
    );
}

/// The smallest exact distance from the free vertices of element `member` (skipping the
/// first `skip` of every `per` vertices: a strand's held roots) to the triangles of the mesh
/// element `collider`, in `scene`.
fn closest_to_mesh(scene: &Scene, member: &str, per: usize, skip: usize, collider: &str) -> f64 {
    let c = scene.iter().find(|e| e.name == collider).unwrap();
    let weft_scene::Geometry::Mesh(m) = &*c.geometry else {
        panic!("'{collider}' is a mesh")
    };
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
/// (60 rounds: 3e-13 of the segment) with [`distance_to_triangle`] finds its minimum; a
/// triangle whose distance to the segment's middle, less half the segment, is already no
/// closer than the best so far is skipped. `per` vertices a strand; segments whose second
/// vertex is below `skip` (both ends held) are left out.
fn closest_segment_to_mesh(
    scene: &Scene,
    member: &str,
    per: usize,
    skip: usize,
    collider: &str,
) -> f64 {
    let c = scene.iter().find(|e| e.name == collider).unwrap();
    let weft_scene::Geometry::Mesh(m) = &*c.geometry else {
        panic!("'{collider}' is a mesh")
    };
    let p = positions_of(scene, member);
    let mut closest = f64::INFINITY;
    for i in 0..p.len() - 1 {
        if i % per == per - 1 || i % per + 1 < skip {
            continue;
        }
        let (a, b) = (p[i], p[i + 1]);
        let half = 0.5 * norm(sub(b, a));
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
fn positions_of<'s>(scene: &'s Scene, name: &str) -> &'s [[f64; 3]] {
    scene
        .iter()
        .find(|e| e.name == name)
        .unwrap()
        .geometry
        .positions()
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

/// The point a fraction `s` of the way from `a` to `b`.
fn along(a: [f64; 3], b: [f64; 3], s: f64) -> [f64; 3] {
    [0, 1, 2].map(|k| a[k] + s * (b[k] - a[k]))
}

/// The least of `f` over segment a→b, for `f` convex along it (the distance to a convex
/// set is): golden-section search (60 rounds: 3e-13 of the segment), and the ends.
fn least_along(a: [f64; 3], b: [f64; 3], f: impl Fn([f64; 3]) -> f64) -> f64 {
    let f = |s: f64| f(along(a, b, s));
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut lo, mut hi) = (0.0, 1.0);
    for _ in 0..60 {
        let (l, r) = (hi - g * (hi - lo), lo + g * (hi - lo));
        if f(l) <= f(r) {
            hi = r;
        } else {
            lo = l;
        }
    }
    f(0.5 * (lo + hi)).min(f(0.0)).min(f(1.0))
}

/// The exact distance from p to segment a→b (the clamped projection).
fn distance_to_segment(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let (ab, ap) = (sub(b, a), sub(p, a));
    let l2 = ab.iter().map(|x| x * x).sum::<f64>();
    let s = if l2 > 0.0 {
        (ab.iter().zip(&ap).map(|(x, y)| x * y).sum::<f64>() / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    norm(sub(p, along(a, b, s)))
}

/// hair_underwater through its coupled solver (stage C takes the contacts): the current
/// presses the upstream strands onto the turning head, which they reach after about 2.7 s
/// (frame 66); without contacts they were inside its mesh from frame 94 on (measured: 1.7 mm
/// inside the sphere at frame 100). Over 110 frames every free hair vertex, and every point
/// of every segment with a free vertex, keeps the 1 mm from the head's mesh, less what the
/// solver is [`allowed`] (1e-4 m/s, 1/24 s steps: 9.3e-6 m), and the hair does touch it
/// (within 0.1 mm of the distance kept).
#[test]
fn hair_underwater_stays_out_of_the_head() {
    let mut g = example_scene("hair_underwater.json", "result.scene");
    let (mut closest, mut between) = (f64::INFINITY, f64::INFINITY);
    for f in 0..=110 {
        let v = g.pull("scene", Context::new(f)).unwrap();
        let scene = v.get::<Scene>().unwrap();
        // 48 strands of 11 vertices, the first 2 held.
        closest = closest.min(closest_to_mesh(scene, "hair", 11, 2, "head"));
        between = between.min(closest_segment_to_mesh(scene, "hair", 11, 2, "head"));
    }
    let bound = 1e-3 - allowed(1e-4, 1.0 / 24.0, 1e-3);
    assert!(closest >= bound, "closest vertex {closest} m");
    assert!(between >= bound, "closest segment {between} m");
    assert!(between < 1e-3 + 1e-4, "the hair never touched: {between} m");
}

/// hair_on_head: strands fall onto the turning head and rest on it. Over 2 s every free hair
/// vertex, and every point of every segment with a free vertex, keeps the 2 mm both
/// thicknesses ask from the head's mesh, less what the solver is [`allowed`] (1e-4 m/s, 1/48
/// s steps: 6.2e-6 m; measured: segments 3.2e-6 m short, vertices 3.1e-6 m over; with vertex
/// contacts alone, `segment_face` off, segments came to 0.68 mm), checked by the independent
/// distances; the
/// hair does touch (within 0.1 mm) and hangs below the roots (its centre below the head's
/// centre, 1.6 m).
#[test]
fn hair_on_head_rests_on_the_turning_head() {
    let mut g = example_scene("hair_on_head.json", "solve.scene");
    let (mut closest, mut between) = (f64::INFINITY, f64::INFINITY);
    let mut centre = 0.0;
    for f in 0..=48 {
        let v = g.pull("scene", Context::new(f)).unwrap();
        let scene = v.get::<Scene>().unwrap();
        // 64 strands of 13 vertices, the first 2 held.
        closest = closest.min(closest_to_mesh(scene, "hair", 13, 2, "head"));
        between = between.min(closest_segment_to_mesh(scene, "hair", 13, 2, "head"));
        let hair = scene.iter().find(|e| e.name == "hair").unwrap();
        centre = hair.geometry.positions().iter().map(|p| p[1]).sum::<f64>()
            / hair.vertex_count() as f64;
    }
    let bound = 2e-3 - allowed(1e-4, 1.0 / 48.0, 2e-3);
    assert!(closest >= bound, "closest vertex {closest} m");
    assert!(between >= bound, "closest segment {between} m");
    assert!(between < 2e-3 + 1e-4, "the hair never touched: {between} m");
    assert!(centre < 1.6, "hair centre at {centre} m");
}

/// A 0.2 m cloth patch (9 × 9 vertices, 0.15 kg/m²) centred at `at` on the x axis,
/// dropped from 1 cm above the top of a collider that spins about the y axis at `spin`
/// [rad/s]: a sphere (radius 0.25 m, 32 × 64 facets, centre at 0.5 m on the axis) or, when
/// `table`, a flat 1.2 m square turntable at 0.75 m; both sides friction `mu`, 1 mm thick;
/// no damping but implicit Euler's own; 4 steps a frame, Newton and ADMM to 1e-8 m/s.
fn patch_on_turning(mu: f64, spin: f64, table: bool, at: f64) -> Graph {
    let collider = if table {
        r#"{"type": "geo.grid", "params": {"width": 1.2, "height": 1.2, "nx": 9, "ny": 9, "plane": "xz", "center": [0.0, 0.75, 0.0]}}"#
    } else {
        r#"{"type": "geo.sphere", "params": {"center": [0.0, 0.5, 0.0], "radius": 0.25, "rings": 32, "sectors": 64}}"#
    };
    graph(&file(
        &format!(
            r#""grid":   {{"type": "geo.grid", "params": {{"width": 0.2, "height": 0.2, "nx": 9, "ny": 9, "plane": "xz", "center": [{at}, 0.762, 0.0]}}}},
               "cloth":  {{"type": "convert.cloth", "inputs": {{"mesh": "grid.mesh"}}, "params": {{"name": "patch"}}}},
               "dens":   {{"type": "sec.density", "inputs": {{"element": "cloth.element"}}, "params": {{"area_density": 0.15}}}},
               "csec":   {{"type": "sec.collider", "inputs": {{"element": "dens.element"}}, "params": {{"friction": {mu}, "thickness": 1e-3}}}},
               "turn":   {{"type": "xform.animate", "params": {{"axis": [0.0, 1.0, 0.0], "spin": {spin}}}}},
               "ball":   {collider},
               "body":   {{"type": "convert.collider", "inputs": {{"mesh": "ball.mesh", "transform": "turn.transform"}}, "params": {{"name": "body"}}}},
               "ssec":   {{"type": "sec.collider", "inputs": {{"element": "body.element"}}, "params": {{"friction": {mu}, "thickness": 1e-3}}}},
               "group":  {{"type": "convert.collision_group"}},
               "mat":    {{"type": "behavior.discrete_shell"}},
               "grav":   {{"type": "behavior.gravity"}},
               "col":    {{"type": "behavior.collision"}},
               "tree":   {{"type": "behavior.tree", "inputs": {{"behaviors": ["mat.behavior", "grav.behavior", "col.behavior"]}}}},
               "solve":  {{"type": "solver.solid", "inputs": {{"elements": ["csec.element", "ssec.element", "group.element"], "tree": "tree.tree"}},
                           "params": {{"substeps": 4, "tolerance": 1e-8, "max_iterations": 100, "contact_iterations": 5000}}}}"#
        ),
        r#""scene": "solve.scene""#,
    ))
}

/// The patch's angular velocity about the y axis [rad/s] (its angular momentum about the
/// axis over its moment of inertia, equal masses), and its largest vertex speed [m/s].
fn spin_and_speed(g: &mut Graph, frame: i64) -> (f64, f64) {
    let (x, v) = state(g, frame);
    let (mut l, mut i, mut fastest) = (0.0, 0.0, 0.0f64);
    for (p, u) in x.iter().zip(&v) {
        l += p[2] * u[0] - p[0] * u[2];
        i += p[0] * p[0] + p[2] * p[2];
        fastest = fastest.max((u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt());
    }
    (l / i, fastest)
}

/// VERIFY, friction twist: on a sphere turning at 1 rad/s the patch resting on its top turns
/// with it when μ = 0.5 (its angular velocity within 1 % of the sphere's from 1 s on: its
/// weight presses it on, and the pull it needs, ω² r at 0.1 m, is a fiftieth of μ g). With
/// μ = 0 the answer is exact only on a surface of revolution about the spin axis: a faceted
/// sphere's facets rise and fall under a resting vertex and push it round (measured: 0.23
/// rad/s after 1 s with 64 or 256 sectors, 0.14 with 16 steps a frame), so the frictionless
/// case is a flat turntable, on which a patch 0.2 m off the axis stays still (below 1e-6 m/s
/// and rad/s: the solver's 1e-8 m/s) while the table turns under it, and turns with it when
/// μ = 0.5 (the table's rim speed at the patch, 0.2 m/s, within 1 %).
#[test]
fn friction_turns_a_patch_with_a_rotating_sphere() {
    let mut sphere = patch_on_turning(0.5, 1.0, false, 0.0);
    let mut stick = patch_on_turning(0.5, 1.0, true, 0.2);
    let mut slip = patch_on_turning(0.0, 1.0, true, 0.2);
    for f in [24, 36, 48] {
        let (w, _) = spin_and_speed(&mut sphere, f);
        assert!(
            (w - 1.0).abs() < 0.01,
            "sphere, μ = 0.5, frame {f}: ω = {w} rad/s"
        );
        let (w, _) = spin_and_speed(&mut stick, f);
        assert!(
            (w - 1.0).abs() < 0.01,
            "table, μ = 0.5, frame {f}: ω = {w} rad/s"
        );
        let (w, fastest) = spin_and_speed(&mut slip, f);
        assert!(
            w.abs() < 1e-6 && fastest < 1e-6,
            "table, μ = 0, frame {f}: ω = {w} rad/s, fastest {fastest} m/s"
        );
    }
}

/// VERIFY, quiet resting contact: the patch dropped 1 cm onto the still sphere (μ = 0.5)
/// comes to rest with no jitter: after 2 s every vertex is slower than 1e-4 m/s, with no
/// damping but implicit Euler's.
#[test]
fn resting_contact_is_quiet() {
    let mut g = patch_on_turning(0.5, 0.0, false, 0.0);
    for f in [48, 60, 72] {
        let (_, fastest) = spin_and_speed(&mut g, f);
        assert!(fastest < 1e-4, "frame {f}: a vertex moves at {fastest} m/s");
    }
}

/// A 0.5 m cloth (13 × 13 vertices) dropped from 5 cm above a collider made by the graph
/// nodes `collider` (a node `shape` giving its mesh), μ 0.4, 1 mm thickness each side, 4
/// steps a frame, Newton and ADMM to 1e-6 m/s.
fn cloth_onto(collider: &str, top: f64) -> Graph {
    let y = top + 0.05;
    graph(&file(
        &format!(
            r#""grid":   {{"type": "geo.grid", "params": {{"width": 0.5, "height": 0.5, "nx": 13, "ny": 13, "plane": "xz", "center": [0.03, {y}, 0.02]}}}},
               "cloth":  {{"type": "convert.cloth", "inputs": {{"mesh": "grid.mesh"}}, "params": {{"name": "cloth"}}}},
               "csec":   {{"type": "sec.collider", "inputs": {{"element": "cloth.element"}}, "params": {{"friction": 0.4}}}},
               {collider},
               "body":   {{"type": "convert.collider", "inputs": {{"mesh": "shape.mesh"}}, "params": {{"name": "body"}}}},
               "bsec":   {{"type": "sec.collider", "inputs": {{"element": "body.element"}}, "params": {{"friction": 0.4}}}},
               "group":  {{"type": "convert.collision_group"}},
               "mat":    {{"type": "behavior.discrete_shell"}},
               "grav":   {{"type": "behavior.gravity"}},
               "col":    {{"type": "behavior.collision"}},
               "tree":   {{"type": "behavior.tree", "inputs": {{"behaviors": ["mat.behavior", "grav.behavior", "col.behavior"]}}}},
               "solve":  {{"type": "solver.solid", "inputs": {{"elements": ["csec.element", "bsec.element", "group.element"], "tree": "tree.tree"}},
                           "params": {{"substeps": 4, "tolerance": 1e-6, "max_iterations": 100}}}}"#
        ),
        r#""scene": "solve.scene""#,
    ))
}

/// VERIFY, no penetration on a box and on a mesh: the cloth dropped on a box (sharp edges
/// and corners: its vertices slide over them) and on a bumpy terrain read from an OBJ file
/// (an open mesh with valleys, where a vertex meets two faces) keeps, at every frame over
/// 1 s, the 2 mm both thicknesses ask from every triangle, less what the solver is
/// [`allowed`] (1e-6 m/s, 1/96 s steps), by the independent exact distance; and it touches.
#[test]
fn cloth_stays_out_of_a_box_and_a_mesh() {
    let dir = std::env::temp_dir().join(format!("weft-contacts-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // Terrain: y = 0.03 sin(12 x) cos(9 z) over a 0.8 m square, 25 × 25 vertices.
    let mut terrain = weft_scene::procedural::grid(
        [0.8, 0.8],
        [25, 25],
        weft_scene::procedural::Plane::Xz,
        [0.0; 3],
    );
    for p in &mut terrain.positions {
        p[1] = 0.03 * (12.0 * p[0]).sin() * (9.0 * p[2]).cos();
    }
    let obj = dir.join("terrain.obj");
    let mut f = std::fs::File::create(&obj).unwrap();
    weft_scene::write_obj_mesh(&terrain, &mut f).unwrap();
    drop(f);
    let cases = [
        (
            r#""shape": {"type": "geo.box", "params": {"center": [0.0, 0.1, 0.0], "width": 0.3, "height": 0.2, "depth": 0.25}}"#
                .to_string(),
            0.2,
        ),
        (
            format!(
                r#""shape": {{"type": "geo.obj", "params": {{"path": {:?}}}}}"#,
                obj.to_str().unwrap()
            ),
            0.03,
        ),
    ];
    for (collider, top) in cases {
        let mut g = cloth_onto(&collider, top);
        let mut closest = f64::INFINITY;
        for f in 0..=24 {
            let v = g.pull("scene", Context::new(f)).unwrap();
            let scene = v.get::<Scene>().unwrap();
            closest = closest.min(closest_to_mesh(scene, "cloth", 1, 0, "body"));
        }
        let what = &collider[..40];
        assert!(
            closest >= 2e-3 - allowed(1e-6, 1.0 / 96.0, 2e-3),
            "{what}: closest approach {closest} m"
        );
        assert!(closest < 2e-3 + 1e-4, "{what}: never touched ({closest} m)");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// True when segment p→q meets triangle t, written here independently of the solver: the
/// ends on opposite sides of (or on) its plane by more than rounding (1e-12 of the
/// coordinates), and the crossing point inside it (to rounding). Both ends on the plane
/// (coplanar pieces, as flat cloth is): it meets when an end or its middle is inside by more
/// than 1e-9 m (an overlap of flat pieces; touching edges are not an intersection).
fn segment_meets_triangle(p: [f64; 3], q: [f64; 3], t: [[f64; 3]; 3]) -> bool {
    type V = nalgebra::Vector3<f64>;
    let (p, q, t) = (V::from(p), V::from(q), t.map(V::from));
    let n = (t[1] - t[0]).cross(&(t[2] - t[0]));
    let Some(n) = n.try_normalize(0.0) else {
        return false;
    };
    let scale = [p, q, t[0], t[1], t[2]]
        .iter()
        .fold(1.0f64, |m, x| m.max(x.amax()));
    let tol = 1e-12 * scale;
    let (dp, dq) = ((p - t[0]).dot(&n), (q - t[0]).dot(&n));
    let inside = |x: V, margin: f64| {
        (0..3).all(|k| {
            let e = t[(k + 1) % 3] - t[k];
            e.cross(&(x - t[k])).dot(&n) / e.norm() >= margin
        })
    };
    if (dp > tol && dq > tol) || (dp < -tol && dq < -tol) {
        return false;
    }
    if dp.abs() <= tol && dq.abs() <= tol {
        return [p, q, 0.5 * (p + q)].iter().any(|&x| inside(x, 1e-9));
    }
    let x = p + dp / (dp - dq) * (q - p);
    inside(x, -tol)
}

/// Pairs of triangles of the cloth elements `names` in `scene` (between them and within
/// each, skipping pairs that share a vertex) that intersect: an edge of one meets the other.
fn intersecting_triangles(scene: &Scene, names: &[&str]) -> usize {
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
    let bound = |t: &[[f64; 3]; 3], a: usize| {
        let v = [t[0][a], t[1][a], t[2][a]];
        (
            v.iter().copied().fold(f64::INFINITY, f64::min),
            v.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        )
    };
    let mut count = 0;
    for i in 0..tris.len() {
        for j in i + 1..tris.len() {
            if ids[i].iter().any(|v| ids[j].contains(v)) {
                continue;
            }
            let apart = (0..3).any(|a| {
                let ((li, hi), (lj, hj)) = (bound(&tris[i], a), bound(&tris[j], a));
                li > hj || lj > hi
            });
            if apart {
                continue;
            }
            let (ti, tj) = (tris[i], tris[j]);
            if (0..3).any(|k| segment_meets_triangle(ti[k], ti[(k + 1) % 3], tj))
                || (0..3).any(|k| segment_meets_triangle(tj[k], tj[(k + 1) % 3], ti))
            {
                count += 1;
            }
        }
    }
    count
}

/// The cloth pile example: at every frame no triangle of the three sheets meets another
/// (between sheets and within each), by the exact test above; and the pile lands: the upper
/// sheet, dropped from 18 cm above the box's top, ends with its centre between 10 cm below
/// the top and the top (it lies on the others and drapes over the box's edges; measured
/// 0.26 m) and no point more than 5 cm above the top (its folds: 2.6 cm measured).
#[test]
fn the_cloth_pile_never_intersects() {
    let mut g = example_scene("cloth_pile.json", "solve.scene");
    let (mut top, mut centre) = (0.0, 0.0);
    for f in 0..=24 {
        let v = g.pull("scene", Context::new(f)).unwrap();
        let scene = v.get::<Scene>().unwrap();
        let crossing = intersecting_triangles(scene, &["lower", "middle", "upper"]);
        assert_eq!(crossing, 0, "frame {f}");
        let upper = scene.iter().find(|e| e.name == "upper").unwrap();
        let y: Vec<f64> = upper.geometry.positions().iter().map(|p| p[1]).collect();
        top = y.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        centre = y.iter().sum::<f64>() / y.len() as f64;
    }
    assert!(
        (0.2..0.3).contains(&centre),
        "the upper sheet's centre is at {centre} m"
    );
    assert!(top < 0.35, "the upper sheet's highest point is {top} m");
}

/// The least distance between two segments of the hair `member` in `scene` that share no
/// vertex (of one strand or of two), independently of the solver: the distance from a point
/// moving along one segment to the other (a convex set) is convex, so [`least_along`] finds
/// it; pairs whose bounding boxes are already farther apart than the best so far are
/// skipped. `per` vertices a strand; segments with both ends held (below `skip`) are left out.
fn closest_hair_pair(scene: &Scene, member: &str, per: usize, skip: usize) -> f64 {
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

/// The hair pile example (hair falling on a shoulder-like cloth): at every frame no hair
/// segment meets a triangle of the cloth and no two triangles of the cloth meet, by the exact
/// test above; two hair segments keep the 0.4 mm both thicknesses ask, less what the solver
/// is [`allowed`] (1e-3 m/s, 1/192 s steps: 1.1e-5 m; measured: 0.3992 mm at worst, from
/// frame 9, where 20 strands land in a tuft and slide over each other: before the exact
/// check re-linearized held edge pairs where the solve ended, they ended up to 0.19 mm
/// deep); the hair keeps the head's 1.2 mm less what the solver is [`allowed`] (measured:
/// 1.1988 mm); and the hair lands on the cloth: in the last quarter second (frames 19–24) some
/// hair vertex comes within 0.1 mm of the 1.2 mm hair and cloth keep (measured: 1.1993 mm),
/// and the hair's lowest point is below the head (measured: 0.259 m, on the cloth over the
/// box's top at 0.25 m). Not at one frame: the pile still settles at 1 s and its strands
/// spring off the draping cloth and land again, in the run converged to 1e-5 m/s as well
/// (the closest hair vertex 8.4 mm off the cloth at frame 14, 1.29 mm at frame 23, 1.20 mm
/// at frames 19–22 and 24).
#[test]
fn the_hair_pile_never_crosses() {
    let mut g = example_scene("hair_pile.json", "solve.scene");
    let (mut hair_hair, mut head, mut on_cloth, mut lowest) =
        (f64::INFINITY, f64::INFINITY, f64::INFINITY, 0.0);
    for f in 0..=24 {
        let v = g.pull("scene", Context::new(f)).unwrap();
        let scene = v.get::<Scene>().unwrap();
        assert_eq!(intersecting_triangles(scene, &["cloth"]), 0, "frame {f}");
        let cloth = scene.iter().find(|e| e.name == "cloth").unwrap();
        let weft_scene::Geometry::Mesh(m) = &*cloth.geometry else {
            panic!("the cloth is a mesh")
        };
        let hair = scene.iter().find(|e| e.name == "hair").unwrap();
        let p = hair.geometry.positions();
        // 20 strands of 9 vertices, the first 2 held.
        for i in (0..p.len() - 1).filter(|i| i % 9 != 8) {
            for t in &m.triangles {
                let tri = t.map(|v| m.positions[v as usize]);
                assert!(
                    !segment_meets_triangle(p[i], p[i + 1], tri),
                    "frame {f}: hair segment {i} meets cloth triangle {t:?}"
                );
            }
        }
        hair_hair = hair_hair.min(closest_hair_pair(scene, "hair", 9, 2));
        head = head.min(closest_segment_to_mesh(scene, "hair", 9, 2, "head"));
        if f >= 19 {
            on_cloth = on_cloth.min(closest_to_mesh(scene, "hair", 9, 2, "cloth"));
        }
        lowest = p.iter().map(|x| x[1]).fold(f64::INFINITY, f64::min);
        println!(
            "frame {f}: hair–hair {hair_hair:e}, head {head:e}, cloth {on_cloth:e}, lowest {lowest}"
        );
    }
    assert!(
        hair_hair >= 4e-4 - allowed(1e-3, 1.0 / 192.0, 4e-4),
        "closest hair segments {hair_hair} m"
    );
    let bound = 1.2e-3 - allowed(1e-3, 1.0 / 192.0, 1.2e-3);
    assert!(head >= bound, "closest to the head {head} m");
    assert!(
        on_cloth < 1.2e-3 + 1e-4,
        "the hair is not on the cloth in frames 19–24: {on_cloth} m"
    );
    assert!(lowest < 0.38, "the hair's lowest point is at {lowest} m");
    // Every retried substep says why (this run retries four: a contact solve that diverged,
    // one at Newton's limit, two that would end with primitives passing through each other).
    let report = g.node_report("solve").expect("the solver's report");
    let frames = report["solid_frames"].as_array().unwrap();
    let retries: u64 = frames.iter().map(|f| f["retries"].as_u64().unwrap()).sum();
    let causes: Vec<&str> = frames
        .iter()
        .flat_map(|f| f["retry_causes"].as_array().unwrap())
        .map(|c| c.as_str().unwrap())
        .collect();
    assert_eq!(causes.len() as u64, retries, "{causes:?}");
    assert!(causes.iter().all(|c| !c.is_empty()), "{causes:?}");
}
