//! Validation and compilation: authoring model → [`Graph`].
//!
//! Every check collects into one list, so a file with five mistakes gets five messages, each
//! naming the node, the port or parameter, and the line. Anything that passes here cannot fail
//! later for a structural reason: types match, required inputs are connected, there are no
//! cycles, parameters are in range, and node factories have accepted their parameters.

use crate::composite::{CompositeKernel, CompositePlan};
use crate::diag::{Diagnostic, LoadError, Severity, nearest};
use crate::engine::{Graph, Slot};
use crate::file::{FileModel, NodeDecl, Ref, SubInput, SubgraphDecl, parse_model};
use crate::locate;
use crate::params::{Params, check_param};
use crate::registry::{Factory, Registry};
use crate::spec::{NodeSpec, ParamSpec, TimeClass, TypeRef};
use crate::value::Value;
use petgraph::graph::DiGraph;
use std::collections::{BTreeMap, HashMap};
use std::sync::Arc;

/// A node type defined by a subgraph in the file being loaded.
#[derive(Clone)]
pub(crate) struct LocalType {
    spec: Arc<NodeSpec>,
    factory: Factory,
    hash: u128,
}

/// What a body can instance: the registry plus the file's own subgraph types.
#[derive(Clone)]
pub(crate) struct Env {
    pub registry: Arc<Registry>,
    local: Arc<BTreeMap<String, LocalType>>,
}

impl Env {
    fn lookup(&self, name: &str) -> Option<(Arc<NodeSpec>, Factory)> {
        if let Some(t) = self.registry.node_type(name) {
            return Some((t.spec.clone(), t.factory.clone()));
        }
        self.local
            .get(name)
            .map(|t| (t.spec.clone(), t.factory.clone()))
    }
    fn suggest(&self, name: &str) -> Option<String> {
        let names = self
            .registry
            .specs()
            .map(|s| s.name.as_str())
            .chain(self.local.keys().map(|s| s.as_str()));
        nearest(name, names)
    }
}

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
            && json_value(&env.registry, &i.ty, j).is_none()
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

/// Where a connection comes from, before slots are numbered.
#[derive(Clone, Copy)]
enum Src {
    Node(usize, usize),
    In(usize),
}

struct Pre<'a> {
    id: &'a str,
    decl: &'a NodeDecl,
    spec: Arc<NodeSpec>,
    factory: Factory,
    /// Every parameter validated (present, of its kind, in range).
    params_ok: bool,
    params: Params,
    conns: Vec<Vec<Src>>,
}

fn parse_ref_parts<'a>(
    r: &'a Ref,
    d: &mut Vec<Diagnostic>,
    node: &str,
    field: &str,
) -> Option<(&'a str, &'a str)> {
    match r.text.split_once('.') {
        Some((n, p)) if !n.is_empty() && !p.is_empty() => Some((n, p)),
        _ => {
            d.push(
                Diagnostic::error(
                    r.path.clone(),
                    format!("expected \"node.port\", got \"{}\"", r.text),
                )
                .node(node)
                .field(field),
            );
            None
        }
    }
}

