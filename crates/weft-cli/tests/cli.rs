//! The `weft` binary, run as a user runs it.

use expect_test::expect;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn weft(args: &[&str], cwd: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_weft"))
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("weft runs")
}

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

#[test]
fn run_prints_a_table_of_outputs() {
    let o = weft(&["run", "graphs/hypot_static.json"], &root());
    assert!(o.status.success(), "{}", text(&o.stderr));
    expect![[r#"
        frame	hyp1	hyp2	length	vector
        0	5.0	13.0	13.92838827718412	[5.0,13.0,0.0]
    "#]]
    .assert_eq(&text(&o.stdout));
}

#[test]
fn run_with_frames_set_out_and_stats() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("result");
    let stats = dir.path().join("stats.json");
    let o = weft(
        &[
            "run",
            "graphs/stiff_newton.json",
            "--frames",
            "0..3",
            "--set",
            "solve.check.tolerance=1e-14",
            "--out",
            out.to_str().unwrap(),
            "--stats",
            "--stats-json",
            stats.to_str().unwrap(),
        ],
        &root(),
    );
    let err = text(&o.stderr);
    assert!(o.status.success(), "{err}");
    // Not a terminal: plain progress lines, one per frame.
    assert!(
        err.contains("frame 0 (1/4): ") && err.contains("frame 3 (4/4): "),
        "{err}"
    );
    assert!(err.contains("iterations over 3 frame solves"), "{err}");
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("outputs.json")).unwrap()).unwrap();
    assert_eq!(j["frames"], serde_json::json!([0, 1, 2, 3]));
    assert_eq!(j["outputs"]["y"][0], serde_json::json!(1.0));
    let csv = std::fs::read_to_string(out.join("outputs.csv")).unwrap();
    assert_eq!(csv.lines().next(), Some("frame,error,exact,residual,y"));
    assert_eq!(csv.lines().count(), 5);
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    let solve = s["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .find(|n| n["node"] == "solve")
        .unwrap();
    assert_eq!(solve["steps"], 3);
    let frames = solve["details"]["frames"].as_array().unwrap();
    assert_eq!(frames.len(), 3);
    let last = frames[2]["iterations"].as_array().unwrap().last().unwrap();
    assert!(last["residual"].as_f64().unwrap().abs() < 1e-14);
    // Each frame's seconds, none of them in output nodes (this graph has none), within the
    // run's.
    let timed = s["frames"].as_array().unwrap();
    assert_eq!(
        timed
            .iter()
            .map(|f| f["frame"].as_i64().unwrap())
            .collect::<Vec<_>>(),
        [0, 1, 2, 3]
    );
    assert!(timed.iter().all(|f| f["output_seconds"] == 0.0));
    let sum: f64 = timed.iter().map(|f| f["seconds"].as_f64().unwrap()).sum();
    assert!(sum > 0.0 && sum <= s["seconds"].as_f64().unwrap());
}

#[test]
fn stats_say_what_writing_files_cost_each_frame() {
    let dir = tempfile::tempdir().unwrap();
    let stats = dir.path().join("stats.json");
    let o = weft(
        &[
            "run",
            "graphs/cloth_hang.json",
            "--frames",
            "0..1",
            "--set",
            "grid.nx=6",
            "--set",
            "grid.ny=6",
            "--set",
            "pins.vertices=[0,5]",
            "--output",
            "obj",
            "--out",
            dir.path().join("out").to_str().unwrap(),
            "--no-checkpoints",
            "-q",
            "--stats-json",
            stats.to_str().unwrap(),
        ],
        &root(),
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    let frames = s["frames"].as_array().unwrap();
    assert_eq!(frames.len(), 2);
    for f in frames {
        // output.obj wrote this frame's mesh: a share of the frame's time, not all of it.
        let (all, out) = (
            f["seconds"].as_f64().unwrap(),
            f["output_seconds"].as_f64().unwrap(),
        );
        assert!(out > 0.0 && out < all, "{f}");
    }
}

#[test]
fn bad_set_and_frames_are_usage_errors() {
    let o = weft(
        &["run", "graphs/oscillator.json", "--set", "rk4.omega=-1"],
        &root(),
    );
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(
        text(&o.stderr),
        "error: --set rk4.omega=-1: node 'rk4': param 'omega': must be > 0, got -1\n"
    );
    let o = weft(
        &["run", "graphs/oscillator.json", "--frames", "9..2"],
        &root(),
    );
    assert_eq!(o.status.code(), Some(2));
    let o = weft(
        &["run", "graphs/oscillator.json", "--output", "x_rk5"],
        &root(),
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o.stderr).contains("has no output 'x_rk5'"));
}

