//! Conversion nodes: wrap geometry into Scene Elements.

use serde_json::json;
use weft_graph::{
    EvalCx, Kernel, NodeError, NodeSpec, ParamSpec, Params, Registry, RegistryError, Value,
};
use weft_scene::{
    Attachment, AttachmentMode, Channel, CollisionGroup, CollisionResponse, Curves, DomainSide,
    ElementKind, FluidDomain, FreezeWeights, Geometry, Members, Mesh, SceneElement, SlideRail,
    SlideSurface, Transform,
};

fn check_name(p: &Params) -> Result<(), String> {
    let n = p.str("name")?;
    // Names become file names in outputs: no separators or parent references.
    if n.is_empty()
        || n.chars().any(|c| c.is_control() || c == '/' || c == '\\')
        || n.contains("..")
    {
        return Err(format!(
            "param 'name': must be a non-empty printable name without '/', '\\' or '..', got {n:?}"
        ));
    }
    Ok(())
}

fn finite(points: &[[f64; 3]], port: &str) -> Result<(), NodeError> {
    match points.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        Some(i) => Err(NodeError::Input {
            port: port.into(),
            message: format!("vertex {i} has a non-finite position {:?}", points[i]),
        }),
        None => Ok(()),
    }
}

/// Sets the `rest` channel: the optional `rest` input's positions (same vertex count
/// required), else the element's own positions.
fn with_rest(cx: &mut EvalCx<'_>, mut e: SceneElement) -> Result<SceneElement, NodeError> {
    let rest = match cx.input_opt("rest")? {
        Some(v) => {
            let r: Vec<[f64; 3]> = v
                .get::<Mesh>()
                .map(|m| m.positions.clone())
                .or_else(|| v.get::<Curves>().map(|c| c.positions.clone()))
                .unwrap_or_default();
            if r.len() != e.vertex_count() {
                return Err(NodeError::Input {
                    port: "rest".into(),
                    message: format!(
                        "has {} vertices but the element has {}",
                        r.len(),
                        e.vertex_count()
                    ),
                });
            }
            finite(&r, "rest")?;
            r
        }
        None => e.geometry.positions().to_vec(),
    };
    e.set_channel("rest", Channel::Vec3(rest.into()));
    Ok(e)
}

/// Sets the `velocity` channel (the solvers' initial velocity) from the `velocity` parameter,
/// unless it is zero (no channel: at rest).
fn with_velocity(cx: &EvalCx<'_>, mut e: SceneElement) -> Result<SceneElement, NodeError> {
    let v = cx.params().vec3("velocity")?;
    if v != [0.0; 3] {
        let n = e.vertex_count();
        e.set_channel("velocity", Channel::Vec3(vec![v; n].into()));
    }
    Ok(e)
}

/// Vertex indices from a list parameter of whole numbers.
pub(crate) fn indices(p: &Params, name: &str) -> Result<Vec<u32>, String> {
    p.floats(name)?
        .iter()
        .map(|&x| {
            if x >= 0.0 && x.fract() == 0.0 && x < u32::MAX as f64 {
                Ok(x as u32)
            } else {
                Err(format!("param '{name}': {x} is not a vertex index"))
            }
        })
        .collect()
}

