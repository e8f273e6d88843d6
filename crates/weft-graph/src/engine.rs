//! The evaluator: lazy pull, pushed dirtiness, per-node caches, stateful checkpoints.
//!
//! Invariants:
//! - Slots are stored in a topological order: every input of slot `n` comes from a slot `< n`.
//! - A slot's cache is valid for a context when the slot is not dirty and either it is
//!   effectively static (nothing upstream depends on time) or the cache was made at that
//!   context. Dirtiness is pushed to every downstream slot when a parameter or input changes.
//! - A stateful slot's checkpoints are the states at frames `start..=k` computed with the
//!   current upstream; any upstream change drops them all (every frame after the start depends
//!   on every input).
//! - Evaluation is iterative over the needed set, so deep chains do not grow the call stack;
//!   only lazy-input and stateful nodes pull recursively, one level per such node.

use crate::diag::Diagnostic;
use crate::interrupt::Interrupt;
use crate::node::Factory;
use crate::node::{EvalCx, EvalError, Kernel, NodeError};
use crate::params::Params;
use crate::registry::Registry;
use crate::spec::{NodeSpec, TimeClass};
use crate::value::Value;
use serde::Serialize;
use std::any::TypeId;
use std::collections::{BTreeMap, HashMap};
use std::sync::Arc;
use std::time::{Duration, Instant};

mod inspect;

/// Where in time a value is asked for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Context {
    /// Frame number.
    pub frame: i64,
    /// Frames per second (time = frame / fps).
    pub fps: f64,
}

impl Context {
    /// Frame `frame` at 24 fps.
    pub fn new(frame: i64) -> Self {
        Context { frame, fps: 24.0 }
    }
    /// Frame `frame` at `fps`.
    pub fn at(frame: i64, fps: f64) -> Self {
        Context { frame, fps }
    }
    /// Time in seconds.
    pub fn time(&self) -> f64 {
        self.frame as f64 / self.fps
    }
    pub(crate) fn with_frame(self, frame: i64) -> Self {
        Context { frame, ..self }
    }
}

/// Evaluation counters and time of one node.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct NodeStats {
    /// Times the node computed (a stateful node counts one per pull that was not cached).
    pub evaluations: u64,
    /// Times a cached output was returned instead.
    pub cache_hits: u64,
    /// Stateful nodes: frame steps taken.
    pub steps: u64,
    /// Stateful nodes: states restored from disk checkpoints instead of stepped.
    pub restored: u64,
    /// Time spent in the node itself, excluding upstream nodes it pulled.
    pub seconds: f64,
}

/// One row of [`Graph::stats`].
#[derive(Clone, Debug, Serialize)]
pub struct NodeReport {
    /// Node id.
    pub node: String,
    /// Node type.
    #[serde(rename = "type")]
    pub type_name: String,
    /// Counters.
    #[serde(flatten)]
    pub stats: NodeStats,
    /// The node's own report (iterations, residuals, cache files), if it keeps one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub details: Option<serde_json::Value>,
}

/// A warning raised while running.
#[derive(Clone, Debug, PartialEq)]
pub struct RunWarning {
    /// Node id.
    pub node: String,
    /// Frame, for time-dependent nodes.
    pub frame: Option<i64>,
    /// What happened.
    pub message: String,
}

pub(crate) struct Cached {
    ctx: Context,
    outputs: Vec<Value>,
}

pub(crate) struct Slot {
    pub id: String,
    pub spec: Arc<NodeSpec>,
    pub params: Arc<Params>,
    pub factory: Option<Factory>,
    pub kernel: Option<Kernel>,
    /// Source slots (graph inputs) hold their value here.
    pub source: Option<Value>,
    /// Per input port, the connected (slot, output port) pairs.
    pub inputs: Vec<Vec<(usize, usize)>>,
    pub input_defaults: Vec<Option<Value>>,
    pub out_types: Vec<Option<TypeId>>,
    pub out_type_names: Vec<String>,
    pub downstream: Vec<usize>,
    pub eff_static: bool,
    pub dirty: bool,
    pub(crate) cache: Option<Cached>,
    pub(crate) checkpoints: crate::checkpoints::Checkpoints,
    pub(crate) ckpt_fps: f64,
    pub(crate) hash: Option<u128>,
    /// Hash of a source value or of what the kernel adds.
    pub external: u128,
    /// Per output port, what a host feeds in place of the node's own result
    /// ([`Graph::feed`]); empty when nothing is fed.
    pub(crate) feeds: Vec<Option<crate::feed::Samples>>,
    /// Hash of the feeds (zero when none).
    pub(crate) feed_hash: u128,
    /// Parameters driven by connections: (input index, parameter name).
    pub(crate) param_links: Vec<(usize, String)>,
    pub(crate) stats: NodeStats,
}

