//! Scene + Behavior tree → system → frames.

use std::sync::Arc;
use weft_scene::procedural::{Plane, grid, strands_on_sphere};
use weft_scene::{
    Attachment, AttachmentMode, Channel, DiscreteShell, ElementKind, Geometry, Rod, SceneElement,
};
use weft_sim::*;
use weft_solid::Settings;

fn cloth(nx: usize) -> SceneElement {
    SceneElement::new(
        "cloth",
        ElementKind::Cloth,
        Geometry::Mesh(grid([1.0, 1.0], [nx, nx], Plane::Xy, [0.0, 0.0, 0.0])),
    )
}

fn pins(target: &str, vertices: Vec<u32>) -> SceneElement {
    let mut a = SceneElement::new("pins", ElementKind::Attachment, Geometry::None);
    a.secs.insert(Attachment {
        target: target.into(),
        vertices,
        mode: AttachmentMode::Hard,
        clamps: Vec::new(),
    });
    a
}

/// A horizontal n × n cloth pinned at the two corners of its last row.
fn hanging_cloth(n: usize) -> Vec<SceneElement> {
    let horizontal = SceneElement::new(
        "cloth",
        ElementKind::Cloth,
        Geometry::Mesh(grid([1.0, 1.0], [n, n], Plane::Xz, [0.0, 0.0, 0.0])),
    );
    vec![
        horizontal,
        pins("cloth", vec![(n * n - n) as u32, (n * n - 1) as u32]),
    ]
}

fn tree() -> BehaviorTree {
    BehaviorTree {
        behaviors: vec![
            Arc::new(DiscreteShellMaterial),
            Arc::new(RodMaterial),
            Arc::new(Gravity {
                acceleration: [0.0, -9.81, 0.0],
            }),
            Arc::new(AttachmentBehavior),
        ],
    }
}

#[test]
fn a_cloth_compiles_to_exactly_its_terms_with_documented_defaults() {
    let n = 5;
    let scene = vec![
        cloth(n),
        pins("cloth", vec![(n * n - n) as u32, (n * n - 1) as u32]),
    ];
    let c = compile(&scene, &tree()).unwrap();
    // 4×4 cells → 32 triangles; one bending element per vertex.
    assert_eq!(c.terms["membranes"], 32);
    assert_eq!(c.terms["shell_bends"], n * n);
    assert_eq!(c.terms["rod_stretches"], 0, "no rods without hair");
    assert_eq!(c.terms["pinned"], 2);
    // Default density 0.2 kg/m² over 1 m².
    let mass: f64 = c.system.mass.iter().sum();
    assert!((mass - 0.2).abs() < 1e-14, "{mass}");
    assert!(c.warnings.is_empty(), "{:?}", c.warnings);
}

