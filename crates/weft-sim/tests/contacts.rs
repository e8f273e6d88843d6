//! Contacts with colliders at the scene level: what gets built, bad colliders, a start that
//! is already inside a collider, and determinism across thread counts.

use std::sync::Arc;
use weft_scene::procedural::{Plane, grid, sphere};
use weft_scene::{
    Collider, CollisionGroup, CollisionResponse, ElementKind, Geometry, Members, Mesh, SceneElement,
};
use weft_sim::*;

fn cloth(n: usize, y: f64) -> SceneElement {
    SceneElement::new(
        "cloth",
        ElementKind::Cloth,
        Geometry::Mesh(grid([0.6, 0.6], [n, n], Plane::Xz, [0.0, y, 0.0])),
    )
}

fn collider(name: &str, mesh: Mesh) -> SceneElement {
    SceneElement::new(name, ElementKind::Collider, Geometry::Mesh(mesh))
}

fn group(strength: f64) -> SceneElement {
    let mut g = SceneElement::new("contacts", ElementKind::Collision, Geometry::None);
    g.secs.insert(CollisionGroup::default());
    g.secs.insert(CollisionResponse {
        strength,
        damping: 0.0,
    });
    g
}

fn tree(gravity: f64) -> BehaviorTree {
    BehaviorTree {
        behaviors: vec![
            Arc::new(DiscreteShellMaterial),
            Arc::new(Gravity {
                acceleration: [0.0, -gravity, 0.0],
            }),
            Arc::new(Collision),
        ],
    }
}

/// A cloth falling onto a sphere: the contacts, step by step, are bit-identical on 1 and 2
/// threads (detection is sequential and sorted; assembly is by colour). Newton to 1e-4 m/s
/// as the examples: the draped cloth is in compression, where projected Newton is slow.
#[test]
fn contacts_are_bit_identical_on_one_and_two_threads() {
    let scene = vec![
        cloth(12, 0.32),
        collider("ball", sphere([0.0, 0.0, 0.0], 0.3, 12, 16)),
        group(0.5),
    ];
    let c = Arc::new(compile(&scene, &tree(9.81)).unwrap());
    let run = |threads: usize| {
        weft_check::on_threads(threads, || {
            let settings = StepperSettings {
                solver: weft_solid::Settings {
                    tolerance: 1e-4,
                    max_iterations: 100,
                    ..Default::default()
                },
                ..Default::default()
            };
            let mut s = SolidStepper::new(c.clone(), settings).unwrap();
            let mut state = s.initial_state(&scene);
            let mut touched = 0;
            for f in 1..=5 {
                let (next, stats) = s.advance(&state, &scene, f, 1.0 / 24.0).unwrap();
                touched += stats.contacts.unwrap().contacts;
                state = next;
            }
            (state.solid.x, touched)
        })
    };
    let (one, touched) = run(1);
    assert!(touched > 0, "the cloth reached the ball");
    let (two, _) = run(2);
    assert!(
        weft_check::bit_identical(&one, &two),
        "2 threads differ from 1"
    );
}

/// Without a collision element nothing is built (and the tree's Collision Behavior says
/// so); the frame statistics have no contact part.
#[test]
fn no_collision_element_builds_no_contact_machinery() {
    let scene = vec![cloth(4, 1.0), collider("ball", sphere([0.0; 3], 0.3, 8, 8))];
    let c = Arc::new(compile(&scene, &tree(9.81)).unwrap());
    assert!(c.collisions.is_none());
    assert_eq!(c.terms["contact_pairs"], 0);
    assert!(
        c.warnings
            .iter()
            .any(|w| w.contains("no collision element")),
        "{:?}",
        c.warnings
    );
    let mut s = SolidStepper::new(c, StepperSettings::default()).unwrap();
    let st = s.initial_state(&scene);
    let (_, stats) = s.advance(&st, &scene, 1, 1.0 / 24.0).unwrap();
    assert!(stats.contacts.is_none());
}