impl Slot {
    pub(crate) fn new(id: String, spec: Arc<NodeSpec>, params: Params) -> Self {
        let n_in = spec.inputs.len();
        let n_out = spec.outputs.len();
        Slot {
            id,
            spec,
            params: Arc::new(params),
            factory: None,
            kernel: None,
            source: None,
            inputs: vec![Vec::new(); n_in],
            input_defaults: vec![None; n_in],
            out_types: vec![None; n_out],
            out_type_names: vec![String::new(); n_out],
            downstream: Vec::new(),
            eff_static: true,
            dirty: true,
            cache: None,
            checkpoints: Default::default(),
            ckpt_fps: 0.0,
            hash: None,
            external: 0,
            feeds: Vec::new(),
            feed_hash: 0,
            param_links: Vec::new(),
            stats: NodeStats::default(),
        }
    }
}

impl std::fmt::Debug for Graph {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Graph")
            .field(
                "nodes",
                &self.slots.iter().map(|s| s.id.as_str()).collect::<Vec<_>>(),
            )
            .field("outputs", &self.outputs.keys().collect::<Vec<_>>())
            .finish()
    }
}

/// A compiled, evaluable graph.
pub struct Graph {
    pub(crate) registry: Arc<Registry>,
    pub(crate) slots: Vec<Slot>,
    pub(crate) ids: HashMap<String, usize>,
    pub(crate) outputs: BTreeMap<String, (usize, usize)>,
    pub(crate) inputs: BTreeMap<String, usize>,
    warnings: Vec<RunWarning>,
    timers: Vec<Duration>,
    mark: Vec<u32>,
    mark_gen: u32,
    pub(crate) load_warnings: Vec<Diagnostic>,
    interrupt: Interrupt,
    output_root: Option<std::path::PathBuf>,
    pub(crate) checkpoint_dir: Option<std::path::PathBuf>,
    warning_sink: Option<WarningSink>,
    /// Per slot, its id shared for the run's activity line ([`Interrupt::activity`]), made
    /// at its first evaluation.
    labels: Vec<Arc<str>>,
}

/// Called with each new warning as it is raised (a command line prints it at once).
pub type WarningSink = Arc<dyn Fn(&RunWarning) + Send + Sync>;

/// The first non-finite number in a float-valued payload (`float`, `vec3`, `floats`).
/// Physics types check their own data where they are made.
pub(crate) fn non_finite(v: &Value) -> Option<f64> {
    let bad = |x: &f64| !x.is_finite();
    if let Some(x) = v.get::<f64>() {
        return bad(x).then_some(*x);
    }
    if let Some(a) = v.get::<[f64; 3]>() {
        return a.iter().copied().find(|x| bad(x));
    }
    v.get::<Vec<f64>>()
        .and_then(|a| a.iter().copied().find(|x| bad(x)))
}

pub(crate) fn nonce() -> u128 {
    use std::sync::atomic::{AtomicU64, Ordering};
    static N: AtomicU64 = AtomicU64::new(1);
    let t = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    (t << 32) ^ ((std::process::id() as u128) << 64) ^ N.fetch_add(1, Ordering::Relaxed) as u128
}

impl Graph {
    pub(crate) fn new(registry: Arc<Registry>) -> Self {
        Graph {
            registry,
            slots: Vec::new(),
            ids: HashMap::new(),
            outputs: BTreeMap::new(),
            inputs: BTreeMap::new(),
            warnings: Vec::new(),
            timers: Vec::new(),
            mark: Vec::new(),
            mark_gen: 0,
            load_warnings: Vec::new(),
            interrupt: Interrupt::new(),
            output_root: None,
            checkpoint_dir: None,
            warning_sink: None,
            labels: Vec::new(),
        }
    }