#[test]
fn unread_secs_missing_materials_and_bad_parameters_are_reported() {
    let mut e = cloth(3);
    e.secs.insert(Rod::default());
    let c = compile(&[e], &tree()).unwrap();
    assert_eq!(
        c.warnings,
        vec![
            "element 'cloth' carries a 'rod' SEC that no Behavior in the tree reads for it"
                .to_string()
        ]
    );

    let only_gravity = BehaviorTree {
        behaviors: vec![Arc::new(Gravity {
            acceleration: [0.0, -9.81, 0.0],
        })],
    };
    let err = compile(&[cloth(3)], &only_gravity).unwrap_err();
    assert!(
        err.to_string()
            .contains("no material Behavior in the tree applies to this cloth"),
        "{err}"
    );

    let mut e = cloth(3);
    e.secs.insert(DiscreteShell {
        poisson_ratio: 0.5,
        ..Default::default()
    });
    assert_eq!(
        compile(&[e], &tree()).unwrap_err().to_string(),
        "element 'cloth': discrete_shell.poisson_ratio must be in [0, 0.5), got 0.5"
    );
    let mut e = cloth(3);
    e.secs.insert(DiscreteShell {
        youngs_modulus: -1.0,
        ..Default::default()
    });
    assert_eq!(
        compile(&[e], &tree()).unwrap_err().to_string(),
        "element 'cloth': discrete_shell.youngs_modulus must be > 0, got -1"
    );

    let err = compile(&[cloth(3), pins("cloth", vec![9])], &tree()).unwrap_err();
    assert_eq!(
        err.to_string(),
        "attachment 'pins': vertex 9 is out of range (element 'cloth' has 9 vertices)"
    );
    let err = compile(&[cloth(3), pins("shirt", vec![0])], &tree()).unwrap_err();
    assert_eq!(
        err.to_string(),
        "attachment 'pins': no element named 'shirt' in the scene"
    );

    let mut e = cloth(3);
    e.set_channel("rest", Channel::Vec3(vec![[0.0; 3]; 4].into()));
    assert_eq!(
        compile(&[e], &tree()).unwrap_err().to_string(),
        "element 'cloth': rest channel 'rest' has 4 entries but the element has 9 vertices"
    );

    let mut e = cloth(3);
    if let Geometry::Mesh(m) = e.geometry_mut() {
        m.positions[4] = [f64::NAN, 0.0, 0.0];
    }
    assert_eq!(
        compile(&[e], &tree()).unwrap_err().to_string(),
        "element 'cloth': vertex 4 has a non-finite position [NaN, 0.0, 0.0]"
    );

    let mut e = cloth(3);
    if let Geometry::Mesh(m) = e.geometry_mut() {
        m.triangles.push([0, 1, 2]); // collinear: the bottom row
    }
    assert_eq!(
        compile(&[e], &tree()).unwrap_err().to_string(),
        "element 'cloth': triangle 8 [0, 1, 2] has zero rest area (0e0 m²)"
    );
}

#[test]
fn a_non_manifold_edge_gets_no_bending_and_one_warning() {
    let mut e = cloth(3);
    if let Geometry::Mesh(m) = e.geometry_mut() {
        // Two fins on the boundary edge (0, 1): three triangles share it.
        let extra = m.positions.len() as u32;
        m.positions.push([0.0, 0.0, 0.5]);
        m.positions.push([0.5, 0.0, -0.5]);
        m.triangles.push([0, 1, extra]);
        m.triangles.push([1, 0, extra + 1]);
    }
    let c = compile(&[e], &tree()).unwrap();
    assert_eq!(c.warnings.len(), 1);
    assert!(
        c.warnings[0].contains("1 non-manifold edge(s)"),
        "{:?}",
        c.warnings
    );
    // The edge's two vertices get no (trace) bending: 9 + 2 vertices, 2 without; every
    // triangle keeps its deviatoric term, with the non-manifold edge free.
    assert_eq!(c.terms["shell_bends"], 9 + 2 - 2);
    assert_eq!(c.terms["shell_midedges"], 8 + 2);
}

#[test]
fn a_pinned_cloth_falls_swings_and_stays_finite() {
    let n = 9;
    let scene = hanging_cloth(n);
    let c = Arc::new(compile(&scene, &tree()).unwrap());
    let mut s = SolidStepper::new(
        c,
        StepperSettings {
            substeps: 2,
            ..Default::default()
        },
    )
    .unwrap();
    let mut state = s.initial_state(&scene);
    let y0: f64 = state.solid.x.iter().map(|p| p.y).sum::<f64>() / state.solid.x.len() as f64;
    for f in 1..=24 {
        let (next, stats) = s.advance(&state, &scene, f, 1.0 / 24.0).unwrap();
        assert!(stats.steps >= 2 && stats.max_residual < 1e-6);
        state = next;
    }
    let y1: f64 = state.solid.x.iter().map(|p| p.y).sum::<f64>() / state.solid.x.len() as f64;
    // Free fall would drop 4.9 m in 1 s; hanging from two corners of a 1 m cloth the centre of
    // mass cannot drop more than ~0.6 m, and it must drop well over 0.1 m.
    assert!(y1 < y0 - 0.1 && y1 > y0 - 0.8, "mean height {y0} → {y1}");
    // Pinned corners did not move.
    for v in [n * n - n, n * n - 1] {
        assert_eq!(state.solid.x[v], c_x(&scene, v));
    }
    let out = s.scene_at(&scene, &state);
    assert_eq!(out[0].vertex_count(), n * n);
    assert!(out[0].vec3_channel("velocity").is_some());
}

