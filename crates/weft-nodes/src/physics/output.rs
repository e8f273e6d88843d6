//! Output nodes: OBJ sequences, a USD (.usda) file with time-sampled points, and PNG preview
//! frames. They write when pulled (at each frame `weft run` evaluates); every file is written
//! atomically, and the output value is the path written.

use super::types::Scene;
use std::path::{Path, PathBuf};
use weft_graph::{EvalCx, Kernel, NodeError, NodeSpec, ParamSpec, Registry, RegistryError};
use weft_scene::preview::{PreviewItem, auto_camera, render, write_png};
use weft_scene::{
    ElementKind, Geometry, SceneElement, UsdaScene, bounds, write_obj_curves, write_obj_mesh,
};

fn fail(path: &Path, e: impl std::fmt::Display) -> NodeError {
    NodeError::Failed(format!("cannot write {}: {e}", path.display()))
}

/// Elements with geometry, optionally restricted to a comma-separated list of names.
fn selected<'a>(scene: &'a Scene, names: &str) -> Vec<&'a SceneElement> {
    let wanted: Vec<&str> = names
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .collect();
    scene
        .iter()
        .filter(|e| !matches!(*e.geometry, Geometry::None))
        .filter(|e| wanted.is_empty() || wanted.contains(&e.name.as_str()))
        .collect()
}

fn obj(cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
    let scene = cx.input_as::<Scene>("scene")?;
    let dir = PathBuf::from(cx.params().str("directory"));
    let frame = cx.frame();
    for e in selected(&scene, cx.params().str("elements")) {
        let path = dir.join(format!("{}.{frame:04}.obj", e.name));
        let r = weft_graph::atomic_write_with(&path, |w| match &*e.geometry {
            Geometry::Mesh(m) => write_obj_mesh(m, &mut &mut *w),
            Geometry::Curves(c) => write_obj_curves(c, &mut &mut *w),
            _ => Ok(()),
        });
        r.map_err(|err| fail(&path, err))?;
    }
    cx.set("path", dir.display().to_string());
    Ok(())
}

/// Accumulates frames of one scene into a .usda file, rewritten after every frame.
struct UsdOut {
    scene: Option<(UsdaScene, Vec<String>)>,
    /// Identity of the upstream definition the samples came from: a change upstream makes
    /// every earlier sample stale, so the file starts over.
    upstream: u128,
}

impl weft_graph::Compute for UsdOut {
    fn compute(&mut self, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
        let scene = cx.input_as::<Scene>("scene")?;
        let path = PathBuf::from(cx.params().str("path"));
        let elements = selected(&scene, cx.params().str("elements"));
        let names: Vec<String> = elements.iter().map(|e| e.name.clone()).collect();
        let upstream = cx.input_structure_hash("scene")?;
        let fresh = upstream != self.upstream
            || self
                .scene
                .as_ref()
                .is_none_or(|(s, n)| *n != names || s.fps() != cx.context().fps);
        self.upstream = upstream;
        if fresh {
            let mut u = UsdaScene::new(cx.context().fps).map_err(|e| fail(&path, e))?;
            for e in &elements {
                match &*e.geometry {
                    Geometry::Mesh(m) => u.add_mesh(&e.name, m),
                    Geometry::Curves(c) => u.add_curves(&e.name, c, None),
                    Geometry::Points(_) | Geometry::None => continue,
                }
                .map_err(|err| fail(&path, err))?;
            }
            self.scene = Some((u, names));
        }
        let (u, _) = self.scene.as_mut().expect("built above");
        let positions: Vec<&[[f64; 3]]> = elements
            .iter()
            .filter(|e| matches!(*e.geometry, Geometry::Mesh(_) | Geometry::Curves(_)))
            .map(|e| e.geometry.positions())
            .collect();
        u.add_frame(cx.frame(), &positions)
            .map_err(|e| fail(&path, e))?;
        weft_graph::atomic_write(&path, u.to_string().as_bytes()).map_err(|e| fail(&path, e))?;
        cx.set("path", path.display().to_string());
        Ok(())
    }
}

fn color(kind: ElementKind) -> [u8; 3] {
    match kind {
        ElementKind::Cloth => [214, 120, 66],
        ElementKind::Hair => [96, 62, 36],
        _ => [170, 172, 178],
    }
}