    /// Slot `n`'s id for the activity line.
    fn label(&mut self, n: usize) -> Arc<str> {
        while self.labels.len() <= n {
            let k = self.labels.len();
            self.labels.push(Arc::from(self.slots[k].id.as_str()));
        }
        self.labels[n].clone()
    }

    /// Appends a slot; its inputs must refer to earlier slots.
    pub(crate) fn push_slot(&mut self, slot: Slot) -> usize {
        let n = self.slots.len();
        self.ids.insert(slot.id.clone(), n);
        self.slots.push(slot);
        n
    }

    /// Links downstream lists and time dependence once every slot is in.
    pub(crate) fn finish(&mut self) {
        for n in 0..self.slots.len() {
            let srcs: Vec<usize> = self.slots[n]
                .inputs
                .iter()
                .flatten()
                .map(|&(s, _)| s)
                .collect();
            for &s in &srcs {
                debug_assert!(s < n, "slots must be in topological order");
                if !self.slots[s].downstream.contains(&n) {
                    self.slots[s].downstream.push(n);
                }
            }
        }
        self.refresh_time();
        self.mark = vec![0; self.slots.len()];
    }

    /// Recomputes which slots are effectively static: a node is when its type is static and
    /// all its inputs are, or when a host feeds every output one value for all frames; a
    /// fed output that varies by frame makes its node time-dependent.
    pub(crate) fn refresh_time(&mut self) {
        for n in 0..self.slots.len() {
            let s = &self.slots[n];
            let fed = crate::feed::time_of(&s.feeds, s.spec.outputs.len());
            let eff_static = match fed {
                crate::feed::FedTime::All { varies } => !varies,
                crate::feed::FedTime::Some { varies } => {
                    !varies
                        && s.spec.time == TimeClass::Static
                        && s.inputs
                            .iter()
                            .flatten()
                            .all(|&(src, _)| self.slots[src].eff_static)
                }
            };
            self.slots[n].eff_static = eff_static;
        }
    }

    /// True when any node (not only those feeding outputs) depends on time: a subgraph whose
    /// loop test or feedback reads the frame is time-dependent even if its outputs are not.
    pub(crate) fn any_time_dependent(&self) -> bool {
        self.slots.iter().any(|s| !s.eff_static)
    }

    /// A fresh mark generation; on wrap-around the marks are cleared so no stale mark matches.
    fn next_mark(&mut self) -> u32 {
        self.mark_gen = self.mark_gen.wrapping_add(1);
        if self.mark_gen == 0 {
            self.mark.iter_mut().for_each(|m| *m = 0);
            self.mark_gen = 1;
        }
        self.mark_gen
    }

    fn valid(&self, n: usize, ctx: &Context) -> bool {
        let s = &self.slots[n];
        !s.dirty
            && s.cache
                .as_ref()
                .is_some_and(|c| s.eff_static || c.ctx == *ctx)
    }

    fn pulls_itself(&self, n: usize) -> bool {
        let s = &self.slots[n];
        s.spec.lazy_inputs || s.spec.time == TimeClass::Stateful
    }

    /// Makes slot `n`'s cache valid at `ctx`, evaluating what it needs and nothing else.
    fn ensure(&mut self, target: usize, ctx: Context) -> Result<(), EvalError> {
        if self.valid(target, &ctx) {
            self.slots[target].stats.cache_hits += 1;
            return Ok(());
        }
        let generation = self.next_mark();
        let mut need = Vec::new();
        let mut stack = vec![target];
        while let Some(n) = stack.pop() {
            if self.mark[n] == generation {
                continue;
            }
            self.mark[n] = generation;
            if self.valid(n, &ctx) || (n != target && self.unset_input(n)) {
                continue;
            }
            need.push(n);
            // A node whose every output a host feeds is not computed: nor are its inputs.
            let all_fed =
                crate::feed::all_fed(&self.slots[n].feeds, self.slots[n].spec.outputs.len());
            if !self.pulls_itself(n) && !all_fed {
                for &(s, _) in self.slots[n].inputs.iter().flatten() {
                    if self.mark[s] != generation {
                        stack.push(s);
                    }
                }
            }
        }
        // Ascending index is a topological order, so every input is ready before its reader.
        need.sort_unstable();
        for n in need {
            if !self.valid(n, &ctx) {
                self.evaluate(n, ctx)?;
            }
        }
        Ok(())
    }

