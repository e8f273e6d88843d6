//! The graph handle: loading, listing, parameters, host-fed data, pulling, statistics.

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

/// The node at `index` of `graph` (evaluation order), if both exist.
///
/// # Safety
/// `graph` is NULL or live.
unsafe fn node<'a>(graph: *const WeftGraph, index: usize) -> Option<&'a NodeNames> {
    // SAFETY: NULL or live, by contract.
    unsafe { graph.as_ref() }.and_then(|g| g.nodes.get(index))
}

/// The number of nodes in `graph` (0 for NULL).
///
/// # Safety
/// `graph` is NULL or live.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_graph_node_count(graph: *const WeftGraph) -> usize {
    // SAFETY: NULL or live, by contract.
    unsafe { graph.as_ref() }.map_or(0, |g| g.nodes.len())
}

/// The id of node `index` (in evaluation order), owned by the graph; NULL when out of range.
///
/// # Safety
/// `graph` is NULL or live.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_graph_node_id(
    graph: *const WeftGraph,
    index: usize,
) -> *const c_char {
    // SAFETY: contract passed through.
    unsafe { node(graph, index) }.map_or(std::ptr::null(), |n| n.id.as_ptr())
}

/// The type of node `index` (`geo.grid`, `solver.solid`, …), owned by the graph; NULL when
/// out of range.
///
/// # Safety
/// `graph` is NULL or live.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_graph_node_type(
    graph: *const WeftGraph,
    index: usize,
) -> *const c_char {
    // SAFETY: contract passed through.
    unsafe { node(graph, index) }.map_or(std::ptr::null(), |n| n.ty.as_ptr())
}

/// The index of the node with id `id`, or −1 when there is none.
///
/// # Safety
/// `graph` is NULL or live; `id` is NULL or a NUL-terminated string.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_graph_node_index(graph: *const WeftGraph, id: *const c_char) -> i64 {
    quiet(-1, || {
        // SAFETY: contracts passed through.
        let (Some(g), Ok(id)) = (unsafe { graph.as_ref() }, unsafe { str_arg(id, "id") }) else {
            return -1;
        };
        g.nodes
            .iter()
            .position(|n| n.id.to_bytes() == id.as_bytes())
            .map_or(-1, |i| i as i64)
    })
}

/// The name (0) or the type or kind (1) of a listed port, parameter or output.
fn pair_text(p: &(CString, CString), which: usize) -> *const c_char {
    if which == 0 {
        p.0.as_ptr()
    } else {
        p.1.as_ptr()
    }
}

/// The ports of `n` in `direction` (a [`WeftPortDirection`] as an integer: C may pass any
/// value in an enum, and an invalid Rust enum would be undefined behaviour); none for an
/// unknown direction.
fn ports(n: &NodeNames, direction: u32) -> &[(CString, CString)] {
    match direction {
        d if d == WeftPortDirection::WeftInput as u32 => &n.inputs,
        d if d == WeftPortDirection::WeftOutput as u32 => &n.outputs,
        _ => &[],
    }
}

/// The number of input or output ports of node `index` (`direction`: a
/// [`WeftPortDirection`]; 0 when out of range or unknown).
///
/// # Safety
/// `graph` is NULL or live.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_graph_port_count(
    graph: *const WeftGraph,
    index: usize,
    direction: u32,
) -> usize {
    // SAFETY: contract passed through.
    unsafe { node(graph, index) }.map_or(0, |n| ports(n, direction).len())
}

/// The name of port `port` of node `index`, owned by the graph; NULL when out of range.
///
/// # Safety
/// `graph` is NULL or live.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_graph_port_name(
    graph: *const WeftGraph,
    index: usize,
    direction: u32,
    port: usize,
) -> *const c_char {
    // SAFETY: contract passed through.
    unsafe { node(graph, index) }
        .and_then(|n| ports(n, direction).get(port))
        .map_or(std::ptr::null(), |p| pair_text(p, 0))
}

/// The type of port `port` of node `index` (`mesh`, `curves`, `scene`, `float`, …; an
/// output's as compiled), owned by the graph; NULL when out of range.
///
/// # Safety
/// `graph` is NULL or live.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_graph_port_type(
    graph: *const WeftGraph,
    index: usize,
    direction: u32,
    port: usize,
) -> *const c_char {
    // SAFETY: contract passed through.
    unsafe { node(graph, index) }
        .and_then(|n| ports(n, direction).get(port))
        .map_or(std::ptr::null(), |p| pair_text(p, 1))
}