pub(crate) fn register(r: &mut Registry) -> Result<(), RegistryError> {
    r.register(
        NodeSpec::new(
            "convert.cloth",
            "wraps a mesh into a cloth Scene Element (its positions, or the rest input's, become the rest shape)",
        )
        .input("mesh", "mesh", "the cloth's mesh")
        .input_default("rest", "mesh", json!(null), "rest shape with the same vertices (default: the mesh itself)")
        .output("element", "element", "the cloth element")
        .param(ParamSpec::string("name", "cloth").doc("element name, unique in the scene"))
        .param(ParamSpec::vec3("velocity", [0.0; 3]).unit("m/s").doc("initial velocity of every vertex")),
        |p| {
            check_name(p)?;
            Ok(Kernel::from_fn(|cx| {
                let m = cx.input_as::<Mesh>("mesh")?;
                finite(&m.positions, "mesh")?;
                if m.triangles.is_empty() {
                    return Err(NodeError::Input {
                        port: "mesh".into(),
                        message: "has no triangles".into(),
                    });
                }
                let name = cx.params().str("name")?.to_string();
                let e = with_rest(cx, SceneElement::new(&name, ElementKind::Cloth, Geometry::Mesh(m)))?;
                let e = with_velocity(cx, e)?;
                cx.set("element", Value::new(e));
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new(
            "convert.hair",
            "wraps curves into a hair Scene Element (its positions, or the rest input's, become the rest shape)",
        )
        .input("curves", "curves", "the strands")
        .input_default("rest", "curves", json!(null), "rest shape with the same vertices (default: the curves themselves)")
        .output("element", "element", "the hair element")
        .param(ParamSpec::string("name", "hair").doc("element name, unique in the scene"))
        .param(ParamSpec::vec3("velocity", [0.0; 3]).unit("m/s").doc("initial velocity of every vertex")),
        |p| {
            check_name(p)?;
            Ok(Kernel::from_fn(|cx| {
                let c = cx.input_as::<Curves>("curves")?;
                finite(&c.positions, "curves")?;
                if c.is_empty() {
                    return Err(NodeError::Input {
                        port: "curves".into(),
                        message: "has no curves".into(),
                    });
                }
                let name = cx.params().str("name")?.to_string();
                let e = with_rest(cx, SceneElement::new(&name, ElementKind::Hair, Geometry::Curves(c)))?;
                let e = with_velocity(cx, e)?;
                cx.set("element", Value::new(e));
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new("convert.collider", "a kinematic object: a mesh placed by an optional (animated) transform; shown in previews, never simulated")
            .input("mesh", "mesh", "the object's mesh, in its own frame")
            .input_default("transform", "transform", json!(null), "where the object is at this frame (identity when unconnected)")
            .output("element", "element", "the collider element")
            .param(ParamSpec::string("name", "collider").doc("element name, unique in the scene")),
        |p| {
            check_name(p)?;
            Ok(Kernel::from_fn(|cx| {
                let mut m = cx.input_as::<Mesh>("mesh")?;
                let t = match cx.input_opt("transform")? {
                    Some(v) => v.get::<Transform>().copied(),
                    None => None,
                };
                if let Some(t) = t {
                    for p in &mut m.positions {
                        let q = t.transform_point(&nalgebra::Point3::new(p[0], p[1], p[2]));
                        *p = [q.x, q.y, q.z];
                    }
                }
                let mut e = SceneElement::new(cx.params().str("name")?, ElementKind::Collider, Geometry::Mesh(m));
                e.transform = t;
                cx.set("element", Value::new(e));
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new("convert.collision_group", "a collision element: which cloth and hair elements collide with which colliders, with each other and with themselves, and how (a Collision Group SEC and a Collision Response SEC on a data-less element; several may coexist); needs behavior.collision in the solver's tree")
            .output("element", "element", "a data-less collision element")
            .param(ParamSpec::string("name", "collision").doc("element name, unique in the scene"))
            .param(ParamSpec::string("members", "all").doc("the cloth and hair elements that collide: all, or names separated by commas"))
            .param(ParamSpec::string("colliders", "all").doc("the collider elements they collide with: all, or names separated by commas"))
            .param(ParamSpec::bool("vertex_face", true).doc("detect every member vertex against the colliders' triangles"))
            .param(ParamSpec::bool("segment_face", true).doc("detect every member hair segment against the colliders' triangles (a strand touches between its vertices too)"))
            .param(ParamSpec::bool("edge_edge", true).doc("detect the members' cloth edges and hair segments against each other's (crossing edges touch between their vertices; hair on hair has no faces)"))
            .param(ParamSpec::bool("between_members", true).doc("members collide with each other (layers of clothing, hair on a collar)"))
            .param(ParamSpec::bool("self_collision", false).doc("each member collides with itself (a skirt folding onto itself, strands of one groom on each other); primitives sharing a vertex never do"))
            .param(ParamSpec::float("strength", CollisionResponse::default().strength).gt(0.0).le(1.0).doc("fraction of an existing penetration resolved per step (a start inside a collider separates over steps)"))
            .param(ParamSpec::float("damping", CollisionResponse::default().damping).ge(0.0).unit("1/s").doc("damping of the normal relative velocity at a contact")),
        |p| {
            check_name(p)?;
            for field in ["members", "colliders"] {
                if let Members::Names(n) = Members::parse(p.str(field)?)
                    && n.is_empty()
                {
                    return Err(format!("param '{field}': names no element (use all, or names separated by commas)"));
                }
            }
            Ok(Kernel::from_fn(|cx| {
                let p = cx.params();
                let mut e = SceneElement::new(p.str("name")?, ElementKind::Collision, Geometry::None);
                e.secs.insert(CollisionGroup {
                    members: Members::parse(p.str("members")?),
                    colliders: Members::parse(p.str("colliders")?),
                    vertex_face: p.bool("vertex_face")?,
                    segment_face: p.bool("segment_face")?,
                    edge_edge: p.bool("edge_edge")?,
                    between_members: p.bool("between_members")?,
                    self_collision: p.bool("self_collision")?,
                });
                e.secs.insert(CollisionResponse {
                    strength: p.f64("strength")?,
                    damping: p.f64("damping")?,
                });
                cx.set("element", Value::new(e));
                Ok(())
            }))
        },
    )?;
    let sides = ["wall", "open", "inflow", "periodic"];
    let mut spec = NodeSpec::new("convert.fluid_domain", "a fluid domain: the box a fluid fills (given, or the solids' bounds plus padding at the start frame), its cell size and its six sides; carries a Fluid Domain SEC (attach sec.fluid for air or a custom fluid; water by default)")
        .output("element", "element", "a data-less fluid-domain element")
        .param(ParamSpec::string("name", "fluid").doc("element name, unique in the scene"))
        .param(ParamSpec::bool("auto_bounds", true).doc("true: the solids' and colliders' bounds plus padding; false: min and max"))
        .param(ParamSpec::vec3("min", [-1.0; 3]).unit("m").doc("minimum corner (auto_bounds = false)"))
        .param(ParamSpec::vec3("max", [1.0; 3]).unit("m").doc("maximum corner (auto_bounds = false)"))
        .param(ParamSpec::float("padding", 0.1).ge(0.0).unit("m").doc("margin around the solids (auto_bounds = true)"))
        .param(ParamSpec::float("cell_size", 0.02).gt(0.0).unit("m").doc("cell size Δx; a grid too large for memory is refused before allocating"))
        .param(ParamSpec::vec3("flow", [0.0; 3]).unit("m/s").doc("the current or wind: the initial velocity, and the velocity at inflow sides"));
    for s in ["x_min", "x_max", "y_min", "y_max", "z_min", "z_max"] {
        spec = spec.param(ParamSpec::choice(s, &sides, "wall").doc("wall: no flow through; open: still fluid at zero pressure; inflow: the flow enters or leaves; periodic: wraps to the opposite side (set both)"));
    }
    r.register(spec, |p| {
        check_name(p)?;
        for axis in ["x", "y", "z"] {
            let (lo, hi) = (p.str(&format!("{axis}_min"))?, p.str(&format!("{axis}_max"))?);
            if (lo == "periodic") != (hi == "periodic") {
                return Err(format!("param '{axis}_min'/'{axis}_max': a periodic axis must be periodic on both sides (got {lo} and {hi})"));
            }
        }
        if !p.bool("auto_bounds")? {
            let (lo, hi) = (p.vec3("min")?, p.vec3("max")?);
            if (0..3).any(|a| hi[a] <= lo[a]) {
                return Err(format!("param 'max': must exceed 'min' on every axis (min {lo:?}, max {hi:?})"));
            }
        }
        Ok(Kernel::from_fn(|cx| {
            let p = cx.params();
            let side = |name: &str| {
                Ok::<_, weft_graph::ParamError>(match p.str(name)? {
                    "open" => DomainSide::Open,
                    "inflow" => DomainSide::Inflow,
                    "periodic" => DomainSide::Periodic,
                    _ => DomainSide::Wall,
                })
            };
            let bounds = if p.bool("auto_bounds")? {
                None
            } else {
                Some((p.vec3("min")?, p.vec3("max")?))
            };
            let sec = FluidDomain {
                bounds,
                padding: p.f64("padding")?,
                cell_size: p.f64("cell_size")?,
                lo: [side("x_min")?, side("y_min")?, side("z_min")?],
                hi: [side("x_max")?, side("y_max")?, side("z_max")?],
                flow: p.vec3("flow")?,
            };
            let mut e = SceneElement::new(p.str("name")?, ElementKind::FluidDomain, Geometry::None);
            e.secs.insert(sec);
            cx.set("element", Value::new(e));
            Ok(())
        }))
    })?;
    r.register(
        NodeSpec::new("convert.attachment", "attaches vertices of an element to where they are at the start frame, carried by an optional animated transform")
            .input("target", "element", "the element whose vertices are attached")
            .input_default("transform", "transform", json!(null), "moves the attachment points (fixed in place when unconnected); with mode = slide, places the rails (their curves are in its frame)")
            .input_default("along", "curves", json!(null), "mode = slide: rails (polylines); each listed vertex slides on the rail or surface nearest to it at the start, moved onto it there, and stays on it exactly (a rail's ends are stops)")
            .input_default("onto", "mesh", json!(null), "mode = slide: a surface (a collider's mesh, say) the listed vertices slide on, exactly (its open borders are stops)")
            .input_default("weight", "float", json!(1.0), "mode = freeze: the weight w ≥ 0, read at every frame (wire a time-driven node to key it): w ≥ 1 holds each listed vertex exactly at the target's animated input, 0 < w < 1 pulls it there by a zero-length spring of stiffness w/(1 − w)·m/Δt² (m its mass, Δt the frame time), 0 leaves it free")
            .output("element", "element", "a data-less attachment element")
            .param(ParamSpec::string("name", "attachment").doc("element name, unique in the scene"))
            .param(ParamSpec::choice("select", &["vertices", "curve_roots"], "vertices").doc("vertices: the listed indices; curve_roots: the first vertices of every curve"))
            .param(ParamSpec::floats("vertices", &[]).doc("vertex indices (select = vertices)"))
            .param(ParamSpec::int("root_vertices", 2).ge(1.0).le(16.0).doc("vertices per curve root: 1 holds the root vertex and lets the strand turn about it; k >= 2 holds the first k - 1 and clamps the strand's direction at the last of them (2: a strand clamped at its root, bending over its whole length)"))
            .param(ParamSpec::bool("clamp", false).doc("select = vertices: also hold the direction the element leaves them in, as it starts and turned with the transform (cloth: its tangent plane along every border edge whose two vertices are listed, so one listed row is a clamped edge, not a hinge; strands: where the free strand leaves a listed vertex)"))
            .param(ParamSpec::choice("mode", &["hard", "spring", "slide", "rigid", "freeze"], "hard").doc("hard: exactly; spring: a zero-length spring; slide: on the rails ('along') or the surface ('onto'), free along them, exactly; rigid: the listed vertices move as one rigid body, free (a button, a bead), their distances kept exactly; to weld a group to an animated transform, attach its vertices hard instead; freeze: blended between simulated and the target's animated input by 'weight' (× 'vertex_weights'), so regions can be locked and released over time"))
            .param(ParamSpec::floats("vertex_weights", &[]).doc("mode = freeze: a factor ≥ 0 on 'weight' per listed vertex, in the order of 'vertices' (empty: 1 for all)"))
            .param(ParamSpec::float("mass", 0.0).ge(0.0).unit("kg").doc("mode = rigid: mass added to the group, shared equally among its vertices (a button's)"))
            .param(ParamSpec::float("friction", 0.0).ge(0.0).doc("mode = slide: Coulomb friction coefficient μ along the rail or surface (0: frictionless)"))
            .param(ParamSpec::float("stiffness", 1e3).gt(0.0).unit("N/m").doc("spring stiffness (mode = spring)")),
        |p| {
            check_name(p)?;
            indices(p, "vertices")?;
            let mode = p.str("mode")?;
            if p.bool("clamp")? && matches!(mode, "slide" | "rigid" | "freeze") {
                return Err(format!(
                    "param 'clamp': a clamp holds the direction at held vertices; with mode {mode} they are not held (use mode hard)"
                ));
            }
            let weights = p.floats("vertex_weights")?;
            if let Some(w) = weights.iter().find(|w| !(**w >= 0.0 && w.is_finite())) {
                return Err(format!("param 'vertex_weights': {w} is not a weight (≥ 0)"));
            }
            if !weights.is_empty() {
                if mode != "freeze" {
                    return Err(format!(
                        "param 'vertex_weights': only mode freeze reads weights (mode is {mode})"
                    ));
                }
                if p.str("select")? != "vertices" || weights.len() != p.floats("vertices")?.len() {
                    return Err(format!(
                        "param 'vertex_weights': {} weights for {} listed vertices (one per entry of 'vertices', with select = vertices)",
                        weights.len(),
                        p.floats("vertices")?.len()
                    ));
                }
            }
            Ok(Kernel::from_fn(attachment))
        },
    )
}

fn attachment(cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
    let target = cx.input_as::<SceneElement>("target")?;
    let p = cx.params().clone();
    let mode = match p.str("mode")? {
        "spring" => AttachmentMode::Spring(p.f64("stiffness")?),
        "slide" => AttachmentMode::Slide {
            friction: p.f64("friction")?,
        },
        "rigid" => AttachmentMode::Rigid {
            mass: p.f64("mass")?,
        },
        "freeze" => {
            let weight = cx.f64_input("weight")?;
            if !(weight >= 0.0 && weight.is_finite()) {
                return Err(NodeError::Input {
                    port: "weight".into(),
                    message: format!("a freeze weight must be ≥ 0, got {weight}"),
                });
            }
            AttachmentMode::Freeze { weight }
        }
        _ => AttachmentMode::Hard,
    };
    let along = cx
        .input_opt("along")?
        .and_then(|v| v.get::<Curves>().cloned());
    let onto = cx.input_opt("onto")?.and_then(|v| v.get::<Mesh>().cloned());
    let sliding = matches!(mode, AttachmentMode::Slide { .. });
    if sliding {
        let input = |port: &str, message: &str| NodeError::Input {
            port: port.into(),
            message: message.into(),
        };
        if along.is_none() && onto.is_none() {
            return Err(input(
                "along",
                "mode = slide needs a rail or a surface: connect curves to 'along' (geo.line, geo.arc, geo.polyline) or a mesh to 'onto'",
            ));
        }
        if along.as_ref().is_some_and(|c| c.is_empty()) {
            return Err(input("along", "the rails have no curves"));
        }
        if onto.as_ref().is_some_and(|m| m.triangles.is_empty()) {
            return Err(input("onto", "the surface has no triangles"));
        }
    }
    let sec = match p.str("select")? {
        "curve_roots" => match &*target.geometry {
            Geometry::Curves(c) => {
                Attachment::curve_roots(&target.name, c, p.usize("root_vertices")? as u32, mode)
            }
            _ => {
                return Err(NodeError::Input {
                    port: "target".into(),
                    message: format!(
                        "'{}' has no curves to take roots from (select = curve_roots)",
                        target.name
                    ),
                });
            }
        },
        _ => {
            let vertices = indices(&p, "vertices").map_err(NodeError::Failed)?;
            let clamps = if p.bool("clamp")? {
                Attachment::clamps_of(&target.geometry, &vertices)
            } else {
                Vec::new()
            };
            Attachment {
                target: target.name.clone(),
                vertices,
                mode,
                clamps,
            }
        }
    };
    let n = target.vertex_count();
    if let Some(v) = sec.vertices.iter().find(|&&v| v as usize >= n) {
        return Err(NodeError::Failed(format!(
            "param 'vertices': vertex {v} is out of range ('{}' has {n} vertices)",
            target.name
        )));
    }
    let freeze_weights = p.floats("vertex_weights")?;
    let mut e = SceneElement::new(p.str("name")?, ElementKind::Attachment, Geometry::None);
    e.secs.insert(sec);
    if !freeze_weights.is_empty() {
        e.secs.insert(FreezeWeights {
            weights: freeze_weights,
        });
    }
    if sliding {
        if let Some(curves) = along {
            e.secs.insert(SlideRail { curves });
        }
        if let Some(mesh) = onto {
            e.secs.insert(SlideSurface { mesh });
        }
    }
    e.transform = match cx.input_opt("transform")? {
        Some(v) => v.get::<Transform>().copied(),
        None => None,
    };
    cx.set("element", Value::new(e));
    Ok(())
}
