//! The authoring model: a graph file as written, before validation.
//!
//! Parsed by hand from `serde_json::Value` rather than derived, so that *every* problem
//! (unknown field, wrong shape) is collected with its JSON path instead of stopping at the
//! first, as `#[serde(deny_unknown_fields)]` would.

use crate::diag::{Diagnostic, nearest};
use serde_json::{Map, Value as Json};
use std::collections::BTreeMap;

/// The only `format` accepted.
pub const FORMAT: &str = "weft-graph";
/// File versions this build reads.
pub const SUPPORTED_VERSIONS: &[u64] = &[1];

pub(crate) type Path = Vec<String>;

/// A connection reference, `"node.port"`, as written.
#[derive(Clone, Debug)]
pub(crate) struct Ref {
    pub text: String,
    pub path: Path,
}

#[derive(Clone, Debug)]
pub(crate) struct NodeDecl {
    pub ty: String,
    /// Input port → connected references, and whether they were written as a list.
    pub inputs: BTreeMap<String, (Vec<Ref>, bool)>,
    pub params: BTreeMap<String, Json>,
    pub path: Path,
}

impl NodeDecl {
    /// The JSON path of something inside this node's declaration (built only for errors).
    pub fn at(&self, parts: &[&str]) -> Path {
        let mut v = self.path.clone();
        v.extend(parts.iter().map(|s| s.to_string()));
        v
    }
}

#[derive(Clone, Debug)]
pub(crate) struct SubInput {
    pub ty: String,
    pub doc: String,
    pub default: Option<Json>,
    pub path: Path,
}

#[derive(Clone, Debug)]
pub(crate) struct SubOutput {
    pub from: Ref,
    pub doc: String,
    pub initial: Option<Json>,
    pub path: Path,
}

#[derive(Clone, Debug)]
pub(crate) struct IterateDecl {
    pub feedback: BTreeMap<String, Ref>,
    pub until: Ref,
    pub residual: Option<Ref>,
    pub max_iterations: i64,
    pub on_limit_error: bool,
}

#[derive(Clone, Debug)]
pub(crate) struct SubgraphDecl {
    pub doc: String,
    pub inputs: BTreeMap<String, SubInput>,
    pub outputs: BTreeMap<String, SubOutput>,
    pub nodes: BTreeMap<String, NodeDecl>,
    pub iterate: Option<IterateDecl>,
    /// Input → the output whose previous-frame value feeds it.
    pub step: Option<BTreeMap<String, (String, Path)>>,
    pub path: Path,
}

#[derive(Clone, Debug, Default)]
pub(crate) struct FileModel {
    pub nodes: BTreeMap<String, NodeDecl>,
    pub outputs: BTreeMap<String, Ref>,
    pub subgraphs: BTreeMap<String, SubgraphDecl>,
}

fn p(base: &Path, k: &str) -> Path {
    let mut v = base.clone();
    v.push(k.to_string());
    v
}

fn check_fields(
    obj: &Map<String, Json>,
    allowed: &[&str],
    what: &str,
    path: &Path,
    d: &mut Vec<Diagnostic>,
) {
    for k in obj.keys() {
        if !allowed.contains(&k.as_str()) {
            d.push(
                Diagnostic::error(
                    p(path, k),
                    format!(
                        "unknown field '{k}' in {what} (allowed: {})",
                        allowed.join(", ")
                    ),
                )
                .help(nearest(k, allowed.iter().copied())),
            );
        }
    }
}

fn as_obj<'a>(
    v: &'a Json,
    what: &str,
    path: &Path,
    d: &mut Vec<Diagnostic>,
) -> Option<&'a Map<String, Json>> {
    let o = v.as_object();
    if o.is_none() {
        d.push(Diagnostic::error(
            path.clone(),
            format!("{what} must be an object, got {}", kind(v)),
        ));
    }
    o
}

fn kind(v: &Json) -> &'static str {
    match v {
        Json::Null => "null",
        Json::Bool(_) => "a boolean",
        Json::Number(_) => "a number",
        Json::String(_) => "a string",
        Json::Array(_) => "a list",
        Json::Object(_) => "an object",
    }
}