/// The number of parameters of node `index` (0 when out of range).
///
/// # Safety
/// `graph` is NULL or live.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_graph_param_count(graph: *const WeftGraph, index: usize) -> usize {
    // SAFETY: contract passed through.
    unsafe { node(graph, index) }.map_or(0, |n| n.params.len())
}

/// The name of parameter `param` of node `index`, owned by the graph; NULL when out of range.
///
/// # Safety
/// `graph` is NULL or live.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_graph_param_name(
    graph: *const WeftGraph,
    index: usize,
    param: usize,
) -> *const c_char {
    // SAFETY: contract passed through.
    unsafe { node(graph, index) }
        .and_then(|n| n.params.get(param))
        .map_or(std::ptr::null(), |p| pair_text(p, 0))
}

/// The kind of parameter `param` of node `index`: `float`, `int`, `bool`, `string`, `enum`,
/// `vec3`, `floats` or `json`; owned by the graph; NULL when out of range.
///
/// # Safety
/// `graph` is NULL or live.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_graph_param_kind(
    graph: *const WeftGraph,
    index: usize,
    param: usize,
) -> *const c_char {
    // SAFETY: contract passed through.
    unsafe { node(graph, index) }
        .and_then(|n| n.params.get(param))
        .map_or(std::ptr::null(), |p| pair_text(p, 1))
}

/// Copies parameter `param` of node `index` as JSON into `buf` (snprintf convention): its
/// spec (kind with range or choices, default, unit, doc) and current value, as
/// `{"name", "kind", "default", "unit", "doc", "value"}`. Its length; 0 when out of range.
///
/// # Safety
/// `graph` is NULL or live; `buf` is NULL or writable for `capacity` bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_graph_param_json(
    graph: *const WeftGraph,
    index: usize,
    param: usize,
    buf: *mut c_char,
    capacity: usize,
) -> usize {
    quiet(0, || {
        // SAFETY: NULL or live, by contract.
        let Some(h) = (unsafe { graph.as_ref() }).filter(|h| !h.poisoned) else {
            return 0;
        };
        let Some(n) = h.nodes.get(index) else {
            return 0;
        };
        let id = n.id.to_string_lossy();
        let Some(j) = h
            .graph
            .param_descriptions(&id)
            .and_then(|mut all| (param < all.len()).then(|| all.swap_remove(param)))
        else {
            return 0;
        };
        // SAFETY: buffer contract passed through.
        unsafe { write_str(&c_string(&j.to_string()), buf, capacity) }
    })
}

/// The number of the graph's outputs (its `outputs` section).
///
/// # Safety
/// `graph` is NULL or live.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_graph_output_count(graph: *const WeftGraph) -> usize {
    // SAFETY: NULL or live, by contract.
    unsafe { graph.as_ref() }.map_or(0, |g| g.outputs.len())
}

/// The name of graph output `index` (sorted by name), owned by the graph; NULL when out of
/// range.
///
/// # Safety
/// `graph` is NULL or live.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_graph_output_name(
    graph: *const WeftGraph,
    index: usize,
) -> *const c_char {
    // SAFETY: NULL or live, by contract.
    unsafe { graph.as_ref() }
        .and_then(|g| g.outputs.get(index))
        .map_or(std::ptr::null(), |o| pair_text(o, 0))
}

/// The type of graph output `index`, owned by the graph; NULL when out of range.
///
/// # Safety
/// `graph` is NULL or live.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_graph_output_type(
    graph: *const WeftGraph,
    index: usize,
) -> *const c_char {
    // SAFETY: NULL or live, by contract.
    unsafe { graph.as_ref() }
        .and_then(|g| g.outputs.get(index))
        .map_or(std::ptr::null(), |o| pair_text(o, 1))
}

