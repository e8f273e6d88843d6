//! The graph handle: loading and freeing, the output root; the rest of its calls in the
//! child modules (listing, feeding, pulling).

use crate::value::WeftValue;
use crate::{
    Failure, WeftError, WeftStatus, c_string, guard, quiet, status, str_arg, write_slice, write_str,
};
use std::ffi::{CString, c_char};
use std::sync::{Arc, OnceLock};
use weft_graph::{Context, Diagnostic, Graph, Interrupt, LoadError, Registry, TypeRef, Value};
use weft_scene::{Curves, Mesh};

/// A loaded graph, with the names a host lists kept as C strings.
pub struct WeftGraph {
    graph: Graph,
    nodes: Vec<NodeNames>,
    outputs: Vec<(CString, CString)>,
    /// Set when a panic left the graph half-updated: every later call refuses.
    poisoned: bool,
}

/// A node's id, type, ports (name, type) and parameters (name, kind).
struct NodeNames {
    id: CString,
    ty: CString,
    inputs: Vec<(CString, CString)>,
    outputs: Vec<(CString, CString)>,
    params: Vec<(CString, CString)>,
}

/// A stop request that any thread may set while another pulls (see [`weft_interrupt_set`]).
pub struct WeftInterrupt(Interrupt);

/// Which ports [`weft_graph_port_count`] and its companions list.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WeftPortDirection {
    /// The node's inputs.
    WeftInput = 0,
    /// The node's outputs.
    WeftOutput = 1,
}

fn registry() -> &'static Arc<Registry> {
    static R: OnceLock<Arc<Registry>> = OnceLock::new();
    R.get_or_init(weft_nodes::registry)
}

fn kind_name(k: &weft_graph::ParamKind) -> &'static str {
    use weft_graph::ParamKind as K;
    match k {
        K::Float { .. } => "float",
        K::Int { .. } => "int",
        K::Bool => "bool",
        K::String => "string",
        K::Enum(_) => "enum",
        K::Vec3 => "vec3",
        K::FloatList => "floats",
        K::Json => "json",
    }
}

impl WeftGraph {
    fn new(graph: Graph) -> Self {
        let mut nodes = Vec::new();
        for id in graph.node_ids() {
            let spec = graph.node_spec(id).expect("listed");
            let input_type = |t: &TypeRef| match t {
                TypeRef::Named(n) => n.clone(),
                TypeRef::Any => "any".into(),
                TypeRef::SameAs(i) => format!("same as input '{i}'"),
                TypeRef::FromParam(p) => format!("named by param '{p}'"),
            };
            nodes.push(NodeNames {
                id: c_string(id),
                ty: c_string(&spec.name),
                inputs: spec
                    .inputs
                    .iter()
                    .map(|p| (c_string(&p.name), c_string(&input_type(&p.ty))))
                    .collect(),
                outputs: spec
                    .outputs
                    .iter()
                    .map(|p| {
                        let ty = graph.node_output_type(id, &p.name).unwrap_or("any");
                        (c_string(&p.name), c_string(ty))
                    })
                    .collect(),
                params: spec
                    .params
                    .iter()
                    .map(|p| (c_string(&p.name), c_string(kind_name(&p.kind))))
                    .collect(),
            });
        }
        let outputs = graph
            .output_names()
            .map(|o| (c_string(o), c_string(graph.output_type(o).unwrap_or("any"))))
            .collect();
        WeftGraph {
            graph,
            nodes,
            outputs,
            poisoned: false,
        }
    }
}

fn load_failure(e: LoadError) -> Failure {
    let errors: Vec<&Diagnostic> = e.errors().collect();
    let first = errors.first().map(|d| d.to_string()).unwrap_or_default();
    Failure::with_diagnostics(
        WeftStatus::WeftLoadFailed,
        format!(
            "{}: {} error(s); the first: {first}",
            e.source_name,
            errors.len()
        ),
        errors,
    )
}

