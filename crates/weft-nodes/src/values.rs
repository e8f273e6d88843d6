//! Constant nodes.

use weft_graph::{Kernel, NodeSpec, ParamSpec, Registry, RegistryError, Value};

pub(crate) fn register(r: &mut Registry) -> Result<(), RegistryError> {
    r.register(
        NodeSpec::new("value.float", "a constant number")
            .output("out", "float", "the number")
            .param(ParamSpec::float("value", 0.0).doc("the number")),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let v = cx.params().f64("value")?;
                cx.set("out", v);
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new("value.int", "a constant integer")
            .output("out", "int", "the integer")
            .param(ParamSpec::int("value", 0).doc("the integer")),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let v = cx.params().i64("value")?;
                cx.set("out", v);
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new("value.bool", "a constant boolean")
            .output("out", "bool", "the boolean")
            .param(ParamSpec::bool("value", false).doc("the boolean")),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let v = cx.params().bool("value")?;
                cx.set("out", v);
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new("value.vec3", "a constant 3-vector")
            .output("out", "vec3", "the vector")
            .param(ParamSpec::vec3("value", [0.0; 3]).doc("the vector")),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let v = cx.params().vec3("value")?;
                cx.set("out", v);
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new("value.string", "a constant string")
            .output("out", "string", "the text")
            .param(ParamSpec::string("value", "").doc("the text")),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let v = Value::from(cx.params().str("value")?.to_string());
                cx.set("out", v);
                Ok(())
            }))
        },
    )
}
