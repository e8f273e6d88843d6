//! `scene.wrap`: a render mesh deformed by a simulated cloth (the proxy), for output.

use super::types::Scene;
use weft_graph::{EvalCx, Kernel, NodeError, NodeSpec, ParamSpec, Registry, RegistryError, Value};
use weft_scene::{ElementKind, Geometry, Mesh, SceneElement};
use weft_sim::Wrap;

/// The node's kernel: the binding, kept while the render mesh and the proxy's rest shape
/// (the structure upstream) stay the same.
struct WrapNode {
    binding: Option<((u128, u128, String), Wrap)>,
}

impl weft_graph::Compute for WrapNode {
    fn compute(&mut self, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
        let scene = cx.input_as::<Scene>("scene")?;
        let render = cx.input_as::<Mesh>("render")?;
        let p = cx.params().clone();
        let (proxy_name, name) = (p.str("proxy")?.to_string(), p.str("name")?.to_string());
        let input = |message: String| NodeError::Input {
            port: "scene".into(),
            message,
        };
        let Some(proxy) = scene.iter().find(|e| e.name == proxy_name) else {
            let names: Vec<&str> = scene.iter().map(|e| e.name.as_str()).collect();
            return Err(input(format!(
                "has no element '{proxy_name}' to wrap (elements: {})",
                names.join(", ")
            )));
        };
        let Geometry::Mesh(now) = &*proxy.geometry else {
            return Err(input(format!(
                "element '{proxy_name}' is a {} without a triangle mesh: only cloth can carry a wrap",
                proxy.kind.name()
            )));
        };
        if scene.iter().any(|e| e.name == name) {
            return Err(NodeError::Failed(format!(
                "param 'name': the scene already has an element '{name}'"
            )));
        }
        let key = (
            cx.input_structure_hash("scene")?,
            cx.input_structure_hash("render")?,
            proxy_name.clone(),
        );
        if self.binding.as_ref().is_none_or(|(k, _)| *k != key) {
            let rest = proxy
                .vec3_channel("rest")
                .filter(|r| r.len() == now.positions.len())
                .unwrap_or(&now.positions);
            let w = Wrap::bind(rest, &now.triangles, &render.positions).map_err(|e| {
                NodeError::Failed(format!("binding '{}' to '{proxy_name}': {e}", name))
            })?;
            self.binding = Some((key, w));
        }
        let (_, w) = self.binding.as_ref().expect("bound above");
        let mesh = Mesh {
            positions: w.apply(&now.positions, &now.triangles),
            triangles: render.triangles.clone(),
        };
        let mut out: Scene = scene.to_vec();
        out.push(SceneElement::new(
            &name,
            ElementKind::Render,
            Geometry::Mesh(mesh),
        ));
        cx.set("scene", Value::new(out));
        Ok(())
    }
}

pub(crate) fn register(r: &mut Registry) -> Result<(), RegistryError> {
    r.register(
        NodeSpec::new(
            "scene.wrap",
            "a render mesh deformed by a simulated cloth (the proxy): bound once at rest (each vertex to the proxy's closest point and its offset in that triangle's frame), it follows the proxy's triangles; the scene gains it as a render element (written and shown, never simulated)",
        )
        .input("scene", "scene", "the simulated scene (the proxy in it)")
        .input("render", "mesh", "the render mesh, at the proxy's rest pose")
        .output("scene", "scene", "the scene with the wrapped render mesh added")
        .param(ParamSpec::string("proxy", "cloth").doc("name of the cloth element that drives it"))
        .param(ParamSpec::string("name", "render").doc("name of the render element added")),
        |_| Ok(Kernel::Compute(Box::new(WrapNode { binding: None }))),
    )
}