fn c_x(scene: &[SceneElement], v: usize) -> nalgebra::Vector3<f64> {
    let p = scene[0].geometry.positions()[v];
    nalgebra::Vector3::new(p[0], p[1], p[2])
}

#[test]
fn hair_roots_follow_an_animated_transform() {
    let curves = strands_on_sphere([0.0; 3], 0.1, 10, 6, 0.1, 60.0);
    let roots: Vec<u32> = (0..curves.len())
        .flat_map(|k| [curves.offsets[k], curves.offsets[k] + 1])
        .collect();
    let hair = SceneElement::new("hair", ElementKind::Hair, Geometry::Curves(curves));
    let mut att = pins("hair", roots.clone());
    att.transform = Some(weft_scene::Transform::identity());
    let scene0 = vec![hair, att];
    let c = Arc::new(compile(&scene0, &tree()).unwrap());
    let mut s = SolidStepper::new(c, StepperSettings::default()).unwrap();
    let state = s.initial_state(&scene0);
    let mut scene1 = scene0.clone();
    scene1[1].transform = Some(weft_scene::Transform::translation(0.05, 0.0, 0.0));
    let (next, _) = s.advance(&state, &scene1, 1, 1.0 / 24.0).unwrap();
    for &r in &roots {
        let d = next.solid.x[r as usize] - state.solid.x[r as usize];
        assert!(
            (d - nalgebra::Vector3::new(0.05, 0.0, 0.0)).norm() < 1e-12,
            "root {r} moved by {d:?}"
        );
    }
}

/// A clamp turns with its attachment: a straight strand along +x, clamped at its root
/// (`root_vertices: 2`), without gravity, solved statically while the transform turns 90°
/// about z. The strand must turn rigidly with it (bending and stretch both vanish there):
/// every vertex at the rotated start position to 1e-9 m (Newton stops at steps of 1e-11 m
/// on positions of 0.1 m). Without the clamp turning, the strand would stay along +x, bent.
/// `root_vertices: 3` holds two vertices and clamps at the second.
#[test]
fn a_clamped_root_turns_with_its_transform() {
    let curves = weft_scene::Curves {
        positions: (0..=8).map(|i| [0.0125 * i as f64, 0.0, 0.0]).collect(),
        offsets: vec![0, 9],
    };
    let mut att = SceneElement::new("roots", ElementKind::Attachment, Geometry::None);
    att.secs.insert(Attachment::curve_roots(
        "hair",
        &curves,
        2,
        AttachmentMode::Hard,
    ));
    att.transform = Some(weft_scene::Transform::identity());
    let three = Attachment::curve_roots("hair", &curves, 3, AttachmentMode::Hard);
    assert_eq!(
        (three.vertices.clone(), three.clamps.clone()),
        (vec![0, 1], vec![[1, 2]])
    );
    let one = Attachment::curve_roots("hair", &curves, 1, AttachmentMode::Hard);
    assert_eq!((one.vertices.clone(), one.clamps.len()), (vec![0], 0));
    let mut hair = SceneElement::new("hair", ElementKind::Hair, Geometry::Curves(curves));
    hair.secs.insert(Rod {
        youngs_modulus: 1e9,
        radius: 5e-4,
        ..Default::default()
    });
    let scene0 = vec![hair, att];
    let tree = BehaviorTree {
        behaviors: vec![Arc::new(RodMaterial), Arc::new(AttachmentBehavior)],
    };
    let c = Arc::new(compile(&scene0, &tree).unwrap());
    assert_eq!((c.terms["rod_clamps"], c.terms["pinned"]), (1, 1));
    turned_rigidly(c, &scene0, 4, 9);
}

