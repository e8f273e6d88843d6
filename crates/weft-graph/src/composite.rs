//! Composite nodes: a subgraph declared in the file, instanced as a node type.
//!
//! The instance owns a compiled inner [`Graph`]. A plain composite pulls its outputs once. An
//! *iterating* composite runs the inner graph in a loop: after each pass, every `feedback`
//! input takes the value of an inner output, until the `until` output is true or
//! `max_iterations` is reached; each pass is recorded with its residual and per-stage times.
//! A *stepped* composite is stateful: at frame f its `step.feedback` inputs take the outputs
//! of frame f − 1, and at the start frame its outputs are the initial condition. Inner caches
//! persist across iterations and frames, so stages that do not depend on what changed do not
//! re-run.

use crate::diag::Diagnostic;
use crate::engine::{Context, Graph};
use crate::file::SubgraphDecl;
use crate::node::{Compute, EvalCx, EvalError, Kernel, NodeError, Step};
use crate::params::Params;
use crate::registry::Registry;
use crate::value::Value;
use serde::Serialize;
use std::collections::{BTreeMap, VecDeque};
use std::sync::Arc;
use std::time::Instant;

/// Iteration settings resolved against the compiled inner graph.
pub(crate) struct IterPlan {
    feedback: Vec<(String, String, String)>,
    until: (String, String),
    residual: Option<(String, String)>,
    on_limit_error: bool,
}

/// Everything about a subgraph type that does not change per instance.
pub(crate) struct CompositePlan {
    inputs: Vec<String>,
    outputs: Vec<String>,
    iterate: Option<IterPlan>,
    /// (input index, output index): input at frame f is output at frame f − 1.
    step: Option<Vec<(usize, usize)>>,
    initial: Vec<Option<Value>>,
    hash: u128,
}

fn split(r: &str) -> (String, String) {
    let (a, b) = r.split_once('.').unwrap_or((r, ""));
    (a.to_string(), b.to_string())
}

impl CompositePlan {
    /// Hash of the subgraph's definition and of every subgraph it instances.
    pub(crate) fn hash(&self) -> u128 {
        self.hash
    }

