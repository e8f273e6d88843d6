//! Validation and compilation: authoring model → [`Graph`].
//!
//! Every check collects into one list, so a file with five mistakes gets five messages, each
//! naming the node, the port or parameter, and the line. Anything that passes here cannot fail
//! later for a structural reason: types match, required inputs are connected, there are no
//! cycles, parameters are in range, and node factories have accepted their parameters.

use crate::body::{Env, LocalType, compile_body, cycles};
use crate::composite::{CompositeKernel, CompositePlan};
use crate::diag::{Diagnostic, LoadError, Severity, nearest};
use crate::engine::Graph;
use crate::file::{FileModel, Ref, SubgraphDecl, parse_model};
use crate::locate;
use crate::node::Factory;
use crate::params::Params;
use crate::registry::Registry;
use crate::spec::{NodeSpec, ParamSpec, TimeClass};

use petgraph::graph::DiGraph;
use std::collections::{BTreeMap, HashMap};
use std::sync::Arc;

/// Loads a graph from JSON text. `source_name` labels messages (a path or `<memory>`).
pub fn load_str(
    registry: &Arc<Registry>,
    text: &str,
    source_name: &str,
) -> Result<Graph, LoadError> {
    let fail = |diagnostics| LoadError {
        source_name: source_name.to_string(),
        diagnostics,
    };
    let root: serde_json::Value = match serde_json::from_str(text) {
        Ok(v) => v,
        Err(e) => {
            let mut d = Diagnostic::error(vec![], format!("invalid JSON: {e}"));
            d.line = Some(e.line());
            d.column = Some(e.column());
            // serde_json appends " at line L column C"; keep the message short.
            if let Some(i) = d.message.find(" at line ") {
                d.message.truncate(i);
            }
            return Err(fail(vec![d]));
        }
    };
    let dups = locate::scan(text, false).duplicates;
    let mut d = Vec::new();
    for (path, line, col) in &dups {
        let what = match path.as_slice() {
            [nodes, id] if nodes == "nodes" => format!("duplicate node id '{id}'"),
            _ => format!(
                "duplicate key '{}'",
                path.last().cloned().unwrap_or_default()
            ),
        };
        let mut x = Diagnostic::error(path.clone(), what);
        if path.len() == 2 && path[0] == "nodes" {
            x.node = Some(path[1].clone());
        }
        x.line = Some(*line);
        x.column = Some(*col);
        d.push(x);
    }
    let model = parse_model(&root, &mut d);
    let graph = compile_model(registry, &model, &mut d);
    let loc = if d.iter().any(|x| x.line.is_none()) {
        locate::scan(text, true)
    } else {
        Default::default()
    };
    for x in &mut d {
        if x.line.is_none()
            && let Some((l, c)) = loc.find(&x.path)
        {
            x.line = Some(l);
            x.column = Some(c);
        }
    }
    d.sort_by_key(|x| (x.line.unwrap_or(0), x.column.unwrap_or(0)));
    match graph {
        Some(mut g) if !d.iter().any(|x| x.severity == Severity::Error) => {
            g.load_warnings = d;
            Ok(g)
        }
        _ => Err(fail(d)),
    }
}

/// Loads a graph file.
pub fn load_path(registry: &Arc<Registry>, path: &std::path::Path) -> Result<Graph, LoadError> {
    let name = path.display().to_string();
    match std::fs::read_to_string(path) {
        Ok(text) => load_str(registry, &text, &name),
        Err(e) => Err(LoadError {
            source_name: name,
            diagnostics: vec![Diagnostic::error(vec![], format!("cannot read file: {e}"))],
        }),
    }
}

