//! The Rust side of the plugin API: a crate outside `weft-graph` registers its own port type
//! (with JSON form and byte codec) and node types, and graphs use them like built-ins,
//! including copy-on-write sharing and the disk cache.

mod common;
use std::sync::Arc;
use weft::graph::{
    Context, Kernel, NodeSpec, ParamSpec, PortType, Registry, RegistryError, Value, load_str,
};

/// A plugin's data type: a polyline.
#[derive(Clone, Debug, PartialEq)]
struct Polyline(Vec<[f64; 2]>);

fn plugin_registry() -> Arc<Registry> {
    let mut r = Registry::new();
    weft::nodes::register_all(&mut r).unwrap();
    r.register_port_type(
        PortType::of::<Polyline>("polyline", "2-D points joined in order").with_codec(
            |v| {
                v.get::<Polyline>().map(|p| {
                    p.0.iter()
                        .flat_map(|q| q.iter().flat_map(|x| x.to_le_bytes()))
                        .collect()
                })
            },
            |b| {
                let xs: Vec<f64> = b
                    .chunks_exact(8)
                    .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
                    .collect();
                Ok(Value::new(Polyline(
                    xs.chunks_exact(2).map(|c| [c[0], c[1]]).collect(),
                )))
            },
        ),
    )
    .unwrap();
    r.register(
        NodeSpec::new("poly.circle", "a regular polygon on the unit circle")
            .output("out", "polyline", "the polygon")
            .param(
                ParamSpec::int("segments", 8)
                    .ge(3.0)
                    .doc("number of vertices"),
            ),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let n = cx.params().i64("segments")?;
                let pts = (0..=n).map(|i| {
                    let a = std::f64::consts::TAU * i as f64 / n as f64;
                    [a.cos(), a.sin()]
                });
                cx.set("out", Value::new(Polyline(pts.collect())));
                Ok(())
            }))
        },
    )
    .unwrap();
    r.register(
        NodeSpec::new("poly.length", "total length of a polyline")
            .input("p", "polyline", "the polyline")
            .output("out", "float", "length"),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let p = cx.input_as::<Polyline>("p")?;
                let l =
                    p.0.windows(2)
                        .map(|w| ((w[1][0] - w[0][0]).powi(2) + (w[1][1] - w[0][1]).powi(2)).sqrt())
                        .sum::<f64>();
                cx.set("out", l);
                Ok(())
            }))
        },
    )
    .unwrap();
    // A registration that names an unknown port type is refused, not deferred to load time.
    let e = r.register(
        NodeSpec::new("poly.bad", "x").input("m", "point_cloud", "x"),
        |_| Err("unused".into()),
    );
    assert_eq!(
        e,
        Err(RegistryError::UnknownPortType {
            node: "poly.bad".into(),
            port: "m".into(),
            ty: "point_cloud".into()
        })
    );
    Arc::new(r)
}

#[test]
fn plugin_types_load_run_type_check_and_cache() {
    let reg = plugin_registry();
    let dir = tempfile::tempdir().unwrap();
    let text = format!(
        r#"{{"format": "weft-graph", "version": 1, "nodes": {{
            "c": {{"type": "poly.circle", "params": {{"segments": 64}}}},
            "disk": {{"type": "cache.disk", "inputs": {{"in": "c.out"}}, "params": {{"path": {:?}}}}},
            "l": {{"type": "poly.length", "inputs": {{"p": "disk.out"}}}}}},
            "outputs": {{"length": "l.out", "shape": "c.out"}}}}"#,
        dir.path().to_str().unwrap()
    );
    let mut g = load_str(&reg, &text, "plugin").unwrap();
    // Perimeter of a regular 64-gon inscribed in the unit circle: 2n sin(π/n).
    let want = 128.0 * (std::f64::consts::PI / 64.0).sin();
    let l = *g
        .pull("length", Context::new(0))
        .unwrap()
        .get::<f64>()
        .unwrap();
    assert!((l - want).abs() < 1e-13, "{l} vs {want}");
    // The shape output and the cache share one allocation: no copy was made on the way.
    let a = g.pull("shape", Context::new(0)).unwrap();
    let b = g.pull("shape", Context::new(0)).unwrap();
    assert!(a.ptr_eq(&b));
    // A fresh run reads the polyline back from disk through the plugin's codec.
    let mut g2 = load_str(&reg, &text, "plugin").unwrap();
    assert_eq!(
        g2.pull("length", Context::new(0)).unwrap().get::<f64>(),
        Some(&l)
    );
    assert_eq!(g2.evaluations("c"), 0);
    // Static type checking covers plugin types too (cache.disk passes the type through).
    let bad = text
        .replace(r#""p": "disk.out""#, r#""p": "c2.out""#)
        .replace(r#""l": {"#, r#""c2": {"type": "value.float"}, "l": {"#);
    let e = load_str(&reg, &bad, "plugin").unwrap_err().to_string();
    assert!(
        e.contains("type mismatch: 'c2.out' is float, this input takes polyline"),
        "{e}"
    );
}

/// The header every graph file starts with.
const H: &str = r#""format": "weft-graph", "version": 1"#;

#[test]
fn a_parameter_that_types_an_output_cannot_change_after_load() {
    let mut reg = Registry::new();
    weft::nodes::register_all(&mut reg).unwrap();
    reg.register(
        NodeSpec::new("parse", "JSON to a value of the named type")
            .output("out", "param:type", "value")
            .param(ParamSpec::string("type", "float").doc("port type"))
            .param(ParamSpec::json("value", serde_json::json!(1.0)).doc("the value")),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let t = cx.params().str("type")?.to_string();
                let j = cx.params().get("value").cloned().unwrap_or_default();
                let f = cx
                    .registry()
                    .port_type(&t)
                    .and_then(|p| p.from_json)
                    .expect("checked at load");
                let v: Value = f(&j).map_err(weft::graph::NodeError::Failed)?;
                cx.set("out", v);
                Ok(())
            }))
        },
    )
    .unwrap();
    let reg = std::sync::Arc::new(reg);
    let text = format!(
        r#"{{{H}, "nodes": {{"p": {{"type": "parse"}}, "s": {{"type": "math.scale", "inputs": {{"x": "p.out"}}}}}}, "outputs": {{"y": "s.out"}}}}"#
    );
    let mut g = load_str(&reg, &text, "t").unwrap();
    assert_eq!(
        g.pull("y", Context::new(0)).unwrap().get::<f64>(),
        Some(&1.0)
    );
    let e = g
        .set_param("p", "type", serde_json::json!("bool"))
        .unwrap_err();
    assert!(
        e.describe()
            .starts_with("node 'p': param 'type': sets an output's type"),
        "{}",
        e.describe()
    );
    g.set_param("p", "value", serde_json::json!(4.0)).unwrap();
    assert_eq!(
        g.pull("y", Context::new(0)).unwrap().get::<f64>(),
        Some(&4.0)
    );
}
