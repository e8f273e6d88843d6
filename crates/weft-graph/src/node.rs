//! What a node type implements: a [`Kernel`] that computes outputs from inputs and parameters,
//! and the [`EvalCx`] through which it reads them.

use crate::engine::{Context, Graph};
use crate::params::Params;
use crate::value::Value;
use std::sync::Arc;

/// Why a node failed.
#[derive(Debug, thiserror::Error)]
pub enum NodeError {
    /// An input is missing or has the wrong content.
    ///
    /// `NodeError::Input { port: "mesh".into(), message: "has no triangles".into() }`
    #[error("input '{port}': {message}")]
    Input {
        /// The input port.
        port: String,
        /// What is wrong with it.
        message: String,
    },
    /// The computation itself failed (bad data, a numerical failure).
    ///
    /// `NodeError::Failed("division by zero".into())`
    #[error("{0}")]
    Failed(String),
    /// An iterative method hit its iteration limit.
    ///
    /// `NodeError::NotConverged { iterations: 50, residual: 1e-3 }`
    #[error("did not converge after {iterations} iterations (residual {residual:e})")]
    NotConverged {
        /// Iterations done.
        iterations: usize,
        /// Residual at the last iteration.
        residual: f64,
    },
    /// The evaluation was asked to stop (Ctrl-C, a time limit, a host) before it finished;
    /// what was computed before stays valid.
    ///
    /// `NodeError::Interrupted("time limit of 30 s reached".into())`
    #[error("{0}")]
    Interrupted(String),
    /// An upstream node failed; its own error is passed on unchanged.
    #[error("{0}")]
    Upstream(Box<EvalError>),
}

impl From<crate::memory::MemoryError> for NodeError {
    fn from(e: crate::memory::MemoryError) -> Self {
        NodeError::Failed(e.to_string())
    }
}

impl From<crate::params::ParamError> for NodeError {
    fn from(e: crate::params::ParamError) -> Self {
        NodeError::Failed(e.to_string())
    }
}

/// A failure during evaluation: which node, at which frame, and why.
#[derive(Debug, thiserror::Error)]
#[error("node '{node}'{}: {error}", frame.map(|f| format!(" at frame {f}")).unwrap_or_default())]
pub struct EvalError {
    /// Node id; `outer/inner` for nodes inside an iterating composite.
    pub node: String,
    /// Frame being computed, for time-dependent nodes.
    pub frame: Option<i64>,
    /// The node's error.
    pub error: Box<NodeError>,
}

