//! Cache nodes (`cache.memory`, `cache.disk`) and atomic file writes.
//!
//! Both nodes key what they store by the structural hash of everything upstream (plus the
//! frame when upstream depends on time), so a changed parameter anywhere upstream can never be
//! answered from a stale entry. Both pull their input lazily: a hit does not evaluate upstream.
//! Disk frames are written to a temporary file in the same directory and renamed into place,
//! so a killed run leaves either the old frame or the new one, never a partial file; every
//! frame carries its key and a checksum, and one that does not match is recomputed and
//! rewritten.

use crate::node::{Compute, EvalCx, Kernel, NodeError};
use crate::registry::{Registry, RegistryError};
use crate::spec::{NodeSpec, ParamSpec};
use crate::value::Value;
use std::collections::{HashMap, VecDeque};
use std::io::Write;
use std::path::{Path, PathBuf};

const TMP_PREFIX: &str = ".weft-tmp-";

/// Removes the temporary files that killed processes left in `dir` (named
/// `.weft-tmp-PID-…`, PID no longer running), once per directory per process. A file of a
/// process that is still running (another run writing there) is left alone.
fn sweep_stale_temporaries(dir: &Path) {
    static SWEPT: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());
    let Ok(mut swept) = SWEPT.lock() else { return };
    if swept.iter().any(|d| d == dir) || !Path::new("/proc/self").exists() {
        return;
    }
    swept.push(dir.to_path_buf());
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let name = e.file_name();
        let Some(rest) = name.to_str().and_then(|n| n.strip_prefix(TMP_PREFIX)) else {
            continue;
        };
        let pid = rest.split('-').next().and_then(|p| p.parse::<u32>().ok());
        if let Some(pid) = pid
            && pid != std::process::id()
            && !Path::new(&format!("/proc/{pid}")).exists()
        {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

/// Writes a file atomically: `fill` writes into a temporary file next to `path`, which is
/// flushed to disk and renamed over `path` only if `fill` succeeds, so a reader (or a run
/// killed at any moment) sees the old file or the new one, never a part. On error the
/// temporary file is removed; one a killed process left behind is removed by the next
/// write into the same directory.
pub fn atomic_write_with(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> std::io::Result<()> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir)?;
    sweep_stale_temporaries(dir);
    let mut tmp = tempfile::Builder::new()
        .prefix(&format!("{TMP_PREFIX}{}-", std::process::id()))
        .tempfile_in(dir)?;
    {
        let mut w = std::io::BufWriter::new(tmp.as_file_mut());
        fill(&mut w)?;
        w.flush()?;
    }
    tmp.as_file().sync_data()?;
    tmp.persist(path).map_err(|e| e.error)?;
    Ok(())
}

/// Writes `bytes` to `path` atomically.
pub fn atomic_write(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    atomic_write_with(path, |w| w.write_all(bytes))
}

const MAGIC: &[u8; 10] = b"WEFTCACHE\x01";

/// Serializes one cached frame: magic, key, frame, type name, payload, checksum.
pub(crate) fn encode_frame(key: u128, frame: i64, type_name: &str, payload: &[u8]) -> Vec<u8> {
    let mut b = Vec::with_capacity(payload.len() + 64);
    b.extend_from_slice(MAGIC);
    b.extend_from_slice(&key.to_le_bytes());
    b.extend_from_slice(&frame.to_le_bytes());
    b.extend_from_slice(&(type_name.len() as u16).to_le_bytes());
    b.extend_from_slice(type_name.as_bytes());
    b.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    b.extend_from_slice(payload);
    let sum = xxhash_rust::xxh3::xxh3_64(&b);
    b.extend_from_slice(&sum.to_le_bytes());
    b
}

/// Parses a cached frame; `None` for anything corrupt, truncated or of another key.
pub(crate) fn decode_frame(b: &[u8], key: u128, frame: i64) -> Option<(String, &[u8])> {
    let body_len = b.len().checked_sub(8)?;
    let (body, sum) = b.split_at(body_len);
    if xxhash_rust::xxh3::xxh3_64(body).to_le_bytes() != sum {
        return None;
    }
    let rest = body.strip_prefix(MAGIC)?;
    let (k, rest) = rest.split_at_checked(16)?;
    let (f, rest) = rest.split_at_checked(8)?;
    if u128::from_le_bytes(k.try_into().ok()?) != key
        || i64::from_le_bytes(f.try_into().ok()?) != frame
    {
        return None;
    }
    let (n, rest) = rest.split_at_checked(2)?;
    let (name, rest) = rest.split_at_checked(u16::from_le_bytes(n.try_into().ok()?) as usize)?;
    let (len, payload) = rest.split_at_checked(8)?;
    if u64::from_le_bytes(len.try_into().ok()?) as usize != payload.len() {
        return None;
    }
    Some((String::from_utf8(name.to_vec()).ok()?, payload))
}

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

pub(crate) fn register(r: &mut Registry) -> Result<(), RegistryError> {
    r.register(
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
        |_| {
            Ok(Kernel::Compute(Box::new(MemoryCache {
                entries: HashMap::new(),
                order: VecDeque::new(),
                bytes: 0,
                hits: 0,
                misses: 0,
                evicted_for_memory: 0,
            })))
        },
    )?;
    r.register(
        NodeSpec::new(
            "cache.disk",
            "stores each frame of its input on disk, keyed by the upstream hash; reused across runs while the key matches",
        )
        .input("in", "any", "value to cache (its type needs a byte codec)")
        .output("out", "same:in", "the cached value")
        .param(ParamSpec::string("path", "").required().doc("directory of the cache files (under --out when given, else the working directory)"))
        .lazy(),
        |p| {
            if p.str("path")?.is_empty() {
                return Err("param 'path' must not be empty".into());
            }
            Ok(Kernel::Compute(Box::new(DiskCache::default())))
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_codec_rejects_corruption_and_other_keys() {
        let b = encode_frame(42, 7, "float", &1.5f64.to_le_bytes());
        let (t, p) = decode_frame(&b, 42, 7).unwrap();
        assert_eq!((t.as_str(), p), ("float", &1.5f64.to_le_bytes()[..]));
        assert!(decode_frame(&b, 43, 7).is_none(), "another key");
        assert!(decode_frame(&b, 42, 8).is_none(), "another frame");
        for cut in 0..b.len() {
            assert!(
                decode_frame(&b[..cut], 42, 7).is_none(),
                "truncated at {cut}"
            );
        }
        let mut flipped = b.clone();
        flipped[30] ^= 1;
        assert!(decode_frame(&flipped, 42, 7).is_none(), "bit flip");
    }

    #[test]
    fn interrupted_write_leaves_no_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("frame.wcache");
        atomic_write(&path, b"old").unwrap();
        let r = atomic_write_with(&path, |w| {
            w.write_all(b"half of the new")?;
            Err(std::io::Error::other("killed"))
        });
        assert!(r.is_err());
        // The old content is intact and no temporary file is left behind.
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }
}
