//! The memory a run may take, as a user meets it: under an address-space ceiling (`ulimit
//! -v`, set in a child shell) a run finishes or is refused with the estimate, naming the
//! node; it never aborts in an allocation. Issue 70: the drape example at 24 × 2424 cells
//! aborted under 6 GiB allocating its split factorization's separator blocks (3.4 GB), which
//! the estimate did not count.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// An example graph with `from` replaced by `to` in its text, written into `dir`.
fn variant(dir: &Path, example: &str, edits: &[(&str, &str)]) -> PathBuf {
    let mut text = std::fs::read_to_string(root().join("graphs").join(example)).unwrap();
    for (from, to) in edits {
        assert!(text.contains(from), "{example} has no {from}");
        text = text.replace(from, to);
    }
    let path = dir.join(example);
    std::fs::write(&path, text).unwrap();
    path
}

/// `weft run GRAPH --frames FRAMES` in `dir` under `ulimit -v` of `ceiling_mib` (none: 0),
/// with `env` set.
fn run(dir: &Path, graph: &Path, frames: &str, ceiling_mib: u64, env: &[(&str, &str)]) -> Output {
    let weft = env!("CARGO_BIN_EXE_weft");
    let limit = if ceiling_mib > 0 {
        format!("ulimit -v {};", ceiling_mib * 1024)
    } else {
        String::new()
    };
    let script = format!(
        "{limit} exec '{weft}' run '{}' --frames {frames} -q --no-checkpoints --out out",
        graph.display()
    );
    let mut c = Command::new("sh");
    c.args(["-c", &script]).current_dir(dir);
    for (k, v) in env {
        c.env(k, v);
    }
    c.output().unwrap()
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// Ended by itself (exit 0), or refused with the estimate (exit 1): never killed by a
/// signal (an allocation failing aborts the process).
fn ended_or_refused(o: &Output, what: &str) -> bool {
    let err = text(&o.stderr);
    match o.status.code() {
        Some(0) => true,
        Some(1) => {
            assert!(
                err.contains("needs about") && err.contains("available"),
                "{what}: exit 1 without an estimate: {err}"
            );
            false
        }
        _ => panic!("{what}: {:?}: {err}", o.status),
    }
}

#[test]
fn the_split_factorization_is_estimated_before_it_is_allocated() {
    let dir = tempfile::tempdir().unwrap();
    // 25 × 2425 vertices, cut across: the split's separator would be some 6,900 vertices,
    // three dense blocks of 3.4 GB. Frame 0 builds the solver (its analysis and factors).
    let graph = variant(
        dir.path(),
        "cloth_drape.json",
        &[
            ("\"ny\": 24", "\"ny\": 2424"),
            ("\"coefficient\": 0.1", "\"coefficient\": 1e18"),
        ],
    );
    let o = run(dir.path(), &graph, "0..0", 6 << 10, &[]);
    assert!(
        ended_or_refused(&o, "6 GiB"),
        "the whole factor fits in 6 GiB: {}",
        text(&o.stderr)
    );
}

/// A 64 × 64 sheet's first frame builds its factor split in two, the one-ring
/// preconditioner and the single-precision twin (its factorization costs more than 1e8
/// flops), each within what its ceiling leaves: from one too low for the scene to one with
/// room for everything, every run ends or is refused.
#[test]
fn under_any_address_space_ceiling_a_run_ends_or_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let graph = variant(
        dir.path(),
        "cloth_hang.json",
        &[
            ("\"nx\": 24, \"ny\": 24", "\"nx\": 64, \"ny\": 64"),
            ("\"margin\":", "\"width\": 64, \"height\": 48, \"margin\":"),
        ],
    );
    let ended: Vec<bool> = [100, 130, 160, 220, 400]
        .iter()
        .map(|&mib| {
            let o = run(dir.path(), &graph, "0..1", mib, &[]);
            ended_or_refused(&o, &format!("{mib} MiB"))
        })
        .collect();
    assert!(ended.last() == Some(&true), "{ended:?}");
}

#[test]
fn a_lowered_memory_limit_refuses_the_solver_naming_the_node() {
    let dir = tempfile::tempdir().unwrap();
    let graph = variant(
        dir.path(),
        "cloth_hang.json",
        &[("\"nx\": 24, \"ny\": 24", "\"nx\": 64, \"ny\": 64")],
    );
    let o = run(
        dir.path(),
        &graph,
        "0..1",
        0,
        &[("WEFT_MEMORY_LIMIT", "20M")],
    );
    let err = text(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("error: node 'solve' at frame 0: the system matrix needs about"),
        "{err}"
    );
    assert!(err.contains("use fewer vertices"), "{err}");
}