#[test]
fn a_failing_frame_exits_1_naming_node_and_frame_and_keeps_what_was_computed() {
    let dir = tempfile::tempdir().unwrap();
    let g = dir.path().join("g.json");
    std::fs::write(
        &g,
        r#"{"format": "weft-graph", "version": 1, "nodes": {
            "clock": {"type": "time.frame"},
            "d": {"type": "math.expr", "params": {"expr": "1 / (3 - x)"}, "inputs": {"x": "clock.time"}}},
            "outputs": {"y": "d.out"}}"#,
    )
    .unwrap();
    let out = dir.path().join("o");
    let o = weft(
        &[
            "run",
            "g.json",
            "--fps",
            "1",
            "--frames",
            "0..5",
            "--out",
            out.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(1));
    let err = text(&o.stderr);
    assert!(
        err.contains("error: node 'd' at frame 3: formula gave inf"),
        "{err}"
    );
    assert!(
        err.contains("frames 0..2 completed before the failure"),
        "{err}"
    );
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("outputs.json")).unwrap()).unwrap();
    assert_eq!(j["frames"], serde_json::json!([0, 1, 2]));
}

#[test]
fn validate_reports_every_error_and_exits_2() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("bad.json"),
        "{\"format\": \"weft-graph\", \"version\": 1,\n \"nodes\": {\"a\": {\"type\": \"math.ad\"},\n \"b\": {\"type\": \"value.float\", \"params\": {\"value\": true}}},\n \"outputs\": {}}",
    )
    .unwrap();
    let o = weft(&["validate", "bad.json"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    expect![[r#"
        bad.json: 2 errors in graph file
          bad.json: warning: the file declares no 'outputs': nothing would be computed
          bad.json: line 2, column 18: error: node 'a': unknown node type 'math.ad' (did you mean 'math.add'?)
          bad.json: line 3, column 42: error: node 'b': param 'value': expected a number, got true
    "#]]
    .assert_eq(&text(&o.stderr));
    let o = weft(
        &[
            "validate",
            "graphs/oscillator.json",
            "graphs/stiff_newton.json",
        ],
        &root(),
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(
        text(&o.stdout)
            .contains("ok: graphs/stiff_newton.json (5 nodes; outputs: error, exact, residual, y)")
    );
}

#[test]
fn nodes_documents_the_registry() {
    let o = weft(&["nodes", "math.below"], &root());
    expect![[r#"
        math.below  (static)
          true when |x| < tolerance (a convergence test)
          in   x          float — residual or error
          out  out        bool — |x| < tolerance
          param tolerance float > 0 = 1e-10 — threshold

    "#]]
    .assert_eq(&text(&o.stdout));
    let o = weft(&["nodes", "--json"], &root());
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let types = j["node_types"].as_array().unwrap();
    assert!(types.len() >= 20, "{}", types.len());
    // Every parameter has a doc line, every stateful node a start_frame.
    for t in types {
        for p in t["params"].as_array().unwrap() {
            assert!(
                !p["doc"].as_str().unwrap().is_empty(),
                "{} {}",
                t["name"],
                p["name"]
            );
        }
        if t["time"] == "stateful" {
            assert!(
                t["params"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .any(|p| p["name"] == "start_frame")
            );
        }
    }
}

#[test]
fn bench_graph_quick_runs() {
    let o = weft(&["bench", "graph", "--quick"], &root());
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(text(&o.stdout).contains("| clean re-pull, chain | 10000 |"));
    let o = weft(&["bench", "nope"], &root());
    assert_eq!(o.status.code(), Some(2));
}

/// Runs `weft bench SUITE --quick` into a scratch directory and checks what every sweep
/// suite promises: exit 0 only when the facts theory fixes hold, every run as CSV (`rows`
/// of them, with the documented header) and JSON with every check passed, and each of
/// `charts` as PNG and SVG.
fn quick_suite(suite: &str, rows: usize, charts: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bench");
    let o = weft(
        &["bench", suite, "--quick", "--out", out.to_str().unwrap()],
        &root(),
    );
    assert!(
        o.status.success(),
        "{}\n{}",
        text(&o.stdout),
        text(&o.stderr)
    );
    let csv = std::fs::read_to_string(out.join(format!("{suite}.csv"))).unwrap();
    assert!(csv.starts_with(
        "scene,method,h,dx,param,param_name,error,error_unit,iterations,seconds,steps,status,pareto\n"
    ));
    assert_eq!(csv.lines().count(), 1 + rows, "{csv}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join(format!("{suite}.json"))).unwrap())
            .unwrap();
    assert_eq!(json["runs"].as_array().unwrap().len(), rows);
    let checks = json["summary"]["checks"].as_array().unwrap();
    assert!(checks.len() >= 4, "{checks:?}");
    assert!(checks.iter().all(|c| c[1] == true), "{checks:?}");
    for chart in charts {
        for ext in ["png", "svg"] {
            let p = out.join(format!("{chart}.{ext}"));
            assert!(
                std::fs::metadata(&p)
                    .map(|m| m.len() > 1000)
                    .unwrap_or(false),
                "{p:?}"
            );
        }
    }
}

/// `weft bench accuracy --quick`: first order within 0.8–1.2 for every method; explicit
/// blows up above 1.2 × its stable step 2/ω and holds below 0.5 × it; newton never blows
/// up; the Newton tolerance's checks; the clamped strand at second order and the two-pin
/// clamp at first. Runs: 4 stiffnesses (three mapped and the convergence one) × 3 methods ×
/// 5 steps, 3 tolerances at one step, and 2 clamps × 3 resolutions.
#[test]
fn bench_accuracy_quick_asserts_theory_and_writes_runs_and_charts() {
    quick_suite(
        "accuracy",
        4 * 3 * 5 + 3 + 2 * 3,
        &[
            "accuracy_error_time",
            "accuracy_error_step",
            "accuracy_stability",
            "accuracy_tolerance",
            "accuracy_clamp",
        ],
    );
}

/// `weft bench convergence --quick`: the orders of the clamped strand, catenary and
/// Taylor–Green in their bands, the shell strip within 0.5 %, the Darcy slab exact. Runs:
/// 3 cantilevers, 3 catenaries, 2 strips, 2 membranes, 2 Taylor–Green, 2 slabs.
#[test]
fn bench_convergence_quick_asserts_orders_and_writes_runs_and_chart() {
    quick_suite("convergence", 14, &["convergence_error_size"]);
}

/// `weft bench coupling --quick`: newton never blows up and is first order; staggered fails
/// where h·K/m ≥ 200 and newton holds there; the settling sheet falls at Darcy's speed.
/// Runs: 3 drag scales × 3 methods × 3 steps for the strand, 3 × 3 for the sheet.
#[test]
fn bench_coupling_quick_maps_where_staggered_fails_and_newton_holds() {
    quick_suite(
        "coupling",
        27 + 9,
        &[
            "coupling_stability",
            "coupling_error_step",
            "coupling_error_time",
            "coupling_sheet_error_step",
        ],
    );
}

/// `weft run` writes a list output and a vec3 output as columns of outputs.csv: NAME.0 …
/// NAME.N−1 and NAME.x, NAME.y, NAME.z, a row per frame.
#[test]
fn outputs_csv_spreads_lists_and_vectors_over_columns() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("still.json");
    std::fs::write(
        &path,
        include_str!("../../../tests/fields/still_water.json"),
    )
    .unwrap();
    let out = dir.path().join("run");
    let o = Command::new(env!("CARGO_BIN_EXE_weft"))
        .args(["run", path.to_str().unwrap(), "--frames", "0..2", "--out"])
        .arg(&out)
        .args(["--no-checkpoints", "-q"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let csv = std::fs::read_to_string(out.join("outputs.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    let head: Vec<&str> = lines[0].split(',').collect();
    assert_eq!(lines.len(), 4, "{csv}");
    assert_eq!(
        &head[..4],
        ["frame", "absolute", "column.0", "column.1"],
        "{csv}"
    );
    assert!(head.contains(&"column.9") && !head.contains(&"column.10"));
    assert!(head.contains(&"velocity.x") && head.contains(&"vorticity.z"));
    assert_eq!(head.len(), 1 + 1 + 10 + 10 + 1 + 1 + 3 + 3, "{:?}", head);
    let row: Vec<&str> = lines[2].split(',').collect();
    assert_eq!(row.len(), head.len());
    let col = |name: &str| row[head.iter().position(|h| *h == name).unwrap()];
    assert_eq!(col("frame"), "1");
    let top: f64 = col("column.9").parse().unwrap();
    assert!((top - 998.2 * 9.81 * 0.01).abs() < 1e-9, "{top}");
    assert_eq!(col("depth.9").parse::<f64>().unwrap(), 0.18);
}
