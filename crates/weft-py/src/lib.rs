//! `weft-py`: the native half of the `weft` Python module (`weft._weft`), thin over the
//! same engine as the C ABI: load a graph, list it, set parameters, feed host data (NumPy
//! arrays), pull outputs at a frame as NumPy arrays. The Python half (`python/weft/`)
//! gives the public names and docstrings; errors are Python exceptions carrying the node,
//! the parameter or port, the line and the frame.
//!
//! Built by maturin as an abi3 wheel (`pyproject.toml`), tested by `tests/test_weft.py`.

use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray1};
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use pyo3::sync::MutexExt;
use pyo3::types::{PyDict, PyList};
use std::sync::{Arc, Mutex, MutexGuard, OnceLock};
use weft_graph::{Context, Diagnostic, Graph as Engine, Interrupt, Registry, Value};
use weft_nodes::physics::Scene;
use weft_scene::{Curves, Geometry, Mesh};

pyo3::create_exception!(_weft, WeftError, PyException, "Any error Weft reports.");
pyo3::create_exception!(
    _weft,
    LoadError,
    WeftError,
    "A graph file could not be loaded."
);
pyo3::create_exception!(
    _weft,
    GraphError,
    WeftError,
    "A node, port, parameter or output was not found, or a value was refused."
);
pyo3::create_exception!(
    _weft,
    EvalError,
    WeftError,
    "Evaluating the graph failed at a node and frame."
);
pyo3::create_exception!(
    _weft,
    Interrupted,
    WeftError,
    "A pull was stopped by an interrupt."
);

fn registry() -> &'static Arc<Registry> {
    static R: OnceLock<Arc<Registry>> = OnceLock::new();
    R.get_or_init(weft_nodes::registry)
}

/// A problem as a dict: message, node, field, line, column (None when unknown).
fn problem<'py>(py: Python<'py>, d: &Diagnostic) -> PyResult<Bound<'py, PyDict>> {
    let p = PyDict::new(py);
    p.set_item(
        "message",
        match &d.help {
            Some(h) => format!("{} ({h})", d.message),
            None => d.message.clone(),
        },
    )?;
    p.set_item("node", d.node.clone())?;
    p.set_item("field", d.field.clone())?;
    p.set_item("line", d.line)?;
    p.set_item("column", d.column)?;
    Ok(p)
}

/// An exception of type `T` with `message` and attributes `problems` (a list of dicts),
/// `node`, `field`, `line` and `frame` taken from the first problem.
fn error<T: pyo3::PyTypeInfo>(
    py: Python<'_>,
    message: String,
    diagnostics: &[&Diagnostic],
    frame: Option<i64>,
) -> PyErr {
    let err = PyErr::new::<T, _>(message);
    let value = err.value(py);
    let set = || -> PyResult<()> {
        let list = PyList::empty(py);
        for d in diagnostics {
            list.append(problem(py, d)?)?;
        }
        value.setattr("problems", list)?;
        let first = diagnostics.first();
        value.setattr("node", first.and_then(|d| d.node.clone()))?;
        value.setattr("field", first.and_then(|d| d.field.clone()))?;
        value.setattr("line", first.and_then(|d| d.line))?;
        value.setattr("frame", frame)?;
        Ok(())
    };
    match set() {
        Ok(()) => err,
        Err(e) => e,
    }
}

/// Host data refused for output `port` of `node`.
fn refused(py: Python<'_>, node: &str, port: &str, message: String) -> PyErr {
    graph_error(
        py,
        Box::new(Diagnostic::about(
            node,
            Some(&format!("output '{port}'")),
            message,
        )),
    )
}

fn graph_error(py: Python<'_>, d: Box<Diagnostic>) -> PyErr {
    error::<GraphError>(py, d.to_string(), &[&d], None)
}

fn eval_error(py: Python<'_>, e: weft_graph::EvalError) -> PyErr {
    let d = Diagnostic::about(&e.node, None, e.error.to_string());
    let message = match e.frame {
        Some(f) => format!("node '{}', frame {f}: {}", e.node, e.error),
        None => format!("node '{}': {}", e.node, e.error),
    };
    if matches!(*e.error, weft_graph::NodeError::Interrupted(_)) {
        error::<Interrupted>(py, message, &[&d], e.frame)
    } else {
        error::<EvalError>(py, message, &[&d], e.frame)
    }
}

