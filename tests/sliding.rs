//! Sliding attachments (issue 17, item 1) through graphs as a user writes them: a bead on a
//! tilted straight wire and on a circular wire, against the analytic motion, and the
//! distance to the rail every frame.

mod common;
use common::*;
use weft::graph::{Context, Graph};

fn vec3_at(g: &mut Graph, output: &str, frame: i64) -> [f64; 3] {
    let v = g
        .pull(output, Context::new(frame))
        .unwrap_or_else(|e| panic!("{e}"));
    *v.get::<[f64; 3]>().expect("a vec3 output")
}

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

/// A bead (a one-segment strand, both vertices sliding) on the rail `rail_node`, starting
/// between `a` and `b`.
fn bead_graph(rail_node: &str, a: [f64; 3], b: [f64; 3], substeps: u32) -> Graph {
    let nodes = format!(
        r#""rail": {rail_node},
        "line": {{"type": "geo.line", "params": {{"start": {a:?}, "end": {b:?}, "segments": 1}}}},
        "bead": {{"type": "convert.hair", "inputs": {{"curves": "line.curves"}}, "params": {{"name": "bead"}}}},
        "rod": {{"type": "sec.rod", "inputs": {{"element": "bead.element"}}, "params": {{"radius": 0.001}}}},
        "mass": {{"type": "sec.density", "inputs": {{"element": "rod.element"}}, "params": {{"line_density": 0.01}}}},
        "slide": {{"type": "convert.attachment", "inputs": {{"target": "mass.element", "along": "rail.curves"}},
                   "params": {{"name": "slide", "mode": "slide", "vertices": [0, 1]}}}},
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

#[test]
fn a_bead_on_a_tilted_wire_accelerates_at_g_sin_theta() {
    // A wire through the origin, 30° below +x in the xy plane; gravity −y.
    let th = 30f64.to_radians();
    let t = [th.cos(), -th.sin(), 0.0];
    let at = |s: f64| [s * t[0], s * t[1], s * t[2]];
    let wire = [at(-5.0), at(5.0)];
    let rail = format!(
        r#"{{"type": "geo.line", "params": {{"start": {:?}, "end": {:?}, "segments": 1}}}}"#,
        wire[0], wire[1]
    );
    let substeps = 4;
    let mut g = bead_graph(&rail, at(0.0), at(0.01), substeps);
    let h = 1.0 / (24.0 * substeps as f64);
    let a = 9.81 * th.sin();
    for frame in 1..=24i64 {
        let p = vec3_at(&mut g, "v0", frame);
        let q = vec3_at(&mut g, "v1", frame);
        // On the wire, every frame (rounding: the points are made on its segment).
        for x in [p, q] {
            let d = to_polyline(x, &wire);
            assert!(d < 1e-9, "frame {frame}: {d:e} m off the wire");
        }
        // Implicit Euler under a constant force along the wire: v_n = n h a exactly, so
        // s_n = a h² n (n + 1) / 2. The issue asks for g sin θ within 0.5 %; with the solve's
        // tolerance of 1e-9 m/s it is within 1e-12 (measured 5e-13 at frame 24).
        let n = (frame as u32 * substeps) as f64;
        let want = a * h * h * n * (n + 1.0) / 2.0;
        let s = p[0] * t[0] + p[1] * t[1] + p[2] * t[2];
        assert!(
            (s - want).abs() < 1e-9 * want,
            "frame {frame}: {s} m along the wire, want {want}"
        );
    }
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