/// Bad colliders and groups: a collider without triangles and a group naming a hair that is
/// not there are errors naming the element; an open mesh is a warning (only distance is
/// defined); a negative friction on an element's Collider SEC names the field.
#[test]
fn bad_colliders_are_named() {
    let empty = collider("empty", Mesh::default());
    let e = compile(&[cloth(4, 1.0), empty, group(0.5)], &tree(9.81)).unwrap_err();
    assert!(
        e.to_string().contains("empty") && e.to_string().contains("no triangles"),
        "{e}"
    );

    let mut g = group(0.5);
    g.secs.insert(CollisionGroup {
        members: Members::Names(vec!["hair".into()]),
        ..Default::default()
    });
    let e = compile(&[cloth(4, 1.0), g], &tree(9.81))
        .unwrap_err()
        .to_string();
    assert!(e.contains("contacts") && e.contains("'hair'"), "{e}");

    let plane = collider("floor", grid([2.0, 2.0], [2, 2], Plane::Xz, [0.0; 3]));
    let c = compile(&[cloth(4, 1.0), plane, group(0.5)], &tree(9.81)).unwrap();
    assert!(
        c.warnings
            .iter()
            .any(|w| w.contains("floor") && w.contains("not a closed")),
        "{:?}",
        c.warnings
    );

    let mut bad = cloth(4, 1.0);
    bad.secs.insert(Collider {
        friction: -0.1,
        ..Default::default()
    });
    let e = compile(
        &[
            bad,
            collider("ball", sphere([0.0; 3], 0.3, 8, 8)),
            group(0.5),
        ],
        &tree(9.81),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("collider.friction"), "{e}");
}

/// A cloth that starts 0.5 mm deep inside the 1 mm it should keep from a floor (its default
/// thickness; the floor has no Collider SEC; no gravity) is pushed out by `strength` of the
/// depth in a step, not at once: with strength 0.25 and one step a frame, after frame 1 the
/// depth is 0.75 × 0.5 mm and the cloth leaves at 0.25 × 0.5 mm per step (to 1e-9 m; it then
/// coasts out, nothing pushes harder), and the reported penetration falls to zero.
#[test]
fn a_start_inside_a_collider_separates_by_strength() {
    let plane = collider("floor", grid([2.0, 2.0], [2, 2], Plane::Xz, [0.0; 3]));
    let scene = vec![cloth(4, 5e-4), plane, group(0.25)];
    let c = Arc::new(compile(&scene, &tree(0.0)).unwrap());
    let settings = StepperSettings {
        substeps: 1,
        solver: weft_solid::Settings {
            tolerance: 1e-12,
            ..Default::default()
        },
        ..Default::default()
    };
    let h = 1.0 / 24.0;
    let mut s = SolidStepper::new(c, settings).unwrap();
    let mut st = s.initial_state(&scene);
    let mut reported = Vec::new();
    for f in 1..=6 {
        let (next, stats) = s.advance(&st, &scene, f, h).unwrap();
        reported.push(stats.contacts.unwrap().max_penetration);
        st = next;
        if f == 1 {
            for (x, v) in st.solid.x.iter().zip(&st.solid.v) {
                let depth = 1e-3 - x.y;
                assert!((depth - 0.75 * 5e-4).abs() < 1e-9, "depth {depth}");
                assert!((v.y * h - 0.25 * 5e-4).abs() < 1e-9, "speed {}", v.y);
            }
        }
    }
    assert!((reported[0] - 0.75 * 5e-4).abs() < 1e-9, "{reported:?}");
    assert!(reported[5] == 0.0, "{reported:?}");
}

/// A closed prism along z whose top has a shallow V notch: a concave edge along z at
/// y = −2 mm, faces rising at 1 in 50 to y = 0 at x = ±0.1 m; bottom at y = −0.1 m; z in
/// ±0.05 m. Outward triangles, the cross-section fanned from the notch.
fn notched_prism() -> Mesh {
    let section = [
        [-0.1, -0.1],
        [0.1, -0.1],
        [0.1, 0.0],
        [0.0, -2e-3],
        [-0.1, 0.0],
    ];
    let n = section.len() as u32;
    let mut positions = Vec::new();
    for z in [-0.05, 0.05] {
        positions.extend(section.iter().map(|p| [p[0], p[1], z]));
    }
    let mut triangles = Vec::new();
    for i in 0..n {
        let j = (i + 1) % n;
        // The section runs counter-clockwise: (dy, −dx) points out of each side.
        triangles.push([i, j, n + j]);
        triangles.push([i, n + j, n + i]);
    }
    for [a, b, c] in [[3, 4, 0], [3, 0, 1], [3, 1, 2]] {
        triangles.push([n + a, n + b, n + c]);
        triangles.push([c, b, a]);
    }
    Mesh {
        positions,
        triangles,
    }
}

