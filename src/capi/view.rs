//! Views: a pinhole camera as C describes it, and the named cameras and
//! walk paths of a scene as views.

use std::ffi::c_char;

use glam::Vec3;

use super::args;
use super::error::{guard, Failure};
use super::scene::rw_scene;
use super::status::rw_status;
use crate::camera::Camera;
use crate::scene::CameraDesc;

/// A pinhole camera: where it is, the point it looks at, the image's up
/// direction and the vertical field of view.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct rw_view {
    pub position: [f32; 3],
    pub look_at: [f32; 3],
    pub up: [f32; 3],
    pub vfov_degrees: f32,
}

impl rw_view {
    /// The camera a scene's camera of the same pose gives, refusing what
    /// the scene format refuses.
    pub(crate) fn camera(&self, width: u32, height: u32) -> Result<Camera, Failure> {
        let position = Vec3::from(self.position);
        let look_at = Vec3::from(self.look_at);
        let up = Vec3::from(self.up);
        for (name, v) in [("position", position), ("look_at", look_at), ("up", up)] {
            if !v.is_finite() {
                return Err(Failure::invalid(format!("view `{name}` {v} is not finite")));
            }
        }
        if !(self.vfov_degrees > 0.0 && self.vfov_degrees < 180.0) {
            return Err(Failure::invalid(format!(
                "view `vfov_degrees` {} must lie in (0, 180)",
                self.vfov_degrees
            )));
        }
        let desc = CameraDesc {
            name: "rw_view".into(),
            position,
            direction: (look_at - position).normalize_or_zero(),
            up,
            vfov_deg: self.vfov_degrees,
        };
        desc.perspective(width, height)
            .map_err(|e| Failure::invalid(format!("{e:#}")))
    }

    fn of(desc: &CameraDesc) -> Self {
        Self {
            position: desc.position.into(),
            look_at: (desc.position + desc.direction).into(),
            up: desc.up.into(),
            vfov_degrees: desc.vfov_deg,
        }
    }
}

/// Writes the view `pick` finds by name in the scene into `*out`.
///
/// # Safety
/// As [`rw_scene_camera`].
unsafe fn named(
    scene: *const rw_scene,
    name: *const c_char,
    out: *mut rw_view,
    pick: impl FnOnce(&crate::scene::Scene, &str) -> anyhow::Result<CameraDesc>,
) -> rw_status {
    guard(|| {
        // SAFETY: as the caller promises.
        let scene = unsafe { args::handle(scene, "scene") }?;
        // SAFETY: as the caller promises.
        let name = unsafe { args::string(name, "name") }?;
        args::out(out, "out")?;
        let desc = pick(&scene.scene, &name).map_err(|e| Failure::invalid(format!("{e:#}")))?;
        // SAFETY: checked not NULL; writable by the caller's promise.
        unsafe { out.write(rw_view::of(&desc)) };
        Ok(())
    })
}

/// The scene's camera `name` as a view (`look_at` one unit ahead).
///
/// # Safety
/// `scene` is NULL or a live scene; `name` NULL or a NUL-terminated string;
/// `out` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn rw_scene_camera(
    scene: *const rw_scene,
    name: *const c_char,
    out: *mut rw_view,
) -> rw_status {
    // SAFETY: passed on as the caller promises.
    unsafe { named(scene, name, out, |s, name| s.camera(name).cloned()) }
}

/// The viewer of the scene's walk path `name` at `time` (keys interpolated
/// as `rangewalk walk` does).
///
/// # Safety
/// As [`rw_scene_camera`].
#[no_mangle]
pub unsafe extern "C" fn rw_scene_path_view(
    scene: *const rw_scene,
    name: *const c_char,
    time: f32,
    out: *mut rw_view,
) -> rw_status {
    // SAFETY: passed on as the caller promises.
    unsafe {
        named(scene, name, out, |s, name| {
            anyhow::ensure!(time.is_finite(), "time {time} is not finite");
            Ok(s.path(name)?.at(time))
        })
    }
}