/// Resolves `node.port` (or `in.name` inside a subgraph) to a source.
fn resolve(
    r: &Ref,
    pre: &[Pre],
    by_id: &HashMap<&str, usize>,
    sub_inputs: Option<&BTreeMap<String, SubInput>>,
    node: &str,
    field: &str,
    d: &mut Vec<Diagnostic>,
) -> Option<Src> {
    let (n, p) = parse_ref_parts(r, d, node, field)?;
    if let (Some(si), "in") = (sub_inputs, n) {
        return match si.keys().position(|k| k == p) {
            Some(i) => Some(Src::In(i)),
            None => {
                d.push(
                    Diagnostic::error(r.path.clone(), format!("the subgraph has no input '{p}'"))
                        .node(node)
                        .field(field)
                        .help(nearest(p, si.keys().map(|s| s.as_str()))),
                );
                None
            }
        };
    }
    let Some(&j) = by_id.get(n) else {
        d.push(
            Diagnostic::error(r.path.clone(), format!("connection to unknown node '{n}'"))
                .node(node)
                .field(field)
                .help(nearest(n, by_id.keys().copied())),
        );
        return None;
    };
    match pre[j].spec.output_index(p) {
        Some(k) => Some(Src::Node(j, k)),
        None => {
            let outs: Vec<&str> = pre[j]
                .spec
                .outputs
                .iter()
                .map(|o| o.name.as_str())
                .collect();
            d.push(
                Diagnostic::error(
                    r.path.clone(),
                    format!(
                        "node '{n}' ({}) has no output '{p}' (outputs: {})",
                        pre[j].spec.name,
                        outs.join(", ")
                    ),
                )
                .node(node)
                .field(field)
                .help(nearest(p, outs.iter().copied())),
            );
            None
        }
    }
}

