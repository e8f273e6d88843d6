//! Structural hashes: what identifies a node's output (its type, parameters, kernel data and
//! inputs), the key of caches and checkpoints.

use crate::engine::{Context, Graph, nonce};
use crate::value::Value;
use xxhash_rust::xxh3::Xxh3;

impl Graph {
    /// Hash of a value through its port type's codec; a value without one never matches another.
    pub(crate) fn value_hash(&self, v: &Value) -> u128 {
        self.registry
            .port_type_by_id(v.payload_type_id())
            .and_then(|t| t.encode)
            .and_then(|enc| enc(v))
            .map(|b| xxhash_rust::xxh3::xxh3_128(&b))
            .unwrap_or_else(nonce)
    }

    /// Hash of the node type, parameters and everything upstream: equal hashes mean equal
    /// outputs at equal contexts (Gaffer's `hash()` separate from `compute()`).
    pub(crate) fn structural_hash(&mut self, target: usize) -> u128 {
        if let Some(h) = self.slots[target].hash {
            return h;
        }
        let mut stack = vec![(target, false)];
        while let Some((n, ready)) = stack.pop() {
            if self.slots[n].hash.is_some() {
                continue;
            }
            if !ready {
                stack.push((n, true));
                for &(s, _) in self.slots[n].inputs.iter().flatten() {
                    if self.slots[s].hash.is_none() {
                        stack.push((s, false));
                    }
                }
                continue;
            }
            let s = &self.slots[n];
            let mut h = Xxh3::new();
            h.update(s.spec.name.as_bytes());
            h.update(&[0]);
            h.update(s.params.canonical().as_bytes());
            h.update(&s.external.to_le_bytes());
            h.update(&s.feed_hash.to_le_bytes());
            for (i, conns) in s.inputs.iter().enumerate() {
                h.update(&(i as u64).to_le_bytes());
                for &(src, p) in conns {
                    h.update(
                        &self.slots[src]
                            .hash
                            .expect("inputs hashed first")
                            .to_le_bytes(),
                    );
                    h.update(&(p as u64).to_le_bytes());
                }
                if conns.is_empty()
                    && let Some(d) = &s.input_defaults[i]
                {
                    h.update(&self.value_hash(d).to_le_bytes());
                }
            }
            let d = h.digest128();
            self.slots[n].hash = Some(d);
        }
        self.slots[target].hash.expect("computed")
    }

    /// Hash of what is connected to input `port` of `n`, independent of the frame: equal
    /// values mean the same upstream definition (for nodes that accumulate frames).
    pub(crate) fn input_structure_hash(&mut self, n: usize, port: usize) -> u128 {
        let conns = self.slots[n].inputs[port].clone();
        let mut h = Xxh3::new();
        for (src, p) in conns {
            h.update(&self.structural_hash(src).to_le_bytes());
            h.update(&(p as u64).to_le_bytes());
        }
        h.digest128()
    }

    /// Cache key of what is connected to input `port` of `n` at `ctx`.
    pub(crate) fn input_hash(&mut self, n: usize, port: usize, ctx: Context) -> u128 {
        let conns = self.slots[n].inputs[port].clone();
        let mut h = Xxh3::new();
        for (src, p) in conns {
            h.update(&self.structural_hash(src).to_le_bytes());
            h.update(&(p as u64).to_le_bytes());
            if !self.slots[src].eff_static {
                h.update(&ctx.frame.to_le_bytes());
                h.update(&ctx.fps.to_le_bytes());
            }
        }
        h.digest128()
    }
}
