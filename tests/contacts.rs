//! Contacts in the examples, frame by frame (issue 13's verification, and the piles'): the
//! drape over a sphere, hair under water and on a turning head, the cloth and hair piles,
//! each checked by the independent exact distances and intersection tests of `weft_check`
//! (through the shared helpers), so a verdict owes nothing to the solver's geometry. The
//! contact physics on scenes built here (incline, plane, cohesion, friction, boxes and
//! meshes) is tested in `weft-nodes`' `tests/contacts.rs`.

mod common;
use common::*;
use weft_graph::{Context, Graph};
use weft_nodes::physics::Scene;

/// The example `graphs/NAME` with one output, `scene`, from `from` (its file outputs off).
fn example_scene(name: &str, from: &str) -> Graph {
    let text = std::fs::read_to_string(graphs_dir().join(name)).unwrap();
    let mut doc: serde_json::Value = serde_json::from_str(&text).unwrap();
    doc["outputs"] = serde_json::json!({ "scene": from });
    graph(&doc.to_string())
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
                    !weft_check::segment_meets_triangle(p[i], p[i + 1], tri),
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