fn string(v: Option<&Json>, what: &str, path: &Path, d: &mut Vec<Diagnostic>) -> Option<String> {
    match v {
        Some(Json::String(s)) => Some(s.clone()),
        Some(other) => {
            d.push(Diagnostic::error(
                path.clone(),
                format!("{what} must be a string, got {}", kind(other)),
            ));
            None
        }
        None => {
            d.push(Diagnostic::error(path.clone(), format!("missing {what}")));
            None
        }
    }
}

/// Node ids: letters, digits, `_` and `-` (no `.`, which separates node from port).
pub(crate) fn valid_id(id: &str) -> bool {
    !id.is_empty()
        && id
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
}

fn parse_nodes(v: &Json, path: &Path, d: &mut Vec<Diagnostic>) -> BTreeMap<String, NodeDecl> {
    let mut out = BTreeMap::new();
    let Some(obj) = as_obj(v, "'nodes'", path, d) else {
        return out;
    };
    for (id, nv) in obj {
        let np = p(path, id);
        if !valid_id(id) {
            d.push(
                Diagnostic::error(
                    np.clone(),
                    "node ids may use only letters, digits, '_' and '-'",
                )
                .node(id),
            );
            continue;
        }
        let Some(no) = as_obj(nv, &format!("node '{id}'"), &np, d) else {
            continue;
        };
        let before = d.len();
        check_fields(
            no,
            &["type", "inputs", "params", "meta"],
            &format!("node '{id}'"),
            &np,
            d,
        );
        for x in &mut d[before..] {
            x.node = Some(id.clone());
        }
        let Some(ty) = string(no.get("type"), "'type'", &p(&np, "type"), d) else {
            if let Some(x) = d.last_mut() {
                x.node = Some(id.clone());
            }
            continue;
        };
        let mut inputs = BTreeMap::new();
        if let Some(iv) = no.get("inputs") {
            let ip = p(&np, "inputs");
            if let Some(io) = as_obj(iv, "'inputs'", &ip, d) {
                for (port, rv) in io {
                    let pp = p(&ip, port);
                    match rv {
                        Json::String(s) => {
                            inputs.insert(port.clone(), (vec![Ref { text: s.clone(), path: pp }], false));
                        }
                        Json::Array(a) => {
                            let mut refs = Vec::new();
                            for (i, r) in a.iter().enumerate() {
                                let rp = p(&pp, &i.to_string());
                                match r.as_str() {
                                    Some(s) => refs.push(Ref { text: s.to_string(), path: rp }),
                                    None => d.push(
                                        Diagnostic::error(rp, format!("a connection must be a \"node.port\" string, got {}", kind(r)))
                                            .node(id)
                                            .field(format!("input '{port}'")),
                                    ),
                                }
                            }
                            inputs.insert(port.clone(), (refs, true));
                        }
                        other => d.push(
                            Diagnostic::error(pp, format!("a connection must be a \"node.port\" string or a list of them, got {}", kind(other)))
                                .node(id)
                                .field(format!("input '{port}'")),
                        ),
                    }
                }
            } else if let Some(x) = d.last_mut() {
                x.node = Some(id.clone());
            }
        }
        let mut params = BTreeMap::new();
        if let Some(pv) = no.get("params") {
            let pp = p(&np, "params");
            if let Some(po) = as_obj(pv, "'params'", &pp, d) {
                for (k, v) in po {
                    params.insert(k.clone(), v.clone());
                }
            } else if let Some(x) = d.last_mut() {
                x.node = Some(id.clone());
            }
        }
        out.insert(
            id.clone(),
            NodeDecl {
                ty,
                inputs,
                params,
                path: np,
            },
        );
    }
    out
}

fn parse_ref(v: Option<&Json>, what: &str, path: Path, d: &mut Vec<Diagnostic>) -> Option<Ref> {
    string(v, what, &path, d).map(|text| Ref { text, path })
}