    /// Checks `iterate` and `step` against the compiled inner graph.
    pub(crate) fn resolve(
        name: &str,
        s: &SubgraphDecl,
        g: &Graph,
        reg: &Registry,
        deps: &[u128],
        d: &mut Vec<Diagnostic>,
    ) -> Option<CompositePlan> {
        let before = d.len();
        let ref_type = |text: &str| -> Option<String> {
            // Loop tests and feedback read inner nodes' outputs; a subgraph input never changes
            // within a frame's loop, so naming one is a mistake (and `in` is not a node).
            let (n, p) = split(text);
            let spec = g.node_spec(&n)?;
            let k = spec.output_index(&p)?;
            g.slots
                .iter()
                .find(|x| x.id == n)
                .map(|x| x.out_type_names[k].clone())
        };
        let mut iterate = None;
        if let Some(it) = &s.iterate {
            let need =
                |r: &crate::file::Ref, want: Option<&str>, what: &str, d: &mut Vec<Diagnostic>| {
                    match ref_type(&r.text) {
                        None => d.push(Diagnostic::error(
                            r.path.clone(),
                            format!(
                                "{what} '{}' is not an output of a node in the subgraph",
                                r.text
                            ),
                        )),
                        Some(t) => {
                            if let Some(w) = want
                                && t != w
                                && t != "any"
                            {
                                d.push(Diagnostic::error(
                                    r.path.clone(),
                                    format!("{what} '{}' is {t}, must be {w}", r.text),
                                ));
                            }
                        }
                    }
                };
            need(&it.until, Some("bool"), "'until'", d);
            if let Some(r) = &it.residual {
                need(r, Some("float"), "'residual'", d);
            }
            let mut feedback = Vec::new();
            for (k, r) in &it.feedback {
                match s.inputs.get(k) {
                    None => d.push(Diagnostic::error(
                        r.path.clone(),
                        format!("feedback names '{k}', which is not an input of the subgraph"),
                    )),
                    Some(i) => need(
                        r,
                        Some(i.ty.as_str()).filter(|t| *t != "any"),
                        "feedback source",
                        d,
                    ),
                }
                let (n, p) = split(&r.text);
                feedback.push((k.clone(), n, p));
            }
            iterate = Some(IterPlan {
                feedback,
                until: split(&it.until.text),
                residual: it.residual.as_ref().map(|r| split(&r.text)),
                on_limit_error: it.on_limit_error,
            });
        }
        let inputs: Vec<String> = s.inputs.keys().cloned().collect();
        let outputs: Vec<String> = s.outputs.keys().cloned().collect();
        let mut step = None;
        let mut initial = vec![None; outputs.len()];
        if let Some(st) = &s.step {
            let mut pairs = Vec::new();
            for (inp, (out, path)) in st {
                let i = inputs.iter().position(|x| x == inp);
                let o = outputs.iter().position(|x| x == out);
                match (i, o) {
                    (None, _) => d.push(Diagnostic::error(
                        path.clone(),
                        format!(
                            "step feedback names '{inp}', which is not an input of the subgraph"
                        ),
                    )),
                    (_, None) => d.push(Diagnostic::error(
                        path.clone(),
                        format!("step feedback source '{out}' is not an output of the subgraph"),
                    )),
                    (Some(i), Some(o)) => {
                        let ti = s.inputs[inp].ty.as_str();
                        let to = g.output_type(out).unwrap_or("any");
                        if ti != to && ti != "any" && to != "any" {
                            d.push(Diagnostic::error(
                                path.clone(),
                                format!("step feedback: input '{inp}' is {ti} but output '{out}' is {to}"),
                            ));
                        }
                        pairs.push((i, o));
                    }
                }
            }
            for (o, name_o) in outputs.iter().enumerate() {
                let decl = &s.outputs[name_o];
                let fed = pairs.iter().any(|&(_, oo)| oo == o);
                let ty = g.output_type(name_o).unwrap_or("any");
                match (&decl.initial, fed) {
                    (Some(j), _) => match reg.json_value(ty, j) {
                        Some(v) => initial[o] = Some(v),
                        None => d.push(Diagnostic::error(decl.path.clone(), format!("'initial' is not a valid {ty}"))),
                    },
                    (None, true) => {}
                    (None, false) => d.push(Diagnostic::error(
                        decl.path.clone(),
                        format!("output '{name_o}' of stepped subgraph '{name}' feeds no input, so it needs an 'initial' value for the start frame"),
                    )),
                }
            }
            step = Some(pairs);
        }
        if d.len() > before {
            return None;
        }
        let mut h = xxhash_rust::xxh3::Xxh3::new();
        h.update(format!("{name}{s:?}").as_bytes());
        for dep in deps {
            h.update(&dep.to_le_bytes());
        }
        let hash = h.digest128();
        Some(CompositePlan {
            inputs,
            outputs,
            iterate,
            step,
            initial,
            hash,
        })
    }
}

#[derive(Clone, Debug, Serialize)]
struct IterRecord {
    iteration: usize,
    residual: Option<f64>,
    converged: bool,
    seconds: f64,
    /// Seconds spent in each inner stage during this iteration (stages that ran).
    stages: BTreeMap<String, f64>,
}

#[derive(Clone, Debug, Serialize)]
struct FrameReport {
    frame: i64,
    converged: bool,
    iterations: Vec<IterRecord>,
}

/// Reports kept per instance (older frames are dropped to bound memory).
const KEEP_REPORTS: usize = 256;

/// An instance of a subgraph type.
pub(crate) struct CompositeKernel {
    inner: Graph,
    plan: Arc<CompositePlan>,
    /// The value last handed to each inner input, to avoid dirtying unchanged ones.
    fed: Vec<Option<Value>>,
    reports: VecDeque<FrameReport>,
}

impl CompositeKernel {
    pub(crate) fn build(
        mut inner: Graph,
        plan: Arc<CompositePlan>,
        params: &Params,
    ) -> Result<Kernel, String> {
        for (k, v) in params.iter() {
            if let Some((node, p)) = k.split_once('.')
                && inner.node_params(node).and_then(|x| x.get(p)) != Some(v)
            {
                inner
                    .set_param(node, p, v.clone())
                    .map_err(|e| e.to_string())?;
            }
        }
        let fed = vec![None; plan.inputs.len()];
        let stepped = plan.step.is_some();
        let k = CompositeKernel {
            inner,
            plan,
            fed,
            reports: VecDeque::new(),
        };
        Ok(if stepped {
            Kernel::Step(Box::new(Stepped(k)))
        } else {
            Kernel::Compute(Box::new(k))
        })
    }

    fn wrap(node: &str, e: EvalError) -> NodeError {
        NodeError::Upstream(Box::new(EvalError {
            node: format!("{node}/{}", e.node),
            ..e
        }))
    }

