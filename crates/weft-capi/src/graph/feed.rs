//! Host-fed data: meshes, curves and numbers given to a graph's input nodes for one frame
//! or all, checked (NULL with a count, non-finite values, indices out of range) before the
//! graph sees them.

use super::*;

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
