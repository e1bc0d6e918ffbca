//! `rw_render`: the reference path tracer, as `rangewalk render` runs it.

use super::args;
use super::error::{guard, Failure};
use super::scene::rw_scene;
use super::status::rw_status;
use super::view::rw_view;
use crate::accel::{self, Backend};
use crate::render::{self, RenderSettings};

/// Path traces `view` of the scene at `time` into `rgb` (`width * height`
/// RGB triples of linear radiance, rows top to bottom), as `rangewalk
/// render --spp <spp> --seed <seed>` does with its other defaults (the
/// default ray engine, unlimited depth, indirect light traced): the same
/// view, time and seed give the same frame. Builds a ray engine per call.
/// Thread-safe: several threads may render one scene at once.
///
/// # Safety
/// `scene` is NULL or a live scene, `view` NULL or readable, `rgb` NULL or
/// `width * height * 3` writable floats.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn rw_render(
    scene: *const rw_scene,
    view: *const rw_view,
    time: f32,
    width: u32,
    height: u32,
    spp: u32,
    seed: u64,
    rgb: *mut f32,
) -> rw_status {
    guard(|| {
        // SAFETY: as the caller promises.
        let scene = &unsafe { args::handle(scene, "scene") }?.scene;
        // SAFETY: as the caller promises.
        let view = unsafe { args::value(view, "view") }?;
        args::out(rgb, "rgb")?;
        args::floats(width, height, 3)?;
        if spp == 0 {
            return Err(Failure::invalid("spp must be at least 1"));
        }
        scene
            .check_time(time)
            .map_err(|e| Failure::invalid(format!("{e:#}")))?;
        let camera = view.camera(width, height)?;
        let backend = Backend::default_available();
        let render_failed = |e| Failure::of(rw_status::RW_RENDER, e);
        let engine =
            accel::build(backend, &scene.geometry(), &scene.at(time)).map_err(render_failed)?;
        let settings = RenderSettings {
            spp,
            max_depth: None,
            seed,
        };
        let (image, _) = render::render(scene, engine.as_ref(), &camera, time, &settings)
            .map_err(render_failed)?;
        let flat: Vec<f32> = image.radiance.iter().flat_map(|c| c.to_array()).collect();
        // SAFETY: `rgb` is not NULL and holds width * height * 3 floats,
        // `flat`'s length (caller's promise).
        unsafe { args::write(rgb, &flat) };
        Ok(())
    })
}
