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
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
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
    let same = one.iter().zip(&two).all(|(a, b)| {
        a.iter()
            .zip(b.iter())
            .all(|(x, y)| x.to_bits() == y.to_bits())
    });
    assert!(same, "2 threads differ from 1");
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