fn load_error(py: Python<'_>, e: weft_graph::LoadError) -> PyErr {
    let errors: Vec<&Diagnostic> = e.errors().collect();
    let lines: Vec<String> = errors.iter().map(|d| format!("  {d}")).collect();
    error::<LoadError>(
        py,
        format!(
            "{}: {} error(s)\n{}",
            e.source_name,
            errors.len(),
            lines.join("\n")
        ),
        &errors,
        None,
    )
}

/// A fed output as `Graph.fed` lists it: (node, port, frames or None for all frames).
type FedRow = (String, String, Option<Vec<i64>>);

/// A stop request another Python thread may set while a pull runs.
#[pyclass(module = "weft._weft", frozen)]
struct Interrupter(Interrupt);

#[pymethods]
impl Interrupter {
    /// Asks the running (or next) pull to stop; it raises `Interrupted`.
    fn set(&self) {
        self.0.stop();
    }
    /// Clears the request.
    fn reset(&self) {
        self.0.reset();
    }
}

/// A loaded graph. The engine sits behind a mutex (a Python object may be shared between
/// threads); a pull holds it with the GIL released.
#[pyclass(module = "weft._weft")]
struct Graph {
    engine: Mutex<Engine>,
    /// The engine's stop request, outside the mutex: a Cancel must not wait for the pull it
    /// stops.
    interrupt: Interrupt,
}

fn poisoned() -> PyErr {
    WeftError::new_err("an earlier internal error left this graph half-updated; load it again")
}

impl Graph {
    fn new(engine: Engine) -> Self {
        Graph {
            interrupt: engine.interrupt(),
            engine: Mutex::new(engine),
        }
    }

    /// The engine, or an error when an internal error (a panic) left it half-updated. While
    /// another thread holds it (a pull, with the GIL released), waiting releases the GIL too,
    /// so that thread can finish.
    fn engine(&self, py: Python<'_>) -> PyResult<MutexGuard<'_, Engine>> {
        self.engine.lock_py_attached(py).map_err(|_| poisoned())
    }
}

fn context(frame: i64, fps: f64) -> PyResult<Context> {
    if !(fps > 0.0 && fps.is_finite()) {
        return Err(pyo3::exceptions::PyValueError::new_err(format!(
            "fps must be a positive number, not {fps}"
        )));
    }
    Ok(Context::at(frame, fps))
}

fn points(node: &str, port: &str, xyz: &[f64]) -> Result<Vec<[f64; 3]>, String> {
    if !xyz.len().is_multiple_of(3) {
        return Err(format!(
            "node '{node}': output '{port}': positions must be N × 3 (got {} numbers)",
            xyz.len()
        ));
    }
    if let Some(k) = xyz.iter().position(|x| !x.is_finite()) {
        return Err(format!(
            "node '{node}': output '{port}': vertex {} has a non-finite coordinate ({})",
            k / 3,
            xyz[k]
        ));
    }
    Ok(xyz.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
}

/// A value pulled from the graph, as Python objects: numbers and vectors as floats and
/// arrays, meshes as (positions, triangles), curves as (positions, offsets), scenes as a
/// dict of element name → dict(kind, positions, triangles, offsets), paths as str, other
/// types as their JSON summary (a dict or list).
fn to_python<'py>(py: Python<'py>, v: &Value) -> PyResult<Bound<'py, PyAny>> {
    let positions = |p: &[[f64; 3]]| -> PyResult<Bound<'py, PyAny>> {
        Ok(PyArray1::from_slice(py, p.as_flattened())
            .reshape([p.len(), 3])?
            .into_any())
    };
    let indices = |i: &[u32], width: usize| -> PyResult<Bound<'py, PyAny>> {
        let a = PyArray1::from_slice(py, i);
        Ok(if width > 1 {
            a.reshape([i.len() / width, width])?.into_any()
        } else {
            a.into_any()
        })
    };
    if let Some(x) = v.get::<f64>() {
        return Ok(x.into_pyobject(py)?.into_any());
    }
    if let Some(a) = v.get::<[f64; 3]>() {
        return Ok(PyArray1::from_slice(py, a).into_any());
    }
    if let Some(l) = v.get::<Vec<f64>>() {
        return Ok(PyArray1::from_slice(py, l).into_any());
    }
    if let Some(m) = v.get::<Mesh>() {
        return Ok((
            positions(&m.positions)?,
            indices(m.triangles.as_flattened(), 3)?,
        )
            .into_pyobject(py)?
            .into_any());
    }
    if let Some(c) = v.get::<Curves>() {
        return Ok((positions(&c.positions)?, indices(&c.offsets, 1)?)
            .into_pyobject(py)?
            .into_any());
    }
    if let Some(s) = v.get::<Scene>() {
        let d = PyDict::new(py);
        for e in s {
            let el = PyDict::new(py);
            el.set_item("kind", e.kind.name())?;
            el.set_item("positions", positions(e.geometry.positions())?)?;
            match &*e.geometry {
                Geometry::Mesh(m) => {
                    el.set_item("triangles", indices(m.triangles.as_flattened(), 3)?)?
                }
                Geometry::Curves(c) => el.set_item("offsets", indices(&c.offsets, 1)?)?,
                _ => {}
            }
            d.set_item(&e.name, el)?;
        }
        return Ok(d.into_any());
    }
    if let Some(p) = v.get::<String>() {
        return Ok(p.into_pyobject(py)?.into_any());
    }
    let ty = registry().port_type_by_id(v.payload_type_id());
    let json = ty.and_then(|t| t.to_json).and_then(|to| to(v));
    match json {
        Some(j) => {
            let text = j.to_string();
            Ok(py.import("json")?.call_method1("loads", (text,))?)
        }
        None => Ok(py.None().into_bound(py)),
    }
}

