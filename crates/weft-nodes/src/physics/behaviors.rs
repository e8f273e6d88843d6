//! Behavior nodes and the Behavior tree.

use super::types::BehaviorValue;
use std::sync::Arc;
use weft_graph::{Kernel, NodeSpec, ParamSpec, Registry, RegistryError, Value};
use weft_sim::{
    AttachmentBehavior, Behavior, BehaviorTree, Collision, Damping, DiscreteShellMaterial,
    FluidDrag, Gravity, Load, LoadVertices, RodMaterial,
};

fn plain(
    r: &mut Registry,
    name: &str,
    doc: &str,
    make: fn() -> Arc<dyn Behavior>,
) -> Result<(), RegistryError> {
    r.register(
        NodeSpec::new(name, doc).output("behavior", "behavior", "the Behavior"),
        move |_| {
            Ok(Kernel::from_fn(move |cx| {
                cx.set("behavior", Value::new(BehaviorValue(make())));
                Ok(())
            }))
        },
    )
}

pub(crate) fn register(r: &mut Registry) -> Result<(), RegistryError> {
    plain(
        r,
        "behavior.discrete_shell",
        "cloth material: membrane and shell bending (mean curvature at vertices, midedge deviator per triangle) on every cloth element, from its Discrete Shell and Density SECs or their defaults",
        || Arc::new(DiscreteShellMaterial),
    )?;
    plain(
        r,
        "behavior.rod",
        "hair material: stretch and bending on every hair element, from its Rod and Density SECs or their defaults",
        || Arc::new(RodMaterial),
    )?;
    plain(
        r,
        "behavior.attachment",
        "attachments: every attachment element's vertices follow their targets",
        || Arc::new(AttachmentBehavior),
    )?;
    plain(
        r,
        "behavior.fluid_drag",
        "fluid drag: every hair segment and cloth triangle exchanges momentum with the scene's fluid (drag, lift, buoyancy), from its Drag SEC or the defaults; needs solver.coupled and a fluid domain",
        || Arc::new(FluidDrag),
    )?;
    plain(
        r,
        "behavior.collision",
        "contacts with colliders: every collision element's member cloth and hair stay outside its colliders, with exact Coulomb friction and cohesion inside the implicit step (Daviet 2020), from the Collision Group, Collision Response and Collider SECs or their defaults",
        || Arc::new(Collision),
    )?;
    r.register(
        NodeSpec::new(
            "behavior.gravity",
            "uniform gravity on every simulated vertex",
        )
        .output("behavior", "behavior", "the Behavior")
        .param(
            ParamSpec::vec3("acceleration", [0.0, -9.81, 0.0])
                .unit("m/s²")
                .doc("gravitational acceleration"),
        ),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let g = Gravity {
                    acceleration: cx.params().vec3("acceleration")?,
                };
                cx.set("behavior", Value::new(BehaviorValue(Arc::new(g))));
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new(
            "behavior.damping",
            "mass-proportional damping on every simulated vertex (added to the SECs' own)",
        )
        .output("behavior", "behavior", "the Behavior")
        .param(
            ParamSpec::float("coefficient", 0.1)
                .ge(0.0)
                .unit("1/s")
                .doc("damping c: a force −c m v"),
        ),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let d = Damping {
                    coefficient: cx.params().f64("coefficient")?,
                };
                cx.set("behavior", Value::new(BehaviorValue(Arc::new(d))));
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new(
            "behavior.load",
            "a constant force on chosen vertices of one element (a tip load, a weight hung on a point)",
        )
        .output("behavior", "behavior", "the Behavior")
        .param(ParamSpec::string("element", "").doc("name of the loaded element"))
        .param(
            ParamSpec::choice("select", &["all", "curve_tips", "vertices"], "curve_tips")
                .doc("all: every vertex; curve_tips: the last vertex of every strand; vertices: the listed indices"),
        )
        .param(ParamSpec::floats("vertices", &[]).doc("vertex indices (select = vertices)"))
        .param(
            ParamSpec::vec3("force", [0.0, 0.0, 0.0])
                .unit("N")
                .doc("force on each chosen vertex"),
        ),
        |p| {
            super::convert::indices(p, "vertices")?;
            Ok(Kernel::from_fn(|cx| {
                let p = cx.params();
                let vertices = match p.str("select")? {
                    "all" => LoadVertices::All,
                    "vertices" => LoadVertices::Listed(
                        super::convert::indices(p, "vertices")
                            .map_err(weft_graph::NodeError::Failed)?,
                    ),
                    _ => LoadVertices::CurveTips,
                };
                let l = Load {
                    element: p.str("element")?.to_string(),
                    vertices,
                    force: p.vec3("force")?,
                };
                cx.set("behavior", Value::new(BehaviorValue(Arc::new(l))));
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new(
            "behavior.tree",
            "groups Behaviors for a solver, applied in connection order",
        )
        .input_multi("behaviors", "behavior", "the Behaviors")
        .output("tree", "behavior_tree", "the tree"),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let behaviors = cx
                    .inputs("behaviors")?
                    .iter()
                    .filter_map(|v| v.get::<BehaviorValue>().map(|b| b.0.clone()))
                    .collect();
                cx.set("tree", Value::new(BehaviorTree { behaviors }));
                Ok(())
            }))
        },
    )
}
