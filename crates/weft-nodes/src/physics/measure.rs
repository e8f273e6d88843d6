//! Reading numbers out of a scene (for outputs, tests and charts).

use super::types::Scene;
use weft_graph::{EvalCx, Kernel, NodeError, NodeSpec, ParamSpec, Registry, RegistryError};
use weft_scene::{Geometry, SceneElement};

fn element<'a>(cx: &EvalCx<'_>, scene: &'a Scene) -> Result<&'a SceneElement, NodeError> {
    let name = cx.params().str("element")?;
    scene.iter().find(|e| e.name == name).ok_or_else(|| {
        let names: Vec<&str> = scene.iter().map(|e| e.name.as_str()).collect();
        NodeError::Input {
            port: "scene".into(),
            message: format!("has no element '{name}' (elements: {})", names.join(", ")),
        }
    })
}

pub(crate) fn register(r: &mut Registry) -> Result<(), RegistryError> {
    r.register(
        NodeSpec::new(
            "scene.gather",
            "a scene from elements, in connection order (the input of solvers that take a scene)",
        )
        .input_multi("elements", "element", "the elements")
        .output("scene", "scene", "the scene"),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let scene: Scene = cx
                    .inputs("elements")?
                    .iter()
                    .filter_map(|v| v.get::<SceneElement>().cloned())
                    .collect();
                cx.set("scene", weft_graph::Value::new(scene));
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new(
            "scene.centroid",
            "the mean vertex position (and velocity) of one element of a scene, each vertex weighted alike or, for a mesh, by its share of the rest area (the centre of mass of a uniform sheet)",
        )
        .input("scene", "scene", "the scene")
        .output("centroid", "vec3", "mean position [m]")
        .output(
            "velocity",
            "vec3",
            "mean velocity [m/s] (its 'velocity' channel; zero without one)",
        )
        .param(ParamSpec::string("element", "cloth").doc("element name"))
        .param(
            ParamSpec::choice("weights", &["vertices", "area"], "vertices").doc(
                "vertices: every vertex alike; area (meshes): a third of the rest area of each \
                 of its triangles (the mass a uniform sheet lumps at it, so the centroid is the \
                 centre of mass as the solver sees it), from the 'rest' channel or else the \
                 current positions",
            ),
        ),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let scene = cx.input_as::<Scene>("scene")?;
                let e = element(cx, &scene)?;
                let p = e.geometry.positions();
                if p.is_empty() {
                    return Err(NodeError::Input {
                        port: "scene".into(),
                        message: format!("element '{}' has no vertices", e.name),
                    });
                }
                let w = match cx.params().str("weights")? {
                    "area" => {
                        let w = area_weights(e)?;
                        let total: f64 = w.iter().sum();
                        Some((w, total))
                    }
                    _ => None,
                };
                let mean = |values: &[[f64; 3]]| {
                    let mut c = [0.0; 3];
                    match &w {
                        Some((w, total)) => {
                            for (q, wq) in values.iter().zip(w) {
                                for k in 0..3 {
                                    c[k] += wq * q[k] / total;
                                }
                            }
                        }
                        None => {
                            for q in values {
                                for k in 0..3 {
                                    c[k] += q[k] / values.len() as f64;
                                }
                            }
                        }
                    }
                    c
                };
                cx.set("centroid", mean(p));
                let v = e
                    .vec3_channel("velocity")
                    .filter(|c| c.len() == p.len())
                    .map_or([0.0; 3], mean);
                cx.set("velocity", v);
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new(
            "scene.vertex",
            "the position of one vertex of one element of a scene",
        )
        .input("scene", "scene", "the scene")
        .output("position", "vec3", "position [m]")
        .param(ParamSpec::string("element", "cloth").doc("element name"))
        .param(
            ParamSpec::int("index", 0)
                .ge(0.0)
                .doc("vertex index within the element"),
        ),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let scene = cx.input_as::<Scene>("scene")?;
                let e = element(cx, &scene)?;
                let i = cx.params().i64("index")? as usize;
                let p = *e.geometry.positions().get(i).ok_or_else(|| {
                    NodeError::Failed(format!(
                        "param 'index': vertex {i} is out of range ('{}' has {} vertices)",
                        e.name,
                        e.vertex_count()
                    ))
                })?;
                cx.set("position", p);
                Ok(())
            }))
        },
    )
}

