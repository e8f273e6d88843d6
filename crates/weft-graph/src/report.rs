//! What a graph reports about its nodes: counters, times, their own reports, checkpoints.

use crate::engine::{Graph, NodeReport, NodeStats};

impl Graph {
    /// Per-node counters and reports, in evaluation order.
    pub fn stats(&self) -> Vec<NodeReport> {
        self.slots
            .iter()
            .map(|s| NodeReport {
                node: s.id.clone(),
                type_name: s.spec.name.clone(),
                stats: s.stats.clone(),
                details: s.kernel.as_ref().and_then(|k| k.stats_json()),
            })
            .collect()
    }

    /// A node's own report (`--stats` details): iterations and residuals of an iterating
    /// composite, hits and writes of a cache. `None` for nodes that keep none.
    pub fn node_report(&self, id: &str) -> Option<serde_json::Value> {
        let &n = self.ids.get(id)?;
        self.slots[n].kernel.as_ref()?.stats_json()
    }

    /// Counters of one node.
    pub fn node_stats(&self, id: &str) -> Option<&NodeStats> {
        self.ids.get(id).map(|&n| &self.slots[n].stats)
    }

    /// Evaluation count of one node (0 for unknown ids).
    pub fn evaluations(&self, id: &str) -> u64 {
        self.node_stats(id).map_or(0, |s| s.evaluations)
    }

    /// Zeroes every counter.
    pub fn reset_stats(&mut self) {
        for s in &mut self.slots {
            s.stats = NodeStats::default();
        }
    }

    /// Number of stored checkpoints of a stateful node.
    pub fn checkpoint_frames(&self, id: &str) -> Vec<i64> {
        self.ids
            .get(id)
            .map(|&n| self.slots[n].checkpoints.frames())
            .unwrap_or_default()
    }

    /// Drops one node's checkpoints after `frame` (for tests and memory control).
    pub fn drop_checkpoints_after(&mut self, id: &str, frame: i64) {
        if let Some(&n) = self.ids.get(id) {
            let s = &mut self.slots[n];
            s.checkpoints.retain_up_to(frame);
            s.cache = None;
            // Downstream caches stay correct: the states that remain are unchanged.
        }
    }
}
