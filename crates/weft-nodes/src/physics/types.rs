//! Port types for scene data.

use std::sync::Arc;
use weft_graph::{PortType, Registry, RegistryError, Value};
use weft_scene::{Curves, Mesh, SceneElement, Transform};
use weft_sim::{Behavior, BehaviorTree};

/// A whole scene: the elements a solver outputs, in input order.
pub type Scene = Vec<SceneElement>;

/// A Behavior on an edge.
#[derive(Clone, Debug)]
pub struct BehaviorValue(pub Arc<dyn Behavior>);

fn summary(e: &SceneElement) -> serde_json::Value {
    serde_json::json!({
        "name": e.name,
        "kind": e.kind.name(),
        "vertices": e.vertex_count(),
        "secs": e.secs.types().collect::<Vec<_>>(),
    })
}

/// About how many bytes a scene value holds.
pub(crate) fn scene_bytes(v: &Value) -> usize {
    v.get::<Scene>()
        .map_or(0, |s| s.iter().map(SceneElement::heap_bytes).sum())
}

pub(crate) fn register(r: &mut Registry) -> Result<(), RegistryError> {
    r.register_port_type(PortType::of::<Mesh>("mesh", "a triangle mesh (positions in m, triangles)").with_json(
        |_| Err("a mesh cannot be written inline; use geo.grid, geo.obj, …".into()),
        |v| v.get::<Mesh>().map(|m| serde_json::json!({"vertices": m.positions.len(), "triangles": m.triangles.len()})),
    ).with_size(|v| v.get::<Mesh>().map_or(0, |m| 24 * m.positions.len() + 12 * m.triangles.len())))?;
    r.register_port_type(
        PortType::of::<Curves>("curves", "polylines (hair strands)")
            .with_json(
                |_| Err("curves cannot be written inline; use geo.strands".into()),
                |v| {
                    v.get::<Curves>().map(
                        |c| serde_json::json!({"curves": c.len(), "vertices": c.positions.len()}),
                    )
                },
            )
            .with_size(|v| {
                v.get::<Curves>()
                    .map_or(0, |c| 24 * c.positions.len() + 4 * c.offsets.len())
            }),
    )?;
    r.register_port_type(
        PortType::of::<SceneElement>("element", "a Scene Element: geometry, channels and SECs")
            .with_json(
                |_| Err("an element cannot be written inline; use a convert.* node".into()),
                |v| v.get::<SceneElement>().map(summary),
            )
            .with_size(|v| v.get::<SceneElement>().map_or(0, SceneElement::heap_bytes)),
    )?;
    r.register_port_type(
        PortType::of::<Scene>("scene", "the elements of a scene at one frame")
            .with_json(
                |_| Err("a scene cannot be written inline".into()),
                |v| {
                    v.get::<Scene>()
                        .map(|s| serde_json::json!(s.iter().map(summary).collect::<Vec<_>>()))
                },
            )
            .with_size(scene_bytes),
    )?;
    r.register_port_type(PortType::of::<BehaviorValue>(
        "behavior",
        "a Behavior: simulation logic applied to the elements it concerns",
    ))?;
    r.register_port_type(
        PortType::of::<BehaviorTree>("behavior_tree", "the Behaviors a solver applies").with_json(
            |_| Err("a behavior tree is built with behavior.tree".into()),
            |v| {
                v.get::<BehaviorTree>().map(|t| {
                    serde_json::json!(t.behaviors.iter().map(|b| b.name()).collect::<Vec<_>>())
                })
            },
        ),
    )?;
    r.register_port_type(PortType::of::<Transform>("transform", "a rigid transform (rotation and translation)").with_json(
        |j| {
            let a = j.as_array().filter(|a| a.len() == 3).ok_or("expected a translation [x, y, z]")?;
            let c: Vec<f64> = a.iter().filter_map(|x| x.as_f64()).collect();
            if c.len() != 3 {
                return Err("expected three numbers".into());
            }
            Ok(Value::new(Transform::translation(c[0], c[1], c[2])))
        },
        |v| {
            v.get::<Transform>().map(|t| {
                let (axis, angle) = t.rotation.axis_angle().map(|(a, g)| ([a.x, a.y, a.z], g)).unwrap_or(([0.0, 1.0, 0.0], 0.0));
                serde_json::json!({"translation": [t.translation.x, t.translation.y, t.translation.z], "axis": axis, "angle": angle})
            })
        },
    ))
}

/// A frame's contact statistics as the solvers report them (`--stats`).
pub(crate) fn contact_stats_json(c: &weft_sim::ContactFrameStats) -> serde_json::Value {
    serde_json::json!({
        "max_contacts": c.max_contacts,
        "contacts": c.contacts,
        "admm_iterations": c.admm_iterations,
        "resolves": c.resolves,
        "max_penetration": c.max_penetration,
        "max_residual": c.max_residual,
        "detection_seconds": c.detection_seconds,
        "broad_seconds": c.broad_seconds,
        "narrow_seconds": c.narrow_seconds,
        "ccd_seconds": c.ccd_seconds,
        "admm_seconds": c.admm_seconds,
        "crossing_retries": c.crossing_retries,
        "cut_backs": c.cut_backs,
        "started_inside": c.started_inside,
        "pattern_rebuilds": c.pattern_rebuilds,
        "low_rank_joins": c.low_rank_joins,
    })
}