/// Per vertex of a mesh element, a third of the area of each of its triangles in the rest
/// shape (the 'rest' channel, else the current positions): the mass a uniform sheet lumps at
/// it, as the solver does.
fn area_weights(e: &SceneElement) -> Result<Vec<f64>, NodeError> {
    let bad = |message: String| NodeError::Input {
        port: "scene".into(),
        message,
    };
    let Geometry::Mesh(m) = &*e.geometry else {
        return Err(bad(format!(
            "weights 'area' needs a mesh: element '{}' has none",
            e.name
        )));
    };
    let rest = e
        .vec3_channel("rest")
        .filter(|r| r.len() == m.positions.len())
        .unwrap_or(&m.positions);
    let mut w = vec![0.0; rest.len()];
    for t in &m.triangles {
        let [a, b, c] = t.map(|v| rest.get(v as usize).copied());
        let (Some(a), Some(b), Some(c)) = (a, b, c) else {
            return Err(bad(format!(
                "element '{}': a triangle {t:?} names a vertex it does not have ({} vertices)",
                e.name,
                rest.len()
            )));
        };
        let (u, v) = (
            [b[0] - a[0], b[1] - a[1], b[2] - a[2]],
            [c[0] - a[0], c[1] - a[1], c[2] - a[2]],
        );
        let n = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        let third = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt() / 6.0;
        for k in t {
            w[*k as usize] += third;
        }
    }
    let total: f64 = w.iter().sum();
    if !(total.is_finite() && total > 0.0) {
        return Err(bad(format!(
            "weights 'area': element '{}' has no rest area (total {total})",
            e.name
        )));
    }
    Ok(w)
}

#[cfg(test)]
mod tests {
    use super::area_weights;
    use weft_scene::{Channel, ElementKind, Geometry, Mesh, SceneElement};

    /// A unit square split into a right triangle of area ½ and, beside it, a triangle of
    /// area ¼ (an L of three vertices and a far one): each vertex gets a third of its
    /// triangles' areas, from the rest shape when there is one.
    #[test]
    fn area_weights_are_a_third_of_the_rest_area_of_each_triangle() {
        let rest = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 0.5, 0.0],
        ];
        let mesh = Mesh {
            // Moved and stretched: the weights must not follow.
            positions: rest.iter().map(|p| [3.0 * p[0], p[1], 2.0]).collect(),
            triangles: vec![[0, 1, 2], [1, 3, 2]],
        };
        let mut e = SceneElement::new("sheet", ElementKind::Cloth, Geometry::Mesh(mesh));
        e.set_channel("rest", Channel::Vec3(rest.into()));
        let w = area_weights(&e).unwrap();
        // Triangle 2: (1,0), (1,0.5), (0,1): area ½ |(0,0.5) × (−1,1)| = ¼.
        let expect = [0.5 / 3.0, 0.75 / 3.0, 0.75 / 3.0, 0.25 / 3.0];
        for (a, b) in w.iter().zip(expect) {
            assert!((a - b).abs() < 1e-15, "{w:?}");
        }
        // Without a rest channel the current positions count (x stretched ×3).
        e.channels = Default::default();
        let w = area_weights(&e).unwrap();
        assert!((w.iter().sum::<f64>() - 3.0 * 0.75).abs() < 1e-14, "{w:?}");
        // Curves have no area.
        let hair = SceneElement::new("hair", ElementKind::Hair, Geometry::Points(vec![[0.0; 3]]));
        assert!(area_weights(&hair).is_err());
    }
}
