//! `scene.wrap`: a render mesh deformed by a simulated cloth (the proxy); and
//! `scene.interpolate_hair`: render hairs interpolated from simulated guide strands. Both for
//! output.

use super::types::Scene;
use weft_graph::{EvalCx, Kernel, NodeError, NodeSpec, ParamSpec, Registry, RegistryError, Value};
use weft_scene::{Curves, ElementKind, Geometry, Mesh, SceneElement};
use weft_sim::{HairWrap, Wrap};

/// The element named `name` (`what` it is for, in the error), else an error listing the
/// scene's elements.
fn driver<'a>(scene: &'a Scene, name: &str, what: &str) -> Result<&'a SceneElement, NodeError> {
    scene.iter().find(|e| e.name == name).ok_or_else(|| {
        let names: Vec<&str> = scene.iter().map(|e| e.name.as_str()).collect();
        NodeError::Input {
            port: "scene".into(),
            message: format!(
                "has no element '{name}' {what} (elements: {})",
                names.join(", ")
            ),
        }
    })
}

/// Refuses a name the scene already has.
fn fresh(scene: &Scene, name: &str) -> Result<(), NodeError> {
    if scene.iter().any(|e| e.name == name) {
        return Err(NodeError::Failed(format!(
            "param 'name': the scene already has an element '{name}'"
        )));
    }
    Ok(())
}

/// The binding's key: the structure upstream of both inputs and the driver's name.
fn key(cx: &mut EvalCx<'_>, driver: &str) -> Result<(u128, u128, String), NodeError> {
    Ok((
        cx.input_structure_hash("scene")?,
        cx.input_structure_hash("render")?,
        driver.to_string(),
    ))
}

/// Refuses a binding of `n` render vertices that would not fit in memory, before making it.
fn room(cx: &EvalCx<'_>, n: usize, name: &str) -> Result<(), NodeError> {
    weft_graph::memory::check_within(
        weft_graph::memory::product(&[n as u64, weft_sim::BYTES_PER_BOUND_VERTEX]),
        cx.memory_budget(),
        || format!("binding the {n} vertices of '{name}'"),
        "use a coarser render mesh or fewer render hairs",
    )?;
    Ok(())
}

/// A binding's error: interrupted (a stop was asked for) or what was wrong.
fn bind_error(cx: &EvalCx<'_>, e: String, name: &str, driver: &str) -> NodeError {
    if e == weft_sim::WRAP_STOPPED {
        NodeError::Interrupted(format!("{}: binding '{name}'", cx.interrupt().reason()))
    } else {
        NodeError::Failed(format!("binding '{name}' to '{driver}': {e}"))
    }
}

/// The driver's rest positions (its `rest` channel), else its current ones.
fn rest_of<'a>(e: &'a SceneElement, now: &'a [[f64; 3]]) -> &'a [[f64; 3]] {
    e.vec3_channel("rest")
        .filter(|r| r.len() == now.len())
        .unwrap_or(now)
}

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
        let (proxy_name, name) = (p.str("proxy")?, p.str("name")?);
        let proxy = driver(&scene, proxy_name, "to wrap")?;
        let Geometry::Mesh(now) = &*proxy.geometry else {
            return Err(NodeError::Input {
                port: "scene".into(),
                message: format!(
                    "element '{proxy_name}' is a {} without a triangle mesh: only cloth can carry a wrap",
                    proxy.kind.name()
                ),
            });
        };
        fresh(&scene, name)?;
        let key = key(cx, proxy_name)?;
        if self.binding.as_ref().is_none_or(|(k, _)| *k != key) {
            let rest = rest_of(proxy, &now.positions);
            room(cx, render.positions.len(), name)?;
            let stop = cx.interrupt().checker();
            let w = Wrap::bind(rest, &now.triangles, &render.positions, &*stop)
                .map_err(|e| bind_error(cx, e, name, proxy_name))?;
            self.binding = Some((key, w));
        }
        let (_, w) = self.binding.as_ref().expect("bound above");
        let mesh = Mesh {
            positions: w.apply(&now.positions, &now.triangles),
            triangles: render.triangles.clone(),
        };
        let mut out: Scene = scene.to_vec();
        out.push(SceneElement::new(
            name,
            ElementKind::Render,
            Geometry::Mesh(mesh),
        ));
        cx.set("scene", Value::new(out));
        Ok(())
    }
}

/// `scene.interpolate_hair`'s kernel: the binding, kept while the render curves and the
/// guides' rest shape stay the same.
struct HairNode {
    binding: Option<((u128, u128, String), HairWrap)>,
}

impl weft_graph::Compute for HairNode {
    fn compute(&mut self, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
        let scene = cx.input_as::<Scene>("scene")?;
        let render = cx.input_as::<Curves>("render")?;
        let p = cx.params().clone();
        let (guides_name, name) = (p.str("guides")?, p.str("name")?);
        let guides = driver(&scene, guides_name, "to take guide strands from")?;
        let Geometry::Curves(now) = &*guides.geometry else {
            return Err(NodeError::Input {
                port: "scene".into(),
                message: format!(
                    "element '{guides_name}' is a {} without curves: guides are hair",
                    guides.kind.name()
                ),
            });
        };
        fresh(&scene, name)?;
        let key = key(cx, guides_name)?;
        if self.binding.as_ref().is_none_or(|(k, _)| *k != key) {
            let rest = Curves {
                positions: rest_of(guides, &now.positions).to_vec(),
                offsets: now.offsets.clone(),
            };
            room(cx, render.positions.len(), name)?;
            let stop = cx.interrupt().checker();
            let w = HairWrap::bind(&rest, &render, &*stop)
                .map_err(|e| bind_error(cx, e, name, guides_name))?;
            self.binding = Some((key, w));
        }
        let (_, w) = self.binding.as_ref().expect("bound above");
        let curves = Curves {
            positions: w.apply(&now.positions),
            offsets: render.offsets.clone(),
        };
        let mut out: Scene = scene.to_vec();
        out.push(SceneElement::new(
            name,
            ElementKind::Render,
            Geometry::Curves(curves),
        ));
        cx.set("scene", Value::new(out));
        Ok(())
    }
}

pub(crate) fn register(r: &mut Registry) -> Result<(), RegistryError> {
    r.register(
        NodeSpec::new(
            "scene.interpolate_hair",
            "render hairs interpolated from simulated guide strands: bound once at rest (each render strand to the three guides whose roots are nearest, by its root's barycentric weights, and each vertex to the guides' points at the same fraction of their length plus an offset in their frame); the scene gains them as a render element",
        )
        .input("scene", "scene", "the simulated scene (the guides in it)")
        .input("render", "curves", "the render hairs, at the guides' rest pose")
        .output("scene", "scene", "the scene with the interpolated hairs added")
        .param(ParamSpec::string("guides", "hair").doc("name of the hair element whose strands guide them"))
        .param(ParamSpec::string("name", "render_hair").doc("name of the render element added")),
        |_| Ok(Kernel::Compute(Box::new(HairNode { binding: None }))),
    )?;
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
