//! What the integration tests share: the bundled scenes, ray engines over
//! them and the `rangewalk` binary. Each test file that needs them says
//! `mod common;`; a file uses only some, hence `dead_code` allowed.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use rangewalk::accel::{self, Backend, InstancedEngine};
use rangewalk::scene::Scene;

/// The folder of the bundled scenes.
pub fn scenes_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes")
}

/// The scene file of the bundled scene `name`.
pub fn scene_path(name: &str) -> PathBuf {
    scenes_dir().join(name).join("scene.toml")
}

/// [`scene_path`] as a command-line argument.
pub fn scene_arg(name: &str) -> String {
    scene_path(name).to_string_lossy().into_owned()
}

/// The bundled scene `name`; a test cannot go on without it.
pub fn load(name: &str) -> Scene {
    Scene::load(scene_path(name)).unwrap_or_else(|e| panic!("{name}: {e:#}"))
}

/// The scene in `path`.
pub fn load_path(path: &Path) -> Scene {
    Scene::load(path).unwrap_or_else(|e| panic!("{e:#}"))
}

/// A `backend` ray engine over `scene` posed at the animation's start.
pub fn engine(scene: &Scene, backend: Backend) -> Box<dyn InstancedEngine> {
    accel::build(backend, &scene.geometry(), &scene.at(scene.animation.start)).unwrap()
}

/// The default ray engine over `scene` posed at time `t`.
pub fn engine_at(scene: &Scene, t: f32) -> Box<dyn InstancedEngine> {
    accel::build(
        Backend::default_available(),
        &scene.geometry(),
        &scene.at(t),
    )
    .unwrap()
}

/// The `rangewalk` binary, to be given arguments and run.
pub fn command() -> Command {
    Command::new(env!("CARGO_BIN_EXE_rangewalk"))
}

/// `rangewalk args`, run to its end.
pub fn rangewalk(args: &[&str]) -> Output {
    command().args(args).output().expect("running rangewalk")
}