pub(crate) fn parse_subgraph(
    v: &Json,
    path: &Path,
    d: &mut Vec<Diagnostic>,
) -> Option<SubgraphDecl> {
    let o = as_obj(v, "a subgraph", path, d)?;
    check_fields(
        o,
        &[
            "doc", "inputs", "outputs", "nodes", "iterate", "step", "meta",
        ],
        "subgraph",
        path,
        d,
    );
    let doc = o
        .get("doc")
        .and_then(|x| x.as_str())
        .unwrap_or_default()
        .to_string();
    let mut inputs = BTreeMap::new();
    if let Some(iv) = o.get("inputs") {
        let ip = p(path, "inputs");
        if let Some(io) = as_obj(iv, "'inputs'", &ip, d) {
            for (name, decl) in io {
                let dp = p(&ip, name);
                let (ty, doc, default) = match decl {
                    Json::String(t) => (Some(t.clone()), String::new(), None),
                    Json::Object(m) => {
                        check_fields(m, &["type", "doc", "default"], "subgraph input", &dp, d);
                        (
                            string(m.get("type"), "'type'", &p(&dp, "type"), d),
                            m.get("doc")
                                .and_then(|x| x.as_str())
                                .unwrap_or_default()
                                .to_string(),
                            m.get("default").cloned(),
                        )
                    }
                    other => {
                        d.push(Diagnostic::error(
                            dp.clone(),
                            format!(
                                "an input is a type name or {{\"type\": …}}, got {}",
                                kind(other)
                            ),
                        ));
                        (None, String::new(), None)
                    }
                };
                if let Some(ty) = ty {
                    inputs.insert(
                        name.clone(),
                        SubInput {
                            ty,
                            doc,
                            default,
                            path: dp,
                        },
                    );
                }
            }
        }
    }
    let mut outputs = BTreeMap::new();
    match o.get("outputs") {
        Some(ov) => {
            let op = p(path, "outputs");
            if let Some(oo) = as_obj(ov, "'outputs'", &op, d) {
                for (name, decl) in oo {
                    let dp = p(&op, name);
                    match decl {
                        Json::String(s) => {
                            outputs.insert(
                                name.clone(),
                                SubOutput {
                                    from: Ref {
                                        text: s.clone(),
                                        path: dp.clone(),
                                    },
                                    doc: String::new(),
                                    initial: None,
                                    path: dp,
                                },
                            );
                        }
                        Json::Object(m) => {
                            check_fields(m, &["from", "doc", "initial"], "subgraph output", &dp, d);
                            if let Some(from) =
                                parse_ref(m.get("from"), "'from'", p(&dp, "from"), d)
                            {
                                let doc = m
                                    .get("doc")
                                    .and_then(|x| x.as_str())
                                    .unwrap_or_default()
                                    .to_string();
                                outputs.insert(
                                    name.clone(),
                                    SubOutput {
                                        from,
                                        doc,
                                        initial: m.get("initial").cloned(),
                                        path: dp,
                                    },
                                );
                            }
                        }
                        other => d.push(Diagnostic::error(
                            dp,
                            format!(
                                "an output is \"node.port\" or {{\"from\": …}}, got {}",
                                kind(other)
                            ),
                        )),
                    }
                }
            }
        }
        None => d.push(Diagnostic::error(
            path.clone(),
            "a subgraph needs 'outputs'",
        )),
    }
    let nodes = match o.get("nodes") {
        Some(nv) => parse_nodes(nv, &p(path, "nodes"), d),
        None => BTreeMap::new(),
    };
    let iterate = o.get("iterate").and_then(|iv| {
        let ip = p(path, "iterate");
        let io = as_obj(iv, "'iterate'", &ip, d)?;
        check_fields(
            io,
            &[
                "feedback",
                "until",
                "residual",
                "max_iterations",
                "on_limit",
            ],
            "'iterate'",
            &ip,
            d,
        );
        let mut feedback = BTreeMap::new();
        if let Some(fv) = io.get("feedback") {
            let fp = p(&ip, "feedback");
            if let Some(fo) = as_obj(fv, "'feedback'", &fp, d) {
                for (k, r) in fo {
                    if let Some(r) = parse_ref(Some(r), "a feedback source", p(&fp, k), d) {
                        feedback.insert(k.clone(), r);
                    }
                }
            }
        }
        let until = parse_ref(io.get("until"), "'until'", p(&ip, "until"), d)?;
        let residual = io
            .get("residual")
            .and_then(|r| parse_ref(Some(r), "'residual'", p(&ip, "residual"), d));
        let max_iterations = match io.get("max_iterations") {
            None => 50,
            Some(x) => match x.as_i64().filter(|n| *n >= 1) {
                Some(n) => n,
                None => {
                    d.push(Diagnostic::error(
                        p(&ip, "max_iterations"),
                        format!("must be an integer >= 1, got {x}"),
                    ));
                    1
                }
            },
        };
        let on_limit_error = match io.get("on_limit").map(|x| x.as_str()) {
            None | Some(Some("error")) => true,
            Some(Some("warn")) => false,
            Some(_) => {
                d.push(Diagnostic::error(
                    p(&ip, "on_limit"),
                    "must be \"error\" or \"warn\"",
                ));
                true
            }
        };
        Some(IterateDecl {
            feedback,
            until,
            residual,
            max_iterations,
            on_limit_error,
        })
    });
    let step = o.get("step").and_then(|sv| {
        let sp = p(path, "step");
        let so = as_obj(sv, "'step'", &sp, d)?;
        check_fields(so, &["feedback"], "'step'", &sp, d);
        let fp = p(&sp, "feedback");
        let fo = as_obj(
            so.get("feedback").unwrap_or(&Json::Null),
            "'step.feedback'",
            &fp,
            d,
        )?;
        let mut m = BTreeMap::new();
        for (k, v) in fo {
            if let Some(s) = string(
                Some(v),
                "a step feedback source (an output name)",
                &p(&fp, k),
                d,
            ) {
                m.insert(k.clone(), (s, p(&fp, k)));
            }
        }
        Some(m)
    });
    Some(SubgraphDecl {
        doc,
        inputs,
        outputs,
        nodes,
        iterate,
        step,
        path: path.clone(),
    })
}

