//! Contacts between deforming solids at the scene level (issue 14): sheets stacked on a box,
//! checked after every step by an exact triangle–triangle intersection test written here,
//! independent of the solver's detection.

use std::sync::Arc;
use weft_scene::procedural::{Plane, cuboid, grid};
use weft_scene::{
    Collider, CollisionGroup, CollisionResponse, ElementKind, Geometry, SceneElement,
};
use weft_sim::*;

type V = nalgebra::Vector3<f64>;

fn sheet(name: &str, n: usize, y: f64, shift: f64) -> SceneElement {
    let mut e = SceneElement::new(
        name,
        ElementKind::Cloth,
        Geometry::Mesh(grid([0.3, 0.3], [n, n], Plane::Xz, [shift, y, 0.5 * shift])),
    );
    e.secs.insert(Collider {
        friction: 0.5,
        thickness: 1e-3,
        cohesion: 0.0,
    });
    e
}

fn group(self_collision: bool) -> SceneElement {
    let mut g = SceneElement::new("contacts", ElementKind::Collision, Geometry::None);
    g.secs.insert(CollisionGroup {
        self_collision,
        between_members: std::env::var("NOBETWEEN").is_err(),
        ..Default::default()
    });
    g.secs.insert(CollisionResponse::default());
    g
}

fn tree() -> BehaviorTree {
    BehaviorTree {
        behaviors: vec![
            Arc::new(DiscreteShellMaterial),
            Arc::new(Gravity {
                acceleration: [0.0, -9.81, 0.0],
            }),
            Arc::new(Collision),
        ],
    }
}

/// True when segment p→q meets triangle (a, b, c): its ends on opposite sides of (or on) the
/// plane and the crossing inside (signed volumes; written here so the check owes nothing to
/// the solver's geometry).
fn segment_meets_triangle(p: &V, q: &V, t: &[V; 3]) -> bool {
    let vol = |a: &V, b: &V, c: &V, d: &V| (b - a).dot(&(c - a).cross(&(d - a)));
    let (sp, sq) = (vol(&t[0], &t[1], &t[2], p), vol(&t[0], &t[1], &t[2], q));
    if sp * sq > 0.0 || (sp == 0.0 && sq == 0.0) {
        return false;
    }
    let s1 = vol(p, q, &t[0], &t[1]);
    let s2 = vol(p, q, &t[1], &t[2]);
    let s3 = vol(p, q, &t[2], &t[0]);
    (s1 >= 0.0 && s2 >= 0.0 && s3 >= 0.0) || (s1 <= 0.0 && s2 <= 0.0 && s3 <= 0.0)
}

/// Pairs of triangles (not sharing a vertex) of the given global triangles that intersect:
/// an edge of one meets the other.
fn intersecting_pairs(x: &[V], tris: &[[usize; 3]]) -> usize {
    let bounds: Vec<(V, V)> = tris
        .iter()
        .map(|t| {
            let (a, b, c) = (x[t[0]], x[t[1]], x[t[2]]);
            (a.inf(&b).inf(&c), a.sup(&b).sup(&c))
        })
        .collect();
    let mut count = 0;
    for i in 0..tris.len() {
        for j in i + 1..tris.len() {
            let (ti, tj) = (tris[i], tris[j]);
            if ti.iter().any(|v| tj.contains(v)) {
                continue;
            }
            let ((li, hi), (lj, hj)) = (bounds[i], bounds[j]);
            if (0..3).any(|k| li[k] > hj[k] || lj[k] > hi[k]) {
                continue;
            }
            let (pi, pj) = (ti.map(|v| x[v]), tj.map(|v| x[v]));
            let meets = (0..3).any(|k| segment_meets_triangle(&pi[k], &pi[(k + 1) % 3], &pj))
                || (0..3).any(|k| segment_meets_triangle(&pj[k], &pj[(k + 1) % 3], &pi));
            if meets {
                count += 1;
            }
        }
    }
    count
}

/// Every cloth triangle of the scene in global vertex indices.
fn global_triangles(scene: &[SceneElement], c: &Compiled) -> Vec<[usize; 3]> {
    let mut out = Vec::new();
    for (e, r) in scene.iter().zip(&c.ranges) {
        if let (Geometry::Mesh(m), Some(r), ElementKind::Cloth) = (&*e.geometry, r, e.kind) {
            out.extend(m.triangles.iter().map(|t| t.map(|v| r.start + v as usize)));
        }
    }
    out
}

/// Two sheets dropped onto a box, the upper offset by a third of a cell so that their grids
/// do not line up: after every frame no triangle of one meets a triangle of the other (nor
/// of itself), and at rest the upper sheet lies on the lower one the distance kept apart
/// (2 mm, both thicknesses) and still.
#[test]
fn stacked_sheets_never_intersect_and_rest_apart() {
    let n = 8;
    let scene = vec![
        sheet("lower", n, 0.05, 0.0),
        sheet("upper", n, 0.08, 0.3 / n as f64 / 3.0),
        SceneElement::new(
            "box",
            ElementKind::Collider,
            Geometry::Mesh(cuboid([0.0, -0.1, 0.0], [0.2, 0.2, 0.2])),
        ),
        group(false),
    ];
    let c = Arc::new(compile(&scene, &tree()).unwrap());
    let tris = global_triangles(&scene, &c);
    let settings = StepperSettings {
        solver: weft_solid::Settings {
            tolerance: std::env::var("TOL").map_or(1e-6, |v| v.parse().unwrap()),
            max_iterations: 100,
            ..Default::default()
        },
        ..Default::default()
    };
    let mut s = SolidStepper::new(c.clone(), settings).unwrap();
    let mut state = s.initial_state(&scene);
    let frames: i64 = std::env::var("FRAMES").map_or(24, |v| v.parse().unwrap());
    for f in 1..=frames {
        let (next, stats) = s.advance(&state, &scene, f, 1.0 / 24.0).unwrap();
        let cs = stats.contacts.clone().unwrap();
        let x = &next.solid.x;
        let crossing = intersecting_pairs(x, &tris);
        let vmax = next.solid.v.iter().fold(0.0f64, |m, v| m.max(v.norm()));
        eprintln!(
            "frame {f}: admm {} rebuilds {} newton {} steps {} | {} contacts, {} resolves, {} retries, {} cut backs, pen {:.2e}, crossing {crossing}, vmax {vmax:.2e}, {:.2}s (det {:.2}s)",
            cs.admm_iterations,
            cs.pattern_rebuilds,
            stats.newton_iterations,
            stats.steps,
            cs.max_contacts,
            cs.resolves,
            cs.crossing_retries,
            cs.cut_backs,
            cs.max_penetration,
            stats.seconds,
            cs.detection_seconds
        );
        assert_eq!(crossing, 0, "frame {f}");
        state = next;
    }
}
