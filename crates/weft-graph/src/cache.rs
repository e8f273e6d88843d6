//! Cache nodes (`cache.memory`, `cache.disk`).
//!
//! Both nodes key what they store by the structural hash of everything upstream (plus the
//! frame when upstream depends on time), so a changed parameter anywhere upstream can never be
//! answered from a stale entry. Both pull their input lazily: a hit does not evaluate upstream.
//! Disk frames are written to a temporary file in the same directory and renamed into place,
//! so a killed run leaves either the old frame or the new one, never a partial file; every
//! frame carries its key and a checksum, and one that does not match is recomputed and
//! rewritten.

use crate::files::{atomic_write, decode_frame, encode_frame};
use crate::node::{Compute, EvalCx, Factory, Kernel, NodeError};
use crate::spec::{NodeSpec, ParamSpec};
use crate::value::Value;
use std::collections::{HashMap, VecDeque};
use std::path::{Path, PathBuf};
use std::sync::Arc;

struct MemoryCache {
    entries: HashMap<u128, (Value, usize)>,
    order: VecDeque<u128>,
    bytes: usize,
    hits: u64,
    misses: u64,
    evicted_for_memory: u64,
}

/// Below this many bytes a memory cache never asks how much memory is left.
const QUIET_BYTES: usize = 64 << 20;

impl Compute for MemoryCache {
    fn compute(&mut self, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
        let key = cx.input_hash("in")?;
        if let Some((v, _)) = self.entries.get(&key) {
            self.hits += 1;
            cx.set("out", v.clone());
            return Ok(());
        }
        self.misses += 1;
        let v = cx.input("in")?;
        let size = cx.registry().value_bytes(&v);
        let cap = cx.params().usize("max_frames")?.max(1);
        // The oldest entries go first: past max_frames, and past a quarter of the memory the
        // process may still take (a cache never makes a run fail for lack of memory).
        let budget = if self.bytes + size > QUIET_BYTES {
            usize::try_from(cx.memory_budget() / 4).unwrap_or(usize::MAX)
        } else {
            usize::MAX
        };
        while self.order.len() >= cap || (self.bytes + size > budget && !self.order.is_empty()) {
            if self.order.len() < cap {
                self.evicted_for_memory += 1;
            }
            if let Some(old) = self.order.pop_front()
                && let Some((_, b)) = self.entries.remove(&old)
            {
                self.bytes -= b;
            }
        }
        self.entries.insert(key, (v.clone(), size));
        self.bytes += size;
        self.order.push_back(key);
        cx.set("out", v);
        Ok(())
    }
    fn stats_json(&self) -> Option<serde_json::Value> {
        Some(serde_json::json!({
            "hits": self.hits, "misses": self.misses, "entries": self.entries.len(),
            "bytes": self.bytes, "evicted_for_memory": self.evicted_for_memory,
        }))
    }
}

#[derive(Default)]
struct DiskCache {
    hits: u64,
    writes: u64,
    rewrites: u64,
    bytes_written: u64,
}

impl DiskCache {
    fn file(dir: &Path, time_dependent: bool, frame: i64) -> PathBuf {
        if time_dependent {
            dir.join(format!("frame_{frame:06}.wcache"))
        } else {
            dir.join("static.wcache")
        }
    }
}

impl Compute for DiskCache {
    fn compute(&mut self, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
        let dir = cx.output_path("path")?;
        let key = cx.input_hash("in")?;
        let timed = cx.input_time_dependent("in");
        let frame = if timed { cx.frame() } else { 0 };
        let path = Self::file(&dir, timed, frame);
        let existing = std::fs::read(&path).ok();
        if let Some(bytes) = &existing
            && let Some((ty, payload)) = decode_frame(bytes, key, frame)
            && let Some(decode) = cx.registry().port_type(&ty).and_then(|t| t.decode)
            && let Ok(v) = decode(payload)
        {
            self.hits += 1;
            cx.set("out", v);
            return Ok(());
        }
        let v = cx.input("in")?;
        let pt = cx.registry().port_type_by_id(v.payload_type_id()).cloned();
        let (name, payload) = match pt.as_ref().and_then(|t| {
            // Only a type that decodes on its own can be read back from a cache.
            t.decode?;
            Some((t.name.clone(), (t.encode?)(&v)?))
        }) {
            Some(x) => x,
            None => {
                let n = pt
                    .map(|t| t.name)
                    .unwrap_or_else(|| "an unregistered type".into());
                return Err(NodeError::Input {
                    port: "in".into(),
                    message: format!("{n} has no byte codec, so it cannot be cached on disk"),
                });
            }
        };
        let bytes = encode_frame(key, frame, &name, &payload);
        atomic_write(&path, &bytes).map_err(|e| {
            NodeError::Failed(format!("cannot write cache file {}: {e}", path.display()))
        })?;
        self.writes += 1;
        self.bytes_written += bytes.len() as u64;
        if existing.is_some() {
            self.rewrites += 1;
        }
        cx.set("out", v);
        Ok(())
    }
    fn stats_json(&self) -> Option<serde_json::Value> {
        Some(serde_json::json!({
            "hits": self.hits, "writes": self.writes, "rewrites": self.rewrites, "bytes_written": self.bytes_written
        }))
    }
}

/// The cache node types every registry starts with.
pub(crate) fn node_types() -> Vec<(NodeSpec, Factory)> {
    let memory: Factory = Arc::new(|_| {
        Ok(Kernel::Compute(Box::new(MemoryCache {
            entries: HashMap::new(),
            order: VecDeque::new(),
            bytes: 0,
            hits: 0,
            misses: 0,
            evicted_for_memory: 0,
        })))
    });
    let disk: Factory = Arc::new(|p| {
        if p.str("path")?.is_empty() {
            return Err("param 'path' must not be empty".into());
        }
        Ok(Kernel::Compute(Box::new(DiskCache::default())))
    });
    vec![(
        NodeSpec::new(
            "cache.memory",
            "keeps every frame of its input in memory, keyed by the upstream hash",
        )
        .input("in", "any", "value to cache")
        .output("out", "same:in", "the cached value")
        .param(
            ParamSpec::int("max_frames", 10_000)
                .ge(1.0)
                .doc("entries kept; the oldest is dropped first (also when the entries grow past a quarter of the memory left)"),
        )
        .lazy(),
        memory,
    ), (
        NodeSpec::new(
            "cache.disk",
            "stores each frame of its input on disk, keyed by the upstream hash; reused across runs while the key matches",
        )
        .input("in", "any", "value to cache (its type needs a byte codec)")
        .output("out", "same:in", "the cached value")
        .param(ParamSpec::string("path", "").required().doc("directory of the cache files (under --out when given, else the working directory)"))
        .lazy(),
        disk,
    )]
}