/// Compiles one set of nodes (the file's top level or a subgraph's body).
pub(crate) fn compile_body(
    env: &Env,
    nodes: &BTreeMap<String, NodeDecl>,
    outputs: &[(String, &Ref)],
    sub_inputs: Option<&BTreeMap<String, SubInput>>,
    forbid_stateful: Option<&str>,
    d: &mut Vec<Diagnostic>,
) -> Option<Graph> {
    let errors_at_start = d.iter().filter(|x| x.severity == Severity::Error).count();
    let mut pre: Vec<Pre> = Vec::new();
    // Pass 1: types and parameters.
    for (id, decl) in nodes {
        if sub_inputs.is_some() && id == "in" {
            d.push(
                Diagnostic::error(
                    decl.path.clone(),
                    "'in' is reserved inside subgraphs for the subgraph's inputs",
                )
                .node(id),
            );
            continue;
        }
        let Some((spec, factory)) = env.lookup(&decl.ty) else {
            d.push(
                Diagnostic::error(
                    decl.at(&["type"]),
                    format!("unknown node type '{}'", decl.ty),
                )
                .node(id)
                .help(env.suggest(&decl.ty)),
            );
            continue;
        };
        if let (Some(what), TimeClass::Stateful) = (forbid_stateful, spec.time) {
            d.push(Diagnostic::error(
                decl.at(&["type"]),
                format!("stateful node type '{}' cannot run inside {what}: the inner graph sees only the current frame's inputs, so its state would restart whenever they change (use it outside; a stepped subgraph is itself the stateful node)", spec.name),
            ).node(id));
        }
        // A node whose parameters did not all validate never reaches its factory (nor has an
        // output type read from a parameter): factories may rely on every declared parameter
        // being present, of its kind and in range.
        let errors_before = d.len();
        let mut values = BTreeMap::new();
        for (k, v) in &decl.params {
            let path = || decl.at(&["params", k]);
            match spec.param_spec(k) {
                None => d.push(
                    Diagnostic::error(path(), format!("'{}' has no such parameter", spec.name))
                        .node(id)
                        .field(format!("param '{k}'"))
                        .help(nearest(k, spec.params.iter().map(|p| p.name.as_str()))),
                ),
                Some(ps) => match check_param(ps, v) {
                    Ok(v) => {
                        values.insert(k.clone(), v);
                    }
                    Err(m) => d.push(
                        Diagnostic::error(path(), m)
                            .node(id)
                            .field(format!("param '{k}'")),
                    ),
                },
            }
        }
        for ps in &spec.params {
            if !values.contains_key(&ps.name) && !decl.params.contains_key(&ps.name) {
                match &ps.default {
                    Some(v) => {
                        values.insert(ps.name.clone(), v.clone());
                    }
                    None => d.push(
                        Diagnostic::error(
                            decl.path.clone(),
                            format!("missing required parameter ({})", ps.doc),
                        )
                        .node(id)
                        .field(format!("param '{}'", ps.name)),
                    ),
                }
            }
        }
        let n_in = spec.inputs.len();
        let params_ok = d.len() == errors_before;
        pre.push(Pre {
            id,
            decl,
            spec,
            factory,
            params_ok,
            params: Params::from_map(values),
            conns: vec![Vec::new(); n_in],
        });
    }
    let by_id: HashMap<&str, usize> = pre.iter().enumerate().map(|(i, p)| (p.id, i)).collect();
    // Pass 2: connections.
    for i in 0..pre.len() {
        let (id, decl, spec) = (pre[i].id, pre[i].decl, pre[i].spec.clone());
        for (port, (refs, is_list)) in &decl.inputs {
            let path = || decl.at(&["inputs", port]);
            let field = format!("input '{port}'");
            let Some(pi) = spec.input_index(port) else {
                let names: Vec<&str> = spec.inputs.iter().map(|p| p.name.as_str()).collect();
                d.push(
                    Diagnostic::error(
                        path(),
                        format!(
                            "'{}' has no input '{port}' (inputs: {})",
                            spec.name,
                            names.join(", ")
                        ),
                    )
                    .node(id)
                    .field(field)
                    .help(nearest(port, names.iter().copied())),
                );
                continue;
            };
            if *is_list && !spec.inputs[pi].multi {
                d.push(
                    Diagnostic::error(path(), "takes one connection, got a list")
                        .node(id)
                        .field(field),
                );
                continue;
            }
            for r in refs {
                if let Some(src) = resolve(r, &pre, &by_id, sub_inputs, id, &field, d) {
                    pre[i].conns[pi].push(src);
                }
            }
        }
        for ps in &spec.inputs {
            if ps.required && !decl.inputs.contains_key(&ps.name) {
                d.push(
                    Diagnostic::error(
                        decl.path.clone(),
                        format!("missing required input ({}: {})", ps.ty.describe(), ps.doc),
                    )
                    .node(id)
                    .field(format!("input '{}'", ps.name)),
                );
            }
        }
    }
    let mut outs: Vec<(String, Src, &Ref)> = Vec::new();
    for (name, r) in outputs {
        if let Some(src) = resolve(
            r,
            &pre,
            &by_id,
            sub_inputs,
            "",
            &format!("output '{name}'"),
            d,
        ) {
            outs.push((name.clone(), src, r));
        }
    }
    // Cycles.
    let mut dg = DiGraph::<usize, ()>::new();
    let ix: Vec<_> = (0..pre.len()).map(|i| dg.add_node(i)).collect();
    for (i, p) in pre.iter().enumerate() {
        for src in p.conns.iter().flatten() {
            if let Src::Node(j, _) = src {
                dg.add_edge(ix[*j], ix[i], ());
            }
        }
    }
    let mut has_cycle = false;
    let order: Vec<usize> = match petgraph::algo::toposort(&dg, None) {
        Ok(o) => o.into_iter().map(|n| dg[n]).collect(),
        Err(_) => {
            for cycle in cycles(&dg) {
                let ids: Vec<&str> = cycle.iter().map(|&i| pre[i].id).collect();
                d.push(
                    Diagnostic::error(
                        pre[cycle[0]].decl.path.clone(),
                        format!("cycle: {} -> {}", ids.join(" -> "), ids[0]),
                    )
                    .node(ids[0]),
                );
            }
            // Keep checking types in declaration order: an output whose type is inferred from
            // a source not yet seen stays "any", which never raises a false mismatch.
            has_cycle = true;
            (0..pre.len()).collect()
        }
    };
    // Types, in topological order.
    let in_types: Vec<String> = sub_inputs
        .map(|s| s.values().map(|i| i.ty.clone()).collect())
        .unwrap_or_default();
    let mut out_types: Vec<Vec<String>> = pre
        .iter()
        .map(|p| vec!["any".to_string(); p.spec.outputs.len()])
        .collect();
    let src_type = |s: &Src, out_types: &Vec<Vec<String>>| match s {
        Src::Node(j, k) => out_types[*j][*k].clone(),
        Src::In(k) => in_types[*k].clone(),
    };
    let src_name = |s: &Src| match s {
        Src::Node(j, k) => format!("{}.{}", pre[*j].id, pre[*j].spec.outputs[*k].name),
        Src::In(k) => format!(
            "in.{}",
            sub_inputs
                .and_then(|m| m.keys().nth(*k))
                .cloned()
                .unwrap_or_default()
        ),
    };
    for &i in &order {
        let p = &pre[i];
        for (pi, ps) in p.spec.inputs.iter().enumerate() {
            if let TypeRef::Named(want) = &ps.ty {
                for s in &p.conns[pi] {
                    let got = src_type(s, &out_types);
                    if got != "any" && &got != want {
                        let path = p
                            .decl
                            .inputs
                            .get(&ps.name)
                            .map(|_| p.decl.at(&["inputs", &ps.name]))
                            .unwrap_or_else(|| p.decl.path.clone());
                        d.push(
                            Diagnostic::error(
                                path,
                                format!(
                                    "type mismatch: '{}' is {got}, this input takes {want}",
                                    src_name(s)
                                ),
                            )
                            .node(p.id)
                            .field(format!("input '{}'", ps.name)),
                        );
                    }
                }
            }
        }
        for (k, os) in p.spec.outputs.iter().enumerate() {
            let t = match &os.ty {
                TypeRef::Named(t) => t.clone(),
                TypeRef::Any => "any".into(),
                TypeRef::SameAs(inp) => {
                    let pi = p.spec.input_index(inp).expect("checked at registration");
                    match p.conns[pi].first() {
                        Some(s) => src_type(s, &out_types),
                        None => match &p.spec.inputs[pi].ty {
                            TypeRef::Named(t) => t.clone(),
                            _ => "any".into(),
                        },
                    }
                }
                TypeRef::FromParam(pp) => {
                    // An invalid parameter was reported above; its output stays "any".
                    let t = match p.params.get(pp).and_then(|v| v.as_str()) {
                        Some(t) if p.params_ok => t.to_string(),
                        _ => "any".to_string(),
                    };
                    if t != "any" && env.registry.port_type(&t).is_none() {
                        let path = p
                            .decl
                            .params
                            .get(pp)
                            .map(|_| p.decl.at(&["params", pp]))
                            .unwrap_or_else(|| p.decl.path.clone());
                        d.push(
                            Diagnostic::error(path, format!("unknown port type '{t}'"))
                                .node(p.id)
                                .field(format!("param '{pp}'"))
                                .help(nearest(
                                    &t,
                                    env.registry.port_types().map(|x| x.name.as_str()),
                                )),
                        );
                    }
                    t
                }
            };
            out_types[i][k] = t;
        }
    }
    if has_cycle {
        return None;
    }
    // Factories may reject parameter combinations. They run only on parameters that all
    // validated: a node with a bad parameter already has its error, and its factory would
    // read a value that is not there.
    let mut kernels = Vec::with_capacity(pre.len());
    for p in &pre {
        if !p.params_ok {
            kernels.push(None);
            continue;
        }
        match (p.factory)(&p.params) {
            Ok(k) => kernels.push(Some(k)),
            Err(m) => {
                d.push(
                    Diagnostic::error(p.decl.path.clone(), m)
                        .node(p.id)
                        .field("params"),
                );
                kernels.push(None);
            }
        }
    }
    if d.iter().filter(|x| x.severity == Severity::Error).count() > errors_at_start {
        return None;
    }
    // Build: subgraph inputs first, then nodes in topological order.
    let mut g = Graph::new(env.registry.clone());
    let mut in_slots = Vec::new();
    if let Some(si) = sub_inputs {
        for (name, i) in si {
            let spec = Arc::new(
                NodeSpec::new("graph.input", "a value set from outside the graph")
                    .output("value", &i.ty, &i.doc),
            );
            let mut slot = Slot::new(format!("in.{name}"), spec, Params::default());
            slot.out_type_names = vec![i.ty.clone()];
            slot.out_types = vec![env.registry.port_type(&i.ty).map(|t| t.type_id)];
            let n = g.push_slot(slot);
            if let Some(v) = i
                .default
                .as_ref()
                .and_then(|j| json_value(&env.registry, &i.ty, j))
            {
                g.set_input_initial(n, v);
            }
            g.inputs.insert(name.clone(), n);
            in_slots.push(n);
        }
    }
    let base = in_slots.len();
    let mut slot_of = vec![0usize; pre.len()];
    for (pos, &i) in order.iter().enumerate() {
        slot_of[i] = base + pos;
    }
    for &i in &order {
        let p = &pre[i];
        let mut slot = Slot::new(p.id.to_string(), p.spec.clone(), p.params.clone());
        slot.factory = Some(p.factory.clone());
        let k = kernels[i].take().expect("all factories succeeded");
        slot.external = k.kernel_hash();
        slot.kernel = Some(k);
        for (pi, conns) in p.conns.iter().enumerate() {
            slot.inputs[pi] = conns
                .iter()
                .map(|s| match s {
                    Src::Node(j, k) => (slot_of[*j], *k),
                    Src::In(k) => (in_slots[*k], 0),
                })
                .collect();
            if let (Some(dv), TypeRef::Named(t)) =
                (&p.spec.inputs[pi].default, &p.spec.inputs[pi].ty)
            {
                slot.input_defaults[pi] = json_value(&env.registry, t, dv);
            }
        }
        slot.out_types = out_types[i]
            .iter()
            .map(|t| env.registry.port_type(t).map(|x| x.type_id))
            .collect();
        slot.out_type_names = out_types[i].clone();
        g.push_slot(slot);
    }
    for (name, src, _) in outs {
        let target = match src {
            Src::Node(j, k) => (slot_of[j], k),
            Src::In(k) => (in_slots[k], 0),
        };
        g.outputs.insert(name, target);
    }
    g.finish();
    Some(g)
}

