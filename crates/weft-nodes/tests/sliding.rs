//! Sliding attachments (issue 17, item 1) through graphs as a user writes them: a bead on a
//! tilted straight wire and on a circular wire, against the analytic motion, and the
//! distance to the rail every frame.

mod common;
use common::*;
use weft_graph::{Context, Graph};

/// Distance from `p` to the polyline `points`.
fn to_polyline(p: [f64; 3], points: &[[f64; 3]]) -> f64 {
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    points
        .windows(2)
        .map(|w| {
            let e = sub(w[1], w[0]);
            let s = (dot(sub(p, w[0]), e) / dot(e, e)).clamp(0.0, 1.0);
            let q = [0, 1, 2].map(|k| w[0][k] + s * e[k]);
            dot(sub(p, q), sub(p, q)).sqrt()
        })
        .fold(f64::INFINITY, f64::min)
}

/// A bead (a one-segment strand, both vertices sliding) starting between `a` and `b`, on
/// what the extra nodes `target` make and `onto` names (e.g. `"along": "rail.curves"`), with
/// friction `mu`.
fn bead_on(target: &str, onto: &str, mu: f64, a: [f64; 3], b: [f64; 3], substeps: u32) -> Graph {
    let nodes = format!(
        r#"{target},
        "line": {{"type": "geo.line", "params": {{"start": {a:?}, "end": {b:?}, "segments": 1}}}},
        "bead": {{"type": "convert.hair", "inputs": {{"curves": "line.curves"}}, "params": {{"name": "bead"}}}},
        "rod": {{"type": "sec.rod", "inputs": {{"element": "bead.element"}}, "params": {{"radius": 0.001}}}},
        "mass": {{"type": "sec.density", "inputs": {{"element": "rod.element"}}, "params": {{"line_density": 0.01}}}},
        "slide": {{"type": "convert.attachment", "inputs": {{"target": "mass.element", {onto}}},
                   "params": {{"name": "slide", "mode": "slide", "vertices": [0, 1], "friction": {mu}}}}},
        "material": {{"type": "behavior.rod"}},
        "gravity": {{"type": "behavior.gravity"}},
        "attach": {{"type": "behavior.attachment"}},
        "tree": {{"type": "behavior.tree", "inputs": {{"behaviors": ["material.behavior", "gravity.behavior", "attach.behavior"]}}}},
        "solve": {{"type": "solver.solid", "inputs": {{"elements": ["mass.element", "slide.element"], "tree": "tree.tree"}},
                   "params": {{"substeps": {substeps}, "tolerance": 1e-9}}}},
        "v0": {{"type": "scene.vertex", "inputs": {{"scene": "solve.scene"}}, "params": {{"element": "bead", "index": 0}}}},
        "v1": {{"type": "scene.vertex", "inputs": {{"scene": "solve.scene"}}, "params": {{"element": "bead", "index": 1}}}}"#
    );
    graph(&file(&nodes, r#""v0": "v0.position", "v1": "v1.position""#))
}

/// A bead on the rail the node `rail_node` makes.
fn bead_graph(rail_node: &str, a: [f64; 3], b: [f64; 3], substeps: u32) -> Graph {
    bead_on(
        &format!(r#""rail": {rail_node}"#),
        r#""along": "rail.curves""#,
        0.0,
        a,
        b,
        substeps,
    )
}

/// A straight wire through the origin, θ below +x in the xy plane: its rail node and a
/// point at s metres along it.
fn wire(theta: f64) -> (String, [[f64; 3]; 2], impl Fn(f64) -> [f64; 3]) {
    let t = [theta.cos(), -theta.sin(), 0.0];
    let at = move |s: f64| [s * t[0], s * t[1], s * t[2]];
    let ends = [at(-5.0), at(5.0)];
    let node = format!(
        r#"{{"type": "geo.line", "params": {{"start": {:?}, "end": {:?}, "segments": 1}}}}"#,
        ends[0], ends[1]
    );
    (node, ends, at)
}

/// Displacement along the unit direction `t` after `n` implicit Euler steps of `h` from rest
/// under a constant acceleration `a` along it: v_k = k h a exactly, so s = a h² n (n + 1)/2.
fn euler_distance(a: f64, h: f64, n: f64) -> f64 {
    a * h * h * n * (n + 1.0) / 2.0
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[test]
fn a_bead_on_a_tilted_wire_accelerates_at_g_sin_theta() {
    // A wire 30° below +x in the xy plane; gravity −y.
    let th = 30f64.to_radians();
    let (rail, ends, at) = wire(th);
    let t = at(1.0);
    let substeps = 4;
    let mut g = bead_graph(&rail, at(0.0), at(0.01), substeps);
    let h = 1.0 / (24.0 * substeps as f64);
    for frame in 1..=24i64 {
        let p = vec3_at(&mut g, "v0", frame);
        let q = vec3_at(&mut g, "v1", frame);
        // On the wire, every frame (rounding: the points are made on its segment).
        for x in [p, q] {
            let d = to_polyline(x, &ends);
            assert!(d < 1e-9, "frame {frame}: {d:e} m off the wire");
        }
        // The issue asks for g sin θ within 0.5 %; with the solve's tolerance of 1e-9 m/s it
        // is within 1e-12 of implicit Euler's exact answer (measured 5e-13 at frame 24).
        let want = euler_distance(9.81 * th.sin(), h, (frame as u32 * substeps) as f64);
        let s = dot(p, t);
        assert!(
            (s - want).abs() < 1e-9 * want,
            "frame {frame}: {s} m along the wire, want {want}"
        );
    }
}

#[test]
fn friction_along_a_wire_slows_the_bead_by_coulomb_and_holds_it_below_the_friction_angle() {
    // Sliding: θ = 30°, μ = 0.2, a = g (sin θ − μ cos θ) = 3.206 m/s². The normal force is
    // the step's own at convergence (mg cos θ on a straight wire), and the bead moves faster
    // than the mollifier's ε_v = 1e-4 m/s from the first step: Coulomb's law exactly.
    let th = 30f64.to_radians();
    let (rail, ends, at) = wire(th);
    let (mu, substeps) = (0.2, 4);
    let node = format!(r#""rail": {rail}"#);
    let mut g = bead_on(
        &node,
        r#""along": "rail.curves""#,
        mu,
        at(0.0),
        at(0.01),
        substeps,
    );
    let h = 1.0 / (24.0 * substeps as f64);
    let a = 9.81 * (th.sin() - mu * th.cos());
    for frame in [1i64, 12, 24] {
        let p = vec3_at(&mut g, "v0", frame);
        assert!(to_polyline(p, &ends) < 1e-9);
        let want = euler_distance(a, h, (frame as u32 * substeps) as f64);
        let s = dot(p, at(1.0));
        // Newton's tolerance 1e-9 m/s against a velocity of ~3 m/s.
        assert!(
            (s - want).abs() < 1e-8 * want,
            "frame {frame}: {s} m along the wire, want {want}"
        );
    }
    // Sticking: θ = 10° below the friction angle of μ = 0.3 (16.7°). The mollified law lets
    // it creep below ε_v = 1e-4 m/s: under 1e-4 m in a second.
    let th = 10f64.to_radians();
    let (rail, _, at) = wire(th);
    let node = format!(r#""rail": {rail}"#);
    let mut g = bead_on(
        &node,
        r#""along": "rail.curves""#,
        0.3,
        at(0.0),
        at(0.01),
        4,
    );
    let s = dot(vec3_at(&mut g, "v0", 24), at(1.0));
    assert!(s.abs() < 1e-4, "crept {s} m in 1 s");
}

#[test]
fn a_bead_on_a_tilted_plane_slides_down_its_fall_line_and_stops_at_its_border() {
    // A 2 m square (geo.grid, horizontal) turned θ = 25° about z by the attachment's transform;
    // the bead lies along z at the origin. Downhill is −(cos θ, sin θ, 0); with μ = 0.2 it
    // accelerates at g (sin θ − μ cos θ) down the fall line, on the plane to rounding.
    let th = 25f64.to_radians();
    let mu = 0.2;
    let target = format!(
        r#""plane": {{"type": "geo.grid", "params": {{"width": 2.0, "height": 2.0, "nx": 5, "ny": 5}}}},
        "tilt": {{"type": "xform.animate", "params": {{"axis": [0, 0, 1], "angle": {th}}}}}"#
    );
    let onto = r#""onto": "plane.mesh", "transform": "tilt.transform""#;
    let substeps = 4;
    let mut g = bead_on(&target, onto, mu, [0.0; 3], [0.0, 0.0, 0.01], substeps);
    let h = 1.0 / (24.0 * substeps as f64);
    let down = [-th.cos(), -th.sin(), 0.0];
    let normal = [-th.sin(), th.cos(), 0.0];
    let a = 9.81 * (th.sin() - mu * th.cos());
    for frame in [1i64, 6, 12] {
        let p = vec3_at(&mut g, "v0", frame);
        let off = dot(p, normal).abs();
        assert!(off < 1e-9, "frame {frame}: {off:e} m off the plane");
        assert!(
            p[2].abs() < 1e-9,
            "frame {frame}: left the fall line ({})",
            p[2]
        );
        let want = euler_distance(a, h, (frame as u32 * substeps) as f64);
        let s = dot(p, down);
        assert!(
            (s - want).abs() < 1e-8 * want,
            "frame {frame}: {s} m down the plane, want {want}"
        );
    }
    // By 2 s it has reached the border 1 m down (at ~1.1 s) and rests on it.
    let (p, q) = (vec3_at(&mut g, "v0", 48), vec3_at(&mut g, "v0", 47));
    assert!((dot(p, down) - 1.0).abs() < 1e-9, "{p:?}");
    assert!(dot(p, normal).abs() < 1e-9);
    assert!(dot([p[0] - q[0], p[1] - q[1], p[2] - q[2]], down).abs() < 1e-9);
}

#[test]
fn a_bead_on_a_circular_wire_swings_with_the_pendulum_period() {
    // A circle of radius R = 0.5 m in the xy plane, angle 0 at the bottom; the bead starts at
    // rest 10° up (its two vertices at 10° and 10.2°).
    let r = 0.5f64;
    let rail = r#"{"type": "geo.arc", "params": {"radius": 0.5, "axis": [0, 0, 1], "from": [0, -1, 0],
                   "start_angle": -170, "end_angle": 170, "segments": 4000}}"#;
    let on = |deg: f64| {
        let a = deg.to_radians();
        [r * a.sin(), -r * a.cos(), 0.0]
    };
    let substeps = 8;
    let mut g = bead_graph(rail, on(10.0), on(10.2), substeps);
    let arc: Vec<[f64; 3]> = (0..=4000)
        .map(|i| on(-170.0 + 340.0 * i as f64 / 4000.0))
        .collect();
    // Angle of the bead's middle from the bottom, per frame.
    let mut phi = Vec::new();
    for frame in 0..=96i64 {
        let p = vec3_at(&mut g, "v0", frame);
        let q = vec3_at(&mut g, "v1", frame);
        for x in [p, q] {
            let d = to_polyline(x, &arc);
            assert!(d < 1e-9, "frame {frame}: {d:e} m off the wire");
        }
        let m = [(p[0] + q[0]) / 2.0, (p[1] + q[1]) / 2.0];
        phi.push(m[0].atan2(-m[1]));
    }
    // Zero crossings by linear interpolation (the swing is nearly a sine, straight where it
    // crosses): every second one a period apart.
    let crossings: Vec<f64> = phi
        .windows(2)
        .enumerate()
        .filter(|(_, w)| w[0] * w[1] < 0.0)
        .map(|(i, w)| (i as f64 + w[0] / (w[0] - w[1])) / 24.0)
        .collect();
    assert!(crossings.len() >= 5, "{crossings:?}");
    let period = (crossings[4] - crossings[0]) / 2.0;
    // Pendulum of amplitude θ₀ (Landau & Lifshitz §11 series): T = 2π√(R/g)(1 + θ₀²/16 +
    // 11θ₀⁴/3072). Both vertices are at R from the centre, so the two-point bead is the same
    // pendulum (its centre of mass at R cos 0.1°: 1.5e-6 relative, neglected). Implicit
    // Euler at h = 1/192 s lengthens the period by ~(ωh)²/3 = 1.8e-4 and damps the swing
    // (the amplitude falls ~15 % over the two periods, shortening the period by ~0.05 %).
    // Measured: 1.4210 s against 1.4213 s, −1.9e-4. The issue asks for 0.5 %; asserted at
    // 0.1 %, room for the integrator's error and no more.
    let th0 = 10.1f64.to_radians();
    let want = 2.0
        * std::f64::consts::PI
        * (r / 9.81).sqrt()
        * (1.0 + th0 * th0 / 16.0 + 11.0 * th0.powi(4) / 3072.0);
    assert!(
        (period - want).abs() < 1e-3 * want,
        "period {period} s, want {want} s (crossings {crossings:?})"
    );
}

#[test]
fn a_bead_on_a_wire_in_a_current_stays_on_the_wire_in_the_coupled_solver() {
    // The same constraint through solver.coupled: a bead on a horizontal wire along x in
    // water flowing at 0.15 m/s along it. The wire takes gravity, buoyancy and the transverse
    // drag; along it, drag alone pulls the bead towards the current's speed, never past it.
    let nodes = r#""wire": {"type": "geo.line", "params": {"start": [-1, 0.5, 0.2], "end": [1, 0.5, 0.2], "segments": 1}},
        "line": {"type": "geo.line", "params": {"start": [0, 0.5, 0.2], "end": [0.01, 0.5, 0.2], "segments": 1}},
        "bead": {"type": "convert.hair", "inputs": {"curves": "line.curves"}, "params": {"name": "bead"}},
        "rod": {"type": "sec.rod", "inputs": {"element": "bead.element"}, "params": {"radius": 0.001}},
        "drag": {"type": "sec.drag", "inputs": {"element": "rod.element"}, "params": {"diameter": 0.002}},
        "slide": {"type": "convert.attachment", "inputs": {"target": "drag.element", "along": "wire.curves"},
                  "params": {"name": "slide", "mode": "slide", "vertices": [0, 1]}},
        "water": {"type": "convert.fluid_domain", "params": {"name": "water", "padding": 0.06, "cell_size": 0.02,
                  "flow": [0.15, 0.0, 0.0], "x_min": "inflow", "x_max": "open"}},
        "scene": {"type": "scene.gather", "inputs": {"elements": ["drag.element", "slide.element", "water.element"]}},
        "material": {"type": "behavior.rod"},
        "gravity": {"type": "behavior.gravity"},
        "attach": {"type": "behavior.attachment"},
        "fluid": {"type": "behavior.fluid_drag"},
        "tree": {"type": "behavior.tree", "inputs": {"behaviors": ["material.behavior", "gravity.behavior", "attach.behavior", "fluid.behavior"]}},
        "setup": {"type": "coupled.setup", "inputs": {"scene": "scene.scene", "tree": "tree.tree"}},
        "solve": {"type": "solver.coupled", "inputs": {"scene": "scene.scene", "state": "setup.state", "iterate": "setup.state"},
                  "params": {"solid.tolerance": 1.0e-9, "update.tolerance": 1.0e-6}},
        "result": {"type": "coupled.scene", "inputs": {"state": "solve.state"}},
        "v0": {"type": "scene.vertex", "inputs": {"scene": "result.scene"}, "params": {"element": "bead", "index": 0}},
        "v1": {"type": "scene.vertex", "inputs": {"scene": "result.scene"}, "params": {"element": "bead", "index": 1}}"#;
    let mut g = graph(&file(nodes, r#""v0": "v0.position", "v1": "v1.position""#));
    let mut last = (0.0, 0.0);
    for frame in 1..=12i64 {
        let p = vec3_at(&mut g, "v0", frame);
        let q = vec3_at(&mut g, "v1", frame);
        for x in [p, q] {
            // On the wire: y and z exactly where the wire is (the retraction's closest point
            // on an axis-aligned segment keeps them bit for bit).
            assert!(
                (x[1] - 0.5).abs() < 1e-12 && (x[2] - 0.2).abs() < 1e-12,
                "frame {frame}: {x:?}"
            );
        }
        let v = (p[0] - last.0) * 24.0;
        assert!(
            v > last.1 && v < 0.15,
            "frame {frame}: {v} m/s after {} m/s",
            last.1
        );
        last = (p[0], v);
    }
}

/// The error text of pulling `output` at frame 1.
fn pull_error(g: &mut Graph, output: &str) -> String {
    match g.pull(output, Context::new(1)) {
        Ok(_) => panic!("'{output}' evaluated but should not have"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn bad_sliding_input_is_a_clear_error_naming_the_node() {
    // mode slide with nothing to slide on: the node and the port.
    let mut g = bead_on(
        r#""t": {"type": "xform.animate"}"#,
        r#""transform": "t.transform""#,
        0.0,
        [0.0; 3],
        [0.01, 0.0, 0.0],
        1,
    );
    let e = pull_error(&mut g, "v0");
    assert!(
        e.contains("'slide'") && e.contains("'along'") && e.contains("needs a rail or a surface"),
        "{e}"
    );
    // A rail whose only segment has no length.
    let rail = r#""rail": {"type": "geo.polyline", "params": {"points": [0, 0, 0, 0, 0, 0]}}"#;
    let mut g = bead_on(
        rail,
        r#""along": "rail.curves""#,
        0.0,
        [0.0; 3],
        [0.01, 0.0, 0.0],
        1,
    );
    let e = pull_error(&mut g, "v0");
    assert!(
        e.contains("slide") && e.contains("segment of positive length"),
        "{e}"
    );
    // Negative friction and bad rails are refused when the file loads.
    let e = load_error(&file(
        r#""a": {"type": "geo.arc", "params": {"axis": [0, 0, 1], "from": [0, 0, 2]}},
           "b": {"type": "geo.arc", "params": {"start_angle": 10, "end_angle": 10}},
           "c": {"type": "geo.polyline", "params": {"points": [0, 0, 0, 1]}},
           "d": {"type": "convert.attachment", "params": {"mode": "slide", "friction": -1}},
           "e": {"type": "convert.attachment", "params": {"mode": "rigid", "clamp": true}}"#,
        r#""a": "a.curves""#,
    ));
    for want in [
        "line 1, column 50: error: node 'a': params: param 'from': must not be parallel to 'axis'",
        "node 'b': params: param 'end_angle': the arc must turn by more than 0",
        "node 'c': params: param 'points': needs x, y, z of two points or more (got 4 numbers)",
        "node 'd': param 'friction': must be >= 0, got -1",
        "node 'e': params: param 'clamp': a clamp holds the direction at held vertices; with mode rigid they are not held",
    ] {
        assert!(e.contains(want), "missing {want:?} in {e}");
    }
}

#[test]
fn a_bead_sliding_down_its_wire_stops_against_a_collider_on_it() {
    // Sliding vertices take contacts like any vertex: a bead slides down a wire (slope 1:2)
    // into a sphere (r = 5 cm) sitting on the wire, and rests against it: on the wire, outside
    // the sphere by the contact thickness, at rest. The contact solve does not see the rail
    // (its directions are put back on it by the retraction): exact at convergence; measured
    // 1.4 Newton iterations a step, 9e-10 m deepest.
    let nodes = r#""rail": {"type": "geo.line", "params": {"start": [-1, 0.5, 0], "end": [1, -0.5, 0], "segments": 1}},
        "line": {"type": "geo.line", "params": {"start": [-0.5, 0.25, 0], "end": [-0.4911, 0.2455, 0], "segments": 1}},
        "bead": {"type": "convert.hair", "inputs": {"curves": "line.curves"}, "params": {"name": "bead"}},
        "rod": {"type": "sec.rod", "inputs": {"element": "bead.element"}, "params": {"radius": 0.001}},
        "mass": {"type": "sec.density", "inputs": {"element": "rod.element"}, "params": {"line_density": 0.01}},
        "slide": {"type": "convert.attachment", "inputs": {"target": "mass.element", "along": "rail.curves"},
                  "params": {"name": "slide", "mode": "slide", "vertices": [0, 1]}},
        "ballmesh": {"type": "geo.sphere", "params": {"center": [0.2, -0.1, 0], "radius": 0.05, "rings": 32, "sectors": 48}},
        "ball": {"type": "convert.collider", "inputs": {"mesh": "ballmesh.mesh"}, "params": {"name": "ball"}},
        "touch": {"type": "convert.collision_group", "params": {"name": "touch", "members": "bead", "colliders": "ball"}},
        "material": {"type": "behavior.rod"},
        "gravity": {"type": "behavior.gravity"},
        "attach": {"type": "behavior.attachment"},
        "collide": {"type": "behavior.collision"},
        "tree": {"type": "behavior.tree", "inputs": {"behaviors": ["material.behavior", "gravity.behavior", "attach.behavior", "collide.behavior"]}},
        "solve": {"type": "solver.solid", "inputs": {"elements": ["mass.element", "slide.element", "ball.element", "touch.element"], "tree": "tree.tree"},
                  "params": {"substeps": 4, "tolerance": 1e-6}},
        "v1": {"type": "scene.vertex", "inputs": {"scene": "solve.scene"}, "params": {"element": "bead", "index": 1}}"#;
    let mut g = graph(&file(nodes, r#""v1": "v1.position""#));
    let wire = [[-1.0, 0.5, 0.0], [1.0, -0.5, 0.0]];
    let mut closest = f64::INFINITY;
    for frame in 1..=36i64 {
        let p = vec3_at(&mut g, "v1", frame);
        assert!(to_polyline(p, &wire) < 1e-9, "frame {frame}: off the wire");
        closest = closest.min(dist(p, [0.2, -0.1, 0.0]));
    }
    // The sphere's mesh is inside the sphere; the contact keeps the default thickness from
    // it (1 mm): never closer than the radius, resting within 2 mm of it (measured 0.98 mm).
    assert!(closest > 0.05, "{closest} m from the centre");
    let (a, b) = (vec3_at(&mut g, "v1", 35), vec3_at(&mut g, "v1", 36));
    assert!(
        dist(b, [0.2, -0.1, 0.0]) < 0.052,
        "{b:?} does not rest against the sphere"
    );
    assert!(dist(a, b) < 1e-9, "still moving: {a:?} → {b:?}");
}

/// A strand of 8 segments from the origin to `end` (0.01 kg/m, radius 1 mm) whose root
/// slides with friction `mu` on the wire `rail`, 2 substeps a frame at `tolerance`: a hair
/// tie or a bead on a rod, what hangs from it swinging.
fn hanging_strand(rail: &str, mu: f64, end: [f64; 3], tolerance: f64) -> Graph {
    hanging_strand_by(rail, mu, end, tolerance, None)
}

/// [`hanging_strand`], with a sphere collider (centre, radius) the strand touches where
/// `ball` is given.
fn hanging_strand_by(
    rail: &str,
    mu: f64,
    end: [f64; 3],
    tolerance: f64,
    ball: Option<([f64; 3], f64)>,
) -> Graph {
    let (extra, elements, collide) = match ball {
        Some((center, radius)) => (
            format!(
                r#""ballmesh": {{"type": "geo.sphere", "params": {{"center": {center:?}, "radius": {radius}, "rings": 24, "sectors": 32}}}},
        "ball": {{"type": "convert.collider", "inputs": {{"mesh": "ballmesh.mesh"}}, "params": {{"name": "ball"}}}},
        "touch": {{"type": "convert.collision_group", "params": {{"name": "touch", "members": "strand", "colliders": "ball"}}}},
        "collide": {{"type": "behavior.collision"}},"#
            ),
            r#", "ball.element", "touch.element""#,
            r#", "collide.behavior""#,
        ),
        None => (String::new(), "", ""),
    };
    let nodes = format!(
        r#""rail": {rail},
        "line": {{"type": "geo.line", "params": {{"start": [0.0, 0.0, 0.0], "end": {end:?}, "segments": 8}}}},
        "strand": {{"type": "convert.hair", "inputs": {{"curves": "line.curves"}}, "params": {{"name": "strand"}}}},
        "rod": {{"type": "sec.rod", "inputs": {{"element": "strand.element"}}, "params": {{"radius": 0.001}}}},
        "mass": {{"type": "sec.density", "inputs": {{"element": "rod.element"}}, "params": {{"line_density": 0.01}}}},
        "slide": {{"type": "convert.attachment", "inputs": {{"target": "mass.element", "along": "rail.curves"}},
                   "params": {{"name": "slide", "mode": "slide", "vertices": [0], "friction": {mu}}}}},
        {extra}
        "material": {{"type": "behavior.rod"}},
        "gravity": {{"type": "behavior.gravity"}},
        "attach": {{"type": "behavior.attachment"}},
        "tree": {{"type": "behavior.tree", "inputs": {{"behaviors": ["material.behavior", "gravity.behavior", "attach.behavior"{collide}]}}}},
        "solve": {{"type": "solver.solid", "inputs": {{"elements": ["mass.element", "slide.element"{elements}], "tree": "tree.tree"}},
                   "params": {{"substeps": 2, "tolerance": {tolerance:e}}}}},
        "root": {{"type": "scene.vertex", "inputs": {{"scene": "solve.scene"}}, "params": {{"element": "strand", "index": 0}}}},
        "tip": {{"type": "scene.vertex", "inputs": {{"scene": "solve.scene"}}, "params": {{"element": "strand", "index": 8}}}}"#
    );
    graph(&file(
        &nodes,
        r#""root": "root.position", "tip": "tip.position""#,
    ))
}

/// The frames in which the solver held a contact.
fn touching_frames(g: &Graph) -> Vec<i64> {
    let report = g.node_report("solve").expect("the solver's report");
    report["solid_frames"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|f| f["contacts"]["contacts"].as_u64().unwrap_or(0) > 0)
        .map(|f| f["frame"].as_i64().unwrap())
        .collect()
}

/// The substeps the solver retried (smaller steps where Newton did not converge).
fn retried(g: &Graph) -> u64 {
    let report = g.node_report("solve").expect("the solver's report");
    report["solid_frames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["retries"].as_u64().unwrap())
        .sum()
}

#[test]
fn a_strand_hanging_from_a_sliding_root_slides_by_coulomb_as_a_whole() {
    // θ = 30°, μ = 0.2: sliding as one body, the strand accelerates at a = g (sin θ − μ cos θ)
    // along the wire with a normal force of M g cos θ, and hangs still in that frame along
    // g − a t. Started in that shape at rest it keeps it, and implicit Euler's velocity is
    // exact for a constant acceleration (v_k = k h a). The root's friction reads the normal
    // force the wire supplies to the whole strand, through its stiff first segment (EA/L
    // = 1.8e5 N/m against the root's m/h² of 0.61 N/m): at the default tolerance and below.
    let (th, mu) = (30f64.to_radians(), 0.2);
    let (rail, ends, at) = wire(th);
    let t = at(1.0);
    let a = 9.81 * (th.sin() - mu * th.cos());
    let down = [-a * t[0], -9.81 - a * t[1], 0.0];
    let l = 0.42 / dot(down, down).sqrt();
    let h = 1.0 / 48.0;
    // At the default tolerance and at 1e-6 m/s. Each step's velocity is within Newton's
    // tolerance; a one-sided error would add up through the velocity to as much as
    // h·tol·n(n + 1)/2 after n steps (2.4e-3 m over the 48 steps at 1e-4), but each step's
    // loop ends with its last correction taken, so the error stays within the tolerance
    // over the elapsed time, tol·n h (1e-4 m at frame 24 at 1e-4: measured 8.8e-5 m; 1e-6 m
    // at 1e-6: measured 2.9e-7 m) — the bound this test held before the rate stop reached
    // frictional steps, kept.
    for tolerance in [1e-4, 1e-6] {
        let mut g = hanging_strand(&rail, mu, down.map(|c| l * c), tolerance);
        for frame in [1i64, 12, 24] {
            let root = vec3_at(&mut g, "root", frame);
            let tip = vec3_at(&mut g, "tip", frame);
            assert!(to_polyline(root, &ends) < 1e-9);
            let steps = 2.0 * frame as f64;
            let want = euler_distance(a, h, steps);
            let s = dot(root, t);
            let bound = tolerance * steps * h;
            assert!(
                (s - want).abs() < bound,
                "tolerance {tolerance:e}, frame {frame}: root {s} m along the wire, want {want}"
            );
            // Still hanging along g − a t: the tip where the root's shift put it, but for the
            // strand's stretch under its weight (0.04 N over EA = 9.4e3 N: measured 8.1e-7 m
            // at 1e-6) and the swing Newton's tolerance leaves (tol over the second;
            // measured 1.0e-5 m at 1e-4).
            let moved = [0, 1, 2].map(|k| tip[k] - root[k] - l * down[k]);
            assert!(
                dot(moved, moved).sqrt() < tolerance + 2e-6,
                "tolerance {tolerance:e}, frame {frame}: the tip is {moved:?} from its place"
            );
        }
        assert_eq!(retried(&g), 0, "substeps retried at {tolerance:e}");
    }
}

#[test]
fn a_swinging_strand_whose_root_slides_with_friction_converges_at_the_default_tolerance() {
    // The strand starts 45° from the vertical and swings while its root slides down a wire
    // 30° below +x with μ = 0.2 (under tan 30°: it slides). Its normal force changes as it
    // swings; read from the iterate's gradient, through the stiff first segment, it was
    // noise (1.84 N where the strand weighs 0.04 N) and Newton stalled: 276 retried
    // substeps, and at a tolerance of 1e-3 the root ended 0.18 m down the wire against
    // 1.87 m (BENCHMARKS.md, thirty-fourth and thirty-fifth sessions). Reference: the same
    // graph at 1e-9 m/s.
    let (rail, ends, at) = wire(30f64.to_radians());
    let run = |tolerance: f64| {
        let mut g = hanging_strand(&rail, 0.2, [0.3, -0.3, 0.0], tolerance);
        let root = vec3_at(&mut g, "root", 24);
        let tip = vec3_at(&mut g, "tip", 24);
        assert!(to_polyline(root, &ends) < 1e-9);
        (root, tip, retried(&g))
    };
    let (root, tip, retries) = run(1e-9);
    assert_eq!(retries, 0, "substeps retried at 1e-9");
    // It slid (measured 1.87 m); a held root would not have moved.
    assert!(dot(root, at(1.0)) > 1.5, "root at {root:?}");
    for tolerance in [1e-3, 1e-4] {
        let (r, t, retries) = run(tolerance);
        assert_eq!(retries, 0, "substeps retried at {tolerance}");
        // A velocity error of the tolerance over the run's second: the tolerance in metres
        // (root and tip measured 6.8e-4 and 6.6e-4 m at 1e-3, 2.3e-5 and 1.3e-5 m at 1e-4,
        // with the loop's rate stop once friction's normal forces settle; 2.3e-4 and 3.6e-5
        // m for the root without it; with the Newton steps' test alone, 2.8e-3 m at 1e-3).
        for (got, want) in [(r, root), (t, tip)] {
            let d = dist(got, want);
            assert!(
                d < tolerance,
                "at {tolerance}: {d:e} m from the run at 1e-9"
            );
        }
    }
}

#[test]
fn a_strand_sliding_with_friction_resumes_from_a_checkpoint_bit_for_bit() {
    // Friction's normal force comes from each step's own Newton loop (`SlideForces`):
    // nothing is carried from one step to the next, so a resumed run takes the same steps.
    // (Carried, as first written, the resumed run differed.) Free, and swinging into a
    // sphere, so the contact loop's steps are resumed too.
    let (rail, _, _) = wire(30f64.to_radians());
    for ball in [None, Some(([0.2, -0.45, 0.0], 0.12))] {
        let strand = || hanging_strand_by(&rail, 0.2, [0.3, -0.3, 0.0], 1e-4, ball);
        let bits = |g: &mut Graph, frame: i64| vec3_at(g, "tip", frame).map(f64::to_bits);
        let mut seq = strand();
        let reference: Vec<[u64; 3]> = (0..=8).map(|f| bits(&mut seq, f)).collect();
        assert_ne!(reference[0], reference[8], "the strand moved");
        if ball.is_some() {
            // In contact in frames 4–8, after the checkpoint at 3 (measured: 3–8): the resumed
            // steps run the contact loop.
            let touching = touching_frames(&seq);
            assert!(
                touching.iter().any(|&f| (4..=8).contains(&f)),
                "no contact in frames 4–8: {touching:?}"
            );
        }
        let mut resumed = strand();
        bits(&mut resumed, 5);
        resumed.drop_checkpoints_after("solve", 3);
        assert_eq!(
            bits(&mut resumed, 8),
            reference[8],
            "{ball:?}: resumed from frame 3"
        );
        let mut jump = strand();
        assert_eq!(
            bits(&mut jump, 8),
            reference[8],
            "{ball:?}: straight to frame 8"
        );
    }
}

#[test]
fn a_strand_below_its_friction_angle_stays_put_though_its_first_iterations_are_frictionless() {
    // A strand hanging still from a root on a wire tilted 0.1° (tan θ far below μ = 0.2):
    // static friction holds it, though each step's first iteration runs without friction at
    // this stiff root (`STIFF_NODE`) and a frictionless step would slide it at g sin θ
    // (h g sin θ = 3.6e-4 m/s, under the tolerance of 1e-3: such an iteration may not end
    // its step; 8.6e-3 m in the second if it did every step). The mollified law lets it
    // creep below ε_v = 1e-4 m/s: under 1e-4 m (measured 4.3e-7 m; 4.1e-6 m before steps
    // stopped at the stick point).
    let (rail, _, at) = wire(0.1f64.to_radians());
    let mut g = hanging_strand(&rail, 0.2, [0.0, -0.42, 0.0], 1e-3);
    let root = vec3_at(&mut g, "root", 24);
    let s = dot(root, at(1.0));
    assert!(s.abs() < 1e-4, "slid {s} m in 1 s");
    // Each step: the frictionless iteration slides the root 4e-5 m, past the mollifier's
    // ε_v h = 2e-6 m; friction's first model pulls it back, stopped at the stick point
    // (`stick_cap`) instead of across it; the next model, in the mollified zone, holds it.
    // Three Newton iterations a step at most (without the stop the line search halved the
    // reversing steps 6 to 10 times an iteration, and steps took up to 5 at this tolerance,
    // 6 at 1e-4).
    let report = g.node_report("solve").expect("the solver's report");
    let frames = report["solid_frames"].as_array().unwrap();
    assert_eq!(frames.len(), 24, "frames reported");
    for f in frames {
        let most = f["max_newton_iterations"].as_u64().unwrap();
        assert!(
            most <= 3,
            "frame {}: {most} Newton iterations in a step",
            f["frame"]
        );
    }
}