    pub(crate) fn read_input(
        &mut self,
        n: usize,
        port: usize,
        k: usize,
        ctx: Context,
    ) -> Result<Option<Value>, NodeError> {
        let Some(&(src, p)) = self.slots[n].inputs[port].get(k) else {
            return Ok(self.slots[n].input_defaults[port].clone());
        };
        if self.unset_input(src) {
            // As if unconnected.
            return Ok(self.slots[n].input_defaults[port].clone());
        }
        self.ensure(src, ctx)
            .map_err(|e| NodeError::Upstream(Box::new(e)))?;
        Ok(self.slots[src].cache.as_ref().map(|c| c.outputs[p].clone()))
    }

    /// The evaluation context of slot `n` at `ctx`: its parameters, with those driven by
    /// connections read at `ctx` (checked as at load, factory included).
    /// Whether slot `n` is a subgraph's optional input (declared with a null default) left
    /// unconnected outside: it reads as nothing, as an unconnected optional input does, and
    /// is never evaluated.
    fn unset_input(&self, n: usize) -> bool {
        let s = &self.slots[n];
        s.kernel.is_none() && s.source.is_none() && s.spec.name == "graph.input"
    }

    pub(crate) fn cx(&mut self, n: usize, ctx: Context) -> Result<EvalCx<'_>, NodeError> {
        let params = if self.slots[n].param_links.is_empty() {
            self.slots[n].params.clone()
        } else {
            self.linked_params(n, ctx)?
        };
        let outputs = vec![None; self.slots[n].spec.outputs.len()];
        Ok(EvalCx {
            graph: self,
            node: n,
            ctx,
            params,
            outputs,
        })
    }

    /// Slot `n`'s parameters with each connected one set to its connection's value at `ctx`,
    /// validated against its spec (range, kind) and by the node's factory, so a value that
    /// would be refused in the file is refused here, naming the parameter.
    fn linked_params(&mut self, n: usize, ctx: Context) -> Result<Arc<Params>, NodeError> {
        let links = self.slots[n].param_links.clone();
        let mut params = (*self.slots[n].params).clone();
        for (port, name) in &links {
            let fail = |message: String| NodeError::Input {
                port: name.clone(),
                message: format!("param '{name}' from its connection: {message}"),
            };
            let Some(x) = self
                .read_input(n, *port, 0, ctx)?
                .and_then(|v| v.get::<f64>().copied())
            else {
                return Err(fail("not connected to a number".into()));
            };
            let spec = self.slots[n].spec.clone();
            let ps = spec
                .param_spec(name)
                .expect("links are made for declared parameters");
            let json = match ps.kind {
                crate::spec::ParamKind::Int { .. } if x.fract() == 0.0 && x.abs() < 9e15 => {
                    serde_json::json!(x as i64)
                }
                crate::spec::ParamKind::Int { .. } => {
                    return Err(fail(format!("{x} is not an integer")));
                }
                _ => match serde_json::Number::from_f64(x) {
                    Some(v) => serde_json::Value::Number(v),
                    None => return Err(fail(format!("{x} is not a number"))),
                },
            };
            let v = crate::params::check_param(ps, &json).map_err(fail)?;
            params.set(name, v);
        }
        if let Some(f) = self.slots[n].factory.clone() {
            f(&params).map_err(|m| {
                NodeError::Failed(format!("with its connected parameters at this frame: {m}"))
            })?;
        }
        Ok(Arc::new(params))
    }

    fn interrupted(&self, n: usize, frame: i64) -> Result<(), EvalError> {
        if !self.interrupt.is_set() {
            return Ok(());
        }
        let s = &self.slots[n];
        Err(EvalError {
            node: s.id.clone(),
            frame: (!s.eff_static).then_some(frame),
            error: Box::new(NodeError::Interrupted(self.interrupt.reason())),
        })
    }

    fn evaluate(&mut self, n: usize, ctx: Context) -> Result<(), EvalError> {
        self.interrupted(n, ctx.frame)?;
        let t0 = Instant::now();
        self.timers.push(Duration::ZERO);
        let all_fed = crate::feed::all_fed(&self.slots[n].feeds, self.slots[n].spec.outputs.len());
        let result: Result<Vec<Option<Value>>, (NodeError, i64)> = if all_fed {
            Ok(Vec::new())
        } else if self.slots[n].kernel.is_none() {
            match &self.slots[n].source {
                Some(v) => Ok(vec![Some(v.clone())]),
                None => Err((
                    NodeError::Failed("no value was given for this input".into()),
                    ctx.frame,
                )),
            }
        } else {
            let mut kernel = self.slots[n]
                .kernel
                .take()
                .expect("non-source slots have a kernel");
            let label = self.label(n);
            let before = self.interrupt.enter(label);
            let r = match &mut kernel {
                Kernel::Compute(k) => match self.cx(n, ctx) {
                    Ok(mut cx) => k
                        .compute(&mut cx)
                        .map(|()| cx.outputs)
                        .map_err(|e| (e, ctx.frame)),
                    Err(e) => Err((e, ctx.frame)),
                },
                Kernel::Step(k) => self.eval_stateful(n, k.as_mut(), ctx),
            };
            self.interrupt.leave(before);
            self.slots[n].kernel = Some(kernel);
            r
        };
        let child = self.timers.pop().unwrap_or_default();
        let elapsed = t0.elapsed();
        if let Some(parent) = self.timers.last_mut() {
            *parent += elapsed;
        }
        let slot = &mut self.slots[n];
        slot.stats.evaluations += 1;
        slot.stats.seconds += elapsed.saturating_sub(child).as_secs_f64();
        let frame = |f: i64, s: &Slot| (!s.eff_static).then_some(f);
        let outs = match result {
            Ok(o) => crate::feed::apply(&slot.feeds, o, ctx.frame, slot.spec.outputs.len()),
            Err((NodeError::Upstream(e), _)) => return Err(*e),
            Err((e, f)) => {
                return Err(EvalError {
                    node: slot.id.clone(),
                    frame: frame(f, slot),
                    error: Box::new(e),
                });
            }
        };
        let mut values = Vec::with_capacity(outs.len());
        for (i, o) in outs.into_iter().enumerate() {
            let fail = |m: String| EvalError {
                node: slot.id.clone(),
                frame: frame(ctx.frame, slot),
                error: Box::new(NodeError::Failed(m)),
            };
            let Some(v) = o else {
                return Err(fail(format!(
                    "did not set output '{}'",
                    slot.spec.outputs[i].name
                )));
            };
            if let Some(t) = slot.out_types[i]
                && v.payload_type_id() != t
            {
                let got = self
                    .registry
                    .port_type_by_id(v.payload_type_id())
                    .map(|p| p.name.clone())
                    .unwrap_or_else(|| "an unregistered type".into());
                return Err(fail(format!(
                    "output '{}' is declared {} but the node produced {got}",
                    slot.spec.outputs[i].name, slot.out_type_names[i]
                )));
            }
            if let Some(bad) = non_finite(&v) {
                return Err(fail(format!(
                    "produced {bad} on output '{}'; a non-finite number is reported where it appears, never passed on",
                    slot.spec.outputs[i].name
                )));
            }
            values.push(v);
        }
        slot.cache = Some(Cached {
            ctx,
            outputs: values,
        });
        slot.dirty = false;
        Ok(())
    }

    fn eval_stateful(
        &mut self,
        n: usize,
        k: &mut dyn crate::node::Step,
        ctx: Context,
    ) -> Result<Vec<Option<Value>>, (NodeError, i64)> {
        let start = self.slots[n]
            .params
            .i64("start_frame")
            .map_err(|e| (e.into(), ctx.frame))?;
        if self.slots[n].ckpt_fps != ctx.fps {
            self.slots[n].checkpoints.clear();
            self.slots[n].ckpt_fps = ctx.fps;
        }
        // Before the start frame the initial state holds.
        let f = ctx.frame.max(start);
        let resume = self.slots[n].checkpoints.latest_in(start..=f);
        let newer_on_disk =
            self.checkpoint_dir.is_some() && resume.as_ref().is_none_or(|(a, _)| *a < f);
        let from_disk = if newer_on_disk {
            let lo = resume.as_ref().map_or(start, |(a, _)| *a) + 1;
            self.restore_from_disk(n, k, lo, f, start, ctx)?
        } else {
            None
        };
        let (mut at, mut state) = match from_disk.or(resume) {
            Some(r) => r,
            None => {
                let mut cx = self.cx(n, ctx.with_frame(start)).map_err(|e| (e, start))?;
                let s = k.init(&mut cx).map_err(|e| (e, start))?;
                self.keep(n, k, start, &s, start);
                (start, s)
            }
        };
        while at < f {
            if self.interrupt.is_set() {
                return Err((NodeError::Interrupted(self.interrupt.reason()), at + 1));
            }
            at += 1;
            let mut cx = self.cx(n, ctx.with_frame(at)).map_err(|e| (e, at))?;
            state = k.step(&state, &mut cx).map_err(|e| (e, at))?;
            self.keep(n, k, at, &state, start);
            self.slots[n].stats.steps += 1;
            self.save_to_disk(n, k, at, &state, ctx.fps);
        }
        let mut cx = self.cx(n, ctx).map_err(|e| (e, ctx.frame))?;
        k.outputs(&state, &mut cx).map_err(|e| (e, ctx.frame))?;
        Ok(cx.outputs)
    }

    /// Pushes dirtiness from `n` to everything downstream; drops caches, hashes, checkpoints.
    pub(crate) fn mark_dirty(&mut self, n: usize) {
        self.mark_dirty_from(n, i64::MIN);
    }

    /// [`Self::mark_dirty`] for a change that leaves `n`'s outputs at frames before `from`
    /// as they were: downstream stateful nodes keep their states at those frames (a state at
    /// frame k depends on its inputs at frames up to k only).
    pub(crate) fn mark_dirty_from(&mut self, n: usize, from: i64) {
        let generation = self.next_mark();
        let mut stack = vec![n];
        while let Some(m) = stack.pop() {
            if self.mark[m] == generation {
                continue;
            }
            self.mark[m] = generation;
            let s = &mut self.slots[m];
            s.dirty = true;
            s.cache = None;
            s.hash = None;
            if from == i64::MIN {
                s.checkpoints.clear();
            } else {
                s.checkpoints.retain_up_to(from.saturating_sub(1));
            }
            stack.extend(s.downstream.iter().copied());
        }
    }

    /// Evaluates a graph output at `ctx`, computing only what it depends on.
    pub fn pull(&mut self, output: &str, ctx: Context) -> Result<Value, EvalError> {
        let Some(&(n, p)) = self.outputs.get(output) else {
            let known: Vec<&str> = self.output_names().collect();
            return Err(EvalError {
                node: output.to_string(),
                frame: None,
                error: Box::new(NodeError::Failed(format!(
                    "the graph has no output '{output}' (outputs: {})",
                    known.join(", ")
                ))),
            });
        };
        self.pull_slot(n, p, ctx)
    }

    /// Evaluates `node.port` at `ctx`.
    pub fn pull_port(&mut self, node: &str, port: &str, ctx: Context) -> Result<Value, EvalError> {
        let fail = |m: String| EvalError {
            node: node.to_string(),
            frame: None,
            error: Box::new(NodeError::Failed(m)),
        };
        let &n = self
            .ids
            .get(node)
            .ok_or_else(|| fail("no such node".into()))?;
        let p = self.slots[n]
            .spec
            .output_index(port)
            .ok_or_else(|| fail(format!("no output '{port}'")))?;
        self.pull_slot(n, p, ctx)
    }

    pub(crate) fn pull_slot(
        &mut self,
        n: usize,
        p: usize,
        ctx: Context,
    ) -> Result<Value, EvalError> {
        self.ensure(n, ctx)?;
        Ok(self.slots[n].cache.as_ref().expect("ensured").outputs[p].clone())
    }

    /// Seconds spent so far in each node, in slot order (for per-iteration stage timing).
    pub(crate) fn seconds_snapshot(&self) -> Vec<f64> {
        self.slots.iter().map(|s| s.stats.seconds).collect()
    }

    pub(crate) fn input_time_dependent(&self, n: usize, port: usize) -> bool {
        self.slots[n].inputs[port]
            .iter()
            .any(|&(s, _)| !self.slots[s].eff_static)
    }

    pub(crate) fn push_warning(&mut self, n: usize, frame: Option<i64>, message: String) {
        let w = RunWarning {
            node: self.slots[n].id.clone(),
            frame,
            message,
        };
        if !self.warnings.contains(&w) {
            if let Some(sink) = &self.warning_sink {
                sink(&w);
            }
            self.warnings.push(w);
        }
    }
}