/// A JSON value converted through a port type's JSON form.
pub(crate) fn json_value(reg: &Registry, ty: &str, j: &serde_json::Value) -> Option<Value> {
    reg.port_type(ty)
        .and_then(|t| t.from_json)
        .and_then(|f| f(j).ok())
}

/// One simple cycle per strongly connected component that has one, as node weights in order.
fn cycles(dg: &DiGraph<usize, ()>) -> Vec<Vec<usize>> {
    let mut out = Vec::new();
    for scc in petgraph::algo::tarjan_scc(dg) {
        let start = *scc.iter().min_by_key(|n| dg[**n]).expect("non-empty");
        let self_loop = dg.contains_edge(start, start);
        if scc.len() == 1 && !self_loop {
            continue;
        }
        if self_loop {
            out.push(vec![dg[start]]);
            continue;
        }
        // Walk inside the component until we return to the start: a path exists by strong
        // connectivity; breadth-first search finds the shortest.
        let inside: std::collections::HashSet<_> = scc.iter().copied().collect();
        let mut prev = HashMap::new();
        let mut queue = std::collections::VecDeque::from([start]);
        'bfs: while let Some(n) = queue.pop_front() {
            let mut next: Vec<_> = dg.neighbors(n).filter(|m| inside.contains(m)).collect();
            next.sort_by_key(|m| dg[*m]);
            for m in next {
                if m == start {
                    let mut path = vec![n];
                    let mut c = n;
                    while let Some(&p) = prev.get(&c) {
                        path.push(p);
                        c = p;
                    }
                    path.reverse();
                    out.push(path.into_iter().map(|x| dg[x]).collect());
                    break 'bfs;
                }
                if m != start && !prev.contains_key(&m) {
                    prev.insert(m, n);
                    queue.push_back(m);
                }
            }
        }
    }
    out.sort();
    out
}
