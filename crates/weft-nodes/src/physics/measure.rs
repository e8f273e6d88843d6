//! Reading numbers out of a scene (for outputs, tests and charts).

use super::types::Scene;
use weft_graph::{EvalCx, Kernel, NodeError, NodeSpec, ParamSpec, Registry, RegistryError};
use weft_scene::SceneElement;

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
            "the mean vertex position (and velocity) of one element of a scene",
        )
        .input("scene", "scene", "the scene")
        .output("centroid", "vec3", "mean position [m]")
        .output(
            "velocity",
            "vec3",
            "mean velocity [m/s] (its 'velocity' channel; zero without one)",
        )
        .param(ParamSpec::string("element", "cloth").doc("element name")),
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
                let mut c = [0.0; 3];
                for q in p {
                    for k in 0..3 {
                        c[k] += q[k] / p.len() as f64;
                    }
                }
                cx.set("centroid", c);
                let mut v = [0.0; 3];
                if let Some(vel) = e.vec3_channel("velocity").filter(|c| c.len() == p.len()) {
                    for q in vel {
                        for k in 0..3 {
                            v[k] += q[k] / p.len() as f64;
                        }
                    }
                }
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
