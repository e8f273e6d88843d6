//! `weft-fuzz`: a seeded mutation fuzzer for everything a user's files can feed Weft.
//!
//! It takes the example graphs (`graphs/*.json`), the OBJ seeds (`tests/fuzz/seeds/`) and the
//! verification scenes (`crates/weft-bench/scenes/`),
//! mutates them the way users and tools damage files (a number scaled a thousandfold, a node's
//! type swapped, a parameter moved to another node, a connection rewired, a key deleted, bytes
//! cut, an OBJ index out of range or a coordinate `nan`), and runs each case through
//! `weft run` in a supervised worker process with a memory ceiling and a time limit. A panic,
//! an abort or a hang is a defect, kept as a case directory that `weft-fuzz replay` and the
//! regression test (`tests/fuzz/corpus/`) run again; every other outcome is counted by kind.
//!
//! It never changes what it fuzzes: cases are written to temporary directories and run
//! there. Cases are a pure function of (seed, index), so a run is reproducible.
#![warn(missing_docs)]

pub mod mutate;
mod supervise;
mod worker;

pub use supervise::{
    Config, Kind, Outcome, Report, case_dirs, category, fuzz, read_case, replay, write_case,
};
pub use worker::{weft_args, worker_main};

use mutate::Seed;
use std::path::{Path, PathBuf};

/// The repository's root (this crate lives in `crates/weft-fuzz`).
pub fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The default seed directories: the example graphs, the OBJ seeds, and the verification
/// scenes of weft-bench (graphs users could write: static solves, loads, clamped strands
/// and cloth, coupled boxes).
pub fn default_seed_dirs() -> Vec<PathBuf> {
    vec![
        repo_root().join("graphs"),
        repo_root().join("tests/fuzz/seeds"),
        repo_root().join("crates/weft-bench/scenes"),
    ]
}

/// Every `*.json` in `dirs` as a seed, with the `*.obj` files of its directory beside it; a
/// `*.json` file among `dirs` is that one seed (with the `*.obj` files beside it), so a run
/// can fuzz a few examples: `--seeds graphs/cloth_drape.json --seeds graphs/cloth_pile.json`.
pub fn load_seeds(dirs: &[PathBuf]) -> std::io::Result<Vec<Seed>> {
    let mut seeds = Vec::new();
    for dir in dirs {
        let mut json = Vec::new();
        let mut objs = Vec::new();
        let (folder, only) = if dir.is_file() {
            (
                dir.parent().unwrap_or(Path::new(".")).to_path_buf(),
                Some(dir),
            )
        } else {
            (dir.clone(), None)
        };
        let folder = if folder.as_os_str().is_empty() {
            PathBuf::from(".")
        } else {
            folder
        };
        for e in std::fs::read_dir(&folder)? {
            let p = e?.path();
            match p.extension().and_then(|x| x.to_str()) {
                Some("json") if only.is_none_or(|o| o == &p || same_file(o, &p)) => json.push(p),
                Some("obj") => objs.push(p),
                _ => {}
            }
        }
        json.sort();
        objs.sort();
        let mut files = Vec::new();
        for p in &objs {
            let name = p
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            files.push((name, std::fs::read(p)?));
        }
        for p in json {
            seeds.push(Seed {
                name: p
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default(),
                graph: std::fs::read_to_string(&p)?,
                files: files.clone(),
            });
        }
    }
    Ok(seeds)
}

fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    }
}

/// The registry's node type names (what a type mutation picks from).
pub fn node_types() -> Vec<String> {
    let reg = weft_nodes::registry();
    let mut v: Vec<String> = reg.specs().map(|s| s.name.clone()).collect();
    v.extend(
        weft_graph::library_specs(&reg)
            .0
            .into_iter()
            .map(|s| s.name),
    );
    v
}
