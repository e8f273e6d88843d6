//! `weft schema`: the graph files' JSON Schema, checked with a JSON Schema validator (the
//! `jsonschema` crate, as an editor would use the schema): every example graph is valid,
//! and an unknown parameter, an out-of-range value, a malformed connection and an unknown
//! input port are not.

use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn schema() -> jsonschema::Validator {
    let o = Command::new(env!("CARGO_BIN_EXE_weft"))
        .arg("schema")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let schema: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(
        schema["$schema"],
        "https://json-schema.org/draft/2020-12/schema"
    );
    jsonschema::draft202012::new(&schema).expect("a valid JSON Schema")
}

fn example(name: &str) -> serde_json::Value {
    let text = std::fs::read_to_string(root().join("graphs").join(name)).unwrap();
    serde_json::from_str(&text).unwrap()
}

#[test]
fn every_example_graph_is_valid() {
    let v = schema();
    let mut n = 0;
    for e in std::fs::read_dir(root().join("graphs")).unwrap() {
        let path = e.unwrap().path();
        if path.extension().is_none_or(|x| x != "json") {
            continue;
        }
        let name = path.file_name().unwrap().to_str().unwrap().to_string();
        let g = example(&name);
        let errors: Vec<String> = v.iter_errors(&g).map(|e| e.to_string()).collect();
        assert!(errors.is_empty(), "{name}: {errors:?}");
        n += 1;
    }
    assert!(n >= 15, "{n} example graphs");
}

#[test]
fn what_the_loader_refuses_the_schema_refuses() {
    let v = schema();
    let base = example("cloth_drape.json");
    assert!(v.is_valid(&base));
    type Edit = fn(&mut serde_json::Value);
    let cases: [(&str, Edit); 6] = [
        ("an unknown parameter", |g| {
            g["nodes"]["grid"]["params"]["nz"] = 4.into()
        }),
        ("a value below its range", |g| {
            g["nodes"]["contact"]["params"]["thickness"] = (-1.0).into()
        }),
        ("a value of the wrong kind", |g| {
            g["nodes"]["grid"]["params"]["nx"] = "many".into()
        }),
        ("a choice not among the choices", |g| {
            g["nodes"]["grid"]["params"]["plane"] = "xw".into()
        }),
        ("an unknown input port", |g| {
            g["nodes"]["cloth"]["inputs"]["curves"] = "grid.mesh".into()
        }),
        ("a connection that is not node.port", |g| {
            g["nodes"]["cloth"]["inputs"]["mesh"] = "grid".into()
        }),
    ];
    for (what, edit) in cases {
        let mut g = base.clone();
        edit(&mut g);
        assert!(!v.is_valid(&g), "{what} passed");
    }
    // A parameter connected like an input (an animated parameter) is an input port too.
    let mut g = base.clone();
    g["nodes"]["contact"]["params"]
        .as_object_mut()
        .unwrap()
        .remove("thickness");
    g["nodes"]["contact"]["inputs"]["thickness"] = "band.out".into();
    assert!(v.is_valid(&g));
}
