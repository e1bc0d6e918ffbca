#![no_main]
//! The EXR range-image reader on one input (see rangewalk_fuzz::exr).

use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;

static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();

fuzz_target!(|data: &[u8]| {
    let dir = DIR.get_or_init(|| tempfile::tempdir().expect("a scratch folder"));
    let _ = rangewalk_fuzz::exr(dir.path(), data);
});