/// Solves `scene0` statically (`substeps` load steps, Newton to 1e-11 m) while its second
/// element's transform turns 90° about z, and checks that the first `n` vertices turned
/// rigidly with it (to 1e-9 m).
fn turned_rigidly(c: Arc<Compiled>, scene0: &[SceneElement], substeps: usize, n: usize) {
    let settings = StepperSettings {
        substeps,
        solver: Settings {
            method: weft_solid::Method::Static,
            tolerance: 1e-11,
            max_iterations: 200,
        },
        ..Default::default()
    };
    let mut s = SolidStepper::new(c, settings).unwrap();
    let state = s.initial_state(scene0);
    let mut scene1 = scene0.to_vec();
    let turn = nalgebra::UnitQuaternion::from_axis_angle(
        &nalgebra::Vector3::z_axis(),
        std::f64::consts::FRAC_PI_2,
    );
    scene1[1].transform = Some(weft_scene::Transform::from_parts(
        nalgebra::Translation3::identity(),
        turn,
    ));
    let (next, _) = s.advance(&state, &scene1, 1, 1.0 / 24.0).unwrap();
    for i in 0..n {
        let (x, want) = (next.solid.x[i], turn * state.solid.x[i]);
        assert!((x - want).norm() < 1e-9, "vertex {i}: {x:?}, want {want:?}");
    }
}

/// A clamped cloth edge turns with its attachment: a horizontal strip (xz-plane) held along
/// its x = 0 column with clamps on its border edges, no gravity, solved statically while the
/// transform turns 90° about z: the strip turns rigidly with it (every vertex at the turned
/// start position to 1e-9 m), so the ghosts that hold its tangent plane follow the transform.
/// Without the clamp, the held column is a hinge and the strip would stay horizontal. An
/// edge that is not on the border is refused by name.
#[test]
fn a_clamped_cloth_edge_turns_with_its_transform() {
    let (nx, ny) = (6, 3);
    let mut strip = SceneElement::new(
        "cloth",
        ElementKind::Cloth,
        Geometry::Mesh(grid([0.2, 0.1], [nx, ny], Plane::Xz, [0.1, 0.0, 0.0])),
    );
    strip.secs.insert(DiscreteShell {
        youngs_modulus: 1e8,
        ..Default::default()
    });
    let held: Vec<u32> = (0..ny as u32).map(|j| j * nx as u32).collect();
    let clamps = Attachment::clamps_of(&strip.geometry, &held);
    assert_eq!(clamps, vec![[0, 6], [6, 12]]);
    let mut att = pins("cloth", held.clone());
    att.secs.insert(Attachment {
        target: "cloth".into(),
        vertices: held,
        mode: AttachmentMode::Hard,
        clamps,
    });
    att.transform = Some(weft_scene::Transform::identity());
    let scene0 = vec![strip, att];
    let tree = BehaviorTree {
        behaviors: vec![
            Arc::new(DiscreteShellMaterial),
            Arc::new(AttachmentBehavior),
        ],
    };
    let c = Arc::new(compile(&scene0, &tree).unwrap());
    assert_eq!(c.terms["cloth_clamp_ghosts"], 2);
    turned_rigidly(c, &scene0, 8, nx * ny);
    // An interior edge cannot be clamped.
    let mut bad = scene0.clone();
    bad[1].secs.insert(Attachment {
        target: "cloth".into(),
        vertices: vec![1, 7],
        mode: AttachmentMode::Hard,
        clamps: vec![[1, 7]],
    });
    let e = compile(&bad, &tree).unwrap_err().to_string();
    assert!(
        e.contains("(1, 7)") && e.contains("not a boundary edge"),
        "{e}"
    );
}

