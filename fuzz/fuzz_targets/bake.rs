#![no_main]
//! The bake reader on one input (see rangewalk_fuzz::bake).

use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;
use rangewalk::scene::Scene;

/// The scene's folder and the bake's: the scene stays loaded.
static STATE: OnceLock<(tempfile::TempDir, Scene, tempfile::TempDir)> = OnceLock::new();

fuzz_target!(|data: &[u8]| {
    let (_, scene, bake) = STATE.get_or_init(|| {
        let scene_dir = tempfile::tempdir().expect("a scratch folder");
        let scene = rangewalk_fuzz::bake_scene(scene_dir.path());
        (scene_dir, scene, tempfile::tempdir().expect("a scratch folder"))
    });
    let _ = rangewalk_fuzz::bake(bake.path(), scene, data);
});
