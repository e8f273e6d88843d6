//! Output nodes: OBJ sequences, a USD (.usda) file with time-sampled points, and PNG preview
//! frames. They write when pulled (at each frame `weft run` evaluates); every file is written
//! atomically, and the output value is the path written.

use super::coupled::CoupledState;
use super::types::Scene;
use std::path::{Path, PathBuf};
use weft_graph::{EvalCx, Kernel, NodeError, NodeSpec, ParamSpec, Registry, RegistryError};
use weft_scene::preview::{Image, PreviewItem, auto_camera, encode_png, render};
use weft_scene::usd::ClipSet;
use weft_scene::{
    ElementKind, Geometry, Rod, SceneElement, UsdaScene, VolumeField, bounds, write_obj_curves,
    write_obj_mesh,
};

pub(super) fn fail(path: &Path, e: impl std::fmt::Display) -> NodeError {
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
    let dir = cx.output_path("directory")?;
    let frame = cx.frame();
    for e in selected(&scene, cx.params().str("elements")?) {
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
    scene: Option<UsdFile>,
    /// Identity of the upstream definition the samples came from: a change upstream makes
    /// every earlier sample stale, so the file starts over.
    upstream: u128,
}

/// The file being built: the scene, the element names its point prims came from (in order),
/// and the volume prim of the `fields` input with its grid names.
struct UsdFile {
    usd: UsdaScene,
    names: Vec<String>,
    prims: Vec<weft_scene::usd::PrimId>,
    volume: Option<(weft_scene::usd::PrimId, Vec<String>)>,
    /// Per prim without the solver's velocities (a collider), the last frame written and its
    /// positions, from which its velocity over the next frame follows.
    last: Vec<Option<(i64, Vec<[f64; 3]>)>>,
    /// The frames' clips written so far, as the root lists them.
    clips: ClipSet,
    /// Whether the clips' directory and manifest are on disk for these prims.
    manifest: bool,
}

/// `target` relative to the directory `base`, with `/` separators, as USD asset paths want
/// (USD resolves them against the layer's directory). Both are made absolute against the
/// working directory and normalized lexically (`.` dropped, `..` applied) first, so
/// `./scene.usda` beside `fields/x.vdb` gives `./fields/x.vdb`.
fn relative_path(base: &Path, target: &Path) -> String {
    use std::path::Component;
    let absolute = |p: &Path| -> Vec<String> {
        let p = if p.is_absolute() {
            p.to_path_buf()
        } else {
            std::env::current_dir().unwrap_or_default().join(p)
        };
        let mut parts: Vec<String> = Vec::new();
        for c in p.components() {
            match c {
                Component::CurDir | Component::RootDir | Component::Prefix(_) => {}
                Component::ParentDir => {
                    parts.pop();
                }
                Component::Normal(n) => parts.push(n.to_string_lossy().into_owned()),
            }
        }
        parts
    };
    let (b, t) = (absolute(base), absolute(target));
    let common = b.iter().zip(&t).take_while(|(x, y)| x == y).count();
    let mut parts: Vec<String> = vec!["..".to_string(); b.len() - common];
    parts.extend(t[common..].iter().cloned());
    if parts.first().is_none_or(|p| p != "..") {
        parts.insert(0, ".".into());
    }
    parts.join("/")
}

/// A world box: minimum and maximum corners [m].
type Extent = [[f64; 3]; 2];

/// The volume fields a VDB file holds, as USD wants them described, and the box they cover.
fn volume_fields(file: &Path) -> Result<(Vec<VolumeField>, Option<Extent>), NodeError> {
    let bytes = std::fs::read(file).map_err(|e| {
        NodeError::Failed(format!(
            "input 'fields': cannot read {}: {e}",
            file.display()
        ))
    })?;
    let info = weft_scene::vdb::describe(&bytes)
        .map_err(|e| NodeError::Failed(format!("input 'fields': {}: {e}", file.display())))?;
    let mut extent: Option<Extent> = None;
    let mut fields = Vec::new();
    for g in info {
        let vector = g.tree_type.starts_with("Tree_vec3");
        if let Some(e) = g.extent {
            extent = Some(match extent {
                None => e,
                Some(x) => [
                    std::array::from_fn(|k| x[0][k].min(e[0][k])),
                    std::array::from_fn(|k| x[1][k].max(e[1][k])),
                ],
            });
        }
        fields.push(VolumeField {
            data_type: if vector { "float3" } else { "float" },
            role: (vector && g.name.starts_with("vel")).then_some("Vector"),
            name: weft_scene::usd::sanitize_identifier(&g.name),
        });
    }
    Ok((fields, extent))
}

impl weft_graph::Compute for UsdOut {
    fn compute(&mut self, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
        let scene = cx.input_as::<Scene>("scene")?;
        let path = cx.output_path("path")?;
        let elements = selected(&scene, cx.params().str("elements")?);
        let elements: Vec<&SceneElement> = elements
            .into_iter()
            .filter(|e| matches!(*e.geometry, Geometry::Mesh(_) | Geometry::Curves(_)))
            .collect();
        let names: Vec<String> = elements.iter().map(|e| e.name.clone()).collect();
        let fields = match cx.input_opt("fields")? {
            Some(v) => Some(PathBuf::from(v.get::<String>().ok_or_else(|| {
                NodeError::Failed("input 'fields': not a path".into())
            })?)),
            None => None,
        };
        // This frame's file, read once: its grids (for a new volume) and its extent.
        let described = fields.as_deref().map(volume_fields).transpose()?;
        let mut upstream = cx.input_structure_hash("scene")?;
        if fields.is_some() {
            upstream ^= cx.input_structure_hash("fields")?.rotate_left(1);
        }
        let fresh = upstream != self.upstream
            || self.scene.as_ref().is_none_or(|f| {
                f.names != names
                    || f.usd.fps() != cx.context().fps
                    || f.volume.is_some() != fields.is_some()
            });
        self.upstream = upstream;
        // Each frame's points go to their own clip beside the root, `STEM.clips/STEM.FRAME.usda`
        // (see `UsdaScene::write_clip_root` for why), named in the root between `@`s.
        let stem = path
            .file_stem()
            .and_then(|s| s.to_str())
            .filter(|s| !s.is_empty() && !s.contains('@') && !s.chars().any(char::is_control))
            .ok_or_else(|| {
                NodeError::Failed(format!(
                    "param 'path': {}: a USD file needs a UTF-8 name without '@' or control characters (its clips are named after it, between '@'s)",
                    path.display()
                ))
            })?
            .to_string();
        let clip_dir = path.with_file_name(format!("{stem}.clips"));
        // The clips of the frames an upstream change made stale, removed once the root no
        // longer lists them.
        let mut stale: Vec<i64> = Vec::new();
        if fresh {
            if let Some(old) = &self.scene {
                stale.extend(old.clips.frames.keys());
            }
            let mut usd = UsdaScene::new(cx.context().fps).map_err(|e| fail(&path, e))?;
            let mut prims = Vec::new();
            for e in &elements {
                let id = match &*e.geometry {
                    Geometry::Mesh(m) => usd.add_mesh(&e.name, m),
                    Geometry::Curves(c) => {
                        // Renderers draw a strand 2r wide, r from its Rod SEC.
                        let width = e.secs.get::<Rod>().map(|r| [2.0 * r.radius]);
                        usd.add_curves(&e.name, c, width.as_ref().map(|w| &w[..]))
                    }
                    Geometry::Points(_) | Geometry::None => continue,
                }
                .map_err(|err| fail(&path, err))?;
                prims.push(id);
            }
            let volume = match (&fields, &described) {
                (Some(file), Some((f, _))) => {
                    let stem = file
                        .file_name()
                        .and_then(|n| n.to_str())
                        .and_then(|n| n.split('.').next())
                        .unwrap_or("fields");
                    let id = usd.add_volume(stem, f).map_err(|e| fail(&path, e))?;
                    Some((id, f.iter().map(|f| f.name.clone()).collect()))
                }
                _ => None,
            };
            let last = vec![None; prims.len()];
            self.scene = Some(UsdFile {
                usd,
                names,
                prims,
                volume,
                last,
                clips: ClipSet {
                    manifest: format!("./{stem}.clips/manifest.usda"),
                    frames: Default::default(),
                },
                manifest: false,
            });
        }
        let file = self.scene.as_mut().expect("built above");
        let frame = cx.frame();
        let fps = cx.context().fps;
        for ((e, &id), last) in elements.iter().zip(&file.prims).zip(&mut file.last) {
            let x = e.geometry.positions();
            file.usd
                .set_points(id, frame, x)
                .map_err(|err| fail(&path, err))?;
            // Simulated elements carry the solver's velocities as a channel. Colliders and
            // other kinematic elements move by their animation: they get their mean velocity
            // over the frame that ends here, (x_f − x_{f−1})·fps (zero at the first frame
            // written), which is what motion blur over that frame needs.
            // Only kinematic elements keep their last positions.
            let derived: Vec<[f64; 3]>;
            let v: &[[f64; 3]] = match e.vec3_channel("velocity") {
                Some(v) if v.len() == x.len() => v,
                _ => {
                    derived = match last {
                        Some((f, prev)) if *f == frame - 1 && prev.len() == x.len() => x
                            .iter()
                            .zip(prev.iter())
                            .map(|(a, b)| std::array::from_fn(|k| (a[k] - b[k]) * fps))
                            .collect(),
                        _ => vec![[0.0; 3]; x.len()],
                    };
                    *last = Some((frame, x.to_vec()));
                    &derived
                }
            };
            file.usd
                .set_velocities(id, frame, v)
                .map_err(|err| fail(&path, err))?;
        }
        if let (Some(vdb), Some((f, extent)), Some((id, names))) =
            (&fields, &described, &file.volume)
        {
            let now: Vec<String> = f.iter().map(|f| f.name.clone()).collect();
            if &now != names {
                return Err(NodeError::Failed(format!(
                    "input 'fields': {} holds grids {now:?}, earlier frames {names:?}; a volume keeps its fields",
                    vdb.display()
                )));
            }
            let base = path.parent().unwrap_or(Path::new("."));
            let asset = relative_path(base, vdb);
            file.usd
                .set_volume_file(*id, frame, &asset, *extent)
                .map_err(|err| fail(&path, err))?;
        }
        // The frame's clip (and the manifest once), then the root that lists it: each file
        // whole on disk at every moment, and the root never names a clip not yet written.
        if !file.manifest {
            std::fs::create_dir_all(&clip_dir).map_err(|e| fail(&clip_dir, e))?;
            let manifest = clip_dir.join("manifest.usda");
            weft_graph::atomic_write_with(&manifest, |w| file.usd.write_manifest(&mut &mut *w))
                .map_err(|e| fail(&manifest, e))?;
            file.manifest = true;
        }
        let name = clip_name(&stem, frame);
        let clip = clip_dir.join(&name);
        weft_graph::atomic_write_with(&clip, |w| file.usd.write_clip(frame, &mut &mut *w))
            .map_err(|e| fail(&clip, e))?;
        file.clips
            .frames
            .insert(frame, format!("./{stem}.clips/{name}"));
        file.usd.forget_point_samples();
        weft_graph::atomic_write_with(&path, |w| {
            file.usd.write_clip_root(&file.clips, &mut &mut *w)
        })
        .map_err(|e| fail(&path, e))?;
        for old in stale {
            if !file.clips.frames.contains_key(&old) {
                // Best effort: an unlisted clip left behind changes nothing the root shows.
                let _ = std::fs::remove_file(clip_dir.join(clip_name(&stem, old)));
            }
        }
        cx.set("path", path.display().to_string());
        Ok(())
    }
}

/// A frame's clip file: `STEM.FRAME.usda`, the frame zero-padded to four digits as the OBJ
/// and preview sequences are.
fn clip_name(stem: &str, frame: i64) -> String {
    format!("{stem}.{frame:04}.usda")
}

/// A file name prefix as a parameter gives it: non-empty, no directory parts.
pub(super) fn file_prefix(prefix: &str) -> Result<&str, NodeError> {
    if prefix.is_empty() || prefix.contains(['/', '\\']) || prefix.contains("..") {
        return Err(NodeError::Failed(format!(
            "param 'prefix': must be a non-empty file name prefix without '/', '\\' or '..', got {prefix:?}"
        )));
    }
    Ok(prefix)
}

fn color(kind: ElementKind) -> [u8; 3] {
    match kind {
        ElementKind::Cloth => [214, 120, 66],
        ElementKind::Hair => [96, 62, 36],
        // A wrapped render mesh stands for the cloth it follows, in a lighter tone.
        ElementKind::Render => [226, 160, 110],
        _ => [170, 172, 178],
    }
}

/// Speed → colour: dark blue (still) through teal and green to yellow (`speed_scale`).
fn speed_colour(t: f64) -> [u8; 3] {
    const STOPS: [(f64, [f64; 3]); 4] = [
        (0.0, [20.0, 30.0, 90.0]),
        (0.35, [30.0, 120.0, 180.0]),
        (0.65, [90.0, 200.0, 140.0]),
        (1.0, [250.0, 230.0, 90.0]),
    ];
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        1.0
    };
    let k = STOPS.iter().position(|s| s.0 >= t).unwrap_or(3).max(1);
    let ((t0, a), (t1, b)) = (STOPS[k - 1], STOPS[k]);
    let s = (t - t0) / (t1 - t0);
    [0, 1, 2].map(|c| (a[c] + s * (b[c] - a[c])).round() as u8)
}