/// A load names its element and vertices; a wrong name or index is an error naming the
/// field, and a tip load lands on each strand's last vertex only.
#[test]
fn a_load_pushes_the_vertices_it_names_and_refuses_others() {
    let curves = strands_on_sphere([0.0; 3], 0.1, 3, 4, 0.1, 60.0);
    let tips: Vec<usize> = (0..3).map(|k| curves.offsets[k + 1] as usize - 1).collect();
    let hair = SceneElement::new("hair", ElementKind::Hair, Geometry::Curves(curves));
    let load = |element: &str, vertices: LoadVertices| BehaviorTree {
        behaviors: vec![
            Arc::new(RodMaterial),
            Arc::new(Load {
                element: element.into(),
                vertices,
                force: [0.0, -1.0, 0.0],
            }),
        ],
    };
    let c = compile(
        std::slice::from_ref(&hair),
        &load("hair", LoadVertices::CurveTips),
    )
    .unwrap();
    for (i, f) in c.system.forces.iter().enumerate() {
        let want = if tips.contains(&i) { -1.0 } else { 0.0 };
        assert_eq!(f.y, want, "vertex {i}");
    }
    let e = compile(std::slice::from_ref(&hair), &load("hat", LoadVertices::All)).unwrap_err();
    assert!(
        e.to_string().contains("load.element") && e.to_string().contains("hat"),
        "{e}"
    );
    let e = compile(
        std::slice::from_ref(&hair),
        &load("hair", LoadVertices::Listed(vec![99])),
    )
    .unwrap_err();
    assert!(
        e.to_string().contains("load.vertices") && e.to_string().contains("99"),
        "{e}"
    );
}

#[test]
fn a_step_that_cannot_converge_is_retried_then_reported_with_frame_and_substep() {
    let scene = vec![cloth(5)];
    let c = Arc::new(compile(&scene, &tree()).unwrap());
    let settings = StepperSettings {
        substeps: 2,
        max_retries: 2,
        max_bytes: None,
        contact_iterations: 200,
        solver: Settings {
            tolerance: 0.0,
            max_iterations: 2,
            ..Settings::default()
        },
        ..StepperSettings::default()
    };
    let mut s = SolidStepper::new(c, settings).unwrap();
    let st = s.initial_state(&scene);
    let e = s
        .advance(&st, &scene, 7, 1.0 / 24.0)
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with(
            "frame 7, substep 1 of 2 (after 2 retries with smaller steps): Newton did not converge"
        ),
        "{e}"
    );
}

#[test]
fn a_rod_takes_young_s_modulus_or_an_explicit_bend_stiffness() {
    let curves = strands_on_sphere([0.0; 3], 0.1, 2, 4, 0.1, 30.0);
    let bends = |rod: Rod| {
        let mut e = SceneElement::new("hair", ElementKind::Hair, Geometry::Curves(curves.clone()));
        e.secs.insert(rod);
        compile(&[e], &tree())
            .unwrap()
            .system
            .elements
            .bends
            .iter()
            .map(|b| b.k)
            .collect::<Vec<_>>()
    };
    let derived = bends(Rod::default());
    let r = Rod::default();
    let ei = r.youngs_modulus * std::f64::consts::PI * r.radius.powi(4) / 4.0;
    let explicit = bends(Rod {
        bend_stiffness: ei,
        ..Rod::default()
    });
    for (a, b) in derived.iter().zip(&explicit) {
        assert!((a - b).abs() <= 1e-12 * a, "{a} vs {b}");
    }
    let doubled = bends(Rod {
        bend_stiffness: 2.0 * ei,
        ..Rod::default()
    });
    assert!((doubled[0] / derived[0] - 2.0).abs() < 1e-12);
}