/// The graph behind `g` for a call that changes or evaluates it; refuses a poisoned one and
/// poisons it if the call panics (the caller's `guard` reports the panic).
///
/// # Safety
/// `g` is NULL or a live graph not used by another thread.
unsafe fn with_graph<T>(
    g: *mut WeftGraph,
    f: impl FnOnce(&mut Graph) -> Result<T, Failure>,
) -> Result<T, Failure> {
    // SAFETY: NULL or live and unshared, by contract.
    let Some(h) = (unsafe { g.as_mut() }) else {
        return Err(Failure::new(
            WeftStatus::WeftInvalidArgument,
            "graph is NULL",
        ));
    };
    if h.poisoned {
        return Err(poisoned());
    }
    h.poisoned = true;
    let r = f(&mut h.graph);
    h.poisoned = false;
    r
}

fn poisoned() -> Failure {
    Failure::new(
        WeftStatus::WeftPanic,
        "an earlier internal error left this graph half-updated; load it again",
    )
}

fn rejected(d: Box<Diagnostic>) -> Failure {
    let status = if d.message.starts_with("no such") || d.message.starts_with("no output") {
        WeftStatus::WeftNotFound
    } else {
        WeftStatus::WeftRejected
    };
    Failure::with_diagnostics(status, d.to_string(), [&*d])
}

/// Loads the graph file at `path` (UTF-8). NULL on failure, with every problem of the file
/// in `*error` (each naming its node, port or parameter and line).
///
/// # Safety
/// `path` is a NUL-terminated string; `error` is NULL or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_graph_load_file(
    path: *const c_char,
    error: *mut *mut WeftError,
) -> *mut WeftGraph {
    guard(error, std::ptr::null_mut(), || {
        // SAFETY: string contract passed through.
        let path = unsafe { str_arg(path, "path") }?;
        let g =
            weft_graph::load_path(registry(), std::path::Path::new(path)).map_err(load_failure)?;
        Ok(Box::into_raw(Box::new(WeftGraph::new(g))))
    })
}

/// Loads a graph from the JSON text `text`; `name` (may be NULL) names it in messages.
/// NULL on failure, with every problem in `*error`.
///
/// # Safety
/// `text` is a NUL-terminated string, `name` NULL or one; `error` is NULL or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_graph_load_string(
    text: *const c_char,
    name: *const c_char,
    error: *mut *mut WeftError,
) -> *mut WeftGraph {
    guard(error, std::ptr::null_mut(), || {
        // SAFETY: string contracts passed through.
        let text = unsafe { str_arg(text, "text") }?;
        let name = if name.is_null() {
            "<memory>"
        } else {
            // SAFETY: as above.
            unsafe { str_arg(name, "name") }?
        };
        let g = weft_graph::load_str(registry(), text, name).map_err(load_failure)?;
        Ok(Box::into_raw(Box::new(WeftGraph::new(g))))
    })
}

/// Frees a graph (NULL is ignored). Strings it returned become invalid; values pulled from
/// it stay valid.
///
/// # Safety
/// `graph` is NULL or a graph from this library not yet freed.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_graph_free(graph: *mut WeftGraph) {
    if !graph.is_null() {
        // SAFETY: made by `Box::into_raw` at load, freed once by contract.
        let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            drop(unsafe { Box::from_raw(graph) })
        }));
    }
}

/// Sets the directory under which the graph's file outputs (`output.*` nodes) write; NULL
/// for none (paths are then relative to the working directory).
///
/// # Safety
/// `graph` is a live graph; `dir` is NULL or a NUL-terminated string; `error` NULL or
/// writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_graph_set_output_root(
    graph: *mut WeftGraph,
    dir: *const c_char,
    error: *mut *mut WeftError,
) -> WeftStatus {
    status(error, || {
        let dir = if dir.is_null() {
            None
        } else {
            // SAFETY: string contract passed through.
            Some(std::path::PathBuf::from(unsafe { str_arg(dir, "dir") }?))
        };
        // SAFETY: graph contract passed through.
        unsafe {
            with_graph(graph, |g| {
                g.set_output_root(dir);
                Ok(())
            })
        }?;
        Ok(WeftStatus::WeftOk)
    })
}

// In this order, so the header lists the calls as a host uses them.
mod describe;
mod feed;
mod pull;

pub use describe::*;
pub use feed::*;
pub use pull::*;
