//! 3-vector arithmetic.

use serde_json::json;
use weft_graph::{Kernel, NodeSpec, Registry, RegistryError};

pub(crate) fn register(r: &mut Registry) -> Result<(), RegistryError> {
    r.register(
        NodeSpec::new("vec3.make", "builds [x, y, z] from three numbers")
            .input_default("x", "float", json!(0.0), "x")
            .input_default("y", "float", json!(0.0), "y")
            .input_default("z", "float", json!(0.0), "z")
            .output("out", "vec3", "the vector"),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let v = [cx.f64_input("x")?, cx.f64_input("y")?, cx.f64_input("z")?];
                cx.set("out", v);
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new("vec3.split", "the components of a vector")
            .input("v", "vec3", "the vector")
            .output("x", "float", "x")
            .output("y", "float", "y")
            .output("z", "float", "z"),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let v = cx.input_as::<[f64; 3]>("v")?;
                cx.set("x", v[0]);
                cx.set("y", v[1]);
                cx.set("z", v[2]);
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new("vec3.add", "a + b, componentwise")
            .input("a", "vec3", "left")
            .input("b", "vec3", "right")
            .output("out", "vec3", "sum"),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let (a, b) = (cx.input_as::<[f64; 3]>("a")?, cx.input_as::<[f64; 3]>("b")?);
                cx.set("out", [a[0] + b[0], a[1] + b[1], a[2] + b[2]]);
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new("vec3.scale", "v × s")
            .input("v", "vec3", "vector")
            .input_default("s", "float", json!(1.0), "scale")
            .output("out", "vec3", "scaled vector"),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let (v, s) = (cx.input_as::<[f64; 3]>("v")?, cx.f64_input("s")?);
                cx.set("out", [v[0] * s, v[1] * s, v[2] * s]);
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new("vec3.length", "Euclidean length |v|")
            .input("v", "vec3", "vector")
            .output("out", "float", "length"),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let v = cx.input_as::<[f64; 3]>("v")?;
                cx.set("out", (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt());
                Ok(())
            }))
        },
    )
}
