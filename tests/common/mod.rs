//! Helpers of the workspace's graph-level tests: the shared ones (graphs from text, outputs
//! at a frame, probes, the independent contact checks) from `weft-nodes`' tests, and the
//! example graphs of `graphs/`, which only these tests load.
#![allow(dead_code, unused_imports)]

#[path = "../../crates/weft-nodes/tests/common/mod.rs"]
mod shared;

pub use shared::*;

use std::path::{Path, PathBuf};
use weft_graph::{Graph, load_path};

pub fn graphs_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs")
}

/// Loads `graphs/NAME`.
pub fn example(name: &str) -> Graph {
    let path = graphs_dir().join(name);
    load_path(&registry(), &path).unwrap_or_else(|e| panic!("{e}"))
}
