//! Changing a compiled graph: parameters and inputs, each change pushing dirtiness to
//! everything downstream.

use crate::diag::{Diagnostic, nearest};
use crate::engine::Graph;
use crate::params::check_param;
use crate::value::Value;
use std::sync::Arc;

impl Graph {
    /// Changes a parameter (validated as at load) and dirties the node and its downstream.
    pub fn set_param(
        &mut self,
        node: &str,
        param: &str,
        value: serde_json::Value,
    ) -> Result<(), Box<Diagnostic>> {
        self.set_params(node, &[(param, value)])
    }

    /// Sets several parameters of one node at once: each is checked, then the node's factory
    /// runs once on all of them, so a combination that is only valid together (both sides of
    /// a periodic axis) can be made. On any error nothing changes.
    pub fn set_params(
        &mut self,
        node: &str,
        values: &[(&str, serde_json::Value)],
    ) -> Result<(), Box<Diagnostic>> {
        let &n = self.ids.get(node).ok_or_else(|| {
            Diagnostic::error(vec![], "no such node")
                .node(node)
                .help(nearest(node, self.ids.keys().map(|s| s.as_str())))
        })?;
        let spec = self.slots[n].spec.clone();
        let mut params = (*self.slots[n].params).clone();
        for (param, value) in values {
            let ps = spec.param_spec(param).ok_or_else(|| {
                Diagnostic::error(vec![], "no such parameter")
                    .node(node)
                    .field(format!("param '{param}'"))
                    .help(nearest(param, spec.params.iter().map(|p| p.name.as_str())))
            })?;
            if spec
                .outputs
                .iter()
                .any(|o| o.ty == crate::spec::TypeRef::FromParam(param.to_string()))
            {
                return Err(Box::new(
                    Diagnostic::error(vec![], "sets an output's type, so it can only be given in the graph file (connections were type-checked against it at load)")
                        .node(node)
                        .field(format!("param '{param}'")),
                ));
            }
            let v = check_param(ps, value).map_err(|m| {
                Diagnostic::error(vec![], m)
                    .node(node)
                    .field(format!("param '{param}'"))
            })?;
            params.set(param, v);
        }
        let kernel = match self.slots[n].factory.clone() {
            Some(f) => {
                let names: Vec<&str> = values.iter().map(|(p, _)| *p).collect();
                Some(f(&params).map_err(|m| {
                    Diagnostic::error(vec![], m)
                        .node(node)
                        .field(format!("param '{}'", names.join("', '")))
                })?)
            }
            None => None,
        };
        // What the node gave at the frames downstream states were computed from, before the
        // change (a keyed curve: the frames before its first changed key stay valid).
        let before = self.frames_to_compare(n).map(|(frames, fps)| {
            let hashes = self.output_hashes(n, &frames, fps);
            (frames, fps, hashes)
        });
        if let Some(k) = kernel {
            self.slots[n].external = k.kernel_hash();
            self.slots[n].kernel = Some(k);
        }
        self.slots[n].params = Arc::new(params);
        let from = match before {
            Some((frames, fps, old)) => {
                let s = &mut self.slots[n];
                s.cache = None;
                s.hash = None;
                s.dirty = true;
                let new = self.output_hashes(n, &frames, fps);
                frames
                    .iter()
                    .zip(old.iter().zip(&new))
                    .find(|(_, (a, b))| a.is_none() || a != b)
                    .map_or_else(|| frames.last().map_or(i64::MIN, |f| f + 1), |(f, _)| *f)
            }
            None => i64::MIN,
        };
        self.mark_dirty_from(n, from);
        Ok(())
    }

    /// For a time-dependent computed node whose downstream stateful nodes hold states: the
    /// frames those states span (from the earliest to the latest) and their frame rate.
    /// `None` when nothing downstream could be kept.
    fn frames_to_compare(&self, n: usize) -> Option<(Vec<i64>, f64)> {
        let s = &self.slots[n];
        if s.eff_static || !matches!(s.kernel, Some(crate::node::Kernel::Compute(_))) {
            return None;
        }
        let (mut lo, mut hi, mut fps) = (i64::MAX, i64::MIN, None);
        let mut seen = vec![false; self.slots.len()];
        let mut stack = s.downstream.clone();
        while let Some(m) = stack.pop() {
            if std::mem::replace(&mut seen[m], true) {
                continue;
            }
            let d = &self.slots[m];
            let frames = d.checkpoints.frames();
            if let (Some(&a), Some(&b)) = (frames.first(), frames.last()) {
                // States at another frame rate are recomputed anyway.
                if *fps.get_or_insert(d.ckpt_fps) != d.ckpt_fps {
                    return None;
                }
                lo = lo.min(a);
                hi = hi.max(b);
            }
            stack.extend(d.downstream.iter().copied());
        }
        // Comparing costs two evaluations of the node a frame: bounded.
        (lo <= hi && hi - lo < 100_000).then(|| ((lo..=hi).collect(), fps.unwrap_or(24.0)))
    }

    /// Hashes of slot `n`'s outputs at each of `frames` (None where it fails: a frame that
    /// failed before or after a change counts as changed).
    fn output_hashes(&mut self, n: usize, frames: &[i64], fps: f64) -> Vec<Option<u128>> {
        frames
            .iter()
            .map(|&f| {
                let ctx = crate::engine::Context::at(f, fps);
                (0..self.slots[n].spec.outputs.len())
                    .map(|p| self.pull_slot(n, p, ctx).ok().map(|v| self.value_hash(&v)))
                    .try_fold(0u128, |acc, h| h.map(|h| acc.rotate_left(7) ^ h))
            })
            .collect()
    }

    /// Sets a graph input's value and dirties its downstream.
    pub fn set_input(&mut self, name: &str, value: Value) -> Result<(), Box<Diagnostic>> {
        let &n = self.inputs.get(name).ok_or_else(|| {
            Diagnostic::error(vec![], format!("the graph has no input '{name}'"))
                .help(nearest(name, self.inputs.keys().map(|s| s.as_str())))
        })?;
        if let Some(t) = self.slots[n].out_types[0]
            && value.payload_type_id() != t
        {
            return Err(Box::new(Diagnostic::error(
                vec![],
                format!("input '{name}' expects {}", self.slots[n].out_type_names[0]),
            )));
        }
        self.slots[n].external = self.value_hash(&value);
        self.slots[n].source = Some(value);
        self.mark_dirty(n);
        Ok(())
    }

    /// Gives a graph input its value at load time (a declared default).
    pub(crate) fn set_input_initial(&mut self, n: usize, v: Value) {
        self.slots[n].external = self.value_hash(&v);
        self.slots[n].source = Some(v);
    }
}
