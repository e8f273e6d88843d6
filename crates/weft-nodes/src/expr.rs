//! `math.expr`: a formula over up to eight connected numbers.
//!
//! Parsing is done once by the factory, so a malformed formula is a load-time error naming the
//! node and parameter. Evaluation is `exmex` (a well-kept float expression crate): float-only,
//! so `1/2` is 0.5, never integer division.

use exmex::prelude::*;
use weft_graph::{Kernel, NodeError, NodeSpec, ParamSpec, Registry, RegistryError};

/// Variable names, one optional input each.
const VARS: [&str; 8] = ["a", "b", "c", "d", "w", "x", "y", "z"];

pub(crate) fn register(r: &mut Registry) -> Result<(), RegistryError> {
    let mut spec = NodeSpec::new(
        "math.expr",
        "evaluates a formula (+ - * / ^, sin cos tan exp log sqrt abs, PI, E) of its inputs a b c d w x y z",
    )
    .output("out", "float", "the formula's value")
    .param(ParamSpec::string("expr", "0").doc("the formula, e.g. \"x - y/z\""));
    for v in VARS {
        spec = spec.input_default(
            v,
            "float",
            serde_json::Value::Null,
            "a variable of the formula",
        );
    }
    r.register(spec, |p| {
        let text = p.str("expr")?;
        let ex = FlatEx::<f64>::parse(text)
            .map_err(|e| format!("param 'expr': cannot parse {text:?}: {e}"))?;
        let names: Vec<String> = ex.var_names().to_vec();
        if let Some(bad) = names.iter().find(|n| !VARS.contains(&n.as_str())) {
            return Err(format!(
                "param 'expr': unknown variable '{bad}' (variables are {})",
                VARS.join(" ")
            ));
        }
        let mut vals = vec![0.0; names.len()];
        Ok(Kernel::from_fn(move |cx| {
            for (i, n) in names.iter().enumerate() {
                vals[i] = match cx.input_opt(n)? {
                    Some(v) => v.get::<f64>().copied().unwrap_or(f64::NAN),
                    None => {
                        return Err(NodeError::Input {
                            port: n.clone(),
                            message: "the formula uses this variable but nothing is connected"
                                .into(),
                        });
                    }
                };
            }
            let v = ex
                .eval(&vals)
                .map_err(|e| NodeError::Failed(format!("formula failed: {e}")))?;
            if !v.is_finite() {
                return Err(NodeError::Failed(format!(
                    "formula gave {v} for inputs {names:?} = {vals:?}"
                )));
            }
            cx.set("out", v);
            Ok(())
        }))
    })
}

#[cfg(test)]
mod tests {
    use weft_graph::{Context, load_str};

    fn graph(expr: &str) -> String {
        format!(
            r#"{{"format":"weft-graph","version":1,"nodes":{{
            "p":{{"type":"value.float","params":{{"value":3.0}}}},
            "q":{{"type":"value.float","params":{{"value":4.0}}}},
            "e":{{"type":"math.expr","params":{{"expr":"{expr}"}},"inputs":{{"x":"p.out","y":"q.out"}}}}}},
            "outputs":{{"v":"e.out"}}}}"#
        )
    }

    #[test]
    fn evaluates_with_float_semantics() {
        let reg = crate::registry();
        let mut g = load_str(&reg, &graph("sqrt(x^2 + y^2) + 1/2"), "t").unwrap();
        assert_eq!(
            g.pull("v", Context::new(0)).unwrap().get::<f64>(),
            Some(&5.5)
        );
    }

    #[test]
    fn bad_formulas_fail_at_load_or_say_which_input() {
        let reg = crate::registry();
        let e = load_str(&reg, &graph("x + (y"), "t").unwrap_err();
        assert!(
            e.to_string()
                .contains("node 'e': params: param 'expr': cannot parse"),
            "{e}"
        );
        let e = load_str(&reg, &graph("x + q"), "t").unwrap_err();
        assert!(e.to_string().contains("unknown variable 'q'"), "{e}");
        let mut g = load_str(&reg, &graph("x + z"), "t").unwrap();
        let e = g.pull("v", Context::new(0)).unwrap_err();
        assert_eq!(
            e.to_string(),
            "node 'e': input 'z': the formula uses this variable but nothing is connected"
        );
    }
}
