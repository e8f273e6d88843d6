//! Pulled values: their type, a JSON summary, numbers, and a scene's elements (positions,
//! triangles, curve offsets) copied into host buffers.

use crate::{
    Failure, WeftError, WeftStatus, c_string, quiet, status, str_arg, write_slice, write_str,
};
use std::ffi::{CString, c_char};
use weft_graph::{Registry, Value};
use weft_nodes::physics::Scene;
use weft_scene::{Curves, Geometry, Mesh, SceneElement};

/// A value pulled from a graph: it keeps the result alive independently of the graph.
pub struct WeftValue {
    value: Value,
    type_name: CString,
    json: Option<CString>,
    /// A scene's element names, in the scene's order.
    elements: Vec<CString>,
}

impl WeftValue {
    pub(crate) fn boxed(value: Value, registry: &Registry) -> *mut WeftValue {
        let ty = registry.port_type_by_id(value.payload_type_id());
        let type_name = c_string(ty.map_or("unknown", |t| t.name.as_str()));
        let json = ty
            .and_then(|t| t.to_json)
            .and_then(|to| to(&value))
            .map(|j| c_string(&j.to_string()));
        let elements = value
            .get::<Scene>()
            .map(|s| s.iter().map(|e| c_string(&e.name)).collect())
            .unwrap_or_default();
        Box::into_raw(Box::new(WeftValue {
            value,
            type_name,
            json,
            elements,
        }))
    }

    fn element(&self, name: &str) -> Result<&SceneElement, Failure> {
        let Some(scene) = self.value.get::<Scene>() else {
            return Err(Failure::new(
                WeftStatus::WeftRejected,
                format!(
                    "the value is {}, not a scene",
                    self.type_name.to_string_lossy()
                ),
            ));
        };
        scene.iter().find(|e| e.name == name).ok_or_else(|| {
            let names: Vec<&str> = scene.iter().map(|e| e.name.as_str()).collect();
            Failure::new(
                WeftStatus::WeftNotFound,
                format!(
                    "the scene has no element '{name}' (elements: {})",
                    names.join(", ")
                ),
            )
        })
    }
}

/// The value behind `v`, or `WEFT_INVALID_ARGUMENT` for NULL.
///
/// # Safety
/// `v` is NULL or live.
unsafe fn live<'a>(v: *const WeftValue) -> Result<&'a WeftValue, Failure> {
    // SAFETY: NULL or live, by contract.
    unsafe { v.as_ref() }
        .ok_or_else(|| Failure::new(WeftStatus::WeftInvalidArgument, "value is NULL"))
}

/// The value's type (`scene`, `mesh`, `float`, `vec3`, `path`, …), owned by the value; NULL
/// for NULL.
///
/// # Safety
/// `value` is NULL or live.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_value_type(value: *const WeftValue) -> *const c_char {
    // SAFETY: NULL or live, by contract.
    unsafe { value.as_ref() }.map_or(std::ptr::null(), |v| v.type_name.as_ptr())
}

/// Copies the value as JSON into `buf` (snprintf convention): a number, a vector, a path, or
/// a summary for geometry and scenes (element names, kinds, vertex counts). Its length; 0
/// when its type has no JSON form.
///
/// # Safety
/// `value` is NULL or live; `buf` is NULL or writable for `capacity` bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_value_json(
    value: *const WeftValue,
    buf: *mut c_char,
    capacity: usize,
) -> usize {
    quiet(0, || {
        // SAFETY: NULL or live, by contract.
        match unsafe { value.as_ref() }.and_then(|v| v.json.as_ref()) {
            // SAFETY: buffer contract passed through.
            Some(j) => unsafe { write_str(j, buf, capacity) },
            None => 0,
        }
    })
}

fn flat(points: &[[f64; 3]]) -> &[f64] {
    points.as_flattened()
}

/// Copies the value's numbers into `buf` (array convention): a float (1), a vec3 (3), a list
/// of floats, or a mesh's or curves' positions (3 per vertex). `WEFT_REJECTED` for other
/// types (a scene's positions come per element: [`weft_value_element_positions`]).
///
/// # Safety
/// `value` is NULL or live; `buf` is NULL or writable for `capacity` doubles; `len` is NULL
/// or writable; `error` is NULL or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_value_f64s(
    value: *const WeftValue,
    buf: *mut f64,
    capacity: usize,
    len: *mut usize,
    error: *mut *mut WeftError,
) -> WeftStatus {
    status(error, || {
        // SAFETY: contract passed through.
        let v = unsafe { live(value) }?;
        let x = &v.value;
        let numbers: &[f64] = if let Some(f) = x.get::<f64>() {
            std::slice::from_ref(f)
        } else if let Some(a) = x.get::<[f64; 3]>() {
            a
        } else if let Some(l) = x.get::<Vec<f64>>() {
            l
        } else if let Some(m) = x.get::<Mesh>() {
            flat(&m.positions)
        } else if let Some(c) = x.get::<Curves>() {
            flat(&c.positions)
        } else {
            return Err(Failure::new(
                WeftStatus::WeftRejected,
                format!(
                    "a {} value has no numbers to copy (a scene's come per element)",
                    v.type_name.to_string_lossy()
                ),
            ));
        };
        // SAFETY: array contract passed through.
        unsafe { write_slice(numbers, buf, capacity, len) }
    })
}

