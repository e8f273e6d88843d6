//! Stateful nodes' states on disk (`Graph::set_checkpoint_dir`, `weft run --out`): each
//! frame's state written atomically, keyed by everything the node depends on, and restored
//! instead of stepped when a run is resumed. Also the in-memory keeping of states, which
//! both paths go through.

use crate::engine::{Context, Graph};
use crate::node::{NodeError, Step};
use crate::value::Value;
use xxhash_rust::xxh3::Xxh3;

impl Graph {
    /// Keeps a state in memory (within the checkpoints' budget).
    pub(crate) fn keep(&mut self, n: usize, k: &dyn Step, frame: i64, state: &Value, start: i64) {
        let bytes = k.state_bytes(state, &self.registry);
        self.slots[n]
            .checkpoints
            .insert(frame, state.clone(), bytes, start);
    }

    /// The key a node's disk checkpoints carry: its structure (type, parameters, kernel,
    /// everything upstream), the frame rate, and Weft's version (another version's solver
    /// may step differently, so its states are recomputed, not restored).
    fn checkpoint_key(&mut self, n: usize, fps: f64) -> u128 {
        let mut h = Xxh3::new();
        h.update(b"weft-checkpoint-1");
        h.update(env!("CARGO_PKG_VERSION").as_bytes());
        h.update(&self.structural_hash(n).to_le_bytes());
        h.update(&fps.to_le_bytes());
        h.digest128()
    }

    fn checkpoint_file(&self, n: usize, frame: i64) -> Option<std::path::PathBuf> {
        let dir = self.checkpoint_dir.as_ref()?;
        Some(
            dir.join(&self.slots[n].id)
                .join(format!("frame_{frame:06}.wstate")),
        )
    }

    /// The newest state of `n` on disk for a frame in `lo..=hi` whose key matches, restored.
    /// A damaged or stale file is skipped (the frame is then stepped); only the node's own
    /// failure to restore a valid file is an error.
    pub(crate) fn restore_from_disk(
        &mut self,
        n: usize,
        k: &mut dyn Step,
        lo: i64,
        hi: i64,
        start: i64,
        ctx: Context,
    ) -> Result<Option<(i64, Value)>, (NodeError, i64)> {
        let Some(dir) = self
            .checkpoint_dir
            .as_ref()
            .map(|d| d.join(&self.slots[n].id))
        else {
            return Ok(None);
        };
        let Ok(entries) = std::fs::read_dir(&dir) else {
            return Ok(None);
        };
        let mut frames: Vec<i64> = entries
            .flatten()
            .filter_map(|e| {
                e.file_name()
                    .to_str()?
                    .strip_prefix("frame_")?
                    .strip_suffix(".wstate")?
                    .parse()
                    .ok()
            })
            .filter(|f| (lo..=hi).contains(f) && *f > start)
            .collect();
        frames.sort_unstable();
        let key = self.checkpoint_key(n, ctx.fps);
        for frame in frames.into_iter().rev() {
            let Some(path) = self.checkpoint_file(n, frame) else {
                break;
            };
            let Ok(bytes) = std::fs::read(&path) else {
                continue;
            };
            let Some((_, payload)) = crate::files::decode_frame(&bytes, key, frame) else {
                continue;
            };
            let initial = match self.slots[n].checkpoints.get(&start) {
                Some(s) => s.clone(),
                None => {
                    let mut cx = self.cx(n, ctx.with_frame(start)).map_err(|e| (e, start))?;
                    let s = k.init(&mut cx).map_err(|e| (e, start))?;
                    self.keep(n, k, start, &s, start);
                    s
                }
            };
            let mut cx = self.cx(n, ctx.with_frame(frame)).map_err(|e| (e, frame))?;
            let state = k
                .load_state(payload, &initial, &mut cx)
                .map_err(|e| (e, frame))?;
            self.keep(n, k, frame, &state, start);
            self.slots[n].stats.restored += 1;
            return Ok(Some((frame, state)));
        }
        Ok(None)
    }

    /// Writes `state` (frame `at`) to the checkpoint directory, atomically. A failed write
    /// is a warning: the run goes on, only resuming loses that frame.
    pub(crate) fn save_to_disk(
        &mut self,
        n: usize,
        k: &dyn Step,
        at: i64,
        state: &Value,
        fps: f64,
    ) {
        let Some(path) = self.checkpoint_file(n, at) else {
            return;
        };
        let Some(payload) = k.save_state(state, &self.registry) else {
            return;
        };
        let key = self.checkpoint_key(n, fps);
        let bytes = crate::files::encode_frame(key, at, "state", &payload);
        if let Err(e) = crate::files::atomic_write(&path, &bytes) {
            self.push_warning(
                n,
                Some(at),
                format!(
                    "cannot write the checkpoint {}: {e} (resuming will recompute this frame)",
                    path.display()
                ),
            );
        }
    }
}