fn preview(cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
    let scene = cx.input_as::<Scene>("scene")?;
    let p = cx.params().clone();
    let (w, h) = (p.i64("width") as u32, p.i64("height") as u32);
    let elements = selected(&scene, p.str("elements"));
    let items: Vec<PreviewItem<'_>> = elements
        .iter()
        .filter_map(|e| match &*e.geometry {
            Geometry::Mesh(m) => Some(PreviewItem::Mesh(m, color(e.kind))),
            Geometry::Curves(c) => Some(PreviewItem::Curves(c, color(e.kind))),
            _ => None,
        })
        .collect();
    // The camera frames the elements' rest shapes (their `rest` channels, else their current
    // positions) grown by `margin`: fixed over the shot, so frames do not jitter, and the
    // same whichever frame is rendered first.
    let rest: Vec<[f64; 3]> = elements
        .iter()
        .flat_map(|e| {
            e.vec3_channel("rest")
                .unwrap_or(e.geometry.positions())
                .iter()
                .copied()
        })
        .collect();
    let cam = match bounds(&rest) {
        Some((lo, hi)) => {
            let m = p.f64("margin");
            let c: Vec<f64> = (0..3).map(|k| 0.5 * (lo[k] + hi[k])).collect();
            let half: Vec<f64> = (0..3)
                .map(|k| 0.5 * (hi[k] - lo[k]).max(1e-3) * m)
                .collect();
            auto_camera(
                (
                    [c[0] - half[0], c[1] - half[1], c[2] - half[2]],
                    [c[0] + half[0], c[1] + half[1], c[2] + half[2]],
                ),
                w as f64 / h as f64,
            )
        }
        None => auto_camera(([-1.0; 3], [1.0; 3]), w as f64 / h as f64),
    };
    let image = render(&items, &cam, w, h);
    let path = PathBuf::from(p.str("directory")).join(format!(
        "{}.{:04}.png",
        p.str("prefix"),
        cx.frame()
    ));
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| fail(dir, e))?;
    }
    write_png(&image, &path).map_err(|e| fail(&path, e))?;
    cx.set("path", path.display().to_string());
    Ok(())
}

pub(crate) fn register(r: &mut Registry) -> Result<(), RegistryError> {
    let elements = || {
        ParamSpec::string("elements", "")
            .doc("comma-separated element names (empty: every element with geometry)")
    };
    r.register(
        NodeSpec::new("output.obj", "writes each element's geometry at each frame as DIRECTORY/NAME.FRAME.obj (curves as polylines)")
            .input("scene", "scene", "the scene to write")
            .output("path", "string", "the directory written to")
            .param(ParamSpec::string("directory", "out/obj").doc("output directory (relative to the working directory)"))
            .param(elements()),
        |_| Ok(Kernel::from_fn(obj)),
    )?;
    r.register(
        NodeSpec::new("output.usd", "writes a .usda file with time-sampled points: Mesh prims for cloth and colliders, BasisCurves for hair")
            .input("scene", "scene", "the scene to write")
            .output("path", "string", "the file written")
            .param(ParamSpec::string("path", "out/scene.usda").doc("output file (rewritten with all frames so far after each frame)"))
            .param(elements()),
        |_| Ok(Kernel::Compute(Box::new(UsdOut { scene: None, upstream: 0 }))),
    )?;
    r.register(
        NodeSpec::new("output.preview", "renders each frame to DIRECTORY/PREFIX.FRAME.png (software renderer, camera framing the rest shapes)")
            .input("scene", "scene", "the scene to draw")
            .output("path", "string", "the image written")
            .param(ParamSpec::string("directory", "out/preview").doc("output directory (relative to the working directory)"))
            .param(ParamSpec::string("prefix", "frame").doc("file name prefix"))
            .param(ParamSpec::int("width", 640).ge(16.0).le(8192.0).doc("image width [px]"))
            .param(ParamSpec::int("height", 480).ge(16.0).le(8192.0).doc("image height [px]"))
            .param(ParamSpec::float("margin", 2.0).gt(0.0).doc("how much larger than the rest shapes the view is"))
            .param(elements()),
        |_| Ok(Kernel::from_fn(preview)),
    )?;
    Ok(())
}
