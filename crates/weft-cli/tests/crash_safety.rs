//! What a run leaves on disk when it is killed, and what `--out` holds.
//!
//! The kill test runs `weft` as a real child process and SIGKILLs it at random moments
//! (seeded, so a failure can be replayed): every file left must be whole (each kind checked
//! by its own structure), and a rerun must resume from the solver's disk checkpoints (the
//! stats say how many frames were restored instead of stepped) and end with the same bytes
//! as a run that was never interrupted.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn weft(cwd: &Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_weft"));
    c.current_dir(cwd)
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    c
}

/// Every file under `dir`, relative path → bytes.
fn files(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    fn walk(base: &Path, d: &Path, out: &mut BTreeMap<PathBuf, Vec<u8>>) {
        for e in std::fs::read_dir(d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(base, &p, out);
            } else {
                let rel = p.strip_prefix(base).unwrap().to_path_buf();
                out.insert(rel, std::fs::read(&p).unwrap());
            }
        }
    }
    let mut out = BTreeMap::new();
    if dir.exists() {
        walk(dir, dir, &mut out);
    }
    out
}

/// True when `bytes` is a whole file of its kind (a truncated one fails).
fn whole(path: &Path, b: &[u8]) -> Result<(), String> {
    let name = path.file_name().unwrap().to_string_lossy().to_string();
    if name.starts_with(".weft-tmp-") {
        // A killed writer's temporary: never a result file (the next write in that
        // directory removes it).
        return Ok(());
    }
    let ends = |tail: &[u8]| b.ends_with(tail);
    let ok = match path.extension().and_then(|e| e.to_str()) {
        Some("png") => b.starts_with(b"\x89PNG\r\n\x1a\n") && ends(b"IEND\xaeB`\x82"),
        Some("json") => serde_json::from_slice::<serde_json::Value>(b).is_ok(),
        Some("csv") => ends(b"\n"),
        Some("obj") => ends(b"\n") && std::str::from_utf8(b).is_ok(),
        Some("usda") => std::str::from_utf8(b).is_ok_and(|t| t.trim_end().ends_with('}')),
        Some("wstate") => b.starts_with(b"WEFTCACHE") && b.len() > 64,
        _ => return Err(format!("unexpected file {}", path.display())),
    };
    if ok {
        Ok(())
    } else {
        Err(format!(
            "{} is not whole ({} bytes)",
            path.display(),
            b.len()
        ))
    }
}

fn run_to_end(cwd: &Path, args: &[&str]) -> serde_json::Value {
    let stats = cwd.join("stats-of-run.json");
    let o = weft(cwd)
        .args(args)
        .args(["--stats-json", stats.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s = std::fs::read(&stats).unwrap();
    std::fs::remove_file(&stats).unwrap();
    serde_json::from_slice(&s).unwrap()
}

fn restored(stats: &serde_json::Value, node: &str) -> u64 {
    stats["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .find(|n| n["node"] == node)
        .and_then(|n| n["restored"].as_u64())
        .unwrap_or(0)
}

#[test]
fn a_killed_run_leaves_whole_files_and_resumes_to_the_same_bytes() {
    let graph = root().join("graphs/cloth_hang.json");
    let graph = graph.to_str().unwrap();
    let args = ["run", graph, "--frames", "0..8", "--out", "out", "--quiet"];
    let tmp = tempfile::tempdir().unwrap();
    let (reference, killed) = (tmp.path().join("ref"), tmp.path().join("killed"));
    std::fs::create_dir_all(&reference).unwrap();
    std::fs::create_dir_all(&killed).unwrap();
    let t0 = Instant::now();
    let stats = run_to_end(&reference, &args);
    let full = t0.elapsed();
    assert_eq!(restored(&stats, "solve"), 0, "a fresh run restores nothing");
    let want = files(&reference.join("out"));

    // Kill it three times at seeded random moments within the run's length, checking what
    // each kill leaves.
    let mut rng = fastrand::Rng::with_seed(20261123);
    for round in 0..3 {
        let mut child = weft(&killed).args(args).spawn().unwrap();
        let at = full.mul_f64(0.1 + 0.8 * rng.f64());
        std::thread::sleep(at);
        let _ = child.kill(); // SIGKILL
        let _ = child.wait();
        for (p, b) in files(&killed.join("out")) {
            if let Err(e) = whole(&p, &b) {
                panic!("after the kill at {at:?} (round {round}): {e}");
            }
        }
    }

    // The kills left some frames' checkpoints on disk; the rerun restores them.
    run_to_end(&killed, &args);
    let got = files(&killed.join("out"));
    let strip = |m: &BTreeMap<PathBuf, Vec<u8>>| -> BTreeMap<PathBuf, Vec<u8>> {
        m.iter()
            .filter(|(p, _)| !p.starts_with("checkpoints") && !p.ends_with("stats.json"))
            .map(|(p, b)| (p.clone(), b.clone()))
            .collect()
    };
    let (w, g) = (strip(&want), strip(&got));
    assert_eq!(
        w.keys().collect::<Vec<_>>(),
        g.keys().collect::<Vec<_>>(),
        "the same files"
    );
    for (p, b) in &w {
        assert!(
            g[p] == *b,
            "{} differs from the uninterrupted run",
            p.display()
        );
    }
    assert!(
        !got.keys()
            .any(|p| p.to_string_lossy().contains(".weft-tmp-")),
        "temporaries of killed writers are removed by the next run"
    );
    // A rerun over finished frames restores every one of them and steps none.
    let again = run_to_end(&killed, &args);
    assert_eq!(restored(&again, "solve"), 8, "{again}");
}

#[test]
fn out_holds_every_file_a_run_writes() {
    // Two runs of every example, each with its own --out, from one working directory: each
    // result tree is complete and nothing is written beside them.
    let tmp = tempfile::tempdir().unwrap();
    let cwd = tmp.path();
    let mut graphs: Vec<PathBuf> = std::fs::read_dir(root().join("graphs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .collect();
    graphs.sort();
    for g in &graphs {
        for out in ["a", "b"] {
            let o = weft(cwd)
                .args([
                    "run",
                    g.to_str().unwrap(),
                    "--frames",
                    "0..1",
                    "--out",
                    out,
                    "--quiet",
                ])
                .output()
                .unwrap();
            assert!(
                o.status.success(),
                "{}: {}",
                g.display(),
                String::from_utf8_lossy(&o.stderr)
            );
        }
    }
    let mut top: Vec<String> = std::fs::read_dir(cwd)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    top.sort();
    assert_eq!(top, ["a", "b"]);
    let (a, b) = (files(&cwd.join("a")), files(&cwd.join("b")));
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    // The previews, USD and OBJ of the examples are there.
    for want in [
        "out/cloth_hang/cloth_hang.usda",
        "out/cloth_hang/preview/frame.0001.png",
        "out/flag_wind/preview/frame.0000.png",
    ] {
        assert!(
            a.contains_key(Path::new(want)),
            "{want} missing: {:?}",
            a.keys().collect::<Vec<_>>()
        );
    }
    // A path that leaves the output directory is refused, naming the node and parameter.
    let o = weft(cwd)
        .args([
            "run",
            root().join("graphs/cloth_hang.json").to_str().unwrap(),
            "--frames",
            "0",
            "--out",
            "c",
            "--set",
            "usd.path=../escaped.usda",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("node 'usd'")
            && err.contains("param 'path'")
            && err.contains("climbs out of the output directory 'c'"),
        "{err}"
    );
    assert!(!cwd.join("escaped.usda").exists());
}
