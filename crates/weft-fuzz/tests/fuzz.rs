//! The fuzzer as CI runs it: the regression corpus (every input that ever panicked, aborted
//! or hung `weft`) replays with no defect, and a fresh seeded batch finds none.
//!
//! These run the test build (overflow checks on), so they also catch arithmetic that
//! overflows on a user's numbers. A longer run is one command:
//! `cargo run --release -p weft-fuzz -- --seconds 3600 --seed N`.

use std::path::Path;
use std::process::Command;

fn fuzz(args: &[&str]) -> (bool, String) {
    let out = tempfile::tempdir().unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_weft-fuzz"))
        .args(["--save", out.path().join("failures").to_str().unwrap()])
        .args(args)
        .output()
        .unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    (o.status.success(), text)
}

#[test]
fn the_regression_corpus_replays_without_a_defect() {
    let corpus = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/fuzz/corpus");
    let n = std::fs::read_dir(&corpus).unwrap().count();
    assert!(n >= 100, "the corpus holds {n} cases");
    let (ok, text) = fuzz(&["--time-limit", "3", "replay", corpus.to_str().unwrap()]);
    assert!(ok, "{text}");
    assert!(text.contains(&format!("{n} cases in")), "{text}");
    assert!(
        text.contains("defects (panic, abort, hang, silent): 0"),
        "{text}"
    );
}

#[test]
fn a_fresh_seeded_batch_finds_no_defect() {
    let (ok, text) = fuzz(&["--cases", "300", "--seed", "20261123", "--time-limit", "5"]);
    assert!(ok, "{text}");
    assert!(text.contains("300 cases in"), "{text}");
    assert!(
        text.contains("defects (panic, abort, hang, silent): 0"),
        "{text}"
    );
}