    fn feed(&mut self, i: usize, v: Value) -> Result<(), NodeError> {
        if self.fed[i].as_ref().is_some_and(|f| f.ptr_eq(&v)) {
            return Ok(());
        }
        let name = &self.plan.inputs[i];
        self.inner
            .set_input(name, v.clone())
            .map_err(|e| NodeError::Input {
                port: name.clone(),
                message: e.message,
            })?;
        self.fed[i] = Some(v);
        Ok(())
    }

    /// Hands the outer inputs (or `overrides`) to the inner graph and runs it.
    fn run(
        &mut self,
        cx: &mut EvalCx<'_>,
        overrides: &[(usize, Value)],
    ) -> Result<Vec<Value>, NodeError> {
        let stop = cx.interrupt();
        if !self.inner.interrupt().same(&stop) {
            self.inner.set_interrupt(stop);
        }
        if self.inner.output_root() != cx.output_root() {
            self.inner.set_output_root(cx.output_root().map(Into::into));
        }
        for i in 0..self.plan.inputs.len() {
            let v = match overrides.iter().find(|(k, _)| *k == i) {
                Some((_, v)) => Some(v.clone()),
                None => cx.input_opt(&self.plan.inputs[i].clone())?,
            };
            if let Some(v) = v {
                self.feed(i, v)?;
            }
        }
        let ctx = cx.context();
        let node = cx.node_id().to_string();
        let plan = self.plan.clone();
        if let Some(it) = &plan.iterate {
            let max = cx.params().i64("max_iterations")?.max(1) as usize;
            let mut report = FrameReport {
                frame: ctx.frame,
                converged: false,
                iterations: Vec::new(),
            };
            for k in 0..max {
                let t0 = Instant::now();
                let before = self.inner.seconds_snapshot();
                let conv = self
                    .pull(&it.until, ctx, &node)?
                    .get::<bool>()
                    .copied()
                    .unwrap_or(false);
                let residual = match &it.residual {
                    Some(r) => self.pull(r, ctx, &node)?.get::<f64>().copied(),
                    None => None,
                };
                let after = self.inner.seconds_snapshot();
                let stages = self
                    .inner
                    .node_ids()
                    .zip(before.iter().zip(&after))
                    .filter(|(_, (b, a))| a > b)
                    .map(|(id, (b, a))| (id.to_string(), a - b))
                    .collect();
                report.iterations.push(IterRecord {
                    iteration: k,
                    residual,
                    converged: conv,
                    seconds: t0.elapsed().as_secs_f64(),
                    stages,
                });
                if conv {
                    report.converged = true;
                    break;
                }
                if k + 1 == max {
                    let r = residual.unwrap_or(f64::NAN);
                    self.keep(report);
                    if it.on_limit_error {
                        return Err(NodeError::NotConverged {
                            iterations: max,
                            residual: r,
                        });
                    }
                    cx.warn(format!(
                        "did not converge after {max} iterations (residual {r:e})"
                    ));
                    let out = self.outputs(ctx, &node);
                    self.forward_warnings(cx);
                    return out;
                }
                for (input, n, p) in &it.feedback {
                    let v = self.pull(&(n.clone(), p.clone()), ctx, &node)?;
                    let i = plan
                        .inputs
                        .iter()
                        .position(|x| x == input)
                        .expect("resolved");
                    self.feed(i, v)?;
                }
            }
            self.keep(report);
        }
        let out = self.outputs(ctx, &node);
        self.forward_warnings(cx);
        out
    }

    /// Passes the inner graph's warnings on as the instance's, prefixed with the stage.
    fn forward_warnings(&mut self, cx: &mut EvalCx<'_>) {
        for w in self.inner.take_warnings() {
            cx.warn(format!("{}: {}", w.node, w.message));
        }
    }

    fn keep(&mut self, r: FrameReport) {
        if self.reports.len() == KEEP_REPORTS {
            self.reports.pop_front();
        }
        self.reports.push_back(r);
    }

    fn pull(&mut self, r: &(String, String), ctx: Context, node: &str) -> Result<Value, NodeError> {
        self.inner
            .pull_port(&r.0, &r.1, ctx)
            .map_err(|e| Self::wrap(node, e))
    }

    fn outputs(&mut self, ctx: Context, node: &str) -> Result<Vec<Value>, NodeError> {
        let names = self.plan.outputs.clone();
        names
            .iter()
            .map(|o| self.inner.pull(o, ctx).map_err(|e| Self::wrap(node, e)))
            .collect()
    }

    fn report_json(&self) -> Option<serde_json::Value> {
        let mut j = serde_json::json!({ "inner": self.inner.stats() });
        if self.plan.iterate.is_some() {
            j["frames"] = serde_json::json!(self.reports);
        }
        Some(j)
    }
}