/// Sets parameter `param` of node `node` to the JSON value `json` (`0.4`, `true`,
/// `"text"`, `[0, 1, 0]`), validated as in a graph file; the node and everything downstream
/// are recomputed when next pulled. On an error nothing changes.
///
/// # Safety
/// `graph` is a live graph; the strings are NUL-terminated; `error` NULL or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_graph_set_param_json(
    graph: *mut WeftGraph,
    node: *const c_char,
    param: *const c_char,
    json: *const c_char,
    error: *mut *mut WeftError,
) -> WeftStatus {
    status(error, || {
        // SAFETY: string contracts passed through.
        let (node, param, text) = unsafe {
            (
                str_arg(node, "node")?,
                str_arg(param, "param")?,
                str_arg(json, "json")?,
            )
        };
        let value: serde_json::Value = serde_json::from_str(text).map_err(|e| {
            Failure::new(
                WeftStatus::WeftRejected,
                format!("node '{node}': param '{param}': not JSON: {e}"),
            )
        })?;
        // SAFETY: graph contract passed through.
        unsafe { with_graph(graph, |g| g.set_param(node, param, value).map_err(rejected)) }?;
        Ok(WeftStatus::WeftOk)
    })
}

/// Sets a float parameter (see [`weft_graph_set_param_json`]).
///
/// # Safety
/// As [`weft_graph_set_param_json`].
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_graph_set_param_f64(
    graph: *mut WeftGraph,
    node: *const c_char,
    param: *const c_char,
    value: f64,
    error: *mut *mut WeftError,
) -> WeftStatus {
    status(error, || {
        // SAFETY: string contracts passed through.
        let (node, param) = unsafe { (str_arg(node, "node")?, str_arg(param, "param")?) };
        let Some(v) = serde_json::Number::from_f64(value) else {
            return Err(Failure::new(
                WeftStatus::WeftRejected,
                format!("node '{node}': param '{param}': {value} is not a finite number"),
            ));
        };
        // SAFETY: graph contract passed through.
        unsafe {
            with_graph(graph, |g| {
                g.set_param(node, param, serde_json::Value::Number(v))
                    .map_err(rejected)
            })
        }?;
        Ok(WeftStatus::WeftOk)
    })
}

/// `count` × 3 doubles at `p` as points, refusing NULL with a nonzero count.
///
/// # Safety
/// `p` is NULL or readable for `3 count` doubles.
unsafe fn points<'a>(p: *const f64, count: usize, what: &str) -> Result<&'a [f64], Failure> {
    // SAFETY: contract passed through.
    unsafe { array(p, count.saturating_mul(3), what) }
}

/// `count` elements at `p`, refusing NULL with a nonzero count.
///
/// # Safety
/// `p` is NULL or readable for `count` elements.
unsafe fn array<'a, T>(p: *const T, count: usize, what: &str) -> Result<&'a [T], Failure> {
    if count == 0 {
        return Ok(&[]);
    }
    if p.is_null() {
        return Err(Failure::new(
            WeftStatus::WeftInvalidArgument,
            format!("{what} is NULL with a nonzero count"),
        ));
    }
    if count > isize::MAX as usize / std::mem::size_of::<T>().max(1) {
        return Err(Failure::new(
            WeftStatus::WeftInvalidArgument,
            format!("{what}: count {count} is too large"),
        ));
    }
    // SAFETY: non-NULL, readable for `count` elements by contract.
    Ok(unsafe { std::slice::from_raw_parts(p, count) })
}

fn rejected_data(node: &str, port: &str, message: String) -> Failure {
    Failure::new(
        WeftStatus::WeftRejected,
        format!("node '{node}': output '{port}': {message}"),
    )
}