/// A slice of fluid speed through the domain, normal to `slice_axis` at `slice_at` (a
/// fraction of the domain), `height` pixels tall, with the elements' vertices projected onto
/// it as dark dots.
fn fluid_panel(
    grid: &weft_fluid::MacGrid,
    elements: &[&SceneElement],
    p: &weft_graph::Params,
    flow: [f64; 3],
    height: u32,
) -> Result<Image, NodeError> {
    let d = &grid.domain;
    let size = d.size();
    let n = match p.str("slice_axis")? {
        "x" => 0,
        "y" => 1,
        _ => 2,
    };
    // In-plane axes (horizontal, vertical): looking along −z, down −y, or along −x.
    let (a, b) = match n {
        0 => (2, 1),
        1 => (0, 2),
        _ => (0, 1),
    };
    let h = height;
    let w = ((h as f64 * size[a] / size[b]).round() as u32).clamp(16, 4 * h);
    let at = d.origin[n] + p.f64("slice_at")?.clamp(0.0, 1.0) * size[n];
    let mut speeds = vec![0.0; (w * h) as usize];
    for py in 0..h {
        for px in 0..w {
            let mut q = [0.0; 3];
            q[n] = at;
            q[a] = d.origin[a] + (px as f64 + 0.5) / w as f64 * size[a];
            q[b] = d.origin[b] + (1.0 - (py as f64 + 0.5) / h as f64) * size[b];
            let u = grid.velocity_at(q);
            speeds[(py * w + px) as usize] = (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt();
        }
    }
    let wind = (flow[0] * flow[0] + flow[1] * flow[1] + flow[2] * flow[2]).sqrt();
    let scale = match p.f64("speed_scale")? {
        s if s > 0.0 => s,
        _ if wind > 0.0 => 1.5 * wind,
        _ => speeds.iter().cloned().fold(1e-12, f64::max),
    };
    let mut rgb = Vec::with_capacity((w * h * 3) as usize);
    for s in &speeds {
        rgb.extend(speed_colour(s / scale));
    }
    let mut img = Image {
        width: w,
        height: h,
        rgb,
    };
    for e in elements {
        let c = match e.kind {
            ElementKind::Cloth => [110, 40, 10],
            ElementKind::Hair => [35, 20, 10],
            _ => [80, 80, 84],
        };
        for v in e.geometry.positions() {
            let px = ((v[a] - d.origin[a]) / size[a] * w as f64).floor();
            let py = ((1.0 - (v[b] - d.origin[b]) / size[b]) * h as f64).floor();
            for (dx, dy) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
                let (x, y) = (px + dx, py + dy);
                if x >= 0.0 && y >= 0.0 && x < w as f64 && y < h as f64 {
                    let i = ((y as u32 * w + x as u32) * 3) as usize;
                    img.rgb[i..i + 3].copy_from_slice(&c);
                }
            }
        }
    }
    Ok(img)
}

