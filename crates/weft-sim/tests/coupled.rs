//! Scene side of the coupling: drag elements from SECs, the scene's fluid from its fluid
//! domain, colliders as obstacles. The coupled step itself runs through the graph users run
//! (`solver.coupled`): its physics is tested in `crates/weft-bench/tests/coupled.rs`.

use weft_sim::*;

/// Scene side: the Fluid Drag Behavior turns every hair segment and cloth triangle into a
/// drag element with its Drag SEC (or the defaults), names bad drag parameters, and a Drag
/// SEC without the Behavior is reported as unread.
#[test]
fn fluid_drag_behavior_builds_elements_from_secs() {
    use std::sync::Arc;
    use weft_scene::procedural::{Plane, grid, strands_on_sphere};
    use weft_scene::{Drag, ElementKind, Geometry, SceneElement};
    let curves = strands_on_sphere([0.0, 1.0, 0.0], 0.1, 5, 4, 0.2, 60.0);
    let strands = curves.len();
    let mut hair = SceneElement::new("hair", ElementKind::Hair, Geometry::Curves(curves));
    hair.secs.insert(Drag {
        xi_d: 3.0,
        ..Default::default()
    });
    let cloth = SceneElement::new(
        "cloth",
        ElementKind::Cloth,
        Geometry::Mesh(grid([1.0, 1.0], [3, 3], Plane::Xz, [0.0; 3])),
    );
    let tree = |with_drag: bool| {
        let mut behaviors: Vec<Arc<dyn Behavior>> =
            vec![Arc::new(RodMaterial), Arc::new(DiscreteShellMaterial)];
        if with_drag {
            behaviors.push(Arc::new(FluidDrag));
        }
        BehaviorTree { behaviors }
    };
    let c = compile(&[hair.clone(), cloth.clone()], &tree(true)).unwrap();
    assert_eq!(c.drag_elements.len(), strands * 4 + 8);
    assert_eq!(c.terms["drag_elements"], strands * 4 + 8);
    assert_eq!(c.drag_elements[0].params.xi_d, 3.0);
    assert_eq!(
        c.drag_elements.last().unwrap().params.xi_d,
        1.0,
        "cloth: defaults"
    );
    // Without a fluid domain the drag elements feel nothing: said once, and no grid.
    assert_eq!(c.warnings.len(), 1, "{:?}", c.warnings);
    assert!(
        c.warnings[0].contains("no fluid domain"),
        "{:?}",
        c.warnings
    );
    assert!(c.fluid.is_none());
    let c = compile(&[hair.clone(), cloth.clone()], &tree(false)).unwrap();
    assert!(c.drag_elements.is_empty());
    assert!(
        c.warnings.iter().any(|w| w.contains("'drag'")),
        "{:?}",
        c.warnings
    );
    hair.secs.insert(Drag {
        gamma: 1.5,
        ..Default::default()
    });
    let e = compile(&[hair, cloth], &tree(true)).unwrap_err();
    assert!(e.to_string().contains("drag.gamma"), "{e}");
}

/// A fluid-domain element makes the scene's fluid: automatic bounds enclose the solids plus
/// the padding (rounded up to whole cells), the Fluid SEC's properties and the flow are kept,
/// and its SECs count as read. A second domain, and a grid too large for memory, are refused
/// naming the element and field.
#[test]
fn a_fluid_domain_element_makes_the_scenes_fluid() {
    use std::sync::Arc;
    use weft_scene::procedural::strands_on_sphere;
    use weft_scene::{DomainSide, ElementKind, Fluid, FluidDomain, Geometry, SceneElement};
    let curves = strands_on_sphere([0.0, 1.0, 0.0], 0.1, 5, 4, 0.2, 60.0);
    let hair = SceneElement::new("hair", ElementKind::Hair, Geometry::Curves(curves));
    let mut water = SceneElement::new("water", ElementKind::FluidDomain, Geometry::None);
    water.secs.insert(FluidDomain {
        padding: 0.05,
        cell_size: 0.01,
        lo: [DomainSide::Inflow, DomainSide::Wall, DomainSide::Periodic],
        hi: [DomainSide::Open, DomainSide::Wall, DomainSide::Periodic],
        flow: [0.3, 0.0, 0.0],
        ..Default::default()
    });
    water.secs.insert(Fluid::AIR);
    let tree = BehaviorTree {
        behaviors: vec![Arc::new(RodMaterial), Arc::new(FluidDrag)],
    };
    let c = compile(&[hair.clone(), water.clone()], &tree).unwrap();
    assert!(c.warnings.is_empty(), "{:?}", c.warnings);
    let f = c.fluid.as_ref().expect("a fluid");
    let (lo, hi) = weft_scene::bounds(
        &c.state
            .x
            .iter()
            .map(|p| [p.x, p.y, p.z])
            .collect::<Vec<_>>(),
    )
    .unwrap();
    for a in 0..3 {
        assert!((f.domain.origin[a] - (lo[a] - 0.05)).abs() < 1e-12);
        let top = f.domain.origin[a] + f.domain.cells[a] as f64 * 0.01;
        assert!(top >= hi[a] + 0.05 - 1e-9 && top < hi[a] + 0.06, "axis {a}");
    }
    assert_eq!(f.properties.density, Fluid::AIR.density);
    let g = f.initial_grid();
    assert_eq!(g.vel[0][g.domain.face(0, 3, 2, 2)], 0.3);
    assert_eq!(
        f.domain.boundaries.lo[0],
        weft_fluid::Boundary::Inflow([0.3, 0.0, 0.0])
    );
    let mut second = water.clone();
    second.name = "sea".into();
    let e = compile(&[hair.clone(), water.clone(), second], &tree).unwrap_err();
    assert!(e.to_string().contains("'sea'"), "{e}");
    let mut huge = water;
    huge.secs.insert(FluidDomain {
        cell_size: 1e-5,
        ..Default::default()
    });
    let e = compile(&[hair, huge], &tree).unwrap_err().to_string();
    assert!(
        e.contains("fluid_domain.cell_size") && e.contains("GiB"),
        "{e}"
    );
}