#[test]
fn repeated_attachment_vertices_attach_once_and_repeated_behaviors_warn() {
    let mut springs = pins("cloth", vec![0, 0, 2]);
    springs.secs.insert(Attachment {
        target: "cloth".into(),
        vertices: vec![0, 0, 2],
        mode: AttachmentMode::Spring(100.0),
        clamps: Vec::new(),
    });
    let c = compile(&[cloth(3), springs], &tree()).unwrap();
    assert_eq!(
        c.terms["springs"], 2,
        "vertex 0 listed twice gets one spring"
    );
    let mut t = tree();
    t.behaviors.push(Arc::new(Gravity {
        acceleration: [0.0, -9.81, 0.0],
    }));
    let c = compile(&[cloth(3)], &t).unwrap();
    assert_eq!(
        c.warnings,
        vec![
            "the Behavior tree lists 'gravity' more than once: its terms are applied twice"
                .to_string()
        ]
    );
}

/// Determinism across thread counts: a 40×40 cloth (its assembly tree split into several
/// halves run concurrently) stepped on 1, 2 and 3 threads gives the same bits.
#[test]
fn a_cloth_gives_identical_bits_on_one_two_and_three_threads() {
    let n = 40;
    let scene = hanging_cloth(n);
    let c = Arc::new(compile(&scene, &tree()).unwrap());
    let run = |threads: usize| {
        weft_check::on_threads(threads, || {
            let mut s = SolidStepper::new(c.clone(), StepperSettings::default()).unwrap();
            let mut state = s.initial_state(&scene);
            for f in 1..=2 {
                state = s.advance(&state, &scene, f, 1.0 / 24.0).unwrap().0;
            }
            state.solid.x
        })
    };
    let one = run(1);
    assert!(one.iter().all(|p| p.iter().all(|c| c.is_finite())));
    for threads in [2, 3] {
        let other = run(threads);
        let same = weft_check::bit_identical(&one, &other);
        assert!(same, "{threads} threads differ from 1");
    }
}

#[test]
fn changed_sec_values_compile_again_but_a_freeze_weight_or_nothing_does_not() {
    let mut scene = vec![cloth(4), pins("cloth", vec![0])];
    scene[0].secs.insert(DiscreteShell::default());
    let mut freeze = SceneElement::new("freeze", ElementKind::Attachment, Geometry::None);
    freeze.secs.insert(Attachment {
        target: "cloth".into(),
        vertices: vec![15],
        mode: AttachmentMode::Freeze { weight: 1.0 },
        clamps: Vec::new(),
    });
    scene.push(freeze);
    let c = compile(&scene, &tree()).unwrap();
    // The same values in new SECs: nothing to do.
    let mut same = scene.clone();
    same[0].secs.insert(DiscreteShell::default());
    assert!(
        c.with_params(&same, Some(&tree()), 3, None)
            .unwrap()
            .is_none()
    );
    // A freeze weight is read by the stepper every frame: nothing to compile either.
    let mut weight = scene.clone();
    weight[2].secs.insert(Attachment {
        target: "cloth".into(),
        vertices: vec![15],
        mode: AttachmentMode::Freeze { weight: 0.25 },
        clamps: Vec::new(),
    });
    assert!(c.with_params(&weight, None, 3, None).unwrap().is_none());
    // A stiffer cloth: compiled again, stiffer, with the start's rest shape and structure.
    let mut stiffer = scene.clone();
    stiffer[0].secs.insert(DiscreteShell {
        youngs_modulus: 2e6,
        ..Default::default()
    });
    let c2 = c.with_params(&stiffer, None, 3, None).unwrap().unwrap();
    assert_eq!(c2.state.x, c.state.x);
    assert_eq!(c2.system.elements.len(), c.system.elements.len());
    assert!(c2.system.elements.membranes[0].material != c.system.elements.membranes[0].material);
    // Attachments listing other vertices change what is held: refused only if the vertex
    // count changes, otherwise compiled again (the stepper rebuilds its pattern).
    let mut moved = scene.clone();
    moved[1] = pins("cloth", vec![3]);
    let c3 = c.with_params(&moved, None, 3, None).unwrap().unwrap();
    assert!(c3.system.pinned[3] && !c3.system.pinned[0]);
}