fn positions(node: &str, port: &str, xyz: &[f64]) -> Result<Vec<[f64; 3]>, Failure> {
    if let Some(k) = xyz.iter().position(|x| !x.is_finite()) {
        return Err(rejected_data(
            node,
            port,
            format!("vertex {} has a non-finite coordinate ({})", k / 3, xyz[k]),
        ));
    }
    Ok(xyz.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
}

/// Feeds `value` in place of output `port` of `node` at `frame` (or `WEFT_ALL_FRAMES`).
///
/// # Safety
/// As the feed calls.
unsafe fn feed(
    graph: *mut WeftGraph,
    node: &str,
    port: &str,
    frame: i64,
    value: Value,
) -> Result<WeftStatus, Failure> {
    let frame = (frame != crate::WEFT_ALL_FRAMES).then_some(frame);
    // SAFETY: graph contract passed through.
    unsafe {
        with_graph(graph, |g| {
            g.feed(node, port, frame, value).map_err(rejected)
        })
    }?;
    Ok(WeftStatus::WeftOk)
}

/// Feeds a triangle mesh from the host in place of output `port` of node `node` (a mesh
/// output, such as a `geo.grid`'s or a `geo.obj`'s `mesh`): `vertex_count` positions as x, y,
/// z doubles in metres and `triangle_count` triangles as three vertex indices each
/// (counter-clockwise seen from the front). `frame` is the frame this shape belongs to (held
/// until the next frame fed: an animated collider is fed frame by frame) or
/// `WEFT_ALL_FRAMES`. Refused (`WEFT_REJECTED`, nothing changed) for a non-finite
/// coordinate, an index out of range, or a port of another type. Feed every frame before
/// pulling: each feed makes stateful nodes downstream start again.
///
/// # Safety
/// `graph` is a live graph; the strings are NUL-terminated; `positions` is readable for
/// `3 vertex_count` doubles and `triangles` for `3 triangle_count` indices (either may be
/// NULL when its count is 0); `error` is NULL or writable.
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn weft_graph_feed_mesh(
    graph: *mut WeftGraph,
    node: *const c_char,
    port: *const c_char,
    frame: i64,
    positions_xyz: *const f64,
    vertex_count: usize,
    triangles: *const u32,
    triangle_count: usize,
    error: *mut *mut WeftError,
) -> WeftStatus {
    status(error, || {
        // SAFETY: contracts passed through.
        let (node, port, xyz, tri) = unsafe {
            (
                str_arg(node, "node")?,
                str_arg(port, "port")?,
                points(positions_xyz, vertex_count, "positions")?,
                array(triangles, triangle_count.saturating_mul(3), "triangles")?,
            )
        };
        if let Some(k) = tri.iter().position(|&i| i as usize >= vertex_count) {
            return Err(rejected_data(
                node,
                port,
                format!(
                    "triangle {} uses vertex {}, but there are {vertex_count} vertices",
                    k / 3,
                    tri[k]
                ),
            ));
        }
        let mesh = Mesh {
            positions: positions(node, port, xyz)?,
            triangles: tri.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        };
        // SAFETY: graph contract passed through.
        unsafe { feed(graph, node, port, frame, Value::new(mesh)) }
    })
}

/// Feeds curves (hair strands) from the host in place of output `port` of node `node` (a
/// curves output, such as a `geo.strands`' `curves`): `vertex_count` positions as x, y, z
/// doubles in metres, and `curve_count + 1` offsets: curve k is vertices
/// `offsets[k] .. offsets[k + 1]`, the first offset 0 and the last `vertex_count`. Each curve
/// needs at least 2 vertices. `frame` as in [`weft_graph_feed_mesh`].
///
/// # Safety
/// `graph` is a live graph; the strings are NUL-terminated; `positions` is readable for
/// `3 vertex_count` doubles and `offsets` for `curve_count + 1` indices; `error` is NULL or
/// writable.
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn weft_graph_feed_curves(
    graph: *mut WeftGraph,
    node: *const c_char,
    port: *const c_char,
    frame: i64,
    positions_xyz: *const f64,
    vertex_count: usize,
    offsets: *const u32,
    curve_count: usize,
    error: *mut *mut WeftError,
) -> WeftStatus {
    status(error, || {
        // SAFETY: contracts passed through.
        let (node, port, xyz, off) = unsafe {
            (
                str_arg(node, "node")?,
                str_arg(port, "port")?,
                points(positions_xyz, vertex_count, "positions")?,
                array(offsets, curve_count.saturating_add(1), "offsets")?,
            )
        };
        if off.first() != Some(&0) || off.last().map(|&l| l as usize) != Some(vertex_count) {
            return Err(rejected_data(
                node,
                port,
                format!(
                    "offsets must start at 0 and end at the vertex count {vertex_count} (they run from {:?} to {:?})",
                    off.first(),
                    off.last()
                ),
            ));
        }
        if let Some(k) = off.windows(2).position(|w| w[1] < w[0].saturating_add(2)) {
            return Err(rejected_data(
                node,
                port,
                format!(
                    "curve {k} has fewer than 2 vertices (offsets {} to {})",
                    off[k],
                    off[k + 1]
                ),
            ));
        }
        let curves = Curves {
            positions: positions(node, port, xyz)?,
            offsets: off.to_vec(),
        };
        // SAFETY: graph contract passed through.
        unsafe { feed(graph, node, port, frame, Value::new(curves)) }
    })
}

/// Feeds a number in place of a float output `port` of node `node` (a host's animated
/// value), at `frame` or `WEFT_ALL_FRAMES`.
///
/// # Safety
/// `graph` is a live graph; the strings are NUL-terminated; `error` NULL or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_graph_feed_f64(
    graph: *mut WeftGraph,
    node: *const c_char,
    port: *const c_char,
    frame: i64,
    value: f64,
    error: *mut *mut WeftError,
) -> WeftStatus {
    status(error, || {
        // SAFETY: string contracts passed through.
        let (node, port) = unsafe { (str_arg(node, "node")?, str_arg(port, "port")?) };
        // SAFETY: graph contract passed through.
        unsafe { feed(graph, node, port, frame, Value::new(value)) }
    })
}

