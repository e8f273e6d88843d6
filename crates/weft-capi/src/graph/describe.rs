//! Listing a loaded graph for a host's UI: its nodes, their ports and parameters (names,
//! kinds, values as JSON), the graph's outputs, and setting a parameter.

use super::*;

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
