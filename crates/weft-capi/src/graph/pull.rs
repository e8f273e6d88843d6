//! Pulling results, statistics and fed frames out of a graph, and the interrupt a host
//! sets from another thread to stop a pull.

use super::*;

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