/// Stops feeding output `port` of node `node`: the node computes it again. `WEFT_OK` also
/// when it was not fed.
///
/// # Safety
/// `graph` is a live graph; the strings are NUL-terminated; `error` NULL or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_graph_unfeed(
    graph: *mut WeftGraph,
    node: *const c_char,
    port: *const c_char,
    error: *mut *mut WeftError,
) -> WeftStatus {
    status(error, || {
        // SAFETY: string contracts passed through.
        let (node, port) = unsafe { (str_arg(node, "node")?, str_arg(port, "port")?) };
        // SAFETY: graph contract passed through.
        unsafe { with_graph(graph, |g| g.unfeed(node, port).map_err(rejected)) }?;
        Ok(WeftStatus::WeftOk)
    })
}

fn eval_failure(e: weft_graph::EvalError) -> Failure {
    let status = match &*e.error {
        weft_graph::NodeError::Interrupted(_) => WeftStatus::WeftInterrupted,
        _ => WeftStatus::WeftEvalFailed,
    };
    let d = Diagnostic::about(&e.node, None, e.error.to_string());
    let message = match e.frame {
        Some(f) => format!("node '{}', frame {f}: {}", e.node, e.error),
        None => format!("node '{}': {}", e.node, e.error),
    };
    Failure::with_diagnostics(status, message, [&d])
}

fn context(frame: i64, fps: f64) -> Context {
    if fps > 0.0 && fps.is_finite() {
        Context::at(frame, fps)
    } else {
        Context::new(frame)
    }
}

/// Evaluates graph output `output` at `frame` (`fps` frames a second; 0 for the default,
/// 24), computing only what it needs; stateful nodes step from their latest state, so pulling
/// frames in order costs one step each. NULL on failure (`WEFT_EVAL_FAILED` names the node
/// and frame; `WEFT_INTERRUPTED` after [`weft_interrupt_set`]). Free the value with
/// [`crate::weft_value_free`].
///
/// # Safety
/// `graph` is a live graph; `output` is NUL-terminated; `error` NULL or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_graph_pull(
    graph: *mut WeftGraph,
    output: *const c_char,
    frame: i64,
    fps: f64,
    error: *mut *mut WeftError,
) -> *mut WeftValue {
    guard(error, std::ptr::null_mut(), || {
        // SAFETY: string contract passed through.
        let output = unsafe { str_arg(output, "output") }?;
        // SAFETY: graph contract passed through.
        let v = unsafe {
            with_graph(graph, |g| {
                if g.output_type(output).is_none() {
                    let known: Vec<&str> = g.output_names().collect();
                    return Err(Failure::new(
                        WeftStatus::WeftNotFound,
                        format!(
                            "the graph has no output '{output}' (outputs: {})",
                            known.join(", ")
                        ),
                    ));
                }
                g.pull(output, context(frame, fps)).map_err(eval_failure)
            })
        }?;
        Ok(WeftValue::boxed(v, registry()))
    })
}

/// Evaluates output `port` of node `node` at `frame` (see [`weft_graph_pull`]).
///
/// # Safety
/// As [`weft_graph_pull`].
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_graph_pull_port(
    graph: *mut WeftGraph,
    node: *const c_char,
    port: *const c_char,
    frame: i64,
    fps: f64,
    error: *mut *mut WeftError,
) -> *mut WeftValue {
    guard(error, std::ptr::null_mut(), || {
        // SAFETY: string contracts passed through.
        let (node, port) = unsafe { (str_arg(node, "node")?, str_arg(port, "port")?) };
        // SAFETY: graph contract passed through.
        let v = unsafe {
            with_graph(graph, |g| {
                if g.node_output_type(node, port).is_none() {
                    return Err(Failure::new(
                        WeftStatus::WeftNotFound,
                        format!("no output '{port}' on a node '{node}'"),
                    ));
                }
                g.pull_port(node, port, context(frame, fps))
                    .map_err(eval_failure)
            })
        }?;
        Ok(WeftValue::boxed(v, registry()))
    })
}