/// A hair strand that starts inside a collider, level, 0.5 mm under a concave edge (the
/// prism's notch): its vertices (x = −0.03, 0.01, 0.03 m; 1.1, 0.7 and 1.1 mm deep) get
/// contacts from their nearest faces, and its first segment, closest to the surface between
/// its vertices (under the notch), one of its own, whose plane must face out of the
/// collider as theirs do. No gravity, strength 0.5, one step of 1/24 s: the step converges
/// at once (no retry) and every one of those points rises by at least half of (its depth +
/// the 1 mm kept) along its normal (the notch's point 0.75 mm, up), to the solver's tolerance
/// (1e-9 m/s over the step). A segment's point was once taken as outside whatever its side,
/// its plane facing into the collider, opposite its vertices' (hair_pile at frame 10, a
/// vertex 0.65 mm inside the head): contacts no step can meet.
#[test]
fn a_strand_inside_a_collider_leaves_through_the_nearest_surface() {
    use weft_scene::{Collider as ColliderSec, Curves, Rod};
    let y0 = -2e-3 - 5e-4;
    let xs = [-0.03, 0.01, 0.03];
    let mut hair = SceneElement::new(
        "hair",
        ElementKind::Hair,
        Geometry::Curves(Curves {
            positions: xs.iter().map(|&x| [x, y0, 0.0]).collect(),
            offsets: vec![0, 3],
        }),
    );
    hair.secs.insert(Rod {
        youngs_modulus: 1e9,
        radius: 2e-4,
        ..Default::default()
    });
    hair.secs.insert(ColliderSec {
        friction: 0.0,
        thickness: 1e-3,
        cohesion: 0.0,
    });
    let scene = vec![hair, collider("block", notched_prism()), group(0.5)];
    let tree = BehaviorTree {
        behaviors: vec![Arc::new(RodMaterial), Arc::new(Collision)],
    };
    let c = Arc::new(compile(&scene, &tree).unwrap());
    let settings = StepperSettings {
        substeps: 1,
        solver: weft_solid::Settings {
            tolerance: 1e-9,
            ..Default::default()
        },
        ..Default::default()
    };
    let mut s = SolidStepper::new(c, settings).unwrap();
    let st = s.initial_state(&scene);
    let (next, stats) = s.advance(&st, &scene, 1, 1.0 / 24.0).unwrap();
    assert_eq!(stats.retries, 0);
    let x = &next.solid.x;
    let tol = 1e-9 / 24.0;
    // Each vertex under a face sloping at 1 in 50 (outward normal (∓0.02, 1)/|·| for x ≷ 0).
    for (k, &xk) in xs.iter().enumerate() {
        let slope: f64 = if xk < 0.0 { -0.02 } else { 0.02 };
        let normal = nalgebra::Vector2::new(-slope, 1.0).normalize();
        let depth = (-2e-3 + slope * xk - y0) * normal.y;
        let rise = normal.dot(&nalgebra::Vector2::new(x[k].x - xk, x[k].y - y0));
        assert!(
            rise >= 0.5 * (depth + 1e-3) - tol,
            "vertex {k} rose {rise} m"
        );
    }
    // Nothing pushes along the notch: the strand stays in its plane (z = 0; a contact with
    // a triangle other than the nearest once turned it 14 mm sideways).
    assert!(x.iter().all(|p| p.z.abs() < 1e-12), "{x:?}");
    // The first segment's point under the notch (s = 0.75 along it).
    let lifted = 0.25 * x[0].y + 0.75 * x[1].y - y0;
    assert!(
        lifted >= 0.75e-3 - tol,
        "the point under the notch rose {lifted} m"
    );
}
