//! Scalar arithmetic and comparison.

use serde_json::json;
use weft_graph::{Kernel, NodeError, NodeSpec, ParamSpec, Registry, RegistryError};

fn binary(
    r: &mut Registry,
    name: &str,
    doc: &str,
    a0: f64,
    b0: f64,
    f: fn(f64, f64) -> Result<f64, String>,
) -> Result<(), RegistryError> {
    r.register(
        NodeSpec::new(name, doc)
            .input_default("a", "float", json!(a0), "left operand")
            .input_default("b", "float", json!(b0), "right operand")
            .output("out", "float", "result"),
        move |_| {
            Ok(Kernel::from_fn(move |cx| {
                let a = cx.f64_input("a")?;
                let b = cx.f64_input("b")?;
                let v = f(a, b).map_err(NodeError::Failed)?;
                cx.set("out", v);
                Ok(())
            }))
        },
    )
}

pub(crate) fn register(r: &mut Registry) -> Result<(), RegistryError> {
    binary(r, "math.add", "a + b", 0.0, 0.0, |a, b| Ok(a + b))?;
    binary(r, "math.sub", "a − b", 0.0, 0.0, |a, b| Ok(a - b))?;
    binary(r, "math.mul", "a × b", 1.0, 1.0, |a, b| Ok(a * b))?;
    binary(
        r,
        "math.div",
        "a ÷ b (b = 0 is an error, not an infinity)",
        1.0,
        1.0,
        |a, b| {
            if b == 0.0 {
                Err(format!("division by zero ({a} / 0)"))
            } else {
                Ok(a / b)
            }
        },
    )?;
    binary(r, "math.min", "the smaller of a and b", 0.0, 0.0, |a, b| {
        Ok(a.min(b))
    })?;
    binary(r, "math.max", "the larger of a and b", 0.0, 0.0, |a, b| {
        Ok(a.max(b))
    })?;
    r.register(
        NodeSpec::new(
            "math.sum",
            "sum of any number of inputs, in connection order",
        )
        .input_multi("terms", "float", "the terms")
        .output("out", "float", "their sum (0 for none)"),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let mut s = 0.0;
                for v in cx.inputs("terms")? {
                    s += v.get::<f64>().copied().unwrap_or(f64::NAN);
                }
                cx.set("out", s);
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new("math.scale", "x × factor, with the factor a parameter")
            .input("x", "float", "value")
            .output("out", "float", "scaled value")
            .param(ParamSpec::float("factor", 1.0).doc("multiplier")),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let v = cx.f64_input("x")? * cx.params().f64("factor")?;
                cx.set("out", v);
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new(
            "math.below",
            "true when |x| < tolerance (a convergence test)",
        )
        .input("x", "float", "residual or error")
        .output("out", "bool", "|x| < tolerance")
        .param(
            ParamSpec::float("tolerance", 1e-10)
                .gt(0.0)
                .doc("threshold"),
        ),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let x = cx.f64_input("x")?;
                if x.is_nan() {
                    return Err(NodeError::Input {
                        port: "x".into(),
                        message: "is NaN".into(),
                    });
                }
                let below = x.abs() < cx.params().f64("tolerance")?;
                cx.set("out", below);
                Ok(())
            }))
        },
    )
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;
    use weft_graph::{Context, load_str};

    #[test]
    fn division_by_zero_is_a_named_error() {
        let reg = crate::registry();
        let text = r#"{"format":"weft-graph","version":1,"nodes":{
            "z":{"type":"value.float"},"d":{"type":"math.div","inputs":{"b":"z.out"}}},
            "outputs":{"q":"d.out"}}"#;
        let mut g = load_str(&Arc::clone(&reg), text, "t").unwrap();
        let e = g.pull("q", Context::new(0)).unwrap_err();
        assert_eq!(e.to_string(), "node 'd': division by zero (1 / 0)");
    }
}
