//! Compiling one set of nodes (a file's top level or a subgraph's body) into a [`Graph`]:
//! node types and parameters, connections, cycles, types in topological order, factories,
//! then the slots. Every error is collected with its node, port or parameter.

use crate::diag::{Diagnostic, Severity, nearest};
use crate::engine::{Graph, Slot};
use crate::file::{NodeDecl, Ref, SubInput};
use crate::node::Factory;
use crate::params::{Params, check_param};
use crate::registry::Registry;
use crate::spec::{NodeSpec, TimeClass, TypeRef};
use petgraph::graph::DiGraph;
use std::collections::{BTreeMap, HashMap};
use std::sync::Arc;

/// A node type defined by a subgraph in the file being loaded.
#[derive(Clone)]
pub(crate) struct LocalType {
    pub(crate) spec: Arc<NodeSpec>,
    pub(crate) factory: Factory,
    pub(crate) hash: u128,
}

/// What a body can instance: the registry plus the file's own subgraph types.
#[derive(Clone)]
pub(crate) struct Env {
    pub registry: Arc<Registry>,
    pub(crate) local: Arc<BTreeMap<String, LocalType>>,
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
    /// Parameters driven by a connection: (input index, parameter name).
    links: Vec<(usize, String)>,
}

/// Whether parameter `name` of `spec` can be driven by a connection: a float or an integer
/// (one number, checked against its range at every evaluation).
fn linkable(spec: &NodeSpec, name: &str) -> bool {
    spec.param_spec(name).is_some_and(|ps| {
        matches!(
            ps.kind,
            crate::spec::ParamKind::Float { .. } | crate::spec::ParamKind::Int { .. }
        )
    })
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
            links: Vec::new(),
        });
    }
    let by_id: HashMap<&str, usize> = pre.iter().enumerate().map(|(i, p)| (p.id, i)).collect();
    // Pass 2: connections.
    for i in 0..pre.len() {
        let (id, decl) = (pre[i].id, pre[i].decl);
        let mut spec = pre[i].spec.clone();
        for (port, (refs, is_list)) in &decl.inputs {
            let path = || decl.at(&["inputs", port]);
            let field = format!("input '{port}'");
            let pi = match spec.input_index(port) {
                Some(pi) => Some(pi),
                // A float or integer parameter connected like an input: a port of this node
                // alone, whose value the parameter takes at every evaluation (animated
                // parameters: a keyed curve wired to a stiffness).
                None if linkable(&spec, port) => {
                    if decl.params.contains_key(port) {
                        d.push(
                            Diagnostic::error(
                                path(),
                                format!(
                                    "param '{port}' is both given a value and connected: give one"
                                ),
                            )
                            .node(id)
                            .field(field),
                        );
                        continue;
                    }
                    let mut s = (*spec).clone();
                    s.inputs.push(crate::spec::PortSpec {
                        name: port.clone(),
                        ty: TypeRef::Named("float".into()),
                        doc: format!("drives param '{port}' (its value at each frame)"),
                        required: false,
                        multi: false,
                        default: None,
                    });
                    spec = Arc::new(s);
                    pre[i].spec = spec.clone();
                    pre[i].conns.push(Vec::new());
                    let pi = spec.inputs.len() - 1;
                    pre[i].links.push((pi, port.clone()));
                    Some(pi)
                }
                None => None,
            };
            let Some(pi) = pi else {
                let names: Vec<&str> = spec.inputs.iter().map(|p| p.name.as_str()).collect();
                let linkable: Vec<&str> = spec
                    .params
                    .iter()
                    .map(|p| p.name.as_str())
                    .filter(|p| linkable(&spec, p))
                    .collect();
                let also = if linkable.is_empty() {
                    String::new()
                } else {
                    format!("; or a number parameter: {}", linkable.join(", "))
                };
                d.push(
                    Diagnostic::error(
                        path(),
                        format!(
                            "'{}' has no input '{port}' (inputs: {}{also})",
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
                .and_then(|j| env.registry.json_value(&i.ty, j))
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
        slot.param_links = p.links.clone();
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
                slot.input_defaults[pi] = env.registry.json_value(t, dv);
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

/// One simple cycle per strongly connected component that has one, as node weights in order.
pub(crate) fn cycles(dg: &DiGraph<usize, ()>) -> Vec<Vec<usize>> {
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
