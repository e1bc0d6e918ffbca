//! Every input the fuzz targets keep (`tests/fuzz-regressions/<target>/`:
//! the minimized corpus and each input that once crashed), replayed
//! through the same calls the fuzzer made (`fuzz/src/lib.rs`, included
//! here), on the stable toolchain. Each must come back as `Ok` or a
//! clear `Err`: a panic fails the test, naming the file.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};

#[path = "../fuzz/src/lib.rs"]
#[allow(dead_code)]
mod harness;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz-regressions")
}

/// What the saved inputs of `target` gave: (file, outcome) per input,
/// where a panic's message is the outcome `Err("panicked: ...")`.
fn replay(
    target: &str,
    mut run: impl FnMut(&Path, &[u8]) -> Result<(), String>,
) -> Vec<(PathBuf, Result<(), String>, bool)> {
    let mut out = Vec::new();
    for kind in ["corpus", "crashes"] {
        for file in harness::saved_inputs(&root().join(target), kind) {
            let data = std::fs::read(&file).unwrap();
            let dir = tempfile::tempdir().unwrap();
            let outcome = catch_unwind(AssertUnwindSafe(|| run(dir.path(), &data)));
            let panicked = outcome.is_err();
            let result = outcome.unwrap_or_else(|p| {
                let msg = p
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default();
                Err(format!("panicked: {msg}"))
            });
            out.push((file, result, panicked));
        }
    }
    out
}

/// No input panics; some read without error, so that the target still
/// reaches past its first check (a harness whose inputs all fail early
/// would replay nothing worth replaying); every crash input is refused
/// with a message.
fn check(target: &str, results: &[(PathBuf, Result<(), String>, bool)]) {
    assert!(
        results.len() >= 3,
        "{target}: only {} saved input(s)",
        results.len()
    );
    let panics: Vec<String> = results
        .iter()
        .filter(|r| r.2)
        .map(|(f, r, _)| format!("{}: {}", f.display(), r.as_ref().unwrap_err()))
        .collect();
    assert!(panics.is_empty(), "{target}: {}", panics.join("\n"));
    let some_errors: Vec<&String> = results
        .iter()
        .filter_map(|r| r.1.as_ref().err())
        .take(3)
        .collect();
    assert!(
        results.iter().any(|r| r.1.is_ok()),
        "{target}: no saved input reads without error, e.g. {some_errors:#?}"
    );
    for (file, result, _) in results {
        if file.parent().is_some_and(|d| d.ends_with("crashes")) {
            let err = result.as_ref().err();
            assert!(
                err.is_some_and(|e| !e.is_empty()),
                "{}: once crashed, now {result:?}",
                file.display()
            );
        }
    }
}

#[test]
fn scene_inputs_load_or_fail_cleanly() {
    check("scene", &replay("scene", harness::scene));
}

#[test]
fn exr_inputs_read_or_fail_cleanly() {
    check("exr", &replay("exr", harness::exr));
}

#[test]
fn bake_inputs_open_or_fail_cleanly() {
    let scene_dir = tempfile::tempdir().unwrap();
    let scene = harness::bake_scene(scene_dir.path());
    check(
        "bake",
        &replay("bake", |dir, data| harness::bake(dir, &scene, data)),
    );
}