/// Computes outputs from inputs (static and animated nodes).
pub trait Compute: Send {
    /// Reads inputs and parameters from `cx` and sets every output.
    fn compute(&mut self, cx: &mut EvalCx<'_>) -> Result<(), NodeError>;
    /// Hash of anything that defines the output besides type, parameters and inputs
    /// (an inner graph, a file's contents).
    fn kernel_hash(&self) -> u128 {
        0
    }
    /// Per-node report for `--stats` (iterations, residuals, cache hits).
    fn stats_json(&self) -> Option<serde_json::Value> {
        None
    }
}

/// Steps state from frame to frame (stateful nodes). Must be a pure function of the state,
/// inputs and parameters: resuming from a checkpoint must give bit-identical results.
pub trait Step: Send {
    /// The state at the start frame (`cx` is at the start frame).
    fn init(&mut self, cx: &mut EvalCx<'_>) -> Result<Value, NodeError>;
    /// State at frame f from state at f − 1 (`cx` is at frame f).
    fn step(&mut self, state: &Value, cx: &mut EvalCx<'_>) -> Result<Value, NodeError>;
    /// Sets the outputs from a state.
    fn outputs(&mut self, state: &Value, cx: &mut EvalCx<'_>) -> Result<(), NodeError>;
    /// See [`Compute::kernel_hash`].
    fn kernel_hash(&self) -> u128 {
        0
    }
    /// See [`Compute::stats_json`].
    fn stats_json(&self) -> Option<serde_json::Value> {
        None
    }
    /// About how many bytes `state` holds, for the memory budget of checkpoints (thinned
    /// when they grow past it); 0: small.
    fn state_bytes(&self, _state: &Value, _registry: &crate::Registry) -> usize {
        0
    }
    /// The bytes of `state` for a disk checkpoint ([`crate::Graph::set_checkpoint_dir`]),
    /// restored bit for bit by [`Step::load_state`]; `None`: this node keeps no disk
    /// checkpoints (a resumed run recomputes it from the start frame).
    fn save_state(&self, _state: &Value, _registry: &crate::Registry) -> Option<Vec<u8>> {
        None
    }
    /// The state [`Step::save_state`] wrote, at the frame of `cx`; `initial` is the state at
    /// the start frame (for what the bytes do not carry, such as a compiled scene).
    fn load_state(
        &mut self,
        _bytes: &[u8],
        _initial: &Value,
        _cx: &mut EvalCx<'_>,
    ) -> Result<Value, NodeError> {
        Err(NodeError::Failed(
            "this node keeps no disk checkpoints".into(),
        ))
    }
}

/// Builds a node's kernel from its validated parameters. An `Err` is reported as a parameter
/// error at load time (a malformed expression, an unreadable file, values that do not go
/// together).
pub type Factory = Arc<dyn Fn(&Params) -> Result<Kernel, String> + Send + Sync>;

/// A node's implementation.
pub enum Kernel {
    /// Static or animated.
    Compute(Box<dyn Compute>),
    /// Stateful.
    Step(Box<dyn Step>),
}

struct FnCompute<F>(F);
impl<F: FnMut(&mut EvalCx<'_>) -> Result<(), NodeError> + Send> Compute for FnCompute<F> {
    fn compute(&mut self, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
        (self.0)(cx)
    }
}

impl Kernel {
    /// A compute kernel from a closure.
    pub fn from_fn<F>(f: F) -> Self
    where
        F: FnMut(&mut EvalCx<'_>) -> Result<(), NodeError> + Send + 'static,
    {
        Kernel::Compute(Box::new(FnCompute(f)))
    }
    pub(crate) fn kernel_hash(&self) -> u128 {
        match self {
            Kernel::Compute(k) => k.kernel_hash(),
            Kernel::Step(k) => k.kernel_hash(),
        }
    }
    pub(crate) fn stats_json(&self) -> Option<serde_json::Value> {
        match self {
            Kernel::Compute(k) => k.stats_json(),
            Kernel::Step(k) => k.stats_json(),
        }
    }
}

/// A node's view of the graph while it runs: its context, parameters, inputs and outputs.
pub struct EvalCx<'a> {
    pub(crate) graph: &'a mut Graph,
    pub(crate) node: usize,
    pub(crate) ctx: Context,
    pub(crate) params: Arc<Params>,
    pub(crate) outputs: Vec<Option<Value>>,
}

impl EvalCx<'_> {
    /// The frame being computed.
    pub fn frame(&self) -> i64 {
        self.ctx.frame
    }
    /// Time in seconds of the frame being computed.
    pub fn time(&self) -> f64 {
        self.ctx.time()
    }
    /// The evaluation context.
    pub fn context(&self) -> Context {
        self.ctx
    }
    /// The node's parameters.
    pub fn params(&self) -> &Params {
        &self.params
    }
    /// The node's id.
    pub fn node_id(&self) -> &str {
        self.graph.slot_id(self.node)
    }

    fn port_index(&self, port: &str) -> Result<usize, NodeError> {
        self.graph
            .slot_spec(self.node)
            .input_index(port)
            .ok_or_else(|| NodeError::Input {
                port: port.into(),
                message: "the node's spec declares no such input".into(),
            })
    }

    /// The value on a single input, its default when unconnected, `None` when neither.
    pub fn input_opt(&mut self, port: &str) -> Result<Option<Value>, NodeError> {
        let i = self.port_index(port)?;
        let ctx = self.ctx;
        self.graph.read_input(self.node, i, 0, ctx)
    }
    /// The value on a required single input.
    pub fn input(&mut self, port: &str) -> Result<Value, NodeError> {
        self.input_opt(port)?.ok_or_else(|| NodeError::Input {
            port: port.into(),
            message: "not connected and has no default".into(),
        })
    }
    /// All values on a multi-input, in connection order.
    pub fn inputs(&mut self, port: &str) -> Result<Vec<Value>, NodeError> {
        let i = self.port_index(port)?;
        let n = self.graph.input_count(self.node, i);
        let ctx = self.ctx;
        let mut out = Vec::with_capacity(n);
        for k in 0..n {
            if let Some(v) = self.graph.read_input(self.node, i, k, ctx)? {
                out.push(v);
            }
        }
        Ok(out)
    }
    /// The payload of a single input as a `T`.
    pub fn input_as<T: Clone + 'static>(&mut self, port: &str) -> Result<T, NodeError> {
        let v = self.input(port)?;
        v.get::<T>().cloned().ok_or_else(|| NodeError::Input {
            port: port.into(),
            message: format!("expected a {}", std::any::type_name::<T>()),
        })
    }
    /// A float input.
    pub fn f64_input(&mut self, port: &str) -> Result<f64, NodeError> {
        self.input_as::<f64>(port)
    }
    /// A structural hash of what is connected to `port` (for caches keyed on upstream).
    pub fn input_hash(&mut self, port: &str) -> Result<u128, NodeError> {
        let i = self.port_index(port)?;
        Ok(self.graph.input_hash(self.node, i, self.ctx))
    }
    /// A hash of what is connected to `port` that does not depend on the frame: it changes
    /// only when something upstream is redefined (for nodes that accumulate frames, such as
    /// file writers, to notice that earlier frames are stale).
    pub fn input_structure_hash(&mut self, port: &str) -> Result<u128, NodeError> {
        let i = self.port_index(port)?;
        Ok(self.graph.input_structure_hash(self.node, i))
    }
    /// Sets an output.
    pub fn set(&mut self, port: &str, v: impl Into<Value>) {
        match self.graph.slot_spec(self.node).output_index(port) {
            Some(i) => self.outputs[i] = Some(v.into()),
            None => panic!("node '{}' set undeclared output '{port}'", self.node_id()),
        }
    }
    /// Records a warning, shown after the run with the node and frame.
    pub fn warn(&mut self, message: impl Into<String>) {
        let (node, frame) = (self.node, self.ctx.frame);
        self.graph.push_warning(node, Some(frame), message.into());
    }
    /// The handle that says when to stop: long-running kernels pass
    /// [`crate::Interrupt::checker`] to their solvers and fail with
    /// [`NodeError::Interrupted`] when it is set.
    pub fn interrupt(&self) -> crate::Interrupt {
        self.graph.interrupt()
    }
    /// The directory output paths resolve under (see [`Graph::set_output_root`]).
    pub fn output_root(&self) -> Option<&std::path::Path> {
        self.graph.output_root()
    }
    /// Where output parameter `param` (a file or directory path) points: resolved under the
    /// output root when there is one, and refused, naming the parameter, when it leaves it
    /// (`..`, or an absolute path elsewhere) or is empty.
    pub fn output_path(&self, param: &str) -> Result<std::path::PathBuf, NodeError> {
        let rel = self.params.str(param)?;
        crate::paths::resolve_output(self.graph.output_root(), rel)
            .map_err(|m| NodeError::Failed(format!("param '{param}': {m}")))
    }
    /// What this evaluation may still allocate [bytes] ([`crate::memory::available`]):
    /// kernels refuse anything a parameter sizes beyond it, before allocating.
    pub fn memory_budget(&self) -> u64 {
        crate::memory::available()
    }
    /// The registry the graph was compiled with.
    pub fn registry(&self) -> &crate::Registry {
        self.graph.registry()
    }
}

impl EvalCx<'_> {
    /// True when what is connected to `port` depends on the frame.
    pub fn input_time_dependent(&self, port: &str) -> bool {
        let Some(i) = self.graph.slot_spec(self.node).input_index(port) else {
            return false;
        };
        self.graph.input_time_dependent(self.node, i)
    }
}
