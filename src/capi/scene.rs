//! The scene handle.

use std::ffi::c_char;

use super::args;
use super::error::{guard, Failure};
use super::status::rw_status;
use crate::scene::Scene;

/// A loaded, validated scene (opaque). Immutable: every call that takes a
/// `const rw_scene *` may run on several threads at once.
pub struct rw_scene {
    pub(crate) scene: Scene,
}

/// Loads and validates the scene description at `path` (TOML, as
/// `rangewalk`'s commands read it); on success `*out` owns the scene, to be
/// released with `rw_scene_free`.
///
/// # Safety
/// `path` is NULL or a NUL-terminated string; `out` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn rw_scene_load(path: *const c_char, out: *mut *mut rw_scene) -> rw_status {
    guard(|| {
        // SAFETY: as the caller promises.
        let path = unsafe { args::path(path, "path") }?;
        args::out(out, "out")?;
        let scene = Scene::load(&path).map_err(|e| Failure::of(rw_status::RW_SCENE, e))?;
        let handle = Box::into_raw(Box::new(rw_scene { scene }));
        // SAFETY: checked not NULL; writable by the caller's promise.
        unsafe { out.write(handle) };
        Ok(())
    })
}

/// Releases a scene; NULL is a no-op. Bakes opened from it do not depend
/// on it.
///
/// # Safety
/// `scene` is NULL or a scene from `rw_scene_load` not yet freed, which no
/// other thread is using.
#[no_mangle]
pub unsafe extern "C" fn rw_scene_free(scene: *mut rw_scene) {
    if !scene.is_null() {
        // SAFETY: made by `Box::into_raw` in `rw_scene_load`, freed once
        // (caller's promise). Dropping a scene cannot panic.
        drop(unsafe { Box::from_raw(scene) });
    }
}
