//! Geometry nodes: procedural meshes and strands, OBJ files.

use weft_graph::memory::{check_within, product};
use weft_graph::{Kernel, NodeError, NodeSpec, ParamSpec, Registry, RegistryError, Value};

/// Bytes a mesh of `v` vertices and `t` triangles holds once wrapped into an element: its
/// positions, the element's rest channel (a copy) and the triangles.
fn mesh_bytes(v: u64, t: u64) -> u64 {
    product(&[v, 48]).saturating_add(product(&[t, 12]))
}

/// Refuses a mesh or curve set that would not fit, or whose vertices a u32 cannot index.
fn check_size(
    cx: &weft_graph::EvalCx<'_>,
    vertices: u64,
    bytes: u64,
    what: impl Fn() -> String,
    hint: &str,
) -> Result<(), NodeError> {
    if vertices > u32::MAX as u64 {
        return Err(NodeError::Failed(format!(
            "{} makes {vertices} vertices, more than the 4294967295 a mesh or curve set can index; {hint}",
            what()
        )));
    }
    check_within(bytes, cx.memory_budget(), what, hint)?;
    Ok(())
}
use weft_scene::Curves;
use weft_scene::procedural::{Plane, grid, sphere, strands_on_sphere};

pub(crate) fn register(r: &mut Registry) -> Result<(), RegistryError> {
    r.register(
        NodeSpec::new(
            "geo.grid",
            "a rectangular cloth grid with alternating diagonals",
        )
        .output("mesh", "mesh", "the grid")
        .param(
            ParamSpec::float("width", 1.0)
                .gt(0.0)
                .unit("m")
                .doc("extent along x"),
        )
        .param(
            ParamSpec::float("height", 1.0)
                .gt(0.0)
                .unit("m")
                .doc("extent along z (plane xz) or y (plane xy)"),
        )
        .param(
            ParamSpec::int("nx", 16)
                .ge(2.0)
                .le(4096.0)
                .doc("vertices along the width"),
        )
        .param(
            ParamSpec::int("ny", 16)
                .ge(2.0)
                .le(4096.0)
                .doc("vertices along the height"),
        )
        .param(ParamSpec::choice("plane", &["xz", "xy"], "xz").doc("xz: horizontal; xy: vertical"))
        .param(
            ParamSpec::vec3("center", [0.0; 3])
                .unit("m")
                .doc("centre of the grid"),
        ),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let p = cx.params().clone();
                let (nx, ny) = (p.usize("nx")?, p.usize("ny")?);
                let (v, t) = (
                    product(&[nx as u64, ny as u64]),
                    product(&[2, nx as u64 - 1, ny as u64 - 1]),
                );
                check_size(
                    cx,
                    v,
                    mesh_bytes(v, t),
                    || format!("nx × ny = {nx} × {ny} vertices"),
                    "lower nx or ny",
                )?;
                let plane = if p.str("plane")? == "xy" {
                    Plane::Xy
                } else {
                    Plane::Xz
                };
                let m = grid(
                    [p.f64("width")?, p.f64("height")?],
                    [nx, ny],
                    plane,
                    p.vec3("center")?,
                );
                cx.set("mesh", Value::new(m));
                Ok(())
            }))
        },
    )?;
    let mut cuboid = NodeSpec::new(
        "geo.box",
        "a closed box mesh, 12 triangles with outward normals (tables, steps, colliders)",
    )
    .output("mesh", "mesh", "the box")
    .param(ParamSpec::vec3("center", [0.0; 3]).unit("m").doc("centre"));
    for (name, doc) in [
        ("width", "extent along x"),
        ("height", "extent along y"),
        ("depth", "extent along z"),
    ] {
        cuboid = cuboid.param(ParamSpec::float(name, 1.0).gt(0.0).unit("m").doc(doc));
    }
    r.register(cuboid, |_| {
        Ok(Kernel::from_fn(|cx| {
            let p = cx.params();
            let size = [p.f64("width")?, p.f64("height")?, p.f64("depth")?];
            let m = weft_scene::procedural::cuboid(p.vec3("center")?, size);
            cx.set("mesh", Value::new(m));
            Ok(())
        }))
    })?;
    r.register(
        NodeSpec::new("geo.sphere", "a UV sphere mesh (heads, colliders, display)")
            .output("mesh", "mesh", "the sphere")
            .param(ParamSpec::vec3("center", [0.0; 3]).unit("m").doc("centre"))
            .param(
                ParamSpec::float("radius", 0.1)
                    .gt(0.0)
                    .unit("m")
                    .doc("radius"),
            )
            .param(
                ParamSpec::int("rings", 16)
                    .ge(2.0)
                    .le(1024.0)
                    .doc("latitude bands"),
            )
            .param(
                ParamSpec::int("sectors", 24)
                    .ge(3.0)
                    .le(1024.0)
                    .doc("longitude bands"),
            ),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let p = cx.params().clone();
                let (rings, sectors) = (p.usize("rings")?, p.usize("sectors")?);
                let v = product(&[rings as u64, sectors as u64]);
                check_size(
                    cx,
                    v,
                    mesh_bytes(v, 2 * v),
                    || format!("rings × sectors = {rings} × {sectors}"),
                    "lower rings or sectors",
                )?;
                let m = sphere(p.vec3("center")?, p.f64("radius")?, rings, sectors);
                cx.set("mesh", Value::new(m));
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new(
            "geo.strands",
            "straight strands grown along the normals of a sphere cap (even Fibonacci spacing)",
        )
        .output("curves", "curves", "the strands")
        .param(
            ParamSpec::vec3("center", [0.0; 3])
                .unit("m")
                .doc("sphere centre"),
        )
        .param(
            ParamSpec::float("radius", 0.1)
                .gt(0.0)
                .unit("m")
                .doc("sphere radius (roots lie on it)"),
        )
        .param(
            ParamSpec::int("count", 100)
                .ge(1.0)
                .le(10_000_000.0)
                .doc("number of strands"),
        )
        .param(
            ParamSpec::int("segments", 16)
                .ge(1.0)
                .le(10_000.0)
                .doc("segments per strand"),
        )
        .param(
            ParamSpec::float("length", 0.2)
                .gt(0.0)
                .unit("m")
                .doc("strand length"),
        )
        .param(
            ParamSpec::float("cap_degrees", 60.0)
                .gt(0.0)
                .le(180.0)
                .unit("deg")
                .doc("roots within this angle of the +y pole"),
        ),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let p = cx.params().clone();
                let (count, segments) = (p.usize("count")?, p.usize("segments")?);
                let v = product(&[count as u64, segments as u64 + 1]);
                // Positions and the rest channel, and one offset per strand.
                let bytes = product(&[v, 48]).saturating_add(product(&[count as u64, 4]));
                check_size(
                    cx,
                    v,
                    bytes,
                    || {
                        format!(
                            "count × (segments + 1) = {count} × {} vertices",
                            segments + 1
                        )
                    },
                    "lower count or segments",
                )?;
                let c = strands_on_sphere(
                    p.vec3("center")?,
                    p.f64("radius")?,
                    count,
                    segments,
                    p.f64("length")?,
                    p.f64("cap_degrees")?,
                );
                cx.set("curves", Value::new(c));
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new(
            "geo.line",
            "one straight strand from start to end, in equal segments (a fibre, a test strand)",
        )
        .output("curves", "curves", "the strand")
        .param(
            ParamSpec::vec3("start", [0.0; 3])
                .unit("m")
                .doc("first vertex (the root)"),
        )
        .param(
            ParamSpec::vec3("end", [0.1, 0.0, 0.0])
                .unit("m")
                .doc("last vertex (the tip)"),
        )
        .param(
            ParamSpec::int("segments", 8)
                .ge(1.0)
                .le(10_000_000.0)
                .doc("segments along the strand"),
        ),
        |p| {
            if p.vec3("start")? == p.vec3("end")? {
                return Err(
                    "param 'end': must differ from 'start' (a strand needs a length)".into(),
                );
            }
            Ok(Kernel::from_fn(|cx| {
                let p = cx.params().clone();
                let (a, b, n) = (p.vec3("start")?, p.vec3("end")?, p.usize("segments")?);
                let v = n as u64 + 1;
                check_size(
                    cx,
                    v,
                    product(&[v, 48]),
                    || format!("segments = {n}"),
                    "lower segments",
                )?;
                let positions = (0..=n)
                    .map(|i| {
                        let t = i as f64 / n as f64;
                        [0, 1, 2].map(|k| a[k] + t * (b[k] - a[k]))
                    })
                    .collect();
                let c = Curves {
                    positions,
                    offsets: vec![0, v as u32],
                };
                cx.set("curves", Value::new(c));
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new(
            "geo.arc",
            "a circular arc (or a whole circle) as one polyline: a curved rail, a ring, a bent test strand",
        )
        .output("curves", "curves", "the arc")
        .param(ParamSpec::vec3("center", [0.0; 3]).unit("m").doc("centre of the circle"))
        .param(ParamSpec::float("radius", 0.5).gt(0.0).unit("m").doc("radius"))
        .param(ParamSpec::vec3("axis", [0.0, 0.0, 1.0]).doc("normal of the circle's plane; angles turn about it (right hand)"))
        .param(ParamSpec::vec3("from", [1.0, 0.0, 0.0]).doc("direction of angle 0, projected into the plane"))
        .param(ParamSpec::float("start_angle", 0.0).ge(-720.0).le(720.0).unit("deg").doc("angle of the first vertex"))
        .param(ParamSpec::float("end_angle", 360.0).ge(-720.0).le(720.0).unit("deg").doc("angle of the last vertex (at most a turn from the first)"))
        .param(ParamSpec::int("segments", 64).ge(1.0).le(10_000_000.0).doc("segments along the arc")),
        |p| {
            let sweep = p.f64("end_angle")? - p.f64("start_angle")?;
            if sweep == 0.0 || sweep.abs() > 360.0 {
                return Err(format!("param 'end_angle': the arc must turn by more than 0 and at most 360 degrees from 'start_angle' (it turns {sweep})"));
            }
            arc_frame(p.vec3("axis")?, p.vec3("from")?)?;
            Ok(Kernel::from_fn(|cx| {
                let p = cx.params().clone();
                let (u, w) = arc_frame(p.vec3("axis")?, p.vec3("from")?).map_err(NodeError::Failed)?;
                let (c, r, n) = (p.vec3("center")?, p.f64("radius")?, p.usize("segments")?);
                let (a0, a1) = (p.f64("start_angle")?.to_radians(), p.f64("end_angle")?.to_radians());
                let v = n as u64 + 1;
                check_size(cx, v, product(&[v, 48]), || format!("segments = {n}"), "lower segments")?;
                let positions = (0..=n)
                    .map(|i| {
                        let t = a0 + (a1 - a0) * i as f64 / n as f64;
                        let (sin, cos) = t.sin_cos();
                        [0, 1, 2].map(|k| c[k] + r * (cos * u[k] + sin * w[k]))
                    })
                    .collect();
                cx.set("curves", Value::new(Curves { positions, offsets: vec![0, v as u32] }));
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new(
            "geo.polyline",
            "one polyline through the listed points (a rail, a path, a hand-made strand)",
        )
        .output("curves", "curves", "the polyline")
        .param(
            ParamSpec::floats("points", &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0])
                .unit("m")
                .doc("x, y, z of each point in order: two points or more"),
        ),
        |p| {
            let pts = p.floats("points")?;
            if pts.len() < 6 || pts.len() % 3 != 0 {
                return Err(format!(
                    "param 'points': needs x, y, z of two points or more (got {} numbers)",
                    pts.len()
                ));
            }
            if let Some(i) = pts.iter().position(|v| !v.is_finite()) {
                return Err(format!("param 'points': entry {i} is not finite"));
            }
            Ok(Kernel::from_fn(|cx| {
                let pts = cx.params().floats("points")?;
                let positions: Vec<[f64; 3]> =
                    pts.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
                let v = positions.len() as u32;
                cx.set(
                    "curves",
                    Value::new(Curves {
                        positions,
                        offsets: vec![0, v],
                    }),
                );
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new(
            "geo.obj",
            "a triangle mesh read from an OBJ file (all objects merged, faces triangulated)",
        )
        .output("mesh", "mesh", "the mesh")
        .param(
            ParamSpec::string("path", "")
                .required()
                .doc("OBJ file (relative to the working directory)"),
        ),
        |p| {
            if p.str("path")?.is_empty() {
                return Err("param 'path': must not be empty".into());
            }
            // The file's identity (path, size, modification time) enters the node's hash, so a
            // disk cache downstream is rewritten when the file changes between runs.
            let meta = std::fs::metadata(p.str("path")?).ok();
            let stamp = format!(
                "{}|{:?}|{:?}",
                p.str("path")?,
                meta.as_ref().map(|m| m.len()),
                meta.and_then(|m| m.modified().ok())
            );
            Ok(Kernel::Compute(Box::new(ObjFile {
                hash: fnv1a_128(stamp.as_bytes()),
            })))
        },
    )
}

/// Reads its file when evaluated; its hash includes the file's size and modification time at
/// load, so caches downstream notice an edited file.
struct ObjFile {
    hash: u128,
}

fn fnv1a_128(b: &[u8]) -> u128 {
    // FNV-1a, 128-bit: a stable hash with no extra dependency (this only needs to change when
    // the stamp changes).
    let mut h: u128 = 0x6c62272e07bb014262b821756295c58d;
    for &x in b {
        h ^= x as u128;
        h = h.wrapping_mul(0x0000000001000000000000000000013B);
    }
    h
}

impl weft_graph::Compute for ObjFile {
    fn kernel_hash(&self) -> u128 {
        self.hash
    }

    fn compute(&mut self, cx: &mut weft_graph::EvalCx<'_>) -> Result<(), NodeError> {
        let path = std::path::PathBuf::from(cx.params().str("path")?);
        let m = weft_scene::read_obj(&path).map_err(|e| NodeError::Failed(e.to_string()))?;
        cx.set("mesh", Value::new(m));
        Ok(())
    }
}

/// The in-plane frame of an arc: `from` made orthogonal to `axis` (u), and axis × u (w).
fn arc_frame(axis: [f64; 3], from: [f64; 3]) -> Result<([f64; 3], [f64; 3]), String> {
    let a = nalgebra::Vector3::from(axis);
    let f = nalgebra::Vector3::from(from);
    let an = a.norm();
    if !(an > 0.0 && an.is_finite()) {
        return Err("param 'axis': must be a non-zero, finite direction".into());
    }
    let a = a / an;
    let u = f - a * a.dot(&f);
    let un = u.norm();
    if !(un > 1e-9 * f.norm().max(f64::MIN_POSITIVE) && un.is_finite()) {
        return Err(
            "param 'from': must not be parallel to 'axis' (it gives angle 0 in the plane)".into(),
        );
    }
    let u = u / un;
    let w = a.cross(&u);
    Ok((u.into(), w.into()))
}
