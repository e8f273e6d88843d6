//! `cache.disk`: reused across runs while the upstream hash matches, rewritten when it does
//! not, corruption detected, writes atomic.

mod common;
use common::*;
use std::path::Path;
use weft::graph::Graph;

fn cached(dir: &Path) -> Graph {
    graph(&file(
        &format!(
            r#""decay": {{"type": "ode.decay", "params": {{"rate": 2.0, "method": "rk4"}}}},
               "disk":  {{"type": "cache.disk", "inputs": {{"in": "decay.y"}}, "params": {{"path": {:?}}}}},
               "k":     {{"type": "value.float", "params": {{"value": 3.0}}}},
               "kdisk": {{"type": "cache.disk", "inputs": {{"in": "k.out"}}, "params": {{"path": {:?}}}}}"#,
            dir.join("decay").to_str().unwrap(),
            dir.join("k").to_str().unwrap()
        ),
        r#""y": "disk.out", "k": "kdisk.out""#,
    ))
}

fn run(g: &mut Graph) -> Vec<u64> {
    (0..=10).map(|f| f64_at(g, "y", f).to_bits()).collect()
}

fn files(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    v.sort();
    v
}

#[test]
fn a_matching_cache_is_reused_by_the_next_run() {
    let dir = tempfile::tempdir().unwrap();
    let mut first = cached(dir.path());
    let a = run(&mut first);
    assert_eq!(first.node_stats("decay").unwrap().steps, 10);
    assert_eq!(
        files(&dir.path().join("decay")).len(),
        11,
        "one file per frame"
    );

    // A new graph (a new run) with the same upstream reads the frames: no integration at all.
    let mut second = cached(dir.path());
    let b = run(&mut second);
    assert_eq!(a, b, "bit-identical through the disk round trip");
    assert_eq!(second.evaluations("decay"), 0);
    let d = second.node_report("disk").unwrap();
    assert_eq!(
        (d["hits"].as_u64(), d["writes"].as_u64()),
        (Some(11), Some(0))
    );

    // A static input is one file, whatever the frame.
    assert_eq!(f64_at(&mut second, "k", 7), 3.0);
    assert_eq!(files(&dir.path().join("k")), vec!["static.wcache"]);
}

#[test]
fn a_stale_cache_is_rewritten() {
    let dir = tempfile::tempdir().unwrap();
    let a = run(&mut cached(dir.path()));
    let mut changed = cached(dir.path());
    changed
        .set_param("decay", "rate", serde_json::json!(1.0))
        .unwrap();
    let b = run(&mut changed);
    assert_ne!(a[10], b[10]);
    assert_eq!(f64::from_bits(b[0]), 1.0);
    let d = changed.node_report("disk").unwrap();
    assert_eq!(
        (d["hits"].as_u64(), d["rewrites"].as_u64()),
        (Some(0), Some(11))
    );
    // The rewritten cache now serves the new parameters.
    let mut again = cached(dir.path());
    again
        .set_param("decay", "rate", serde_json::json!(1.0))
        .unwrap();
    assert_eq!(run(&mut again), b);
    assert_eq!(again.evaluations("decay"), 0);
}

#[test]
fn a_corrupt_frame_is_recomputed_and_no_temporary_files_remain() {
    let dir = tempfile::tempdir().unwrap();
    let a = run(&mut cached(dir.path()));
    let frame5 = dir.path().join("decay").join("frame_000005.wcache");
    let bytes = std::fs::read(&frame5).unwrap();
    std::fs::write(&frame5, &bytes[..bytes.len() / 2]).unwrap(); // a torn write by another tool
    let mut g = cached(dir.path());
    assert_eq!(run(&mut g), a);
    let d = g.node_report("disk").unwrap();
    assert_eq!(
        (d["hits"].as_u64(), d["rewrites"].as_u64()),
        (Some(10), Some(1))
    );
    assert_eq!(std::fs::read(&frame5).unwrap(), bytes, "rewritten whole");
    assert!(
        files(&dir.path().join("decay"))
            .iter()
            .all(|f| f.ends_with(".wcache")),
        "no temporary files"
    );
}

#[test]
fn an_unwritable_cache_directory_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let blocker = dir.path().join("file");
    std::fs::write(&blocker, b"x").unwrap();
    let mut g = cached(&blocker); // its "directory" is a regular file
    let e = g
        .pull("y", weft::graph::Context::new(1))
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("node 'disk' at frame 1: cannot write cache file"),
        "{e}"
    );
}

/// The header every graph file starts with.
const H: &str = r#""format": "weft-graph", "version": 1"#;

#[test]
fn a_disk_cache_notices_an_edit_inside_a_nested_subgraph() {
    let dir = tempfile::tempdir().unwrap();
    let mk = |from: &str| {
        format!(
            r#"{{{H}, "subgraphs": {{
            "B": {{"inputs": {{"x": "float"}},
                   "nodes": {{"s": {{"type": "math.scale", "params": {{"factor": 2.0}}, "inputs": {{"x": "in.x"}}}},
                              "t": {{"type": "math.scale", "params": {{"factor": 3.0}}, "inputs": {{"x": "in.x"}}}}}},
                   "outputs": {{"y": "{from}"}}}},
            "A": {{"inputs": {{"x": "float"}}, "nodes": {{"b": {{"type": "B", "inputs": {{"x": "in.x"}}}}}}, "outputs": {{"y": "b.y"}}}}}},
          "nodes": {{"c": {{"type": "value.float", "params": {{"value": 1.0}}}},
                     "a": {{"type": "A", "inputs": {{"x": "c.out"}}}},
                     "k": {{"type": "cache.disk", "params": {{"path": {:?}}}, "inputs": {{"in": "a.y"}}}}}},
          "outputs": {{"y": "k.out"}}}}"#,
            dir.path().to_str().unwrap()
        )
    };
    assert_eq!(f64_at(&mut graph(&mk("s.out")), "y", 0), 2.0);
    assert_eq!(f64_at(&mut graph(&mk("t.out")), "y", 0), 3.0);
}