#[pymethods]
impl Graph {
    /// Loads the graph file at `path`; raises `LoadError` listing every problem.
    #[staticmethod]
    fn load(py: Python<'_>, path: std::path::PathBuf) -> PyResult<Self> {
        let engine = weft_graph::load_path(registry(), &path).map_err(|e| load_error(py, e))?;
        Ok(Graph::new(engine))
    }

    /// Loads a graph from JSON text; `name` names it in messages.
    #[staticmethod]
    #[pyo3(signature = (text, name = "<memory>"))]
    fn from_string(py: Python<'_>, text: &str, name: &str) -> PyResult<Self> {
        let engine = weft_graph::load_str(registry(), text, name).map_err(|e| load_error(py, e))?;
        Ok(Graph::new(engine))
    }

    /// Node ids in evaluation order.
    fn nodes(&self, py: Python<'_>) -> PyResult<Vec<String>> {
        Ok(self.engine(py)?.node_ids().map(str::to_string).collect())
    }

    /// A node's description: type, doc, inputs and outputs as lists of (name, type), and
    /// parameters as a list of dicts (name, kind, default, unit, doc, value).
    fn describe<'py>(&self, py: Python<'py>, node: &str) -> PyResult<Bound<'py, PyDict>> {
        // Everything is read under the lock into Rust values, and the lock dropped, before
        // any Python runs (Python may switch threads, and another thread may want the lock).
        let (name, doc, inputs, outputs, params) = {
            let engine = self.engine(py)?;
            let spec = engine.node_spec(node).ok_or_else(|| {
                graph_error(py, Box::new(Diagnostic::about(node, None, "no such node")))
            })?;
            let inputs: Vec<(String, String)> = spec
                .inputs
                .iter()
                .map(|p| {
                    let ty = match &p.ty {
                        weft_graph::TypeRef::Named(n) => n.clone(),
                        _ => "any".into(),
                    };
                    (p.name.clone(), ty)
                })
                .collect();
            let outputs: Vec<(String, String)> = spec
                .outputs
                .iter()
                .map(|p| {
                    let ty = engine.node_output_type(node, &p.name).unwrap_or("any");
                    (p.name.clone(), ty.to_string())
                })
                .collect();
            let params: Vec<String> = engine
                .param_descriptions(node)
                .expect("the node exists")
                .iter()
                .map(|j| j.to_string())
                .collect();
            (spec.name.clone(), spec.doc.clone(), inputs, outputs, params)
        };
        let d = PyDict::new(py);
        d.set_item("type", name)?;
        d.set_item("doc", doc)?;
        d.set_item("inputs", inputs)?;
        d.set_item("outputs", outputs)?;
        let json = py.import("json")?;
        let list = PyList::empty(py);
        for p in params {
            list.append(json.call_method1("loads", (p,))?)?;
        }
        d.set_item("params", list)?;
        Ok(d)
    }

    /// The graph's outputs: name → type.
    fn outputs(&self, py: Python<'_>) -> PyResult<Vec<(String, String)>> {
        let engine = self.engine(py)?;
        Ok(engine
            .output_names()
            .map(|o| {
                (
                    o.to_string(),
                    engine.output_type(o).unwrap_or("any").to_string(),
                )
            })
            .collect())
    }

    /// Sets a parameter from a Python value (float, int, bool, str, list), validated as in
    /// a graph file; raises `GraphError` naming the node and parameter.
    fn set(
        &self,
        py: Python<'_>,
        node: &str,
        param: &str,
        value: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let text: String = py
            .import("json")?
            .call_method1("dumps", (value,))?
            .extract()?;
        let v: serde_json::Value = serde_json::from_str(&text)
            .map_err(|e| pyo3::exceptions::PyValueError::new_err(e.to_string()))?;
        self.engine(py)?
            .set_param(node, param, v)
            .map_err(|d| graph_error(py, d))
    }

    /// Feeds a mesh (positions as a flat float64 array, triangles as a flat uint32 array) in
    /// place of output `port` of `node`, for `frame` or all frames (None).
    #[pyo3(signature = (node, port, positions, triangles, frame = None))]
    fn feed_mesh(
        &self,
        py: Python<'_>,
        node: &str,
        port: &str,
        positions: PyReadonlyArray1<'_, f64>,
        triangles: PyReadonlyArray1<'_, u32>,
        frame: Option<i64>,
    ) -> PyResult<()> {
        let refuse = |m: String| refused(py, node, port, m);
        let xyz = points(node, port, positions.as_slice()?).map_err(refuse)?;
        let tri = triangles.as_slice()?;
        if !tri.len().is_multiple_of(3) {
            return Err(refuse(format!(
                "triangles must be M × 3 (got {} indices)",
                tri.len()
            )));
        }
        if let Some(k) = tri.iter().position(|&i| i as usize >= xyz.len()) {
            return Err(refuse(format!(
                "triangle {} uses vertex {}, but there are {} vertices",
                k / 3,
                tri[k],
                xyz.len()
            )));
        }
        let mesh = Mesh {
            positions: xyz,
            triangles: tri.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        };
        self.engine(py)?
            .feed(node, port, frame, Value::new(mesh))
            .map_err(|d| graph_error(py, d))
    }

    /// Feeds curves (positions as a flat float64 array, offsets: curve count + 1 uint32,
    /// from 0 to the vertex count) in place of output `port` of `node`.
    #[pyo3(signature = (node, port, positions, offsets, frame = None))]
    fn feed_curves(
        &self,
        py: Python<'_>,
        node: &str,
        port: &str,
        positions: PyReadonlyArray1<'_, f64>,
        offsets: PyReadonlyArray1<'_, u32>,
        frame: Option<i64>,
    ) -> PyResult<()> {
        let refuse = |m: String| refused(py, node, port, m);
        let xyz = points(node, port, positions.as_slice()?).map_err(refuse)?;
        let off = offsets.as_slice()?;
        if off.first() != Some(&0) || off.last().map(|&l| l as usize) != Some(xyz.len()) {
            return Err(refuse(format!(
                "offsets must start at 0 and end at the vertex count {}",
                xyz.len()
            )));
        }
        if let Some(k) = off.windows(2).position(|w| w[1] < w[0].saturating_add(2)) {
            return Err(refuse(format!("curve {k} has fewer than 2 vertices")));
        }
        let curves = Curves {
            positions: xyz,
            offsets: off.to_vec(),
        };
        self.engine(py)?
            .feed(node, port, frame, Value::new(curves))
            .map_err(|d| graph_error(py, d))
    }

    /// Feeds a number in place of a float output.
    #[pyo3(signature = (node, port, value, frame = None))]
    fn feed_float(
        &self,
        py: Python<'_>,
        node: &str,
        port: &str,
        value: f64,
        frame: Option<i64>,
    ) -> PyResult<()> {
        self.engine(py)?
            .feed(node, port, frame, Value::new(value))
            .map_err(|d| graph_error(py, d))
    }

    /// Stops feeding an output; whether it was fed.
    fn unfeed(&self, py: Python<'_>, node: &str, port: &str) -> PyResult<bool> {
        self.engine(py)?
            .unfeed(node, port)
            .map_err(|d| graph_error(py, d))
    }

    /// The fed outputs: a list of (node, port, frames or None).
    fn fed(&self, py: Python<'_>) -> PyResult<Vec<FedRow>> {
        Ok(self
            .engine(py)?
            .fed_outputs()
            .into_iter()
            .map(|f| (f.node, f.port, f.frames))
            .collect())
    }

    /// Sets the directory under which file outputs write (None: the working directory).
    #[pyo3(signature = (directory = None))]
    fn set_output_root(
        &self,
        py: Python<'_>,
        directory: Option<std::path::PathBuf>,
    ) -> PyResult<()> {
        self.engine(py)?.set_output_root(directory);
        Ok(())
    }

    /// Evaluates graph output `output` at `frame`; the GIL is released while it runs.
    #[pyo3(signature = (output, frame, fps = 24.0))]
    fn pull<'py>(
        &self,
        py: Python<'py>,
        output: &str,
        frame: i64,
        fps: f64,
    ) -> PyResult<Bound<'py, PyAny>> {
        let ctx = context(frame, fps)?;
        if self.engine(py)?.output_type(output).is_none() {
            let known: Vec<String> = self.engine(py)?.output_names().map(String::from).collect();
            return Err(graph_error(
                py,
                Box::new(Diagnostic::about(
                    "",
                    None,
                    format!(
                        "the graph has no output '{output}' (outputs: {})",
                        known.join(", ")
                    ),
                )),
            ));
        }
        // Locked inside, with the GIL released: the guard never crosses threads.
        let v = py
            .detach(|| {
                self.engine
                    .lock()
                    .map(|mut g| g.pull(output, ctx))
                    .map_err(drop)
            })
            .map_err(|_| poisoned())?
            .map_err(|e| eval_error(py, e))?;
        to_python(py, &v)
    }

    /// Evaluates output `port` of node `node` at `frame`.
    #[pyo3(signature = (node, port, frame, fps = 24.0))]
    fn pull_port<'py>(
        &self,
        py: Python<'py>,
        node: &str,
        port: &str,
        frame: i64,
        fps: f64,
    ) -> PyResult<Bound<'py, PyAny>> {
        let ctx = context(frame, fps)?;
        if self.engine(py)?.node_output_type(node, port).is_none() {
            return Err(graph_error(
                py,
                Box::new(Diagnostic::about(node, None, format!("no output '{port}'"))),
            ));
        }
        // Locked inside, with the GIL released: the guard never crosses threads.
        let v = py
            .detach(|| {
                self.engine
                    .lock()
                    .map(|mut g| g.pull_port(node, port, ctx))
                    .map_err(drop)
            })
            .map_err(|_| poisoned())?
            .map_err(|e| eval_error(py, e))?;
        to_python(py, &v)
    }

    /// Per-node statistics as JSON text (as `weft run --stats-json` writes them).
    fn stats_json(&self, py: Python<'_>) -> PyResult<String> {
        Ok(serde_json::json!({ "nodes": self.engine(py)?.stats() }).to_string())
    }

    /// A stop request for this graph's pulls, to set from another thread.
    fn interrupter(&self) -> Interrupter {
        Interrupter(self.interrupt.clone())
    }
}

/// The module.
#[pymodule]
fn _weft(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add_class::<Graph>()?;
    m.add_class::<Interrupter>()?;
    m.add("WeftError", py.get_type::<WeftError>())?;
    m.add("LoadError", py.get_type::<LoadError>())?;
    m.add("GraphError", py.get_type::<GraphError>())?;
    m.add("EvalError", py.get_type::<EvalError>())?;
    m.add("Interrupted", py.get_type::<Interrupted>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
