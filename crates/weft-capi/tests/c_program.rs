//! The C example (`tests/c/weft_example.c`, which uses every call of `include/weft.h`) is
//! compiled with `-Wall -Wextra -Werror -pedantic` against this crate's shared library and
//! run on `tests/c/host_scene.json`; its own checks must all hold, and the positions it
//! baked through the C ABI must equal, bit for bit, those of the same graph driven from
//! Rust with the same host data (the ABI copies f64s and adds no arithmetic).

use std::path::{Path, PathBuf};
use std::process::Command;
use weft_graph::{Context, Value};
use weft_scene::{Curves, Mesh};

const FRAMES: i64 = 4;

/// The directory holding `libweft_capi.so` built for this test run (cargo builds the
/// library's cdylib with the test's profile, next to the test binary's `deps`).
fn library_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("test binary path");
    let deps = exe.parent().expect("deps directory");
    for dir in [deps, deps.parent().expect("profile directory")] {
        if dir.join("libweft_capi.so").exists() {
            return dir.to_path_buf();
        }
    }
    panic!("libweft_capi.so not found beside {}", deps.display());
}

/// The box the C program feeds at `frame` (the same arithmetic as its `box_at`).
fn box_at(frame: i64) -> Mesh {
    let y = 0.1 + 0.01 * frame as f64;
    let positions = (0..8)
        .map(|k| {
            [
                if k & 1 != 0 { 0.1 } else { -0.1 },
                y + if k & 2 != 0 { 0.1 } else { -0.1 },
                if k & 4 != 0 { 0.1 } else { -0.1 },
            ]
        })
        .collect();
    let faces: [u32; 36] = [
        0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5, 0, 1, 5, 0, 5, 4, 2, 6, 7, 2, 7, 3, 0, 2, 3, 0, 3, 1,
        4, 5, 7, 4, 7, 6,
    ];
    Mesh {
        positions,
        triangles: faces.chunks(3).map(|c| [c[0], c[1], c[2]]).collect(),
    }
}

/// The strands the C program feeds.
fn strands() -> Curves {
    let mut positions = Vec::new();
    for c in 0..2 {
        for k in 0..5 {
            positions.push([
                if c == 0 { -0.05 } else { 0.05 },
                0.6 - 0.025 * k as f64,
                0.025 * k as f64,
            ]);
        }
    }
    Curves {
        positions,
        offsets: vec![0, 5, 10],
    }
}

/// The cloth's and the hair's positions at frames 1..=FRAMES with the graph driven from
/// Rust as the C program drives it.
fn baked_in_rust(graph: &Path) -> Vec<f64> {
    let mut g = weft_graph::load_path(&weft_nodes::registry(), graph).expect("graph loads");
    g.set_param("damping", "coefficient", 0.2.into()).unwrap();
    g.set_param("solve", "substeps", 2.into()).unwrap();
    for f in 0..=FRAMES {
        g.feed("boxmesh", "mesh", Some(f), Value::new(box_at(f)))
            .unwrap();
    }
    g.feed("tuft", "curves", None, Value::new(strands()))
        .unwrap();
    let mut out = Vec::new();
    for f in 1..=FRAMES {
        let v = g.pull("scene", Context::at(f, 24.0)).expect("frame runs");
        let scene = v.get::<weft_nodes::physics::Scene>().expect("a scene");
        for name in ["cloth", "hair"] {
            let e = scene.iter().find(|e| e.name == name).expect("element");
            out.extend(e.geometry.positions().iter().flatten());
        }
    }
    out
}

#[test]
fn the_c_example_uses_every_call_and_bakes_what_rust_bakes() {
    let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let lib = library_dir();
    let tmp = tempfile::tempdir().unwrap();
    let exe = tmp.path().join("weft_example");
    let compiled = Command::new(std::env::var("CC").unwrap_or_else(|_| "cc".into()))
        .args([
            "-std=c11",
            "-Wall",
            "-Wextra",
            "-Werror",
            "-pedantic",
            "-O1",
            "-I",
        ])
        .arg(crate_dir.join("include"))
        .arg(crate_dir.join("tests/c/weft_example.c"))
        .arg("-L")
        .arg(&lib)
        .arg(format!("-Wl,-rpath,{}", lib.display()))
        .args(["-lweft_capi", "-lm", "-o"])
        .arg(&exe)
        .output()
        .expect("a C compiler (cc) runs");
    assert!(
        compiled.status.success(),
        "the C example does not compile cleanly:\n{}",
        String::from_utf8_lossy(&compiled.stderr)
    );
    let graph = crate_dir.join("tests/c/host_scene.json");
    let bin = tmp.path().join("baked.bin");
    // Cargo's LD_LIBRARY_PATH for tests may name target/debug first, where a `cargo build`
    // leaves an older copy of the library; this run must load the one built for the test.
    let ran = Command::new(&exe)
        .arg(&graph)
        .arg(&bin)
        .env("LD_LIBRARY_PATH", &lib)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&ran.stdout);
    assert!(
        ran.status.success(),
        "the C example failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&ran.stderr)
    );
    assert!(stdout.contains("all checks passed"), "{stdout}");
    let bytes = std::fs::read(&bin).unwrap();
    let from_c: Vec<f64> = bytes
        .chunks_exact(8)
        .map(|b| f64::from_le_bytes(b.try_into().unwrap()))
        .collect();
    let from_rust = baked_in_rust(&graph);
    // 25 cloth and 10 hair vertices, 3 coordinates, 4 frames.
    assert_eq!(from_c.len(), (25 + 10) * 3 * FRAMES as usize);
    assert_eq!(from_c.len(), from_rust.len());
    for (k, (c, r)) in from_c.iter().zip(&from_rust).enumerate() {
        assert_eq!(
            c.to_bits(),
            r.to_bits(),
            "coordinate {k}: C {c} against Rust {r}"
        );
    }
    // The host's strands are what the solver simulated: at the last frame their roots (held,
    // with the direction clamped there) are where the host put them, and their tips fell.
    let last = &from_c[from_c.len() - 30..];
    let fed = strands().positions;
    for v in [0, 5] {
        assert_eq!(
            &last[3 * v..3 * v + 3],
            &fed[v][..],
            "hair vertex {v} is held"
        );
    }
    assert!(last[3 * 4 + 1] < fed[4][1], "the first strand's tip fell");
}