/// Two images of the same height, left and right, with a 2-pixel white rule between.
fn side_by_side(l: &Image, r: &Image) -> Image {
    let h = l.height.min(r.height);
    let w = l.width + 2 + r.width;
    let mut rgb = Vec::with_capacity((w * h * 3) as usize);
    for y in 0..h as usize {
        let row = |img: &Image| {
            let s = y * img.width as usize * 3;
            img.rgb[s..s + img.width as usize * 3].to_vec()
        };
        rgb.extend(row(l));
        rgb.extend([255u8; 6]);
        rgb.extend(row(r));
    }
    Image {
        width: w,
        height: h,
        rgb,
    }
}

/// The first element vertex that is not finite: nothing non-finite is drawn into a file.
fn non_finite(elements: &[&SceneElement]) -> Result<(), NodeError> {
    for e in elements {
        if let Some(i) = e
            .geometry
            .positions()
            .iter()
            .position(|p| !p.iter().all(|c| c.is_finite()))
        {
            return Err(NodeError::Failed(format!(
                "element '{}': vertex {i} is not finite ({:?}); nothing was written",
                e.name,
                e.geometry.positions()[i]
            )));
        }
    }
    Ok(())
}

fn preview(cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
    let scene = cx.input_as::<Scene>("scene")?;
    let p = cx.params().clone();
    let (w, h) = (p.usize("width")? as u32, p.usize("height")? as u32);
    let prefix = file_prefix(p.str("prefix")?)?;
    // The render (colour, depth), a fluid panel up to four times as wide with its speeds,
    // and the two side by side: about 40 bytes a pixel of the tallest layout.
    let need = weft_graph::memory::product(&[w as u64 * 5, h as u64, 40]);
    weft_graph::memory::check_within(
        need,
        cx.memory_budget(),
        || format!("a {w} × {h} preview"),
        "lower width or height",
    )?;
    let elements = selected(&scene, p.str("elements")?);
    non_finite(&elements)?;
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
            let m = p.f64("margin")?;
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
    let mut image = render(&items, &cam, w, h);
    if let Some(v) = cx.input_opt("fluid")?
        && let Some(state) = v.get::<CoupledState>()
        && let Some(grid) = &state.fluid
    {
        let flow = state.compiled.fluid.as_ref().map_or([0.0; 3], |f| f.flow);
        let panel = fluid_panel(grid, &elements, &p, flow, h)?;
        image = side_by_side(&image, &panel);
    }
    let path = cx
        .output_path("directory")?
        .join(format!("{prefix}.{:04}.png", cx.frame()));
    weft_graph::atomic_write_with(&path, |w| {
        encode_png(&image, &path, &mut &mut *w).map_err(std::io::Error::other)
    })
    .map_err(|e| fail(&path, e))?;
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
            .param(ParamSpec::string("directory", "out/obj").doc("output directory (under --out when given, else the working directory)"))
            .param(elements()),
        |_| Ok(Kernel::from_fn(obj)),
    )?;
    r.register(
        NodeSpec::new("output.usd", "writes a .usda stage with time-sampled points (each frame a value clip beside the root, STEM.clips/STEM.FRAME.usda): Mesh prims for cloth and colliders, BasisCurves for hair (widths 2r from the Rod SEC), velocities on every prim (the solver's for simulated elements; for colliders their mean velocity over the frame, (x_f − x_{f−1})·fps), and with 'fields' connected a Volume of the fluid's OpenVDB files")
            .input("scene", "scene", "the scene to write")
            .input_default("fields", "string", serde_json::json!(null), "the path of this frame's .vdb file (output.vdb's path): adds a Volume prim named after the files' prefix, one OpenVDBAsset per grid, its filePath time-sampled (relative to the .usda)")
            .output("path", "string", "the file written")
            .param(ParamSpec::string("path", "out/scene.usda").doc("the root layer (under --out when given, else the working directory), rewritten after each frame: the topology, and value clips naming each frame's points, written once to STEM.clips/STEM.FRAME.usda beside it"))
            .param(elements()),
        |_| Ok(Kernel::Compute(Box::new(UsdOut { scene: None, upstream: 0 }))),
    )?;
    r.register(
        NodeSpec::new("output.preview", "renders each frame to DIRECTORY/PREFIX.FRAME.png (software renderer, camera framing the rest shapes); with a coupled state on 'fluid', a slice of fluid speed beside it")
            .input("scene", "scene", "the scene to draw")
            .input_default("fluid", "coupled", serde_json::json!(null), "a coupled solver state: adds a panel with a slice of fluid speed (dark blue still, yellow at speed_scale) and the solids' vertices projected on it")
            .output("path", "string", "the image written")
            .param(ParamSpec::string("directory", "out/preview").doc("output directory (under --out when given, else the working directory)"))
            .param(ParamSpec::string("prefix", "frame").doc("file name prefix"))
            .param(ParamSpec::int("width", 640).ge(16.0).le(8192.0).doc("image width [px]"))
            .param(ParamSpec::int("height", 480).ge(16.0).le(8192.0).doc("image height [px]"))
            .param(ParamSpec::float("margin", 2.0).gt(0.0).doc("how much larger than the rest shapes the view is"))
            .param(ParamSpec::choice("slice_axis", &["x", "y", "z"], "z").doc("fluid panel: the slice's normal"))
            .param(ParamSpec::float("slice_at", 0.5).ge(0.0).le(1.0).doc("fluid panel: where the slice cuts the domain along its normal (fraction)"))
            .param(ParamSpec::float("speed_scale", 0.0).ge(0.0).unit("m/s").doc("fluid panel: the speed drawn yellow; 0: 1.5 × the domain's flow (or the largest speed when there is none)"))
            .param(elements()),
        |_| Ok(Kernel::from_fn(preview)),
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::relative_path;
    use std::path::Path;

    #[test]
    fn asset_paths_are_relative_to_the_layer() {
        let cwd = std::env::current_dir().unwrap();
        assert_eq!(
            relative_path(Path::new("."), Path::new("fields/x.vdb")),
            "./fields/x.vdb"
        );
        assert_eq!(
            relative_path(Path::new("./out"), Path::new("out/f/x.vdb")),
            "./f/x.vdb"
        );
        assert_eq!(
            relative_path(Path::new("a/b"), Path::new("a/c/x.vdb")),
            "../c/x.vdb"
        );
        // A `..` in the base is applied, not undone by another.
        let up = relative_path(Path::new("../s"), Path::new("out/x.vdb"));
        let want = format!(
            "../{}/out/x.vdb",
            cwd.file_name().unwrap().to_string_lossy()
        );
        assert_eq!(up, want);
        // Absolute against relative: both resolved against the working directory.
        assert_eq!(
            relative_path(&cwd.join("r"), Path::new("r/x.vdb")),
            "./x.vdb"
        );
    }
}