/// Colliders are obstacles in the fluid: `FluidSpec::obstacles` finds the faces inside a
/// collider's closed mesh (those within the sphere's radius less the faceting, none beyond
/// it) and gives each the collider's rigid velocity at that face: for a turn by θ about the
/// y axis through the centre over h, (p − R(−θ)p)/h, which for small θ is ω × r. Tolerance:
/// exact rigid motion, to rounding (1e-12 m/s).
#[test]
fn colliders_are_obstacles_moving_with_their_transform() {
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};
    use std::sync::Arc;
    use weft_scene::procedural::{sphere, strands_on_sphere};
    use weft_scene::{ElementKind, FluidDomain, Geometry, SceneElement};
    let centre = [0.0, 0.5, 0.0];
    let place = |angle: f64| {
        Isometry3::from_parts(
            Translation3::new(centre[0], centre[1], centre[2]),
            UnitQuaternion::from_axis_angle(&nalgebra::Vector3::y_axis(), angle),
        )
    };
    let (before, after, h) = (place(0.0), place(0.02), 0.04);
    let mut mesh = sphere([0.0; 3], 0.1, 16, 32);
    for p in &mut mesh.positions {
        let q = after.transform_point(&nalgebra::Point3::from(*p));
        *p = [q.x, q.y, q.z];
    }
    let mut head = SceneElement::new("head", ElementKind::Collider, Geometry::Mesh(mesh));
    head.transform = Some(after);
    let hair = SceneElement::new(
        "hair",
        ElementKind::Hair,
        Geometry::Curves(strands_on_sphere(centre, 0.1, 3, 3, 0.1, 60.0)),
    );
    let mut water = SceneElement::new("water", ElementKind::FluidDomain, Geometry::None);
    water.secs.insert(FluidDomain {
        padding: 0.05,
        cell_size: 0.02,
        ..Default::default()
    });
    let tree = BehaviorTree {
        behaviors: vec![Arc::new(RodMaterial)],
    };
    let scene = [hair, head, water];
    let c = compile(&scene, &tree).unwrap();
    let f = c.fluid.as_ref().unwrap();
    assert_eq!(f.colliders, [1]);
    let mut faces = Vec::new();
    f.obstacles(&scene, &[None, Some(before), None], h, &mut faces);
    assert!(faces.len() > 300, "{}", faces.len());
    let back = before * after.inverse();
    let from_centre = |p: [f64; 3]| {
        (0..3)
            .map(|b| (p[b] - centre[b]).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    for s in &faces {
        let a = s.axis as usize;
        let d = &f.domain;
        let dims = d.face_dims(a);
        let fi = s.face as usize;
        let idx = [
            fi % dims[0],
            (fi / dims[0]) % dims[1],
            fi / (dims[0] * dims[1]),
        ];
        let p = d.face_position(a, idx);
        let r = from_centre(p);
        assert!(r < 0.1, "face at {p:?}, {r} from the centre");
        let p1 = nalgebra::Point3::from(p);
        let want = (p1 - back.transform_point(&p1))[a] / h;
        assert!(
            (s.velocity - want).abs() < 1e-12,
            "{} vs {want}",
            s.velocity
        );
    }
    // A collider at rest (no transform before): its faces do not move.
    f.obstacles(&scene, &[None, None, None], h, &mut faces);
    assert!(faces.iter().all(|s| s.velocity == 0.0));
    // Every face well inside (0.08 m, below the faceting's 0.1·cos(π/16)) is found.
    let inside = faces.len();
    let found: std::collections::HashSet<(u8, u32)> =
        faces.iter().map(|s| (s.axis, s.face)).collect();
    let d = &f.domain;
    let mut deep = 0;
    for a in 0..3 {
        let dims = d.face_dims(a);
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let p = d.face_position(a, [i, j, k]);
                    if from_centre(p) < 0.08 {
                        deep += 1;
                        assert!(
                            found.contains(&(a as u8, d.face(a, i, j, k) as u32)),
                            "{p:?}"
                        );
                    }
                }
            }
        }
    }
    assert!(
        deep > 0 && deep <= inside,
        "{deep} deep faces, {inside} found"
    );
    eprintln!("collider: {inside} faces inside, {deep} within 0.08 m");
}
