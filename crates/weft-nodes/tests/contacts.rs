//! Contacts with colliders, through graphs as a user builds them (issue 13's verification):
//! an incline that sticks exactly or slides by Coulomb, a cloth thrown at a thin plane at
//! 10 m/s, cohesion under a ceiling, friction turning a patch with a rotating sphere, quiet
//! resting contact, and cloth on a box and on a mesh whose clearance is checked by an exact
//! distance computed independently of the solver (`weft_check`, through `common`). The
//! examples' contacts are checked in the workspace's `tests/contacts.rs`.

mod common;
use common::*;
use weft_graph::{Context, Graph};
use weft_nodes::physics::Scene;

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