/// The number of elements of a scene value (0 for other types).
///
/// # Safety
/// `value` is NULL or live.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_value_element_count(value: *const WeftValue) -> usize {
    // SAFETY: NULL or live, by contract.
    unsafe { value.as_ref() }.map_or(0, |v| v.elements.len())
}

/// The name of element `index` of a scene value, owned by the value; NULL when out of range.
///
/// # Safety
/// `value` is NULL or live.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_value_element_name(
    value: *const WeftValue,
    index: usize,
) -> *const c_char {
    // SAFETY: NULL or live, by contract.
    unsafe { value.as_ref() }
        .and_then(|v| v.elements.get(index))
        .map_or(std::ptr::null(), |n| n.as_ptr())
}

/// Copies the positions of element `element` of a scene value into `buf` (array convention:
/// 3 doubles per vertex, metres), in the vertex order of the geometry fed or built (a host
/// mesh fed with `weft_graph_feed_mesh` comes back in its own order).
///
/// # Safety
/// `value` is NULL or live; `element` is NUL-terminated; `buf` is NULL or writable for
/// `capacity` doubles; `len` is NULL or writable; `error` is NULL or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_value_element_positions(
    value: *const WeftValue,
    element: *const c_char,
    buf: *mut f64,
    capacity: usize,
    len: *mut usize,
    error: *mut *mut WeftError,
) -> WeftStatus {
    status(error, || {
        // SAFETY: contracts passed through.
        let (v, name) = unsafe { (live(value)?, str_arg(element, "element")?) };
        let e = v.element(name)?;
        // SAFETY: array contract passed through.
        unsafe { write_slice(flat(e.geometry.positions()), buf, capacity, len) }
    })
}

/// Copies the u32 array `pick` gives for element `element` of a scene value (array
/// convention).
///
/// # Safety
/// As [`weft_value_element_triangles`].
unsafe fn element_u32s(
    value: *const WeftValue,
    element: *const c_char,
    buf: *mut u32,
    capacity: usize,
    len: *mut usize,
    error: *mut *mut WeftError,
    pick: fn(&Geometry) -> &[u32],
) -> WeftStatus {
    status(error, || {
        // SAFETY: contracts passed through.
        let (v, name) = unsafe { (live(value)?, str_arg(element, "element")?) };
        let e = v.element(name)?;
        // SAFETY: array contract passed through.
        unsafe { write_slice(pick(&e.geometry), buf, capacity, len) }
    })
}

/// Copies the triangles of element `element` of a scene value into `buf` (array
/// convention: 3 indices per triangle); an element without triangles (hair, points) has 0.
///
/// # Safety
/// As [`weft_value_element_positions`], with `buf` writable for `capacity` indices.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_value_element_triangles(
    value: *const WeftValue,
    element: *const c_char,
    buf: *mut u32,
    capacity: usize,
    len: *mut usize,
    error: *mut *mut WeftError,
) -> WeftStatus {
    // SAFETY: contracts passed through.
    unsafe {
        element_u32s(value, element, buf, capacity, len, error, |g| match g {
            Geometry::Mesh(m) => m.triangles.as_flattened(),
            _ => &[],
        })
    }
}

/// Copies the curve offsets of element `element` of a scene value into `buf` (array
/// convention: curve count + 1 offsets, as fed with `weft_graph_feed_curves`); an element
/// without curves has 0.
///
/// # Safety
/// As [`weft_value_element_triangles`].
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_value_element_curve_offsets(
    value: *const WeftValue,
    element: *const c_char,
    buf: *mut u32,
    capacity: usize,
    len: *mut usize,
    error: *mut *mut WeftError,
) -> WeftStatus {
    // SAFETY: contracts passed through.
    unsafe {
        element_u32s(value, element, buf, capacity, len, error, |g| match g {
            Geometry::Curves(c) => &c.offsets,
            _ => &[],
        })
    }
}

/// Frees a value (NULL is ignored).
///
/// # Safety
/// `value` is NULL or a value from this library not yet freed.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_value_free(value: *mut WeftValue) {
    if !value.is_null() {
        // SAFETY: made by `Box::into_raw` in `boxed`, freed once by contract.
        let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            drop(unsafe { Box::from_raw(value) })
        }));
    }
}
