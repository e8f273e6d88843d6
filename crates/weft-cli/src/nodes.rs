//! `weft nodes`: the registry, printed.

use std::fmt::Write;
use std::sync::Arc;
use weft_graph::{NodeSpec, ParamKind, Registry};

fn kind_text(k: &ParamKind) -> String {
    use std::ops::Bound::*;
    match k {
        ParamKind::Float { min, max } => {
            let lo = match min {
                Included(x) => format!(" >= {x}"),
                Excluded(x) => format!(" > {x}"),
                Unbounded => String::new(),
            };
            let hi = match max {
                Included(x) => format!(" <= {x}"),
                Excluded(x) => format!(" < {x}"),
                Unbounded => String::new(),
            };
            format!("float{lo}{hi}")
        }
        ParamKind::Int { min, max } => {
            let lo = min.map(|m| format!(" >= {m}")).unwrap_or_default();
            let hi = max.map(|m| format!(" <= {m}")).unwrap_or_default();
            format!("int{lo}{hi}")
        }
        ParamKind::Bool => "bool".into(),
        ParamKind::String => "string".into(),
        ParamKind::Enum(c) => format!("one of {}", c.join("|")),
        ParamKind::Vec3 => "vec3".into(),
        ParamKind::FloatList => "floats".into(),
        ParamKind::Json => "json".into(),
    }
}

/// The registry as text (or JSON), optionally filtered by a substring of the type name.
/// Library subgraphs (composite node types such as `solver.coupled`) are listed with the
/// registered types.
pub fn render(reg: &Arc<Registry>, json: bool, filter: Option<&str>) -> String {
    let (library, _) = weft_graph::library_specs(reg);
    let mut specs: Vec<&NodeSpec> = reg.specs().chain(library.iter()).collect();
    specs.sort_by(|a, b| a.name.cmp(&b.name));
    specs.retain(|s| filter.is_none_or(|f| s.name.contains(f)));
    if json {
        let ports: Vec<_> = reg
            .port_types()
            .map(|t| serde_json::json!({"name": t.name, "doc": t.doc, "disk_cacheable": t.encode.is_some()}))
            .collect();
        let v = serde_json::json!({"port_types": ports, "node_types": specs});
        return serde_json::to_string_pretty(&v).unwrap_or_default() + "\n";
    }
    let mut out = String::new();
    for s in specs {
        let time = format!("{:?}", s.time).to_lowercase();
        let _ = writeln!(out, "{}  ({time})\n  {}", s.name, s.doc);
        for p in &s.inputs {
            let mut extra = String::new();
            if p.multi {
                extra.push_str(", list");
            }
            if let Some(d) = &p.default {
                let _ = write!(extra, ", default {d}");
            } else if !p.required {
                extra.push_str(", optional");
            }
            let _ = writeln!(
                out,
                "  in   {:<10} {}{extra} — {}",
                p.name,
                p.ty.describe(),
                p.doc
            );
        }
        for p in &s.outputs {
            let _ = writeln!(out, "  out  {:<10} {} — {}", p.name, p.ty.describe(), p.doc);
        }
        for p in &s.params {
            let def = p
                .default
                .as_ref()
                .map(|d| format!(" = {d}"))
                .unwrap_or_else(|| " (required)".into());
            let unit = if p.unit.is_empty() {
                String::new()
            } else {
                format!(" [{}]", p.unit)
            };
            let _ = writeln!(
                out,
                "  param {:<9} {}{def}{unit} — {}",
                p.name,
                kind_text(&p.kind),
                p.doc
            );
        }
        out.push('\n');
    }
    if filter.is_none() {
        out.push_str("port types\n");
        for t in reg.port_types() {
            let disk = if t.encode.is_some() {
                ""
            } else {
                " (not disk-cacheable)"
            };
            let _ = writeln!(out, "  {:<10} {}{disk}", t.name, t.doc);
        }
    }
    out
}