/// Reads the authoring model, collecting every shape problem.
pub(crate) fn parse_model(root: &Json, d: &mut Vec<Diagnostic>) -> FileModel {
    let top: Path = vec![];
    let mut m = FileModel::default();
    let Some(o) = as_obj(root, "a graph file", &top, d) else {
        return m;
    };
    check_fields(
        o,
        &["format", "version", "nodes", "outputs", "subgraphs", "meta"],
        "the graph file",
        &top,
        d,
    );
    match o.get("format") {
        Some(Json::String(s)) if s == FORMAT => {}
        Some(other) => d.push(Diagnostic::error(
            vec!["format".into()],
            format!("'format' must be \"{FORMAT}\", got {other}"),
        )),
        None => d.push(Diagnostic::error(
            top.clone(),
            format!("missing \"format\": \"{FORMAT}\""),
        )),
    }
    match o.get("version") {
        Some(v) if v.as_u64().is_some_and(|n| SUPPORTED_VERSIONS.contains(&n)) => {}
        Some(v) => d.push(Diagnostic::error(
            vec!["version".into()],
            format!("unsupported version {v}; this build reads version {SUPPORTED_VERSIONS:?}"),
        )),
        None => d.push(Diagnostic::error(top.clone(), "missing \"version\"")),
    }
    if let Some(sv) = o.get("subgraphs") {
        let sp = vec!["subgraphs".to_string()];
        if let Some(so) = as_obj(sv, "'subgraphs'", &sp, d) {
            for (name, v) in so {
                if let Some(s) = parse_subgraph(v, &p(&sp, name), d) {
                    m.subgraphs.insert(name.clone(), s);
                }
            }
        }
    }
    match o.get("nodes") {
        Some(nv) => m.nodes = parse_nodes(nv, &vec!["nodes".into()], d),
        None => d.push(Diagnostic::error(top.clone(), "missing \"nodes\"")),
    }
    if let Some(ov) = o.get("outputs") {
        let op = vec!["outputs".to_string()];
        if let Some(oo) = as_obj(ov, "'outputs'", &op, d) {
            for (k, r) in oo {
                if let Some(r) = parse_ref(Some(r), "an output (\"node.port\")", p(&op, k), d) {
                    m.outputs.insert(k.clone(), r);
                }
            }
        }
    }
    m
}