/// Copies the graph's statistics as JSON into `buf` (snprintf convention): per node its
/// evaluations, cache hits, steps and seconds, and its own report (a solver's iterations,
/// contacts and residuals per frame), as `weft run --stats-json` writes them. Its length.
///
/// # Safety
/// `graph` is NULL or live; `buf` is NULL or writable for `capacity` bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_graph_stats_json(
    graph: *const WeftGraph,
    buf: *mut c_char,
    capacity: usize,
) -> usize {
    quiet(0, || {
        // SAFETY: NULL or live, by contract.
        let Some(h) = (unsafe { graph.as_ref() }).filter(|h| !h.poisoned) else {
            return 0;
        };
        let j = serde_json::json!({ "nodes": h.graph.stats() });
        // SAFETY: buffer contract passed through.
        unsafe { write_str(&c_string(&j.to_string()), buf, capacity) }
    })
}

/// Copies the frames fed to output `port` of node `node` into `frames` (array convention:
/// `*len` receives their number, 0 when the output is fed for all frames or not fed).
/// Returns `WEFT_OK` when the output is fed, `WEFT_NOT_FOUND` when it is not.
///
/// # Safety
/// `graph` is NULL or live; the strings are NUL-terminated; `frames` is NULL or writable
/// for `capacity` elements; `len` is NULL or writable; `error` NULL or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_graph_fed_frames(
    graph: *const WeftGraph,
    node: *const c_char,
    port: *const c_char,
    frames: *mut i64,
    capacity: usize,
    len: *mut usize,
    error: *mut *mut WeftError,
) -> WeftStatus {
    status(error, || {
        // SAFETY: NULL or live, by contract.
        let Some(h) = (unsafe { graph.as_ref() }) else {
            return Err(Failure::new(
                WeftStatus::WeftInvalidArgument,
                "graph is NULL",
            ));
        };
        if h.poisoned {
            return Err(poisoned());
        }
        // SAFETY: string contracts passed through.
        let (node, port) = unsafe { (str_arg(node, "node")?, str_arg(port, "port")?) };
        let Some(fed) = h
            .graph
            .fed_outputs()
            .into_iter()
            .find(|f| f.node == node && f.port == port)
        else {
            return Err(Failure::new(
                WeftStatus::WeftNotFound,
                format!("node '{node}': output '{port}' is not fed"),
            ));
        };
        let list = fed.frames.unwrap_or_default();
        // SAFETY: array contract passed through.
        unsafe { write_slice(&list, frames, capacity, len) }
    })
}

/// A stop request for `graph`'s pulls, to be set from another thread (a host's Cancel
/// button). Free it with [`weft_interrupt_free`]; it may outlive the graph.
///
/// # Safety
/// `graph` is NULL or live.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_graph_interrupter(graph: *const WeftGraph) -> *mut WeftInterrupt {
    quiet(std::ptr::null_mut(), || {
        // SAFETY: NULL or live, by contract.
        unsafe { graph.as_ref() }.map_or(std::ptr::null_mut(), |g| {
            Box::into_raw(Box::new(WeftInterrupt(g.graph.interrupt())))
        })
    })
}

/// Asks the running (or next) pull of the interrupter's graph to stop: it returns
/// `WEFT_INTERRUPTED` at its next check (before every node and solver iteration), keeping
/// the frames already computed. Safe from any thread.
///
/// # Safety
/// `interrupt` is NULL or live.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_interrupt_set(interrupt: *const WeftInterrupt) {
    // SAFETY: NULL or live, by contract.
    if let Some(i) = unsafe { interrupt.as_ref() } {
        i.0.stop();
    }
}

/// Clears a stop request, so the graph's pulls run again.
///
/// # Safety
/// `interrupt` is NULL or live.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_interrupt_reset(interrupt: *const WeftInterrupt) {
    // SAFETY: NULL or live, by contract.
    if let Some(i) = unsafe { interrupt.as_ref() } {
        i.0.reset();
    }
}

/// Frees an interrupter (NULL is ignored).
///
/// # Safety
/// `interrupt` is NULL or an interrupter from this library not yet freed.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_interrupt_free(interrupt: *mut WeftInterrupt) {
    if !interrupt.is_null() {
        // SAFETY: made by `Box::into_raw`, freed once by contract.
        drop(unsafe { Box::from_raw(interrupt) });
    }
}