fn compile_model(
    registry: &Arc<Registry>,
    m: &FileModel,
    d: &mut Vec<Diagnostic>,
) -> Option<Graph> {
    // Library subgraphs are compiled with the file's own; a file may not reuse their names.
    let mut subs = registry.library().clone();
    for (name, s) in &m.subgraphs {
        if subs.contains_key(name) {
            d.push(Diagnostic::error(
                s.path.clone(),
                format!("subgraph '{name}' has the name of a library subgraph (copy it under another name to change it)"),
            ));
        } else {
            subs.insert(name.clone(), s.clone());
        }
    }
    let env = build_local_types(registry, &subs, d);
    let outputs: Vec<(String, &Ref)> = m.outputs.iter().map(|(k, r)| (k.clone(), r)).collect();
    let before = d.iter().filter(|x| x.severity == Severity::Error).count();
    let g = compile_body(&env, &m.nodes, &outputs, None, None, d);
    if m.outputs.is_empty() && !m.nodes.is_empty() {
        d.push(
            Diagnostic::error(
                vec![],
                "the file declares no 'outputs': nothing would be computed",
            )
            .warning(),
        );
    }
    let after = d.iter().filter(|x| x.severity == Severity::Error).count();
    if after > before { None } else { g }
}

/// The node specs of the registry's library subgraphs (compiled against the registry), with
/// any problem in their definitions as diagnostics.
pub fn library_specs(registry: &Arc<Registry>) -> (Vec<NodeSpec>, Vec<Diagnostic>) {
    let mut d = Vec::new();
    let env = build_local_types(registry, registry.library(), &mut d);
    let specs = env.local.values().map(|t| (*t.spec).clone()).collect();
    (specs, d)
}

/// Orders subgraphs so each comes after those it instances; rejects recursion.
fn build_local_types(
    registry: &Arc<Registry>,
    subs: &BTreeMap<String, SubgraphDecl>,
    d: &mut Vec<Diagnostic>,
) -> Env {
    let names: Vec<&String> = subs.keys().collect();
    let index: HashMap<&str, usize> = names
        .iter()
        .enumerate()
        .map(|(i, n)| (n.as_str(), i))
        .collect();
    let mut dg = DiGraph::<usize, ()>::new();
    let ix: Vec<_> = (0..names.len()).map(|i| dg.add_node(i)).collect();
    for (i, name) in names.iter().enumerate() {
        if registry.node_type(name).is_some() {
            d.push(Diagnostic::error(
                subs[*name].path.clone(),
                format!("subgraph '{name}' has the name of a registered node type"),
            ));
        }
        for n in subs[*name].nodes.values() {
            if let Some(&j) = index.get(n.ty.as_str()) {
                dg.add_edge(ix[j], ix[i], ());
            }
        }
    }
    let mut env = Env {
        registry: registry.clone(),
        local: Arc::new(BTreeMap::new()),
    };
    let order = match petgraph::algo::toposort(&dg, None) {
        Ok(o) => o,
        Err(_) => {
            for cycle in cycles(&dg) {
                let path: Vec<&str> = cycle.iter().map(|&i| names[i].as_str()).collect();
                d.push(Diagnostic::error(
                    subs[names[cycle[0]]].path.clone(),
                    format!(
                        "subgraphs instance each other in a cycle: {} -> {}",
                        path.join(" -> "),
                        path[0]
                    ),
                ));
            }
            return env;
        }
    };
    for i in order {
        let name = names[dg[i]];
        if let Some(t) = local_type(&env, name, &subs[name], d) {
            let mut local = (*env.local).clone();
            local.insert(name.clone(), t);
            env.local = Arc::new(local);
        }
    }
    env
}

