//! Running scenes as users do: graph files loaded with the standard node library and set
//! with the overrides `weft run --set` makes.

use std::sync::{Arc, OnceLock};
use weft_graph::{Graph, Registry};

/// The standard registry, built once.
fn registry() -> &'static Arc<Registry> {
    static R: OnceLock<Arc<Registry>> = OnceLock::new();
    R.get_or_init(weft_nodes::registry)
}

/// Loads a scene template (`name` labels its errors).
pub fn load(template: &str, name: &str) -> Result<Graph, String> {
    weft_graph::load_str(registry(), template, name).map_err(|e| e.to_string())
}

/// Sets `node.param` (or `instance.stage.param` inside a composite) as `weft run --set` does.
pub fn set(g: &mut Graph, what: &str, value: serde_json::Value) -> Result<(), String> {
    let (node, param) = what
        .split_once('.')
        .ok_or_else(|| format!("{what}: expected node.param"))?;
    g.set_param(node, param, value)
        .map_err(|d| format!("{what}: {}", d.describe()))
}