impl Compute for CompositeKernel {
    fn compute(&mut self, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
        let outs = self.run(cx, &[])?;
        for (name, v) in self.plan.outputs.clone().iter().zip(outs) {
            cx.set(name, v);
        }
        Ok(())
    }
    fn kernel_hash(&self) -> u128 {
        self.plan.hash
    }
    fn stats_json(&self) -> Option<serde_json::Value> {
        self.report_json()
    }
}

/// A stepped composite: the state is the vector of its outputs.
struct Stepped(CompositeKernel);

impl Step for Stepped {
    fn init(&mut self, cx: &mut EvalCx<'_>) -> Result<Value, NodeError> {
        let plan = self.0.plan.clone();
        let pairs = plan.step.as_ref().expect("stepped");
        let mut state = Vec::with_capacity(plan.outputs.len());
        for (o, init) in plan.initial.iter().enumerate() {
            let v = match (init, pairs.iter().find(|&&(_, oo)| oo == o)) {
                (Some(v), _) => v.clone(),
                (None, Some(&(i, _))) => cx.input(&plan.inputs[i])?,
                (None, None) => unreachable!("checked at load: every output has an initial value"),
            };
            state.push(v);
        }
        Ok(Value::new(state))
    }
    fn step(&mut self, state: &Value, cx: &mut EvalCx<'_>) -> Result<Value, NodeError> {
        let prev = state.get::<Vec<Value>>().expect("composite state");
        let pairs = self.0.plan.step.clone().expect("stepped");
        let overrides: Vec<(usize, Value)> =
            pairs.iter().map(|&(i, o)| (i, prev[o].clone())).collect();
        Ok(Value::new(self.0.run(cx, &overrides)?))
    }
    fn outputs(&mut self, state: &Value, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
        let s = state.get::<Vec<Value>>().expect("composite state");
        for (name, v) in self.0.plan.outputs.iter().zip(s) {
            cx.set(name, v.clone());
        }
        Ok(())
    }
    fn kernel_hash(&self) -> u128 {
        self.0.plan.hash
    }
    fn stats_json(&self) -> Option<serde_json::Value> {
        self.0.report_json()
    }
    fn state_bytes(&self, state: &Value, registry: &crate::Registry) -> usize {
        state
            .get::<Vec<Value>>()
            .map_or(0, |s| s.iter().map(|v| registry.value_bytes(v)).sum())
    }
    /// Each output's payload through its port type's encoding; `None` when one has none.
    fn save_state(&self, state: &Value, registry: &crate::Registry) -> Option<Vec<u8>> {
        let s = state.get::<Vec<Value>>()?;
        let mut w = crate::codec::Writer::new();
        w.u64(s.len() as u64);
        for v in s {
            let t = registry.port_type_by_id(v.payload_type_id())?;
            w.bytes(t.name.as_bytes()).bytes(&(t.encode?)(v)?);
        }
        Some(w.finish())
    }
    fn load_state(
        &mut self,
        bytes: &[u8],
        initial: &Value,
        cx: &mut EvalCx<'_>,
    ) -> Result<Value, NodeError> {
        let bad = |m: String| NodeError::Failed(format!("checkpoint: {m}"));
        let init = initial
            .get::<Vec<Value>>()
            .ok_or_else(|| bad("the start state is not a composite state".into()))?;
        let mut inputs = Vec::new();
        for name in self.0.plan.inputs.clone() {
            if let Some(v) = cx.input_opt(&name)? {
                inputs.push((name, v));
            }
        }
        let mut r = crate::codec::Reader::new(bytes);
        let n = r.u64().map_err(bad)?;
        if n != init.len() as u64 {
            return Err(bad(format!("{n} values, the node has {}", init.len())));
        }
        let mut out = Vec::with_capacity(init.len());
        for template in init {
            let name = String::from_utf8_lossy(r.bytes().map_err(bad)?).into_owned();
            let payload = r.bytes().map_err(bad)?;
            let t = cx
                .registry()
                .port_type(&name)
                .ok_or_else(|| bad(format!("unknown port type '{name}'")))?;
            let v = match (t.decode, t.restore) {
                (Some(d), _) => d(payload),
                (None, Some(f)) => f(payload, template, &inputs),
                (None, None) => Err(format!("'{name}' cannot be restored")),
            }
            .map_err(bad)?;
            out.push(v);
        }
        r.end().map_err(bad)?;
        Ok(Value::new(out))
    }
}
