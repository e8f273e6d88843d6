//! The graph's settings and what it says about itself: interrupt and output root, the
//! nodes, their specs, parameters and output types, the outputs' time dependence, warnings.
//! Read-only over the slots except for the settings; evaluation is in the parent module.

use super::{Graph, RunWarning, WarningSink};
use crate::diag::Diagnostic;
use crate::interrupt::Interrupt;
use crate::params::Params;
use crate::registry::Registry;
use crate::spec::NodeSpec;

impl Graph {
    /// The handle that stops this graph's evaluations (clone it to a Ctrl-C handler, or set
    /// a time limit on it). Composite instances share their outer graph's.
    pub fn interrupt(&self) -> Interrupt {
        self.interrupt.clone()
    }
    /// Makes `i` the handle that stops this graph.
    pub fn set_interrupt(&mut self, i: Interrupt) {
        self.interrupt = i;
    }

    /// Makes `root` the directory that output nodes' relative paths resolve under (`weft run
    /// --out`); `None`: the working directory. Paths that leave it are refused.
    pub fn set_output_root(&mut self, root: Option<std::path::PathBuf>) {
        self.output_root = root;
    }
    /// See [`Graph::set_output_root`].
    pub fn output_root(&self) -> Option<&std::path::Path> {
        self.output_root.as_deref()
    }

    /// Keeps every frame's state of stateful nodes that support it ([`crate::Step::save_state`])
    /// in `dir` (`DIR/NODE/frame_NNNNNN.wstate`, written atomically, keyed by everything the
    /// node depends on), and resumes from them: a frame whose state is on disk is restored
    /// instead of stepped, bit for bit, so a run killed at frame k and run again recomputes
    /// nothing before k. `None`: memory checkpoints only.
    pub fn set_checkpoint_dir(&mut self, dir: Option<std::path::PathBuf>) {
        self.checkpoint_dir = dir;
    }

    /// The registry this graph was compiled with.
    pub fn registry(&self) -> &Registry {
        &self.registry
    }
    pub(crate) fn slot_id(&self, n: usize) -> &str {
        &self.slots[n].id
    }
    pub(crate) fn slot_spec(&self, n: usize) -> &NodeSpec {
        &self.slots[n].spec
    }
    pub(crate) fn input_count(&self, n: usize, port: usize) -> usize {
        self.slots[n].inputs[port].len()
    }

    /// Names of the graph's outputs.
    pub fn output_names(&self) -> impl Iterator<Item = &str> {
        self.outputs.keys().map(|s| s.as_str())
    }
    /// Names of the graph's inputs (settable with [`Graph::set_input`]).
    pub fn input_names(&self) -> impl Iterator<Item = &str> {
        self.inputs.keys().map(|s| s.as_str())
    }
    /// Node ids in evaluation order.
    pub fn node_ids(&self) -> impl Iterator<Item = &str> {
        self.slots.iter().map(|s| s.id.as_str())
    }
    /// The spec of a node.
    pub fn node_spec(&self, id: &str) -> Option<&NodeSpec> {
        self.ids.get(id).map(|&n| &*self.slots[n].spec)
    }
    /// A node's current parameters.
    pub fn node_params(&self, id: &str) -> Option<&Params> {
        self.ids.get(id).map(|&n| &*self.slots[n].params)
    }
    /// The parameters of node `id` as hosts list them: each its spec (name, kind with range
    /// or choices, default, unit, doc) as JSON with its current `value` added.
    pub fn param_descriptions(&self, id: &str) -> Option<Vec<serde_json::Value>> {
        let (spec, values) = (self.node_spec(id)?, self.node_params(id)?);
        Some(
            spec.params
                .iter()
                .map(|p| {
                    let mut j = serde_json::to_value(p).unwrap_or(serde_json::Value::Null);
                    if let Some(o) = j.as_object_mut() {
                        let v = values.get(&p.name).cloned();
                        o.insert("value".into(), v.unwrap_or(serde_json::Value::Null));
                    }
                    j
                })
                .collect(),
        )
    }

    /// The type of output `port` of node `id` as compiled (an output typed by its input or a
    /// parameter resolved), if both exist.
    pub fn node_output_type(&self, id: &str, port: &str) -> Option<&str> {
        let &n = self.ids.get(id)?;
        let p = self.slots[n].spec.output_index(port)?;
        Some(self.slots[n].out_type_names[p].as_str())
    }

    /// True when no output of the graph depends on time.
    pub fn is_static(&self) -> bool {
        self.outputs
            .values()
            .all(|&(n, _)| self.slots[n].eff_static)
    }
    /// True when the output depends on time.
    pub fn output_is_time_dependent(&self, output: &str) -> Option<bool> {
        self.outputs
            .get(output)
            .map(|&(n, _)| !self.slots[n].eff_static)
    }
    /// The declared type of an output.
    pub fn output_type(&self, output: &str) -> Option<&str> {
        self.outputs
            .get(output)
            .map(|&(n, p)| self.slots[n].out_type_names[p].as_str())
    }

    /// Warnings found while loading (the graph still compiled).
    pub fn load_warnings(&self) -> &[Diagnostic] {
        &self.load_warnings
    }

    /// Hands every new warning to `sink` as it is raised (they are still kept for
    /// [`Graph::take_warnings`]): a long run's user learns of a problem when it happens.
    pub fn set_warning_sink(&mut self, sink: Option<WarningSink>) {
        self.warning_sink = sink;
    }

    /// Warnings raised since the last call.
    pub fn take_warnings(&mut self) -> Vec<RunWarning> {
        std::mem::take(&mut self.warnings)
    }
}