/// Validates one subgraph and makes its node type.
fn local_type(
    env: &Env,
    name: &str,
    s: &SubgraphDecl,
    d: &mut Vec<Diagnostic>,
) -> Option<LocalType> {
    let before = d.len();
    // A subgraph's inner graph sees only the current frame's inputs, so state inside it
    // would restart whenever they change: no stateful node (nor stepped subgraph) inside any
    // subgraph, at any depth (each body is checked when its own type is built).
    let forbid = Some("a subgraph");
    for (k, i) in &s.inputs {
        if i.ty != "any" && env.registry.port_type(&i.ty).is_none() {
            let known = env.registry.port_types().map(|t| t.name.as_str());
            d.push(
                Diagnostic::error(
                    i.path.clone(),
                    format!("input '{k}' has unknown type '{}'", i.ty),
                )
                .help(nearest(&i.ty, known)),
            );
        } else if let Some(j) = &i.default
            && !j.is_null()
            && env.registry.json_value(&i.ty, j).is_none()
        {
            let why = match env.registry.port_type(&i.ty).and_then(|t| t.from_json) {
                Some(f) => f(j).err().unwrap_or_default(),
                None => format!("type '{}' has no JSON form", i.ty),
            };
            d.push(Diagnostic::error(
                i.path.clone(),
                format!("input '{k}': bad default: {why}"),
            ));
        }
    }
    let outputs: Vec<(String, &Ref)> = s
        .outputs
        .iter()
        .map(|(k, o)| (k.clone(), &o.from))
        .collect();
    let g = compile_body(env, &s.nodes, &outputs, Some(&s.inputs), forbid, d);
    let tag = |x: &mut Diagnostic| {
        let n = x
            .node
            .take()
            .map(|n| format!("{name}/{n}"))
            .unwrap_or_else(|| name.to_string());
        x.node = Some(n);
    };
    for x in &mut d[before..] {
        tag(x);
    }
    let g = g?;
    // The hash of a subgraph type covers the definitions of the subgraphs it instances, so a
    // cache downstream notices an edit at any depth.
    let deps: Vec<u128> = s
        .nodes
        .values()
        .filter_map(|n| env.local.get(&n.ty))
        .map(|t| t.hash)
        .collect();
    let plan = CompositePlan::resolve(name, s, &g, &env.registry, &deps, d);
    let plan = match plan {
        Some(p) if d.len() == before => p,
        _ => {
            for x in &mut d[before..] {
                if x.node.as_deref().is_none_or(|n| !n.starts_with(name)) {
                    tag(x);
                }
            }
            return None;
        }
    };
    let time = if s.step.is_some() {
        TimeClass::Stateful
    } else if !g.any_time_dependent() {
        TimeClass::Static
    } else {
        TimeClass::Animated
    };
    let mut spec = NodeSpec::new(
        name,
        if s.doc.is_empty() {
            "subgraph defined in the graph file"
        } else {
            &s.doc
        },
    );
    for (k, i) in &s.inputs {
        spec = match &i.default {
            Some(v) => spec.input_default(k, &i.ty, v.clone(), &i.doc),
            None => spec.input(k, &i.ty, &i.doc),
        };
    }
    for (k, o) in &s.outputs {
        let ty = g.output_type(k).unwrap_or("any").to_string();
        spec = spec.output(k, &ty, &o.doc);
    }
    if let Some(it) = &s.iterate {
        spec = spec.param(
            ParamSpec::int("max_iterations", it.max_iterations)
                .ge(1.0)
                .doc("iteration limit of the loop"),
        );
    }
    spec = spec.time(time);
    // Inner parameters are settable on the instance as "stage.param".
    for id in g.node_ids() {
        if let (Some(ns), Some(ps)) = (g.node_spec(id), g.node_params(id)) {
            for p in &ns.params {
                let mut q = p.clone();
                q.name = format!("{id}.{}", p.name);
                q.default = ps.get(&p.name).cloned();
                spec = spec.param(q);
            }
        }
    }
    let hash = plan.hash();
    let plan = Arc::new(plan);
    let env2 = env.clone();
    let decl = Arc::new(s.clone());
    let sub_name = name.to_string();
    let factory: Factory = Arc::new(move |params: &Params| {
        let mut dd = Vec::new();
        let outputs: Vec<(String, &Ref)> = decl
            .outputs
            .iter()
            .map(|(k, o)| (k.clone(), &o.from))
            .collect();
        let g = compile_body(
            &env2,
            &decl.nodes,
            &outputs,
            Some(&decl.inputs),
            forbid,
            &mut dd,
        )
        .ok_or_else(|| format!("subgraph '{sub_name}' failed to compile"))?;
        CompositeKernel::build(g, plan.clone(), params)
    });
    Some(LocalType {
        spec: Arc::new(spec),
        factory,
        hash,
    })
}
