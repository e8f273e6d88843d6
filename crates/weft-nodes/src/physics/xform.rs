//! Animated transforms, and geometry moved by a transform (an animated input for freeze
//! attachments, a collider's shape placed once).

use std::f64::consts::TAU;
use weft_graph::{Kernel, NodeSpec, ParamSpec, Registry, RegistryError, TimeClass, Value};
use weft_scene::{Curves, Mesh, Transform};

pub(crate) fn register(r: &mut Registry) -> Result<(), RegistryError> {
    r.register(
        NodeSpec::new("xform.animate", "a rigid transform over time: offset + amplitude·sin(2πft) translation, rotation about an axis by an angle, at a speed, plus an oscillation")
            .time(TimeClass::Animated)
            .output("transform", "transform", "the transform at the frame's time")
            .param(ParamSpec::vec3("translate", [0.0; 3]).unit("m").doc("constant translation"))
            .param(ParamSpec::vec3("oscillate", [0.0; 3]).unit("m").doc("translation amplitude"))
            .param(ParamSpec::float("frequency", 1.0).ge(0.0).unit("Hz").doc("oscillation frequency f"))
            .param(ParamSpec::vec3("axis", [0.0, 1.0, 0.0]).doc("rotation axis (through the origin)"))
            .param(ParamSpec::float("angle", 0.0).unit("rad").doc("constant rotation (a tilted plane, a turned rail)"))
            .param(ParamSpec::float("spin", 0.0).unit("rad/s").doc("steady rotation speed"))
            .param(ParamSpec::float("swing", 0.0).unit("rad").doc("rotation oscillation amplitude (same frequency)")),
        |p| {
            let a = p.vec3("axis")?;
            if (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt() < 1e-12 {
                return Err("param 'axis': must not be zero".into());
            }
            Ok(Kernel::from_fn(|cx| {
                let p = cx.params();
                let t = cx.time();
                let s = (TAU * p.f64("frequency")? * t).sin();
                let (c, o) = (p.vec3("translate")?, p.vec3("oscillate")?);
                let tr = nalgebra::Translation3::new(c[0] + o[0] * s, c[1] + o[1] * s, c[2] + o[2] * s);
                let a = p.vec3("axis")?;
                let axis = nalgebra::Unit::new_normalize(nalgebra::Vector3::new(a[0], a[1], a[2]));
                let angle = p.f64("angle")? + p.f64("spin")? * t + p.f64("swing")? * s;
                let x = Transform::from_parts(tr, nalgebra::UnitQuaternion::from_axis_angle(&axis, angle));
                cx.set("transform", Value::new(x));
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new("geo.transform", "a mesh moved by a transform (animated when the transform is): an animated input for mode = freeze, a shape placed in the scene")
            .input("mesh", "mesh", "the mesh")
            .input("transform", "transform", "the transform")
            .output("mesh", "mesh", "the mesh's positions transformed (same triangles)"),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let mut m = cx.input_as::<Mesh>("mesh")?;
                let t = cx.input_as::<Transform>("transform")?;
                move_points(&mut m.positions, &t);
                cx.set("mesh", Value::new(m));
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new("geo.transform_curves", "curves moved by a transform (animated when the transform is): an animated input for hair with mode = freeze")
            .input("curves", "curves", "the curves")
            .input("transform", "transform", "the transform")
            .output("curves", "curves", "the curves' positions transformed (same offsets)"),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let mut c = cx.input_as::<Curves>("curves")?;
                let t = cx.input_as::<Transform>("transform")?;
                move_points(&mut c.positions, &t);
                cx.set("curves", Value::new(c));
                Ok(())
            }))
        },
    )
}

fn move_points(points: &mut [[f64; 3]], t: &Transform) {
    for p in points {
        *p = t.transform_point(&nalgebra::Point3::from(*p)).coords.into();
    }
}
